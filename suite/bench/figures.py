"""Issue 25's figures, from the bench's commands and its floor study, as typed records.

* :class:`DenseRunFigures`: the dense target's runs (N traffic seeds, ``--jobs 1``, logs
  on): each run's real-time factor on results.csv's ``wall_s`` (build and loop) and on
  its whole life from its start to its run.json, their medians and range; the worst
  run's behaviour + controller step p99 and max (results.csv ``step_ms_p99``,
  ``step_ms_max``) and the worst ratio of a run's step p99 to its own C/GMRES outer
  update p99 (``outer_ms_p99``);
* :func:`floor_realtime_factor`: the floor, simulated time over the kernel's and SUMO's
  step's time per run (the floor study), the real-time factor with every other part free;
* :class:`CommandFigures`: the whole ``hwyeval run`` command on a dense catalog at
  ``--jobs 1`` (real-time factor, :class:`suite.bench.account.WallAccount`) and its
  ``--jobs 2`` / ``--jobs 1`` ratios (scenario phase, whole command);
* :func:`measured_targets`: the figures each target of :data:`suite.bench.targets.TARGETS`
  is judged on: the dense run's and the whole command's real-time factors as shares of
  the floor [%], the step p99 ratio, the step max, the ``--jobs`` ratio.
"""

from __future__ import annotations

import math
import statistics
from dataclasses import asdict, dataclass
from typing import Any

from suite.bench.account import WallAccount, account
from suite.bench.command import CommandTiming, RunFigures
from suite.bench.floor import GLUE_STAGES, FloorRun, glue_per_step_us
from suite.bench.targets import Measured

__all__ = ["CommandFigures", "DenseRunFigures", "FloorFigures", "floor_realtime_factor",
           "glue_budget_per_step_us", "measured_targets", "share_of_floor_pct",
           "share_of_floor_without_pct"]


def _median(values: list[float]) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return float(statistics.median(finite)) if finite else math.nan


def _worst(runs: tuple[RunFigures, ...], key: str) -> tuple[float, str]:
    finite = [r for r in runs if math.isfinite(getattr(r, key))]
    if not finite:
        return math.nan, ""
    run = max(finite, key=lambda r: float(getattr(r, key)))
    return float(getattr(run, key)), run.scenario


@dataclass(frozen=True)
class DenseRunFigures:
    """The dense runs of one ``--jobs 1`` command (module docstring); real-time factors
    are simulated seconds over wall seconds, step times in ms."""

    runs: int
    duration_s: float
    realtime_factor_median: float
    realtime_factor_min: float
    realtime_factor_max: float
    life_realtime_factor_median: float
    step_p99_ms_worst: float
    step_p99_worst_run: str
    step_max_ms_worst: float
    step_max_worst_run: str
    step_p99_over_outer_p99_worst: float = math.nan
    step_p99_over_outer_p99_worst_run: str = ""
    controller_p99_over_outer_p99_worst: float = math.nan
    controller_p99_over_outer_p99_worst_run: str = ""

    def __post_init__(self) -> None:
        if self.runs < 1:
            raise ValueError(f"runs must be >= 1, got {self.runs}")
        if not self.duration_s > 0:
            raise ValueError(f"duration_s must be > 0, got {self.duration_s}")

    @classmethod
    def of(cls, timing: CommandTiming) -> DenseRunFigures:
        if not timing.runs:
            raise ValueError("the dense command wrote no run")
        rtf = [r.realtime_factor for r in timing.runs]
        life = [r.sim_s / r.span_s if r.span_s > 0 else math.nan for r in timing.runs]
        p99, p99_run = _worst(timing.runs, "step_p99_ms")
        mx, mx_run = _worst(timing.runs, "step_max_ms")
        ratio, ratio_run = _worst(timing.runs, "step_p99_over_outer_p99")
        alone, alone_run = _worst(timing.runs, "controller_p99_over_outer_p99")
        return cls(runs=len(timing.runs), duration_s=max(r.sim_s for r in timing.runs),
                   realtime_factor_median=_median(rtf), realtime_factor_min=min(rtf),
                   realtime_factor_max=max(rtf), life_realtime_factor_median=_median(life),
                   step_p99_ms_worst=p99, step_p99_worst_run=p99_run,
                   step_max_ms_worst=mx, step_max_worst_run=mx_run,
                   step_p99_over_outer_p99_worst=ratio,
                   step_p99_over_outer_p99_worst_run=ratio_run,
                   controller_p99_over_outer_p99_worst=alone,
                   controller_p99_over_outer_p99_worst_run=alone_run)


