"""Whole-command timing: ``python -m suite run CATALOG --out DIR --jobs N [--no-log]`` as a
user runs it, in a fresh process, and what its run directories say.

Per command (:class:`CommandTiming`):

* ``wall_s``: the command's wall time [s], process start, imports, SUMO start, every run,
  every output (parquet, Rerun logs, reports) included; ``realtime_factor`` = the
  catalog's simulated seconds / ``wall_s``;
* ``runs_span_s``: from the first run's start (its SUMO route file written) to the last
  run's end (its run.json written), i.e. the scenario phase without the command's start
  and its reports; ``runs_realtime_factor`` over that span; ``before_runs_s`` (process
  start, imports, catalog checks and the workers' preload, until the first run starts)
  and ``after_runs_s`` (the last run's end to the command's: the reports, the exit) are
  the rest of ``wall_s``;
* per run: wall (build, loop, judging, writing, Rerun log), its stage times, peak RSS of
  its process [MB], status;
* per-step times pooled over the runs (trace columns): ``controller_step`` = the
  controller's ``step`` alone (``controller_s - obstacles_s``), ``behaviour_and_controller``
  = the trace's ``controller_s`` (what ``step_ms_*`` of the metrics is), ``behaviour`` and
  ``dynamics`` (plant + world step), p50/p95/p99/max [us].
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


@dataclass(frozen=True)
class StepStats:
    """Percentiles [us] of per-step times pooled over the runs; ``n`` samples."""

    n: int
    p50_us: float
    p95_us: float
    p99_us: float
    max_us: float

    def __post_init__(self) -> None:
        if self.n < 0:
            raise ValueError(f"n must be >= 0, got {self.n}")

    @classmethod
    def of(cls, times_s: np.ndarray) -> StepStats:
        t = np.asarray(times_s, dtype=np.float64)
        t = t[np.isfinite(t)] * 1e6
        if t.size == 0:
            return cls(0, float("nan"), float("nan"), float("nan"), float("nan"))
        p50, p95, p99 = np.percentile(t, [50, 95, 99])
        return cls(int(t.size), float(p50), float(p95), float(p99), float(t.max()))


@dataclass(frozen=True)
class RunFigures:
    """One run: wall [s] of the whole run and of its recorded stages (behaviour,
    controller, dynamics summed over its steps), simulated time [s], peak RSS of its
    process [MB], Rerun log time [s]."""

    scenario: str
    status: str
    wall_s: float
    stages_s: float
    sim_s: float
    peak_rss_mb: float
    log_s: float

    def __post_init__(self) -> None:
        if self.wall_s < 0 or self.sim_s < 0:
            raise ValueError(f"{self.scenario}: negative wall_s or sim_s")

    @property
    def realtime_factor(self) -> float:
        return self.sim_s / self.wall_s if self.wall_s > 0 else float("nan")


@dataclass(frozen=True)
class CommandTiming:
    """One ``hwyeval run`` command (module docstring); times in seconds."""

    jobs: int
    log: bool
    wall_s: float
    runs_span_s: float
    sim_s: float
    exit_code: int
    runs: tuple[RunFigures, ...]
    steps: dict[str, StepStats] = field(default_factory=dict)
    before_runs_s: float = float("nan")
    after_runs_s: float = float("nan")

    def __post_init__(self) -> None:
        if self.jobs < 1:
            raise ValueError(f"jobs must be >= 1, got {self.jobs}")
        if self.wall_s <= 0:
            raise ValueError(f"wall_s must be > 0, got {self.wall_s}")

    @property
    def realtime_factor(self) -> float:
        """Simulated seconds over the whole command's wall time."""
        return self.sim_s / self.wall_s

    @property
    def runs_realtime_factor(self) -> float:
        """Simulated seconds over the scenario phase."""
        return self.sim_s / self.runs_span_s if self.runs_span_s > 0 else float("nan")

    def as_dict(self) -> dict[str, Any]:
        return {"jobs": self.jobs, "log": self.log, "wall_s": self.wall_s,
                "runs_span_s": self.runs_span_s, "before_runs_s": self.before_runs_s,
                "after_runs_s": self.after_runs_s, "sim_s": self.sim_s,
                "exit_code": self.exit_code, "realtime_factor": self.realtime_factor,
                "runs_realtime_factor": self.runs_realtime_factor,
                "runs": [{**r.__dict__, "realtime_factor": r.realtime_factor}
                         for r in self.runs],
                "steps_us": {k: v.__dict__ for k, v in self.steps.items()}}


