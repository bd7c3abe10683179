"""The runs of a catalog output read for reporting, and results.csv / summary.csv.

Nothing here evaluates: every status, metric and failure is the verdict stored in
``run.json`` by the runner (see :func:`reports.metrics.evaluate`). A run directory that
cannot be read (malformed ``run.json``, a file missing, changed or corrupt: the checks of
:func:`reports.record.load_run`; no verdict for a run that ended 'ok') becomes an
'error' entry carrying the reason (``RunEntry.unreadable``, naming the file), so one bad
directory never stops the report of the others.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from reports.expectation import Xfail, expectation, fails_night, xfail_of
from reports.identity import Setup, setup_of
from reports.metrics.catalogue import REQUIRED_METRICS, SUMMARY_METRICS
from reports.metrics.robustness import robustness
from reports.metrics.timing import loop_times_s
from reports.pool import TimePool
from reports.record import (
    RRD,
    SERIES,
    TRACE,
    TRACEBACK,
    DamagedRun,
    Failure,
    MetricValue,
    RunInfo,
    RunOutcome,
    RunRecord,
    Verdict,
    iter_run_dirs,
    load_run,
)
from reports.record.codec import write_text_atomic
from reports.record.meta import END_OK, STATUSES

UNKNOWN = "?"  # the controller of a run directory whose run.json cannot be read
LEAD_COLUMNS = ("scenario", "controller", "variant", "status", "collision", "min_gap_m",
                "progress_m", "sim_time_s", "wall_s")

# summary.csv: metric -> aggregations over the runs of a group (the catalogue's
# ``Summary`` roles, reports.metrics.catalogue), in column order
# pooled per-step timing over all runs of a group: loop -> percentiles (reports.pool)
SUMMARY_TIMING: dict[str, tuple[int, ...]] = {"step": (50, 99), "outer": (50, 99),
                                              "inner": (50, 99), "sumo": (50, 99)}


@dataclass(frozen=True)
class Parts:
    """Which files of a run directory to load besides run.json (every listed file is
    checked whichever are loaded: :func:`reports.record.load_run`)."""

    trace: bool = False
    neighbours: bool = False
    arrays: bool = False
    series: bool = False
    road: bool = False


VERDICTS_ONLY = Parts()
EVERYTHING = Parts(trace=True, neighbours=True, arrays=True, series=True, road=True)


@dataclass(frozen=True)
class RunEntry:
    """One run directory as the reports see it.

    status: pass | fail | error | timeout (an unreadable directory is 'error').
    error: why a run is 'error' or 'timeout' (its traceback, or the reason it cannot be
        read); '' otherwise.
    unreadable: why the directory cannot be read as a run (naming the file: run.json
        malformed, a file missing, changed or corrupt, never judged); '' when it can.
    record: the loaded parts (:class:`Parts`), None when the directory could not be read.
    variant: the controller and its options that differ among the runs reported
        together (:mod:`reports.variants`); the controller name until set.
    """

    run_dir: Path
    scenario: str
    controller: str
    family: str
    status: str
    error: str = ""
    record: RunRecord | None = None
    variant: str = ""
    unreadable: str = ""

    def __post_init__(self) -> None:
        if self.status not in STATUSES:
            raise ValueError(f"RunEntry.status must be one of {STATUSES}, got {self.status!r}")
        if self.unreadable and (self.status != "error" or self.record is not None):
            raise ValueError("RunEntry: an unreadable run directory is an 'error' entry "
                             f"without a record, got {self.status!r}")

    @property
    def label(self) -> str:
        """The variant label (the controller name when none was set)."""
        return self.variant or self.controller

    @property
    def run_id(self) -> str:
        """Unique name of the run (its directory name)."""
        return self.run_dir.name

    @property
    def info(self) -> RunInfo | None:
        return self.record.info if self.record is not None else None

    @property
    def outcome(self) -> RunOutcome | None:
        return self.record.outcome if self.record is not None else None

    @property
    def verdict(self) -> Verdict | None:
        return self.record.verdict if self.record is not None else None

    @property
    def metrics(self) -> tuple[MetricValue, ...]:
        return self.verdict.metrics if self.verdict is not None else ()

    @property
    def failures(self) -> tuple[Failure, ...]:
        return self.verdict.failures if self.verdict is not None else ()

    @property
    def log_error(self) -> str:
        """Why writing the run's Rerun log failed (its traceback), '' when it did not."""
        outcome = self.outcome
        return (outcome.log_error or "") if outcome is not None else ""

    @property
    def has_log(self) -> bool:
        """Whether the run directory holds its Rerun log (``run.rrd``)."""
        return (self.run_dir / RRD).is_file()

    def value(self, name: str) -> float:
        """The stored value of metric ``name`` (NaN if absent)."""
        return self.verdict.value(name) if self.verdict is not None else math.nan

    @property
    def setup(self) -> Setup | None:
        """The test, limits and system under test it ran with (:mod:`reports.identity`);
        None for an unreadable directory."""
        info = self.info
        return setup_of(info, self.verdict) if info is not None else None

    @property
    def xfail(self) -> Xfail | None:
        """Its known-failure mark (:mod:`reports.expectation`), None without one."""
        info = self.info
        return xfail_of(info.scenario_spec) if info is not None else None

    @property
    def expectation(self) -> str:
        """'xfail' (an expected failure), 'xpass' (an unexpected pass) or ''."""
        return expectation(self.status, self.xfail)

    @property
    def fails_night(self) -> bool:
        """Whether it fails the night (:func:`reports.expectation.fails_night`)."""
        return fails_night(self.status, self.xfail)

    @property
    def wall_s(self) -> float:
        return self.outcome.wall_s if self.outcome is not None else math.nan

    @property
    def sim_time_s(self) -> float:
        return self.outcome.sim_time_s if self.outcome is not None else math.nan


