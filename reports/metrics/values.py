"""Building blocks of the metric layer: a measured metric, extremes of a signal, and the
references from a metric to the per-step signal it summarises.

A metric module returns :class:`Measured` values: the stored :class:`MetricValue` plus,
for cumulative metrics (durations and counts), the per-step ``increments`` whose sum is
the value. The criteria use the increments to find the step at which the running total
first exceeded a limit, and the ``worst_step`` of an extreme for the others, so no
consumer ever has to re-locate where a run failed.

Signal references (``MetricValue.series``) are ``"<group>.<column>"``: ``series.*`` for
:class:`reports.record.SeriesColumns` (computed by the metrics), ``ego.*``,
``safety.*``, ``controller.*``, ``timing.*``, ``decision.*`` for the trace's column
groups. :func:`signal` resolves one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from reports.metrics.catalogue import find, spec
from reports.record import MetricValue, SeriesColumns, Trace
from reports.record.columns import TRACE_GROUPS, FloatColumn

SERIES_GROUP = "series"


@dataclass(frozen=True)
class Measured:
    """A metric and, for a cumulative metric, its per-step ``increments`` (length T,
    same unit as the value; their sum is the value, up to rounding)."""

    metric: MetricValue
    increments: FloatColumn | None = None

    @property
    def name(self) -> str:
        return self.metric.name


def measured(name: str, value: float, unit: str | None = None, kind: str | None = None,
             better: str | None = None, *, worst_step: int | None = None,
             increments: FloatColumn | None = None) -> Measured:
    """A :class:`Measured` (``value`` coerced to float) carrying the unit, kind,
    direction and series of its catalogue entry (:mod:`reports.metrics.catalogue`);
    KeyError for a name the catalogue does not know. The metric modules give only the
    name; ``unit``/``kind``/``better``, when given, replace the entry's (a synthetic
    value in a test; ``better`` 'none' and no series for a name without an entry)."""
    entry = spec(name) if unit is None else find(name)
    return Measured(MetricValue(
        name=name, value=float(value), unit=unit if unit is not None else entry.unit
        if entry is not None else "-",
        kind=kind if kind is not None else entry.kind if entry is not None else "safety",
        better=better if better is not None else entry.better if entry is not None
        else "none", worst_step=worst_step, series=entry.series if entry is not None else ""),
        increments)


def extreme(values: np.ndarray, how: str) -> tuple[float, int | None]:
    """(max or min over the finite samples, row of its first occurrence); (NaN, None)
    when no sample is finite. ``how`` is 'max' or 'min'."""
    v = np.asarray(values, dtype=np.float64)
    ok = np.isfinite(v)
    if not np.any(ok):
        return float("nan"), None
    if how == "max":
        row = int(np.argmax(np.where(ok, v, -np.inf)))
    elif how == "min":
        row = int(np.argmin(np.where(ok, v, np.inf)))
    else:
        raise ValueError(f"extreme: how must be 'max' or 'min', got {how!r}")
    return float(v[row]), row


def first_true(flags: np.ndarray) -> int | None:
    """Row of the first True of a boolean array (None if none)."""
    rows = np.flatnonzero(flags)
    return int(rows[0]) if rows.size else None


def signal(ref: str, trace: Trace, series: SeriesColumns | None) -> FloatColumn | None:
    """The per-step signal a ``MetricValue.series`` reference names, as float64 (None for
    '' or a reference this record cannot resolve, e.g. ``series.*`` without series)."""
    group, _, column = ref.partition(".")
    if not column:
        return None
    if group == SERIES_GROUP:
        source: object = series
    elif group in TRACE_GROUPS:
        source = getattr(trace, group)
    else:
        return None
    values = getattr(source, column, None) if source is not None else None
    if values is None:
        return None
    return np.asarray(values, dtype=np.float64)
