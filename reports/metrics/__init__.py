"""Per-run metrics and pass/fail criteria computed from run records (see ``evaluate_run``)."""

from reports.metrics.criteria import Criteria
from reports.metrics.evaluate import (
    REQUIRED_METRICS,
    EvaluationResult,
    compute_metrics,
    criteria_for,
    evaluate_run,
)

__all__ = [
    "REQUIRED_METRICS",
    "Criteria",
    "EvaluationResult",
    "compute_metrics",
    "criteria_for",
    "evaluate_run",
]