def scenario_family(family: str, scenario: str) -> str:
    """``family`` if set, else the scenario name cut at ``__`` and without a trailing
    seed/index suffix (``_s3``, ``_seed3``, ``-07``)."""
    if family:
        return family
    base = scenario.split("__", 1)[0]
    base = re.sub(r"([_-](seed|s|v)?\d+)+$", "", base)
    return base or scenario


def incomplete(record: RunRecord, parts: Parts) -> str:
    """Why a readable record cannot be reported ('' when it can)."""
    run_dir = record.run_dir if record.run_dir is not None else Path(".")
    ended_ok = record.outcome.end == END_OK
    if record.verdict is None and ended_ok:
        return f"{run_dir.name}: run.json has no verdict (the run was never judged)"
    if parts.trace and ended_ok and not (run_dir / TRACE).is_file():
        return f"{run_dir.name}: {TRACE} is missing"
    if parts.series and record.verdict is not None and len(record.trace):
        if record.series is None:
            return f"{run_dir.name}: {SERIES} is missing"
        if len(record.series) != len(record.trace):
            return (f"{run_dir.name}: {SERIES} has {len(record.series)} rows, "
                    f"{TRACE} {len(record.trace)}")
    return ""


def _error_text(record: RunRecord) -> str:
    if record.outcome.error and record.outcome.error.strip():
        return record.outcome.error
    tb = record.run_dir / TRACEBACK if record.run_dir is not None else None
    if tb is not None and tb.is_file():
        return tb.read_text(errors="replace")
    return ""


def read_entry(run_dir: Path, parts: Parts = VERDICTS_ONLY) -> RunEntry:
    """One run directory as a :class:`RunEntry` (an 'error' entry if it cannot be read)."""
    try:
        record = load_run(run_dir, trace=parts.trace, neighbours=parts.neighbours,
                          arrays=parts.arrays, series=parts.series, road=parts.road)
    except Exception as exc:  # any unreadable directory is reported, never fatal
        return unreadable_entry(run_dir, exc)
    info = record.info
    family = scenario_family(info.family, info.scenario)
    problem = incomplete(record, parts)
    if problem:
        return RunEntry(run_dir, info.scenario, info.controller, family, "error",
                        error=f"report: {problem}", unreadable=problem)
    status = record.status
    error = _error_text(record) if status in ("error", "timeout") else ""
    return RunEntry(run_dir, info.scenario, info.controller, family, status, error, record)


def unreadable_entry(run_dir: Path, exc: Exception) -> RunEntry:
    """The 'error' entry of a run directory :func:`reports.record.load_run` refused with
    ``exc``: ``unreadable`` says why, naming the file; the scenario and controller are
    run.json's when it could be read (only another file is damaged), else the
    directory's name and '?'."""
    if isinstance(exc, DamagedRun):
        why = "; ".join(exc.problems)
    else:
        why = f"{type(exc).__name__}: {exc}"
    info = exc.info if isinstance(exc, DamagedRun) else None
    scenario, controller, family = ((info.scenario, info.controller, info.family)
                                    if info is not None else (run_dir.name, UNKNOWN, ""))
    return RunEntry(run_dir, scenario, controller, scenario_family(family, scenario), "error",
                    error=f"report: cannot read {run_dir}: {why}", unreadable=why)


def find_entry(runs: Sequence[RunEntry], scenario: str, controller: str) -> RunEntry | None:
    """The run of ``scenario`` with ``controller`` among ``runs``; else the only run of
    ``scenario`` (a scenario whose controller changed between two nights); None when
    absent or ambiguous."""
    named = [r for r in runs if r.scenario == scenario]
    for r in named:
        if r.controller == controller:
            return r
    return named[0] if len(named) == 1 else None


def collect_runs(out_dir: str | Path, parts: Parts = VERDICTS_ONLY) -> list[RunEntry]:
    """Every run directory under ``out_dir`` (sorted by name), with ``parts`` loaded.

    One by one: a read on threads was faster only where the checksums of large files
    dominate (x1.2 on 2 cores) and slower where decoding does (x0.6 on 2 000 small runs:
    the threads take turns at the interpreter's lock)."""
    return [read_entry(run_dir, parts) for run_dir in iter_run_dirs(out_dir)]