def run_command(catalog: Path, out: Path, jobs: int, log: bool) -> CommandTiming:
    """Run ``catalog`` through the command line into ``out`` (must not exist) and read
    back what it wrote."""
    if out.exists():
        raise FileExistsError(f"{out} exists: the bench runs into fresh folders")
    args = [sys.executable, "-m", "suite", "run", str(catalog), "--out", str(out),
            "--jobs", str(jobs)] + ([] if log else ["--no-log"])
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    epoch0 = time.time()  # the run files' mtimes are on this clock
    t0 = time.perf_counter()
    proc = subprocess.run(args, cwd=ROOT, env=env, capture_output=True, text=True,
                          check=False)
    wall = time.perf_counter() - t0
    if proc.returncode not in (0, 1):
        raise RuntimeError(f"{' '.join(args)} exited {proc.returncode}:\n{proc.stderr[-2000:]}")
    runs, steps, (first_start, last_end) = _read_runs(out)
    span = last_end - first_start if runs else 0.0
    before = first_start - epoch0 if runs else float("nan")
    after = epoch0 + wall - last_end if runs else float("nan")
    return CommandTiming(jobs=jobs, log=log, wall_s=wall, runs_span_s=span,
                         sim_s=sum(r.sim_s for r in runs), exit_code=proc.returncode,
                         runs=tuple(runs), steps=steps, before_runs_s=before,
                         after_runs_s=after)


def _read_runs(out: Path) -> tuple[list[RunFigures], dict[str, StepStats],
                                   tuple[float, float]]:
    """The runs, their pooled step times and (first run's start, last run's end) as
    epoch seconds (file mtimes; nan, nan without runs)."""
    import pyarrow.parquet as pq

    runs: list[RunFigures] = []
    pools: dict[str, list[np.ndarray]] = {"controller_step": [], "behaviour_and_controller": [],
                                          "behaviour": [], "dynamics": []}
    starts, ends = [], []
    for run_json in sorted(out.glob("*/run.json")):
        run_dir = run_json.parent
        info = json.loads(run_json.read_text())
        outcome = info["outcome"]
        status = (info.get("verdict") or {}).get("status", outcome["end"])
        cols = pq.read_table(run_dir / "trace.parquet",
                             columns=["obstacles_s", "controller_s", "sumo_s"]).to_pydict()
        beh = np.asarray(cols["obstacles_s"], dtype=np.float64)
        both = np.asarray(cols["controller_s"], dtype=np.float64)
        dyn = np.asarray(cols["sumo_s"], dtype=np.float64)
        pools["controller_step"].append(both - beh)
        pools["behaviour_and_controller"].append(both)
        pools["behaviour"].append(beh)
        pools["dynamics"].append(dyn)
        log_s = outcome.get("log_s")
        runs.append(RunFigures(
            scenario=run_dir.name, status=str(status), wall_s=float(outcome["wall_s"]),
            stages_s=float(np.nansum(both) + np.nansum(dyn)), sim_s=float(outcome["sim_time_s"]),
            peak_rss_mb=float(outcome["peak_rss_mb"]),
            log_s=float(log_s) if isinstance(log_s, int | float) else float("nan")))
        routes = run_dir / "sumo" / "routes.rou.xml"
        starts.append((routes if routes.exists() else run_json).stat().st_mtime)
        ends.append(run_json.stat().st_mtime)
    steps = {k: StepStats.of(np.concatenate(v)) for k, v in pools.items() if v}
    bounds = (min(starts), max(ends)) if runs else (float("nan"), float("nan"))
    return runs, steps, bounds
