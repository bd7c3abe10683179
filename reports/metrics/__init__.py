"""The metric layer: judges a typed run record once (:func:`evaluate`), below the runner,
the Rerun log and the reports, which only read the stored verdict and series."""

from reports.metrics.criteria import Criteria
from reports.metrics.evaluate import REQUIRED_METRICS, Evaluation, criteria_for, evaluate
from reports.metrics.values import signal

__all__ = ["REQUIRED_METRICS", "Criteria", "Evaluation", "criteria_for", "evaluate", "signal"]