@dataclass(frozen=True)
class FloorFigures:
    """The floor study of the dense runs: the Python between SUMO's step and the C/GMRES
    kernel per control step [us] and per run [s]; the kernel's and SUMO's per run [s];
    the third-party imports and the rest of the scenario processes' preload, timed in a
    fresh interpreter [s]."""

    runs: int
    glue_per_step_us: float
    glue_per_run_s: float
    kernel_per_run_s: float
    sumo_per_run_s: float
    loop_per_run_s: float
    steps_per_run: float
    third_party_import_s: float
    preload_s: float
    # the glue per run split as suite.bench.floor.GLUE_STAGES [s] (() when not timed)
    glue_stages_per_run_s: tuple[float, ...] = ()
    # the floor study's runs' own results.csv wall_s, mean [s] (NaN: not recorded)
    wall_per_run_s: float = math.nan

    def __post_init__(self) -> None:
        if self.runs < 1:
            raise ValueError(f"runs must be >= 1, got {self.runs}")
        if self.glue_stages_per_run_s and len(self.glue_stages_per_run_s) != len(GLUE_STAGES):
            raise ValueError(f"glue_stages_per_run_s: expected {len(GLUE_STAGES)} parts "
                             f"({', '.join(n for n, _ in GLUE_STAGES)}), got "
                             f"{len(self.glue_stages_per_run_s)}")

    @classmethod
    def of(cls, floor: dict[str, Any]) -> FloorFigures:
        """From :func:`suite.bench.floor.floor_study`'s result."""
        runs = [FloorRun(**{k: v for k, v in row.items()
                            if k not in ("glue_s", "glue_per_step_us")})
                for row in floor["runs"]]
        if not runs:
            raise ValueError("the floor study ran no scenario")
        n = len(runs)
        staged = all(r.staged for r in runs)
        split = (tuple(sum(parts) / n for parts in zip(*(r.glue_by_stage_s() for r in runs),
                                                        strict=True))
                 if staged else ())
        return cls(runs=n, glue_per_step_us=glue_per_step_us(runs),
                   glue_per_run_s=sum(r.glue_s for r in runs) / n,
                   kernel_per_run_s=sum(r.kernel_s for r in runs) / n,
                   sumo_per_run_s=sum(r.sumo_s for r in runs) / n,
                   loop_per_run_s=sum(r.loop_s for r in runs) / n,
                   steps_per_run=sum(r.steps for r in runs) / n,
                   third_party_import_s=float(floor["third_party_import_s"]),
                   preload_s=float(floor.get("preload_s", math.nan)),
                   glue_stages_per_run_s=split,
                   wall_per_run_s=sum(r.wall_s for r in runs) / n)


@dataclass(frozen=True)
class CommandFigures:
    """The whole command on the dense catalog: ``--jobs 1`` (``runs`` runs, simulated and
    wall seconds, real-time factor, the wall-time account) and ``--jobs 1`` / ``--jobs 2``
    time ratios of the scenario phase and of the whole command."""

    runs: int
    sim_s: float
    wall_s: float
    realtime_factor: float
    account: WallAccount
    jobs1_scenario_phase_s: float
    jobs2_scenario_phase_s: float
    jobs1_over_jobs2_scenario_phase: float
    jobs2_wall_s: float
    jobs1_over_jobs2_whole_command: float

    def __post_init__(self) -> None:
        if self.runs < 1 or not self.wall_s > 0:
            raise ValueError(f"need runs >= 1 and wall_s > 0, got {self.runs}, {self.wall_s}")

    @classmethod
    def of(cls, jobs1: CommandTiming, jobs2: CommandTiming) -> CommandFigures:
        if jobs2.jobs != 2 or jobs1.jobs != 1:
            raise ValueError(f"need a --jobs 1 and a --jobs 2 command, got {jobs1.jobs}, "
                             f"{jobs2.jobs}")
        phase = (jobs1.runs_span_s / jobs2.runs_span_s if jobs2.runs_span_s > 0
                 else math.nan)
        return cls(runs=len(jobs1.runs), sim_s=jobs1.sim_s, wall_s=jobs1.wall_s,
                   realtime_factor=jobs1.realtime_factor, account=account(jobs1),
                   jobs1_scenario_phase_s=jobs1.runs_span_s,
                   jobs2_scenario_phase_s=jobs2.runs_span_s,
                   jobs1_over_jobs2_scenario_phase=phase, jobs2_wall_s=jobs2.wall_s,
                   jobs1_over_jobs2_whole_command=jobs1.wall_s / jobs2.wall_s)

    def as_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["account"]["parts_s"] = [list(p) for p in self.account.parts_s]
        out["account"]["unaccounted_s"] = self.account.unaccounted_s
        return out