def metric_names(runs: Sequence[RunEntry]) -> list[str]:
    """Required metric names first, then every other stored one, sorted: the same
    columns in the same order whichever runs a directory holds."""
    others = {m.name for run in runs for m in run.metrics} - set(REQUIRED_METRICS)
    return list(REQUIRED_METRICS) + sorted(others)


def results_frame(runs: Sequence[RunEntry]) -> pd.DataFrame:
    """One row per run: LEAD_COLUMNS, every metric, failed_criteria, robustness and
    robustness_criterion (:mod:`reports.metrics.robustness`), family, run (the run
    directory's name). Error texts are in junit.xml / report.html / traceback.txt."""
    names = metric_names(runs)
    rows = []
    for run in runs:
        values = run.verdict.values() if run.verdict is not None else {}
        row: dict[str, object] = {"scenario": run.scenario, "controller": run.controller,
                                  "variant": run.label,
                                  "status": run.status, "sim_time_s": run.sim_time_s,
                                  "wall_s": run.wall_s}
        for name in names:
            row.setdefault(name, values.get(name, math.nan))
        row["failed_criteria"] = run.verdict.failed_text if run.verdict is not None else ""
        rob = robustness(run.verdict) if run.verdict is not None else None
        row["robustness"] = rob.value if rob is not None else math.nan
        row["robustness_criterion"] = rob.criterion if rob is not None else run.status
        row["family"] = run.family
        row["run"] = run.run_id
        rows.append(row)
    columns = list(LEAD_COLUMNS) + [m for m in names if m not in LEAD_COLUMNS] + [
        "failed_criteria", "robustness", "robustness_criterion", "family", "run"]
    return pd.DataFrame(rows, columns=columns)


def _agg(values: np.ndarray, how: str) -> float:
    """min/max over non-NaN values (inf counts: 'no conflict'); mean/sum over finite ones."""
    values = values[~np.isnan(values)] if how in ("min", "max") else values[np.isfinite(values)]
    if values.size == 0:
        return math.nan
    return float(getattr(np, how)(values))


GroupKey = tuple[str, str]  # (variant, family or "ALL")
Pools = dict[GroupKey, dict[str, TimePool]]


def group_keys(run: RunEntry) -> tuple[GroupKey, GroupKey]:
    """The two summary groups a run belongs to: its variant's family and 'ALL'."""
    return (run.label, run.family), (run.label, "ALL")


def add_to_pools(pools: Pools, run: RunEntry) -> None:
    """Add the per-step times of a run whose trace is loaded to its groups' pools."""
    if run.record is None or len(run.record.trace) == 0:
        return
    for key in group_keys(run):
        loops = pools.setdefault(key, {loop: TimePool() for loop in SUMMARY_TIMING})
        for loop, pool in loops.items():
            pool.add(loop_times_s(run.record.trace, loop))


def pools_of(runs: Sequence[RunEntry]) -> Pools:
    """Timing pools of runs whose traces are loaded (tests and small outputs)."""
    pools: Pools = {}
    for run in runs:
        add_to_pools(pools, run)
    return pools


def summary_frame(runs: Sequence[RunEntry], pools: Pools | None = None) -> pd.DataFrame:
    """Per controller variant and scenario family (plus family 'ALL' per variant):
    status counts, pass rate, aggregated key metrics and pooled per-step timing
    percentiles [ms] (from ``pools``; built from the runs' traces when None)."""
    pools = pools_of(runs) if pools is None else pools
    groups: dict[GroupKey, list[RunEntry]] = {}
    for run in runs:
        for key in group_keys(run):
            groups.setdefault(key, []).append(run)
    rows = []
    for (variant, family), members in sorted(groups.items(),
                                             key=lambda kv: (kv[0][0], kv[0][1] == "ALL",
                                                             kv[0][1])):
        row: dict[str, object] = {"controller": members[0].controller, "variant": variant,
                                  "family": family, "runs": len(members)}
        for status in STATUSES:
            row[status] = sum(1 for r in members if r.status == status)
        row["pass_rate"] = sum(1 for r in members if r.status == "pass") / len(members)
        for metric, hows in SUMMARY_METRICS.items():
            values = np.array([r.value(metric) for r in members], dtype=float)
            for how in hows:
                row[f"{how}_{metric}"] = _agg(values, how)
        loops = pools.get((variant, family), {})
        for loop, percentiles in SUMMARY_TIMING.items():
            pool = loops.get(loop)
            for q in percentiles:
                row[f"{loop}_ms_p{q}"] = pool.percentile(q) * 1e3 if pool is not None \
                    and pool.n else math.nan
        rows.append(row)
    return pd.DataFrame(rows)


def write_results_csv(runs: Sequence[RunEntry], path: str | Path) -> Path:
    """Write results.csv; returns its path."""
    path = Path(path)
    write_text_atomic(path, results_frame(runs).to_csv(index=False))
    return path


def write_summary_csv(runs: Sequence[RunEntry], path: str | Path,
                      pools: Pools | None = None) -> Path:
    """Write summary.csv; returns its path."""
    path = Path(path)
    write_text_atomic(path, summary_frame(runs, pools).to_csv(index=False))
    return path
