"""``hwyeval bench``: the speed targets of issues 11, 25 and 36, measured in one run and
judged (:mod:`suite.bench.targets`), with the machine's load at its start and end (these
machines are shared: every ratio is taken within this one invocation). docs/bench.md
says how to read it.

Phases (:func:`run_all`, a progress line each, with the time since the start):

1. ``controller``: the two-loop controller on the plant-only harness
   (:func:`suite.bench.controller.run_benchmark`): one C/GMRES outer update and the whole
   control step, p50/p95/p99/max;
2. ``solvers``: C/GMRES vs the Ipopt NMPC on the same OCP, Ipopt warm-started with the
   exact Hessian and MUMPS (:func:`suite.bench.solvers.solver_comparison`): p50 and
   variance ratios, raw and per-update minimum over repeats (not measured without
   CasADi);
3. ``extrapolation``: the multi-rate world's extrapolation error against SUMO at the
   control rate (:mod:`suite.bench.multirate`; not with ``--quick``);
4. ``commands``: whole ``hwyeval run`` commands in fresh processes
   (:mod:`suite.bench.command`) after an untimed warm-up: the dense target
   (:func:`suite.bench.catalogs.dense_catalog`: two_loop, 3 lanes, 2400 veh/h, a stalled
   car) with ``seeds`` traffic seeds at ``--jobs 1`` with logs (the one-run figures,
   :class:`suite.bench.figures.DenseRunFigures`); the floor study on the same catalog
   (:mod:`suite.bench.floor`: the Python between SUMO's step and the C/GMRES kernel);
   the dense catalog of ``catalog_runs`` runs at ``--jobs 1`` and ``--jobs 2`` with logs
   (the whole command, its wall-time account and the scaling,
   :class:`suite.bench.figures.CommandFigures`); without ``--quick`` also the dense
   seeds without logs (the logging overhead) and the 12-scenario matrix.

:func:`summary_lines` prints the figures and one line per target: met or not.
"""

from __future__ import annotations

import importlib.util
import json
import os
import platform
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from suite.bench.catalogs import MATRIX_CATALOG, dense_catalog
from suite.bench.command import CommandTiming, run_command
from suite.bench.figures import CommandFigures, DenseRunFigures, FloorFigures, measured_targets
from suite.bench.isolation import isolate
from suite.bench.summary import summary_lines
from suite.bench.targets import TARGETS, Measured, TargetResult, all_met, judge

__all__ = ["QUICK", "TARGETS", "BenchOptions", "BenchResult", "Progress", "run_all",
           "summary_lines", "to_json"]

WARMUP_CATALOG = """
[defaults]
controller = "two_loop"
duration_s = 1.0
step_s = 0.02

[[scenario]]
name = "warmup"
net = "straight_3lane"
ego = { lane = 1, pos_m = 100.0, speed_mps = 25.0 }
traffic = { vehicles_per_hour = 1200, seed = 1 }
"""


