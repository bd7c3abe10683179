"""The judgement of a run: typed metric values, typed failures, one status.

Computed once, by :func:`reports.metrics.evaluate`, right after the run; stored in
``run.json`` under ``verdict``; read (never recomputed) by the reports, the JUnit
file, the comparison and the Rerun log.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

KINDS = ("safety", "comfort", "tracking", "timing", "health")
BETTER = ("lower", "higher", "none")
BOUNDS = ("max", "min")


@dataclass(frozen=True)
class MetricValue:
    """One metric of one run.

    value: in ``unit`` (NaN: not measurable in this run, e.g. no obstacle ever seen).
    kind: safety | comfort | tracking | timing | health; timing metrics are wall-clock
        measurements (noisy across machines and load), the others are behaviour.
    better: which direction is an improvement ('none': informational).
    worst_step: trace row where the value was attained (None for aggregates).
    series: the ``SeriesColumns``/trace column it is an extreme of ('' if none).
    """

    name: str
    value: float
    unit: str
    kind: str
    better: str = "none"
    worst_step: int | None = None
    series: str = ""

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"MetricValue.kind must be one of {KINDS}, got {self.kind!r}")
        if self.better not in BETTER:
            raise ValueError(f"MetricValue.better must be one of {BETTER}, got {self.better!r}")


@dataclass(frozen=True)
class Failure:
    """A criterion the run did not meet: ``value`` of ``metric`` beyond ``limit``.

    bound: 'max' (fails when value > limit) or 'min' (fails when value < limit);
    step / t_s: the trace row and time where it was first (or worst) violated.
    """

    criterion: str
    metric: str
    value: float
    limit: float
    bound: str
    unit: str = ""
    step: int | None = None
    t_s: float | None = None

    def __post_init__(self) -> None:
        if self.bound not in BOUNDS:
            raise ValueError(f"Failure.bound must be one of {BOUNDS}, got {self.bound!r}")

    @property
    def text(self) -> str:
        """``metric=value>limit`` (or ``<``), 4 significant digits: for tables only."""
        op = ">" if self.bound == "max" else "<"
        return f"{self.metric}={fmt_value(self.value)}{op}{fmt_value(self.limit)}"

    @property
    def line(self) -> str:
        """:attr:`text` and where it was violated (or that it is an aggregate)."""
        if self.step is None:
            return f"{self.text} (whole run)"
        when = f"t={self.t_s:.2f} s, " if self.t_s is not None else ""
        return f"{self.text} ({when}step {self.step})"


@dataclass(frozen=True)
class Verdict:
    """status: pass | fail | error | timeout; metrics in report order; failures in
    criteria order (a run without trace rows fails ``steps``)."""

    status: str
    metrics: tuple[MetricValue, ...] = ()
    failures: tuple[Failure, ...] = ()
    criteria: dict[str, float | None] = field(default_factory=dict)

    def metric(self, name: str) -> MetricValue | None:
        for m in self.metrics:
            if m.name == name:
                return m
        return None

    def value(self, name: str) -> float:
        """The value of metric ``name`` (NaN if absent)."""
        m = self.metric(name)
        return m.value if m is not None else math.nan

    def values(self) -> dict[str, float]:
        return {m.name: m.value for m in self.metrics}

    @property
    def failed_text(self) -> str:
        """Failures joined by ';' (results.csv's ``failed_criteria``)."""
        return ";".join(f.text for f in self.failures)


def fmt_value(value: float) -> str:
    """Compact number (4 significant digits; inf/-inf/nan spelled out)."""
    if math.isnan(value):
        return "nan"
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    return f"{value:.4g}"
