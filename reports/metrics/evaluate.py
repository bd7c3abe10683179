"""Evaluate one run record: every metric, the criteria, a pass/fail status."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from reports.metrics.comfort import comfort_metrics
from reports.metrics.criteria import Criteria
from reports.metrics.safety import safety_metrics
from reports.metrics.timing import health_metrics, timing_metrics
from reports.metrics.tracking import tracking_metrics
from reports.run_record import RunRecord

# The metric names every evaluation provides, in report-column order.
REQUIRED_METRICS: tuple[str, ...] = (
    "collision", "min_gap_m", "progress_m", "min_ttc_s", "min_ellipse_margin", "offroad_s",
    "min_long_acc_mps2", "max_long_acc_mps2", "max_abs_lat_acc_mps2", "max_abs_yaw_rate_radps",
    "max_abs_yaw_acc_radps2", "max_abs_long_jerk_mps3", "max_abs_jerk_mps3", "rms_lat_dev_m",
    "mean_speed_mps", "step_ms_p50", "step_ms_p99", "step_ms_max", "step_var_s2",
    "deadline_misses", "residual_max", "fallbacks", "realtime_factor",
)


@dataclass
class EvaluationResult:
    """metrics: name -> value (SI units in the names); failed: ``name=value>limit`` strings;
    status: 'pass' or 'fail'."""

    metrics: dict[str, float]
    failed: list[str] = field(default_factory=list)
    status: str = "pass"

    @property
    def failed_criteria(self) -> str:
        """The failures as one ``;``-separated string (results.csv column)."""
        return ";".join(self.failed)

    def as_row(self) -> dict[str, Any]:
        """metrics + ``failed_criteria`` + ``status``, for tables and run.json."""
        row: dict[str, Any] = dict(self.metrics)
        row["failed_criteria"] = self.failed_criteria
        row["status"] = self.status
        return row


def compute_metrics(record: RunRecord) -> dict[str, float]:
    """Every metric of a run (NaN where not measurable), required names first."""
    found: dict[str, float] = {}
    found.update(safety_metrics(record))
    found.update(comfort_metrics(record))
    found.update(tracking_metrics(record))
    found.update(timing_metrics(record))
    found.update(health_metrics(record))
    ordered = {name: float(found.get(name, float("nan"))) for name in REQUIRED_METRICS}
    for name in sorted(found):
        if name not in ordered:
            ordered[name] = float(found[name])
    return ordered


def criteria_for(record: RunRecord, criteria_overrides: Mapping[str, Any] | None = None,
                 base: Criteria | None = None) -> Criteria:
    """Criteria of a run: defaults (or ``base``), then ``run.json["criteria"]``, then
    ``criteria_overrides``. Raises ValueError on unknown names."""
    criteria = Criteria.from_overrides(record.meta.get("criteria") or None, base=base)
    return Criteria.from_overrides(criteria_overrides, base=criteria)


def evaluate_run(record: RunRecord, criteria_overrides: Mapping[str, Any] | None = None,
                 criteria: Criteria | None = None) -> EvaluationResult:
    """Metrics, failed criteria and 'pass'/'fail' for one run (tolerates an empty trace,
    which fails as ``steps=0<1``). ``criteria`` replaces the defaults as the base the
    run's own ``criteria`` and then ``criteria_overrides`` are applied to."""
    limits = criteria_for(record, criteria_overrides, base=criteria)
    metrics = compute_metrics(record)
    failed = limits.check(metrics)
    if len(record.trace) == 0:
        failed.insert(0, "steps=0<1")
    return EvaluationResult(metrics=metrics, failed=failed, status="fail" if failed else "pass")
