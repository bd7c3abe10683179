"""results.csv and summary.csv, regenerated from the run directories of a catalog output.

Status: a run whose ``run.json`` says 'error' or 'timeout' keeps it; every other run is
re-evaluated (metrics + criteria), so changing criteria and re-running ``hwyeval report``
re-judges the runs. A run directory that cannot be read or evaluated becomes 'error'.
"""

from __future__ import annotations

import math
import re
import traceback
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from reports.metrics.evaluate import REQUIRED_METRICS, EvaluationResult, evaluate_run
from reports.metrics.timing import loop_times_s
from reports.run_record import TRACEBACK, RunRecord, iter_run_dirs, load_run

STATUSES = ("pass", "fail", "error", "timeout")
LEAD_COLUMNS = ("scenario", "controller", "status", "collision", "min_gap_m", "progress_m",
                "sim_time_s", "wall_s")

# summary.csv: metric -> aggregations over the runs of a group (finite values only)
SUMMARY_METRICS: dict[str, tuple[str, ...]] = {
    "collision": ("sum",),
    "min_gap_m": ("min", "mean"),
    "min_ttc_s": ("min", "mean"),
    "progress_m": ("mean",),
    "progress_ratio": ("min", "mean"),
    "offroad_s": ("max", "sum"),
    "rms_lat_dev_m": ("mean", "max"),
    "mean_speed_mps": ("mean",),
    "max_abs_lat_acc_mps2": ("mean", "max"),
    "max_abs_long_jerk_mps3": ("mean", "max"),
    "max_abs_jerk_mps3": ("mean", "max"),
    "max_abs_yaw_rate_radps": ("max",),
    "residual_max": ("max",),
    "fallbacks": ("sum",),
    "deadline_misses": ("sum",),
    "realtime_factor": ("mean", "min"),
}
# pooled per-step timing over all runs of a group: loop -> percentiles
SUMMARY_TIMING: dict[str, tuple[int, ...]] = {"step": (50, 99), "outer": (50, 99),
                                              "inner": (50, 99), "sumo": (50, 99)}


@dataclass
class RunEval:
    """One run directory, loaded and judged."""

    run_dir: Path
    scenario: str
    controller: str
    family: str
    status: str
    meta: dict[str, Any]
    record: RunRecord | None = None
    result: EvaluationResult | None = None
    error: str = ""
    metrics: dict[str, float] = field(default_factory=dict)
    failed: list[str] = field(default_factory=list)

    @property
    def run_id(self) -> str:
        """Unique name of the run (its directory name)."""
        return self.run_dir.name


def scenario_family(meta: Mapping[str, Any], scenario: str) -> str:
    """``run.json`` ``family`` if present, else the scenario name without a trailing
    seed/index suffix (``_s3``, ``_seed3``, ``-07``) and after stripping ``__...``."""
    for key in ("family", "scenario_family"):
        value = meta.get(key)
        if isinstance(value, str) and value:
            return value
    base = scenario.split("__", 1)[0]
    base = re.sub(r"([_-](seed|s|v)?\d+)+$", "", base)
    return base or scenario


def _error_text(run_dir: Path, meta: Mapping[str, Any]) -> str:
    err = meta.get("error")
    if isinstance(err, str) and err.strip():
        return err
    tb = run_dir / TRACEBACK
    if tb.is_file():
        return tb.read_text(errors="replace")
    return ""


def collect_runs(out_dir: str | Path, criteria_overrides: Mapping[str, Any] | None = None,
                 with_arrays: bool = True) -> list[RunEval]:
    """Load and evaluate every run directory under ``out_dir`` (sorted by name)."""
    runs: list[RunEval] = []
    for run_dir in iter_run_dirs(out_dir):
        try:
            record = load_run(run_dir, with_arrays=with_arrays)
        except Exception as exc:  # noqa: BLE001 - a broken run dir must not stop the report
            runs.append(RunEval(run_dir, run_dir.name, "?", run_dir.name, "error", {},
                                error=f"report: cannot load {run_dir}: {exc}"))
            continue
        meta = record.meta
        scenario = str(meta.get("scenario", run_dir.name))
        controller = str(meta.get("controller", "?"))
        run = RunEval(run_dir, scenario, controller, scenario_family(meta, scenario),
                      str(meta.get("status", "")), meta, record)
        try:
            run.result = evaluate_run(record, criteria_overrides)
            run.metrics = run.result.metrics
            run.failed = list(run.result.failed)
        except Exception:  # noqa: BLE001
            run.error = "report: evaluation failed\n" + traceback.format_exc()
            run.status = "error"
            runs.append(run)
            continue
        if run.status in ("error", "timeout"):
            run.error = _error_text(run_dir, meta)
        else:
            run.status = run.result.status
        runs.append(run)
    return runs


