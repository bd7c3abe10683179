"""Base against new for the metric a finding is about: one chart per finding, both runs'
time series of that metric overlaid, with the limit in force.

A metric is drawn as its catalogue entry's ``drawing`` says (:data:`METRIC_SERIES`, from
:mod:`reports.metrics.catalogue`), from the series it is the extreme of: e.g.
``min_ttc_s`` from the time to collision ahead per step (no conflict drawn at 10 s),
``max_abs_long_jerk_mps3`` from the longitudinal jerk, ``min_gap_m`` from the
box-to-box gap, ``rms_lat_dev_m`` from the lateral deviation it aggregates. A metric
without a drawing (counts, timing) gets no chart. Base is drawn grey and dashed, new in colour;
the finding's value on each side is in the legend.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from html import escape
from pathlib import Path

import numpy as np

from reports.charts import Line, Series, fmt, line_chart
from reports.compare.findings import CompareRow
from reports.metrics.catalogue import DRAWN
from reports.metrics.catalogue import TTC_CAP_S as CAP_S
from reports.metrics.values import signal
from reports.record import RecordError, RunRecord, load_run
from reports.record.columns import FloatColumn
from reports.tables import RunEntry, find_entry

__all__ = ["MAX_OVERLAYS", "METRIC_SERIES", "MetricSeries", "overlays_html"]

MAX_OVERLAYS = 24  # charts per page: the first findings of each table, in its order
TTC_CAP_S = CAP_S  # no conflict ahead is drawn at this TTC [s]


@dataclass(frozen=True)
class MetricSeries:
    """The per-step series a metric is drawn from: ``label`` and ``unit`` of the axis,
    ``ref`` the signal (``"<group>.<column>"``, :func:`reports.metrics.values.signal`)
    and ``cap`` (+inf and values above drawn at it; None: non-finite values are gaps)."""

    label: str
    unit: str
    ref: str
    cap: float | None = None

    def values(self, rec: RunRecord) -> FloatColumn | None:
        """(n,) over the trace's ``t_s``, None when the record lacks the signal."""
        y = signal(self.ref, rec.trace, rec.series)
        if y is None:
            return None
        if self.cap is not None:
            out: FloatColumn = np.minimum(y, self.cap)
            return out
        finite: FloatColumn = np.where(np.isfinite(y), y, np.nan)
        return finite


# metric -> how it is drawn: every catalogue entry with a drawing
METRIC_SERIES: dict[str, MetricSeries] = {
    name: MetricSeries(s.drawing.label, s.drawing.unit, s.drawn_series, s.drawing.cap)
    for name, s in DRAWN.items() if s.drawing is not None}


def _run_dir(runs: Sequence[RunEntry], row: CompareRow) -> Path | None:
    entry = find_entry(runs, row.scenario, row.controller)
    return entry.run_dir if entry is not None else None


def _load(run_dir: Path | None) -> RunRecord | None:
    if run_dir is None:
        return None
    try:
        return load_run(run_dir, neighbours=False, arrays=False)
    except (FileNotFoundError, RecordError, OSError):
        return None


def _line(rec: RunRecord | None, ms: MetricSeries, label: str, colour: str,
          dash: bool) -> Series | None:
    if rec is None or len(rec.trace) == 0:
        return None
    y = ms.values(rec)
    if y is None or y.shape != rec.trace.t_s.shape or not np.any(np.isfinite(y)):
        return None
    return Series(label, rec.trace.t_s, y, colour, dash=dash)


def overlay_chart(row: CompareRow, base: RunRecord | None, new: RunRecord | None) -> str:
    """The chart of one finding ('' when its metric has no series or neither side
    has it)."""
    ms = METRIC_SERIES.get(row.metric)
    if ms is None:
        return ""
    lines = [s for s in (
        _line(base, ms, f"base ({fmt(row.base)})", "#94a3b8", True),
        _line(new, ms, f"new ({fmt(row.new)})", "#dc2626", False)) if s is not None]
    if not lines:
        return ""
    hl: list[Line] = [(row.limit, "#b45309", "limit")] if np.isfinite(row.limit) else []
    return line_chart(lines, title=f"{row.key}: {row.metric}", ylabel=ms.unit, hlines=hl)


def overlays_html(rows: Sequence[CompareRow], base: Sequence[RunEntry],
                  new: Sequence[RunEntry], limit: int = MAX_OVERLAYS) -> str:
    """A section with the overlay of each finding in ``rows`` (at most ``limit``
    charts), '' when none can be drawn."""
    charts: list[str] = []
    for row in rows:
        if len(charts) >= limit:
            break
        if row.metric not in METRIC_SERIES:
            continue
        chart = overlay_chart(row, _load(_run_dir(base, row)), _load(_run_dir(new, row)))
        if chart:
            charts.append(f'<div class="overlay" data-key="{escape(row.key)}">{chart}</div>')
    if not charts:
        return ""
    more = len([r for r in rows if r.metric in METRIC_SERIES]) - len(charts)
    tail = f'<p class="none">{more} more not drawn</p>' if more > 0 else ""
    return ("<h2>Base against new, per finding</h2>" + "".join(charts) + tail)
