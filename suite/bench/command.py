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
* per run: ``wall_s`` (results.csv's: from the run's start to its loop's end and SUMO's
  close: building and the loop; judging, the files, the Rerun log and run.json come
  after it), its stage times, peak RSS of its process [MB], status, its step p99 and
  max (results.csv's ``step_ms_p99``, ``step_ms_max``: behaviour + controller), and
  when it ran on the wall clock: its loop's end (SUMO's output files, written at its
  close), its start (that minus ``wall_s``) and its end (run.json written);
* ``lines``: every line the command printed (stdout and stderr), stamped when the bench
  read it, for :mod:`suite.bench.account`; ``manifest_epoch_s`` when the command wrote
  its manifest last (after the reports);
* per-step times pooled over the runs (trace columns): ``controller_step`` = the
  controller's ``step`` alone (``controller_s - obstacles_s``), ``behaviour_and_controller``
  = the trace's ``controller_s`` (what ``step_ms_*`` of the metrics is), ``behaviour`` and
  ``dynamics`` (plant + world step), p50/p95/p99/max [us].
"""

from __future__ import annotations

import csv
import json
import math
import os
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from suite.exec.worker import SCENARIO_CPUS_ENV

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
    """One run: wall [s] of the run (results.csv's ``wall_s``: build and loop) and of its
    recorded stages (behaviour, controller, dynamics summed over its steps), simulated
    time [s], peak RSS of its process [MB], Rerun log time [s], its behaviour +
    controller step p99 and max and its C/GMRES outer update's p99 [ms] (results.csv),
    the controller's step alone p99 [ms] (its trace), and on the wall clock [epoch s] its
    start, its loop's end and its end (run.json written); NaN where unknown."""

    scenario: str
    status: str
    wall_s: float
    stages_s: float
    sim_s: float
    peak_rss_mb: float
    log_s: float
    step_p99_ms: float = math.nan
    step_max_ms: float = math.nan
    start_epoch_s: float = math.nan
    loop_end_epoch_s: float = math.nan
    end_epoch_s: float = math.nan
    outer_p99_ms: float = math.nan
    controller_p99_ms: float = math.nan

    def __post_init__(self) -> None:
        if self.wall_s < 0 or self.sim_s < 0:
            raise ValueError(f"{self.scenario}: negative wall_s or sim_s")
        if self.end_epoch_s < self.loop_end_epoch_s - 0.01:  # file-time granularity
            raise ValueError(f"{self.scenario}: its run.json predates its loop's end")

    @property
    def span_s(self) -> float:
        """From the run's start to its run.json [s] (NaN where unknown)."""
        return self.end_epoch_s - self.start_epoch_s

    @property
    def after_loop_s(self) -> float:
        """After ``wall_s``: judging, the files, the Rerun log, run.json [s]."""
        return self.end_epoch_s - self.loop_end_epoch_s

    @property
    def realtime_factor(self) -> float:
        return self.sim_s / self.wall_s if self.wall_s > 0 else float("nan")

    @property
    def step_p99_over_outer_p99(self) -> float:
        """Behaviour + controller step p99 over the outer update's p99 of this run (NaN
        without both)."""
        ok = self.outer_p99_ms > 0 and math.isfinite(self.step_p99_ms)
        return self.step_p99_ms / self.outer_p99_ms if ok else float("nan")

    @property
    def controller_p99_over_outer_p99(self) -> float:
        """The controller's step alone (the trace's ``controller_s - obstacles_s``, no
        behaviour): its p99 over the outer update's p99 of this run (NaN without both).
        Beside :attr:`step_p99_over_outer_p99` it tells the behaviour's share of the tail
        from the controller's."""
        ok = self.outer_p99_ms > 0 and math.isfinite(self.controller_p99_ms)
        return self.controller_p99_ms / self.outer_p99_ms if ok else float("nan")


@dataclass(frozen=True)
class StampedLine:
    """A line the command printed, ``at_s`` seconds after it was started."""

    at_s: float
    text: str

    def __post_init__(self) -> None:
        if self.at_s < 0:
            raise ValueError(f"at_s must be >= 0, got {self.at_s}")


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
    start_epoch_s: float = float("nan")
    manifest_epoch_s: float = float("nan")
    lines: tuple[StampedLine, ...] = ()

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
                "start_epoch_s": self.start_epoch_s, "manifest_epoch_s": self.manifest_epoch_s,
                "lines": [line.__dict__ for line in self.lines],
                "runs": [{**r.__dict__, "realtime_factor": r.realtime_factor}
                         for r in self.runs],
                "steps_us": {k: v.__dict__ for k, v in self.steps.items()}}