@dataclass(frozen=True)
class BenchOptions:
    """What one bench run measures: ``seeds`` dense runs of ``run_duration_s`` (the
    one-run figures and the floor study), ``catalog_runs`` of them for the whole command
    (``--jobs 1`` and ``--jobs 2``; the ``seeds`` command is reused when equal), the
    solver comparison's repeats and duration; ``quick`` leaves out the parts no target
    is judged on (extrapolation, the no-log command, the matrix); without
    ``include_runner`` no SUMO (phases 3, 4), without ``include_ipopt`` no phase 2;
    ``isolated``: the dense runs pinned to one core with the other load listed
    (:mod:`suite.bench.isolation`), and the step max judged."""

    seeds: int = 4
    catalog_runs: int = 24
    run_duration_s: float = 40.0
    solver_repeats: int = 5
    solver_duration_s: float = 6.0
    quick: bool = False
    include_runner: bool = True
    include_ipopt: bool = True
    isolated: bool = False

    def __post_init__(self) -> None:
        for name in ("seeds", "catalog_runs", "solver_repeats"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        for name in ("run_duration_s", "solver_duration_s"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")

    @property
    def judged(self) -> bool:
        """Whether the targets are judged (not for the controller part alone)."""
        return self.include_runner or self.include_ipopt

    def phases(self) -> int:
        """How many phases :func:`run_all` announces."""
        n = 1 + int(self.include_ipopt)
        if self.include_runner:
            n += 4 + int(self.catalog_runs != self.seeds)  # warm-up, dense, floor, [M], jobs 2
            n += 0 if self.quick else 3  # extrapolation, no log, matrix
        return n


QUICK = BenchOptions(seeds=2, catalog_runs=2, run_duration_s=4.0, solver_repeats=1,
                     solver_duration_s=2.0, quick=True)


class Progress:
    """``bench [  12.3 s] 3/9 what``: a line per phase, through ``print_fn`` (flushed by
    the caller's printer), the time since the bench started."""

    def __init__(self, print_fn: Callable[[str], None] | None, total: int) -> None:
        self.print_fn = print_fn
        self.total = total
        self.done = 0
        self.t0 = time.perf_counter()

    def elapsed_s(self) -> float:
        return time.perf_counter() - self.t0

    def _say(self, text: str) -> None:
        if self.print_fn is not None:
            self.print_fn(f"bench [{self.elapsed_s():7.1f} s] {text}")

    def phase(self, text: str) -> None:
        self.done += 1
        self._say(f"{self.done}/{self.total} {text} ...")

    def note(self, text: str) -> None:
        self._say(f"    {text}")


@dataclass(frozen=True)
class BenchResult:
    """One bench run: ``figures`` (every part, JSON-ready, module docstring), issue 25's
    typed figures (None where not measured) and the targets' results (empty when the
    targets are not judged: the controller part alone)."""

    options: BenchOptions
    figures: dict[str, Any]
    dense: DenseRunFigures | None = None
    floor: FloorFigures | None = None
    command: CommandFigures | None = None
    results: tuple[TargetResult, ...] = field(default_factory=tuple)

    @property
    def all_met(self) -> bool:
        return all_met(self.results)


def _load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def _controller_timing() -> dict[str, Any]:
    from suite.bench.controller import run_benchmark

    res = run_benchmark(print_fn=None)
    return {k: res[k] for k in ("outer_update", "control_step", "outer_loop_per_step",
                                "inner_loop_per_step", "residual_max", "fallbacks")}


def _solvers(repeats: int, duration_s: float) -> dict[str, Any]:
    if importlib.util.find_spec("casadi") is None:
        return {"skipped": "casadi not installed (pip install 'hwyeval[baselines]')"}
    from suite.bench.solvers import solver_comparison

    return solver_comparison(repeats=repeats, duration_s=duration_s)


def _extrapolation() -> dict[str, Any]:
    from suite.bench.multirate import extrapolation_study

    return extrapolation_study()


def _timed(progress: Progress, label: str, catalog: Path, out: Path, jobs: int,
           log: bool, cpus: tuple[frozenset[int], frozenset[int]] | None = None
           ) -> CommandTiming:
    t = run_command(catalog, out, jobs=jobs, log=log, cpus=cpus[0] if cpus else None,
                    scenario_cpus=cpus[1] if cpus else None)
    progress.note(f"{label}: {t.sim_s:.0f} s simulated in {t.wall_s:.2f} s "
                  f"(x{t.realtime_factor:.1f}), exit {t.exit_code}")
    return t


@dataclass(frozen=True)
class _CommandsPart:
    figures: dict[str, Any]
    dense: DenseRunFigures
    floor: FloorFigures
    command: CommandFigures


def _commands(tmp: Path, opts: BenchOptions, progress: Progress) -> _CommandsPart:
    from suite.bench.floor import bound, floor_study

    dur = opts.run_duration_s
    dense_toml, catalog_toml = tmp / "dense.toml", tmp / "catalog.toml"
    dense_toml.write_text(dense_catalog(opts.seeds, dur))
    catalog_toml.write_text(dense_catalog(opts.catalog_runs, dur))
    warm = tmp / "warmup.toml"
    warm.write_text(WARMUP_CATALOG)
    progress.phase("warm-up command (numba caches, untimed)")
    run_command(warm, tmp / "out_warmup", jobs=1, log=True)
    progress.phase(f"dense runs: {opts.seeds} x {dur:g} s, --jobs 1, logs on")
    runs: dict[str, CommandTiming] = {}
    cpus: tuple[frozenset[int], frozenset[int]] | None = None
    isolation: dict[str, Any] | None = None
    if opts.isolated:
        iso = isolate()
        progress.note(iso.line())
        # the scenario process alone on its core; the command's own processes (the
        # parent's watchers, the forkserver) on the others, not beside the timed loop
        cpus = (iso.rest or frozenset({iso.cpu}), frozenset({iso.cpu}))
        isolation = {"cpu": iso.cpu, "sample_s": iso.sample_s, "line": iso.line(),
                     "others": [asdict(o) for o in iso.others]}
    runs["dense_jobs1_log"] = _timed(progress, "dense_jobs1_log", dense_toml,
                                     tmp / "out_dense", 1, True, cpus)
    progress.phase(f"floor study: the same {opts.seeds} runs with timers around the "
                   "C/GMRES kernel and SUMO's step")
    floor = floor_study(dense_toml, tmp / "out_floor")
    if opts.catalog_runs != opts.seeds:
        progress.phase(f"whole command: {opts.catalog_runs} dense runs, --jobs 1, logs on")
        runs["catalog_jobs1_log"] = _timed(progress, "catalog_jobs1_log", catalog_toml,
                                           tmp / "out_catalog1", 1, True)
    jobs1 = runs.get("catalog_jobs1_log", runs["dense_jobs1_log"])
    progress.phase(f"whole command: {opts.catalog_runs} dense runs, --jobs 2, logs on")
    runs["catalog_jobs2_log"] = _timed(progress, "catalog_jobs2_log", catalog_toml,
                                       tmp / "out_catalog2", 2, True)
    if not opts.quick:
        progress.phase(f"dense runs without logs: {opts.seeds} x {dur:g} s, --jobs 1")
        runs["dense_jobs1_nolog"] = _timed(progress, "dense_jobs1_nolog", dense_toml,
                                           tmp / "out_nolog", 1, False)
        matrix = tmp / "matrix.toml"
        matrix.write_text(MATRIX_CATALOG)
        progress.phase("matrix: 12 runs of 20 s, --jobs 1, logs on")
        runs["matrix_jobs1_log"] = _timed(progress, "matrix_jobs1_log", matrix,
                                          tmp / "out_matrix", 1, True)
    out: dict[str, Any] = {k: v.as_dict() for k, v in runs.items()}
    if isolation is not None:
        out["isolation"] = isolation
    out["floor"] = {**floor, "bound": bound(floor, out["dense_jobs1_log"])}
    command = CommandFigures.of(jobs1, runs["catalog_jobs2_log"])
    out["jobs2_over_jobs1"] = {"whole_command": command.jobs1_over_jobs2_whole_command,
                               "scenario_phase": command.jobs1_over_jobs2_scenario_phase}
    if "dense_jobs1_nolog" in runs:
        out["logging_overhead"] = (runs["dense_jobs1_log"].wall_s
                                   / runs["dense_jobs1_nolog"].wall_s)
    return _CommandsPart(out, DenseRunFigures.of(runs["dense_jobs1_log"]),
                         FloorFigures.of(floor), command)


def _solver_targets(sv: dict[str, Any] | None) -> list[Measured]:
    if sv is None:
        return []
    if "skipped" in sv:
        why = str(sv["skipped"])
        return [Measured("ipopt_over_cgmres_p50", float("nan"), why),
                Measured("ipopt_over_cgmres_var", float("nan"), why)]
    ratio = sv["ipopt_barrier_over_cgmres"]
    # The variance is judged on each update's minimum over the repeats: the update
    # sequence is deterministic, so that keeps the solvers' own variation (Ipopt's
    # iteration counts) and drops the shared machine's preemptions, which at ~70 us
    # per C/GMRES update dominate its raw variance (both are printed).
    return [Measured("ipopt_over_cgmres_p50", float(ratio["raw"]["p50_s"])),
            Measured("ipopt_over_cgmres_var", float(ratio["min_of_repeats"]["var_s2"]))]


def run_all(options: BenchOptions | None = None,
            print_fn: Callable[[str], None] | None = None) -> BenchResult:
    """Every phase of ``options`` (module docstring), a progress line each through
    ``print_fn``; the targets judged unless only the controller part ran."""
    opts = options if options is not None else BenchOptions()
    progress = Progress(print_fn, opts.phases())
    figures: dict[str, Any] = {"started": time.strftime("%Y-%m-%dT%H:%M:%S"),
                               "options": asdict(opts),
                               "machine": {"cpus": os.cpu_count(),
                                           "processor": platform.processor()
                                           or platform.machine(),
                                           "python": platform.python_version()},
                               "load_start": _load()}
    progress.phase("controller on the plant-only harness")
    figures["controller"] = _controller_timing()
    if opts.include_ipopt:
        progress.phase(f"solvers: C/GMRES vs Ipopt, {opts.solver_repeats} repeat(s) of "
                       f"{opts.solver_duration_s:g} s")
        figures["solvers"] = _solvers(opts.solver_repeats, opts.solver_duration_s)
    part: _CommandsPart | None = None
    if opts.include_runner:
        if not opts.quick:
            progress.phase("extrapolation error: SUMO at 50 Hz against 10 Hz")
            figures["extrapolation"] = _extrapolation()
        with tempfile.TemporaryDirectory(prefix="hwyeval-bench-") as tmp:
            part = _commands(Path(tmp), opts, progress)
        figures["commands"] = part.figures
    figures["load_end"] = _load()
    figures["elapsed_s"] = progress.elapsed_s()
    results: tuple[TargetResult, ...] = ()
    if opts.judged:
        measured = _solver_targets(figures.get("solvers"))
        if part is not None:
            measured += measured_targets(part.dense, part.floor, part.command)
            figures["issue25"] = {"dense": asdict(part.dense), "floor": asdict(part.floor),
                                  "command": part.command.as_dict()}
        results = judge(measured, isolated=opts.isolated)
    figures["targets"] = [{**asdict(r.target), "comparison": r.target.comparison.value,
                           "value": r.value, "met": r.met, "why_not": r.why_not}
                          for r in results]
    figures["all_met"] = all_met(results)
    progress.note(f"done: {len(results)} target(s) judged")
    return BenchResult(opts, figures, part.dense if part else None,
                       part.floor if part else None, part.command if part else None, results)


def to_json(figures: dict[str, Any]) -> str:
    return json.dumps(figures, indent=1, default=str)
