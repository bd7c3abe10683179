"""Base against new for the metric a finding is about: one chart per finding, both runs'
time series of that metric overlaid, with the limit in force.

A metric is drawn from the series it is the extreme of (:data:`METRIC_SERIES`): e.g.
``min_ttc_s`` from the time to collision ahead per step, ``max_abs_long_jerk_mps3``
from the longitudinal jerk, ``min_gap_m`` from the box-to-box gap. A metric without a
series (counts, timing) gets no chart. Base is drawn grey and dashed, new in colour;
the finding's value on each side is in the legend.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from html import escape
from pathlib import Path

import numpy as np

from reports.charts import Line, Series, fmt, line_chart
from reports.compare.findings import CompareRow
from reports.record import RecordError, RunRecord, load_run
from reports.record.columns import FloatColumn
from reports.tables import RunEntry, find_entry

__all__ = ["MAX_OVERLAYS", "METRIC_SERIES", "MetricSeries", "overlays_html"]

MAX_OVERLAYS = 24  # charts per page: the first findings of each table, in its order
TTC_CAP_S = 10.0  # no conflict ahead is drawn at this TTC [s]


@dataclass(frozen=True)
class MetricSeries:
    """The per-step series a metric is the extreme of: ``label`` and ``unit`` of the
    axis and ``values(record)`` -> (n,) over the trace's ``t_s`` (None when absent)."""

    label: str
    unit: str
    values: Callable[[RunRecord], FloatColumn | None]


def _series(name: str) -> Callable[[RunRecord], FloatColumn | None]:
    def get(rec: RunRecord) -> FloatColumn | None:
        if rec.series is None:
            return None
        out: FloatColumn = np.asarray(getattr(rec.series, name), dtype=np.float64)
        return out
    return get


def _ttc(rec: RunRecord) -> FloatColumn | None:
    if rec.series is None:
        return None
    out: FloatColumn = np.minimum(np.asarray(rec.series.ttc_s, dtype=np.float64), TTC_CAP_S)
    return out


def _gap(rec: RunRecord) -> FloatColumn:
    gap = np.asarray(rec.trace.safety.min_gap_m, dtype=np.float64)
    out: FloatColumn = np.where(np.isfinite(gap), gap, np.nan)
    return out


def _ego(name: str) -> Callable[[RunRecord], FloatColumn]:
    def get(rec: RunRecord) -> FloatColumn:
        out: FloatColumn = np.asarray(getattr(rec.trace.ego, name), dtype=np.float64)
        return out
    return get


_ACC = MetricSeries("longitudinal acceleration", "m/s²", _series("long_acc_mps2"))
METRIC_SERIES: dict[str, MetricSeries] = {
    "min_ttc_s": MetricSeries(f"TTC ahead (none = {TTC_CAP_S:g})", "s", _ttc),
    "min_gap_m": MetricSeries("gap to the nearest vehicle (box to box)", "m", _gap),
    "min_long_acc_mps2": _ACC,
    "max_long_acc_mps2": _ACC,
    "max_abs_lat_acc_mps2": MetricSeries("lateral acceleration", "m/s²",
                                         _series("lat_acc_mps2")),
    "max_abs_long_jerk_mps3": MetricSeries("longitudinal jerk", "m/s³",
                                           _series("long_jerk_mps3")),
    "max_abs_jerk_mps3": MetricSeries("jerk", "m/s³", _series("jerk_mps3")),
    "max_abs_yaw_rate_radps": MetricSeries("yaw rate", "rad/s", _series("yaw_rate_radps")),
    "max_abs_yaw_acc_radps2": MetricSeries("yaw acceleration", "rad/s²",
                                           _series("yaw_acc_radps2")),
    "min_ellipse_margin": MetricSeries("ellipse margin", "-", _series("ellipse_margin")),
    **dict.fromkeys(("offroad_s", "max_offroad_m"), MetricSeries(
        "corner beyond the drivable area", "m", _series("offroad_excess_m"))),
    **dict.fromkeys(("rms_lat_dev_m", "final_abs_lat_dev_m", "max_abs_lat_dev_m"),
                    MetricSeries("lateral deviation", "m", _ego("lat_dev_m"))),
}


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