def run_command(catalog: Path, out: Path, jobs: int, log: bool,
                cpus: frozenset[int] | None = None,
                scenario_cpus: frozenset[int] | None = None) -> CommandTiming:
    """Run ``catalog`` through the command line into ``out`` (must not exist) and read
    back what it wrote; every line it prints is stamped as it arrives. ``cpus``: pin the
    command and every process it starts to these CPUs (``taskset``'s affinity);
    ``scenario_cpus``: the scenario processes pin themselves to these instead
    (:data:`suite.exec.worker.SCENARIO_CPUS_ENV`)."""
    if out.exists():
        raise FileExistsError(f"{out} exists: the bench runs into fresh folders")
    args = [sys.executable, "-m", "suite", "run", str(catalog), "--out", str(out),
            "--jobs", str(jobs)] + ([] if log else ["--no-log"])
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    if scenario_cpus:
        env[SCENARIO_CPUS_ENV] = ",".join(str(c) for c in sorted(scenario_cpus))
    epoch0 = time.time()  # the run files' mtimes are on this clock
    t0 = time.perf_counter()
    lines: list[StampedLine] = []
    def pin() -> None:  # in the child, before it runs Python: its children inherit it
        if cpus:
            os.sched_setaffinity(0, cpus)

    with subprocess.Popen(args, cwd=ROOT, env=env, stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True, bufsize=1,
                          preexec_fn=pin if cpus else None) as proc:
        if proc.stdout is None:  # not with stdout=PIPE
            raise RuntimeError("the command's output pipe is missing")
        for text in proc.stdout:
            lines.append(StampedLine(time.perf_counter() - t0, text.rstrip("\n")))
        code = proc.wait()
    wall = time.perf_counter() - t0
    if code not in (0, 1):
        tail = "\n".join(line.text for line in lines[-30:])
        raise RuntimeError(f"{' '.join(args)} exited {code}:\n{tail}")
    runs, steps = _read_runs(out)
    first_start = min(r.start_epoch_s for r in runs) if runs else math.nan
    last_end = max(r.end_epoch_s for r in runs) if runs else math.nan
    span = last_end - first_start if runs else 0.0
    manifest = out / "manifest.json"
    return CommandTiming(jobs=jobs, log=log, wall_s=wall, runs_span_s=span,
                         sim_s=sum(r.sim_s for r in runs), exit_code=code,
                         runs=tuple(runs), steps=steps, before_runs_s=first_start - epoch0,
                         after_runs_s=epoch0 + wall - last_end, start_epoch_s=epoch0,
                         manifest_epoch_s=(manifest.stat().st_mtime if manifest.exists()
                                           else math.nan),
                         lines=tuple(lines))


@dataclass(frozen=True)
class _Row:
    """results.csv's step times of one run [ms]."""

    step_p99_ms: float
    step_max_ms: float
    outer_p99_ms: float


def _results_rows(out: Path) -> dict[str, _Row]:
    """results.csv's ``step_ms_p99``, ``step_ms_max`` and ``outer_ms_p99`` by scenario
    (none without it)."""
    path = out / "results.csv"
    if not path.exists():
        return {}

    def num(text: str | None) -> float:
        try:
            return float(text) if text else math.nan
        except ValueError:
            return math.nan

    with path.open(newline="") as f:
        return {row["scenario"]: _Row(num(row.get("step_ms_p99")), num(row.get("step_ms_max")),
                                      num(row.get("outer_ms_p99")))
                for row in csv.DictReader(f)}


def _when(run_dir: Path, wall_s: float) -> tuple[float, float, float]:
    """(start, loop end, end) of a run on the wall clock [epoch s]: the loop ended when
    SUMO wrote its outputs at its close (else: when the route file was written, the
    start being then), the run started ``wall_s`` before, it ended with its run.json."""
    end = (run_dir / "run.json").stat().st_mtime
    closed = [p.stat().st_mtime for p in (run_dir / "sumo").glob("*.xml")
              if p.name != "routes.rou.xml"]
    if closed:
        loop_end = max(closed)
        return loop_end - wall_s, loop_end, end
    routes = run_dir / "sumo" / "routes.rou.xml"
    start = routes.stat().st_mtime if routes.exists() else end - wall_s
    return start, min(start + wall_s, end), end


def _read_runs(out: Path) -> tuple[list[RunFigures], dict[str, StepStats]]:
    """The runs (their wall-clock times from file mtimes) and their pooled step times."""
    import pyarrow.parquet as pq

    runs: list[RunFigures] = []
    pools: dict[str, list[np.ndarray]] = {"controller_step": [], "behaviour_and_controller": [],
                                          "behaviour": [], "dynamics": []}
    rows = _results_rows(out)
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
        alone = both - beh
        controller_p99_ms = StepStats.of(alone).p99_us * 1e-3
        pools["controller_step"].append(alone)
        pools["behaviour_and_controller"].append(both)
        pools["behaviour"].append(beh)
        pools["dynamics"].append(dyn)
        log_s = outcome.get("log_s")
        wall_s = float(outcome["wall_s"])
        start, loop_end, end = _when(run_dir, wall_s)
        row = rows.get(run_dir.name, _Row(math.nan, math.nan, math.nan))
        runs.append(RunFigures(
            scenario=run_dir.name, status=str(status), wall_s=wall_s,
            stages_s=float(np.nansum(both) + np.nansum(dyn)), sim_s=float(outcome["sim_time_s"]),
            peak_rss_mb=float(outcome["peak_rss_mb"]),
            log_s=float(log_s) if isinstance(log_s, int | float) else float("nan"),
            step_p99_ms=row.step_p99_ms, step_max_ms=row.step_max_ms, start_epoch_s=start,
            loop_end_epoch_s=loop_end, end_epoch_s=end, outer_p99_ms=row.outer_p99_ms,
            controller_p99_ms=controller_p99_ms))
    steps = {k: StepStats.of(np.concatenate(v)) for k, v in pools.items() if v}
    return runs, steps