def floor_realtime_factor(duration_s: float, floor: FloorFigures) -> float:
    """The floor: ``duration_s`` [s] simulated over the C/GMRES kernel's and SUMO's step's
    time per run [s] (the floor study), the one-run real-time factor with every other
    part free (NaN when they took no time)."""
    compiled = floor.kernel_per_run_s + floor.sumo_per_run_s
    return duration_s / compiled if compiled > 0 else math.nan


def share_of_floor_pct(realtime_factor: float, floor_factor: float) -> float:
    """``realtime_factor`` as a share of ``floor_factor`` [%] (NaN without both)."""
    if not (math.isfinite(realtime_factor) and floor_factor > 0):
        return math.nan
    return 100.0 * realtime_factor / floor_factor


def _floor_run_wall_s(dense: DenseRunFigures, floor: FloorFigures) -> float:
    """The wall time [s] of one run the what-if figures start from: the floor study's own
    runs' mean ``wall_s`` (the same processes the glue and the floor were timed in, so
    the figures add up), else the dense runs' median (NaN without either)."""
    if math.isfinite(floor.wall_per_run_s) and floor.wall_per_run_s > 0:
        return floor.wall_per_run_s
    if dense.realtime_factor_median > 0:
        return dense.duration_s / dense.realtime_factor_median
    return math.nan


def share_of_floor_without_pct(dense: DenseRunFigures, floor: FloorFigures,
                                saved_per_run_s: float) -> float:
    """The one-run share of the floor [%] were ``saved_per_run_s`` [s] of each run free:
    a run's wall time (:func:`_floor_run_wall_s`) less the saving, as a share of the
    floor (NaN when nothing would be left)."""
    floor_x = floor_realtime_factor(dense.duration_s, floor)
    wall_s = _floor_run_wall_s(dense, floor) - saved_per_run_s
    if not (math.isfinite(wall_s) and wall_s > 0):
        return math.nan
    return share_of_floor_pct(dense.duration_s / wall_s, floor_x)


def glue_budget_per_step_us(dense: DenseRunFigures, floor: FloorFigures,
                            share_pct: float) -> float:
    """The glue a control step may cost [us] for one run to reach ``share_pct`` [%] of
    the floor, the rest of the run (its build, the kernel, SUMO's step: a run's wall
    time, :func:`_floor_run_wall_s`, less the floor study's glue) as measured (NaN
    without the figures; negative when the rest alone misses it)."""
    floor_x = floor_realtime_factor(dense.duration_s, floor)
    wall_s = _floor_run_wall_s(dense, floor)
    if not (math.isfinite(wall_s) and floor_x > 0 and floor.steps_per_run > 0
            and share_pct > 0):
        return math.nan
    rest_s = wall_s - floor.glue_per_run_s
    return (dense.duration_s / (share_pct / 100.0 * floor_x) - rest_s) / floor.steps_per_run * 1e6


def measured_targets(dense: DenseRunFigures | None, floor: FloorFigures | None,
                     command: CommandFigures | None) -> list[Measured]:
    """The figures each target is judged on (those the run measured); the shares of the
    floor need the floor study and the dense runs (the floor is per run of the dense
    runs' duration)."""
    out: list[Measured] = []

    def add(name: str, value: float, why: str) -> None:
        out.append(Measured(name, value if math.isfinite(value) else math.nan,
                            "" if math.isfinite(value) else why))

    floor_x = (floor_realtime_factor(dense.duration_s, floor)
               if dense is not None and floor is not None else math.nan)
    if dense is not None:
        if floor is not None:
            add("one_run_share_of_floor",
                share_of_floor_pct(dense.realtime_factor_median, floor_x),
                "no finite wall_s or no floor")
        add("step_p99_over_outer_p99", dense.step_p99_over_outer_p99_worst,
            "no step_ms_p99 and outer_ms_p99 in results.csv")
        add("step_max_ms_worst_run", dense.step_max_ms_worst, "no step_ms_max in results.csv")
    if command is not None:
        if floor is not None and dense is not None:
            add("command_share_of_floor_jobs1",
                share_of_floor_pct(command.realtime_factor, floor_x), "no floor")
        add("jobs2_over_jobs1_scenario_phase", command.jobs1_over_jobs2_scenario_phase,
            "no --jobs 2 scenario phase")
    return out