def results_frame(runs: Sequence[RunEval]) -> pd.DataFrame:
    """One row per run: LEAD_COLUMNS, every metric, failed_criteria, family, run (the run
    directory's name). Error texts are in junit.xml / report.html / traceback.txt."""
    # required names first, then the rest sorted: the same columns in the same order
    # whichever runs a directory holds
    others = {name for run in runs for name in run.metrics} - set(REQUIRED_METRICS)
    metric_names: list[str] = list(REQUIRED_METRICS) + sorted(others)
    rows = []
    for run in runs:
        row: dict[str, Any] = {"scenario": run.scenario, "controller": run.controller,
                               "status": run.status}
        for key in ("sim_time_s", "wall_s"):
            value = run.meta.get(key)
            row[key] = float(value) if isinstance(value, int | float) else math.nan
        for name in metric_names:
            row.setdefault(name, run.metrics.get(name, math.nan))
        row["failed_criteria"] = ";".join(run.failed)
        row["family"] = run.family
        row["run"] = run.run_id
        rows.append(row)
    columns = list(LEAD_COLUMNS) + [m for m in metric_names if m not in LEAD_COLUMNS] + [
        "failed_criteria", "family", "run"]
    return pd.DataFrame(rows, columns=columns)


def _agg(values: np.ndarray, how: str) -> float:
    """min/max over non-NaN values (inf counts: 'no conflict'); mean/sum over finite ones."""
    values = values[~np.isnan(values)] if how in ("min", "max") else values[np.isfinite(values)]
    if values.size == 0:
        return math.nan
    return float(getattr(np, how)(values))


def summary_frame(runs: Sequence[RunEval]) -> pd.DataFrame:
    """Per controller and scenario family (plus family 'ALL' per controller): status
    counts, pass rate, aggregated key metrics and pooled per-step timing percentiles."""
    groups: dict[tuple[str, str], list[RunEval]] = {}
    for run in runs:
        groups.setdefault((run.controller, run.family), []).append(run)
        groups.setdefault((run.controller, "ALL"), []).append(run)
    rows = []
    for (controller, family), members in sorted(groups.items(),
                                                key=lambda kv: (kv[0][0], kv[0][1] == "ALL",
                                                                kv[0][1])):
        row: dict[str, Any] = {"controller": controller, "family": family, "runs": len(members)}
        for status in STATUSES:
            row[status] = sum(1 for r in members if r.status == status)
        row["pass_rate"] = row["pass"] / len(members) if members else math.nan
        for metric, hows in SUMMARY_METRICS.items():
            values = np.array([r.metrics.get(metric, math.nan) for r in members], dtype=float)
            for how in hows:
                row[f"{how}_{metric}"] = _agg(values, how)
        for loop, percentiles in SUMMARY_TIMING.items():
            samples = [loop_times_s(r.record, loop) for r in members if r.record is not None]
            pooled = np.concatenate(samples) if samples else np.zeros(0)
            for q in percentiles:
                row[f"{loop}_ms_p{q}"] = (float(np.percentile(pooled, q) * 1e3) if pooled.size
                                          else math.nan)
        rows.append(row)
    return pd.DataFrame(rows)


def write_results_csv(runs: Sequence[RunEval], path: str | Path) -> Path:
    """Write results.csv; returns its path."""
    path = Path(path)
    results_frame(runs).to_csv(path, index=False)
    return path


def write_summary_csv(runs: Sequence[RunEval], path: str | Path) -> Path:
    """Write summary.csv; returns its path."""
    path = Path(path)
    summary_frame(runs).to_csv(path, index=False)
    return path
