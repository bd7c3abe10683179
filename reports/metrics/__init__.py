"""The metric layer: judges a typed run record once (:func:`evaluate`), below the runner,
the Rerun log and the reports, which only read the stored verdict and series. What each
metric is (unit, direction, series, criterion, tolerance, drawing) is its entry in
:mod:`reports.metrics.catalogue`, which every table about metrics reads."""

from reports.metrics.catalogue import CATALOGUE, REQUIRED_METRICS, spec
from reports.metrics.criteria import Criteria
from reports.metrics.evaluate import Evaluation, criteria_for, evaluate
from reports.metrics.spec import MetricSpec
from reports.metrics.values import signal

__all__ = ["CATALOGUE", "REQUIRED_METRICS", "Criteria", "Evaluation", "MetricSpec",
           "criteria_for", "evaluate", "signal", "spec"]
