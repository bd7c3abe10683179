"""What a metric is, once: :class:`MetricSpec` and the roles it may play.

A :class:`MetricSpec` says everything about a metric that is not its computation:

* ``name``, ``unit`` (``-`` dimensionless), ``kind`` (:data:`KINDS`: which comparison
  rule applies) and ``better`` (:data:`BETTER`: ``lower`` or ``higher`` is better,
  ``none`` informational);
* ``series``: the per-step signal it is an extreme of, as ``"<group>.<column>"``
  (:func:`reports.metrics.values.signal` resolves it; '' for a count or an aggregate);
* ``column``: its place among results.csv's leading columns (``None``: it follows them,
  sorted by name);
* ``criterion``: its default pass/fail bound (:class:`Criterion`), ``tolerance``: how
  far it may move between two runs before compare reports it (:class:`Tolerance`),
  ``timing_ratio``: for a timing metric, the largest new/base ratio compare accepts;
* ``summary``: its aggregations in summary.csv (:class:`Summary`), ``junit``: its
  place in a JUnit case's ``<system-out>``;
* ``drawing``: how its series is drawn (:class:`Drawing`), ``mark``: the colour of its
  failure mark on the run page, ``sparkline``: the history's default sparkline metric.

Every ordered role carries its own rank (``column``, ``Criterion.rank``,
``Summary.rank``, ``junit``): each view lists its metrics by rank, so the order of a
table never depends on where an entry sits in the catalogue.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

KINDS = ("safety", "comfort", "tracking", "timing", "health")
BETTER = ("lower", "higher", "none")
BOUNDS = ("max", "min")
AGGREGATIONS = ("min", "max", "mean", "sum")
GROUPS = ("series", "ego", "safety", "controller", "timing", "decision")


def _finite(value: float, what: str, *, positive: bool = False, nonneg: bool = False) -> None:
    if isinstance(value, bool) or not isinstance(value, int | float) \
            or not math.isfinite(value):
        raise ValueError(f"{what} must be a finite number, got {value!r}")
    if positive and value <= 0:
        raise ValueError(f"{what} must be > 0, got {value!r}")
    if nonneg and value < 0:
        raise ValueError(f"{what} must be >= 0, got {value!r}")


def _series_ref(ref: str, what: str) -> None:
    group, _, column = ref.partition(".")
    if ref and (group not in GROUPS or not column):
        raise ValueError(f"{what} must be '<group>.<column>' with a group of {GROUPS}, "
                         f"got {ref!r}")


@dataclass(frozen=True)
class Criterion:
    """A default bound on the metric: ``name`` (the key of a catalog's ``criteria``
    table), ``bound`` 'max' (fails when value > limit) or 'min' (fails when value <
    limit), ``default`` limit in the metric's unit (None: off unless a catalog sets it),
    ``scale`` s_c > 0 [the metric's unit]: the robustness margin is (L − v)/s_c or
    (v − L)/s_c (:mod:`reports.metrics.robustness`), ``rank``: its place in the order
    criteria are checked and failures listed. ``line``: the entity path and label of its
    limit line in the Rerun log ('' none); ``symmetric``: the bound is on |signal|, drawn
    at ±limit."""

    name: str
    bound: str
    default: float | None
    scale: float
    rank: int
    line: str = ""
    line_label: str = ""
    symmetric: bool = False

    def __post_init__(self) -> None:
        if not self.name.isidentifier():
            raise ValueError(f"Criterion.name must be an identifier, got {self.name!r}")
        if self.bound not in BOUNDS:
            raise ValueError(f"Criterion {self.name}: bound must be one of {BOUNDS}, "
                             f"got {self.bound!r}")
        if self.default is not None:
            _finite(self.default, f"Criterion {self.name}: default")
        _finite(self.scale, f"Criterion {self.name}: scale", positive=True)
        if bool(self.line) != bool(self.line_label):
            raise ValueError(f"Criterion {self.name}: a limit line needs a path and a label")


@dataclass(frozen=True)
class Tolerance:
    """A change between two runs is reported when |new − base| > max(abs, rel·|base|)
    (``abs`` in the metric's unit, ``rel`` [-])."""

    abs: float
    rel: float

    def __post_init__(self) -> None:
        _finite(self.abs, "Tolerance.abs", nonneg=True)
        _finite(self.rel, "Tolerance.rel", nonneg=True)


@dataclass(frozen=True)
class Summary:
    """summary.csv's columns ``<how>_<metric>`` for each aggregation over a group's runs
    (min/max over non-NaN values, mean/sum over finite ones), at ``rank``."""

    hows: tuple[str, ...]
    rank: int

    def __post_init__(self) -> None:
        if not self.hows or any(h not in AGGREGATIONS for h in self.hows):
            raise ValueError(f"Summary.hows must be some of {AGGREGATIONS}, got {self.hows!r}")


@dataclass(frozen=True)
class Drawing:
    """How a metric's signal is drawn: ``label`` of the line, ``unit`` as printed on the
    axis, ``series``: the signal drawn when it is not the metric's own (an aggregate
    such as an RMS is drawn from the signal it aggregates; '' the metric's
    ``series``), ``cap``: +inf ("none") and values above are drawn at this value (None:
    as they are). ``rerun``: the entity path of the series in the Rerun log ('' it is
    logged by hand or not at all), ``rerun_label`` its legend, ``colour`` RGBA."""

    label: str
    unit: str
    series: str = ""
    cap: float | None = None
    rerun: str = ""
    rerun_label: str = ""
    colour: tuple[int, int, int, int] = (255, 255, 255, 255)

    def __post_init__(self) -> None:
        if not self.label:
            raise ValueError("Drawing.label must not be empty")
        _series_ref(self.series, "Drawing.series")
        if self.cap is not None:
            _finite(self.cap, "Drawing.cap")
        if bool(self.rerun) != bool(self.rerun_label):
            raise ValueError(f"Drawing {self.label!r}: a Rerun line needs a path and a label")
        if len(self.colour) != 4 or any(not 0 <= c <= 255 for c in self.colour):
            raise ValueError(f"Drawing.colour must be RGBA in 0..255, got {self.colour!r}")


@dataclass(frozen=True)
class MetricSpec:
    """One metric of the catalogue (see the module doc)."""

    name: str
    unit: str
    kind: str
    better: str
    series: str = ""
    column: int | None = None
    criterion: Criterion | None = None
    tolerance: Tolerance | None = None
    timing_ratio: float | None = None
    summary: Summary | None = None
    junit: int | None = None
    drawing: Drawing | None = None
    mark: str = ""
    sparkline: bool = False

    def __post_init__(self) -> None:
        if not self.name.isidentifier() or self.name != self.name.lower():
            raise ValueError(f"MetricSpec.name must be a lower-case identifier, "
                             f"got {self.name!r}")
        if not self.unit:
            raise ValueError(f"MetricSpec {self.name}: unit must not be empty ('-' if none)")
        if self.kind not in KINDS:
            raise ValueError(f"MetricSpec {self.name}: kind must be one of {KINDS}, "
                             f"got {self.kind!r}")
        if self.better not in BETTER:
            raise ValueError(f"MetricSpec {self.name}: better must be one of {BETTER}, "
                             f"got {self.better!r}")
        _series_ref(self.series, f"MetricSpec {self.name}: series")
        if self.timing_ratio is not None:
            _finite(self.timing_ratio, f"MetricSpec {self.name}: timing_ratio")
            if self.timing_ratio < 1.0 or self.kind != "timing":
                raise ValueError(f"MetricSpec {self.name}: a timing_ratio is >= 1 and "
                                 "belongs to a timing metric")
        if self.mark and not (self.mark.startswith("#") and len(self.mark) == 7):
            raise ValueError(f"MetricSpec {self.name}: mark must be '#rrggbb', "
                             f"got {self.mark!r}")
        if self.drawing is not None and not (self.series or self.drawing.series):
            raise ValueError(f"MetricSpec {self.name}: a drawing needs a series")

    @property
    def drawn_series(self) -> str:
        """The signal its drawing shows ('' when it is not drawn)."""
        if self.drawing is None:
            return ""
        return self.drawing.series or self.series
