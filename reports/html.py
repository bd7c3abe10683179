"""report.html: one self-contained page (inline CSS, JS and SVG; no network request).

Contents: header with status counts; pass/fail matrices (families × controllers and
scenarios × controllers, cells linked to the runs); per-controller summary tables; timing
CDFs per loop (total, outer, inner, SUMO) with one line per controller; then one
collapsible section per run (failed/errored first and open) with its metrics, a
bird's-eye plot (lanes from road.json, stalled cars, other vehicles' paths, the ego path
coloured by speed, failure locations marked) and time series (speed and set-point,
lateral deviation, accelerations, steering, gap/TTC, residual E). Every series is
decimated to ≤ ``MAX_POINTS`` points (min/max per bucket, so peaks survive).
"""

from __future__ import annotations

import datetime as _dt
import html
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from reports.metrics.comfort import comfort_series
from reports.metrics.criteria import Criteria, parse_failure
from reports.metrics.evaluate import REQUIRED_METRICS
from reports.metrics.geometry import box_corners
from reports.metrics.safety import (
    collision_steps,
    ego_boxes,
    ellipse_margin_series,
    lane_is_drivable,
    offroad_steps,
    shoulder_allowed,
    ttc_series,
)
from reports.metrics.timing import loop_times_s
from reports.metrics.tracking import column
from reports.tables import STATUSES, RunEval, summary_frame

MAX_POINTS = 400
STATUS_COLOURS = {"pass": "#15803d", "fail": "#dc2626", "error": "#7c3aed",
                  "timeout": "#d97706"}
STATUS_ORDER = {"error": 0, "timeout": 1, "fail": 2, "pass": 3}
PALETTE = ("#2563eb", "#ea580c", "#059669", "#9333ea", "#db2777", "#0891b2", "#65a30d",
           "#b45309")
VIRIDIS = ("#440154", "#414487", "#2a788e", "#22a884", "#7ad151", "#fde725")
ESC = html.escape


def esc(value: object) -> str:
    """HTML-escaped text (quotes too)."""
    return ESC(str(value), quote=True)


def fmt(value: float, digits: int = 4) -> str:
    """Compact number for tables."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        return esc(value)
    if math.isnan(v):
        return "–"
    if math.isinf(v):
        return "∞" if v > 0 else "−∞"
    if v == int(v) and abs(v) < 1e9:
        return str(int(v))
    return f"{v:.{digits}g}"


# --------------------------------------------------------------------------- decimation


def decimate(x: np.ndarray, y: np.ndarray, max_points: int = MAX_POINTS
             ) -> tuple[np.ndarray, np.ndarray]:
    """At most ``max_points`` samples of (x, y): per bucket the min and max of y (in order)."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    n = y.size
    if n <= max_points:
        return x, y
    keep: list[int] = []
    for bucket in np.array_split(np.arange(n), max(1, max_points // 2)):
        vals = y[bucket]
        ok = np.isfinite(vals)
        if not np.any(ok):
            keep.append(int(bucket[0]))
            continue
        lo = int(bucket[np.flatnonzero(ok)[np.argmin(vals[ok])]])
        hi = int(bucket[np.flatnonzero(ok)[np.argmax(vals[ok])]])
        keep.extend(sorted({lo, hi}))
    idx = np.array(keep, dtype=int)
    return x[idx], y[idx]


# --------------------------------------------------------------------------- charts


@dataclass
class Series:
    """One line of a chart."""

    label: str
    x: np.ndarray
    y: np.ndarray
    colour: str
    dash: bool = False
    width: float = 1.6


def nice_ticks(lo: float, hi: float, n: int = 5) -> list[float]:
    """Round tick values covering [lo, hi]."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return [lo] if math.isfinite(lo) else []
    raw = (hi - lo) / n
    mag = 10 ** math.floor(math.log10(raw))
    step = mag
    for m in (1, 2, 2.5, 5, 10):
        step = m * mag
        if (hi - lo) / step <= n:
            break
    start = math.ceil(lo / step) * step
    ticks = []
    v = start
    while v <= hi + step * 1e-9:
        ticks.append(0.0 if abs(v) < step * 1e-9 else v)
        v += step
    return ticks


def _log_ticks(lo: float, hi: float, n: int = 6) -> list[float]:
    """Whole decades in [lo, hi] (log10 units), thinned to at most ``n``."""
    decades = list(range(math.ceil(lo), math.floor(hi) + 1))
    step = max(1, math.ceil(len(decades) / n))
    return [float(v) for v in decades[::step]]


def _path(px: np.ndarray, py: np.ndarray) -> str:
    parts: list[str] = []
    pen = False
    for a, b in zip(px, py, strict=True):
        if not (math.isfinite(a) and math.isfinite(b)):
            pen = False
            continue
        parts.append(f"{'L' if pen else 'M'}{a:.1f} {b:.1f}")
        pen = True
    return "".join(parts)


def line_chart(series: Sequence[Series], *, title: str, ylabel: str = "",
               xlabel: str = "t [s]", width: int = 860, height: int = 170,
               xlog: bool = False, ylog: bool = False,
               hlines: Iterable[tuple[float, str, str]] = (),
               vlines: Iterable[tuple[float, str, str]] = (),
               legend_inside: bool = False) -> str:
    """Inline SVG line chart. hlines/vlines: (value, colour, label). The legend runs along
    the top edge, or (``legend_inside``) stacked in the plot's lower-right corner."""
    hlines, vlines = list(hlines), list(vlines)

    def tx(v: np.ndarray, log: bool) -> np.ndarray:
        v = np.asarray(v, dtype=np.float64)
        v = np.where(np.isfinite(v), v, np.nan)
        if log:
            with np.errstate(divide="ignore", invalid="ignore"):
                return np.where(v > 0, np.log10(np.where(v > 0, v, 1.0)), np.nan)
        return v

    data = [(s, *decimate(tx(s.x, xlog), tx(s.y, ylog))) for s in series]
    xs = np.concatenate([d[1] for d in data]) if data else np.zeros(0)
    ys = np.concatenate([d[2] for d in data]) if data else np.zeros(0)
    xs, ys = xs[np.isfinite(xs)], ys[np.isfinite(ys)]
    if xs.size == 0 or ys.size == 0:
        return f'<div class="nodata">{esc(title)}: no data</div>'
    x0, x1 = float(xs.min()), float(xs.max())
    y0, y1 = float(ys.min()), float(ys.max())
    for value, _, _ in hlines:
        tv = float(tx(np.array([value]), ylog)[0])
        if math.isfinite(tv):
            y0, y1 = min(y0, tv), max(y1, tv)
    if x1 <= x0:
        x0, x1 = x0 - 0.5, x1 + 0.5
    min_span = 0.5 if ylog else max(1e-12, 1e-6 * max(abs(y0), abs(y1)))
    if y1 - y0 < min_span:  # flat (or numerically flat) signal: show a sensible band
        mid = 0.5 * (y0 + y1)
        pad = max(abs(mid) * 0.1, 0.1) if not ylog else 0.5
        y0, y1 = mid - pad, mid + pad
    pad_y = 0.06 * (y1 - y0)
    y0, y1 = y0 - pad_y, y1 + pad_y
    ml, mr, mt, mb = 64, 12, 22, 30
    pw, ph = width - ml - mr, height - mt - mb

    def mx(v: np.ndarray | float) -> np.ndarray:
        return (np.asarray(v, dtype=np.float64) - x0) / (x1 - x0) * pw

    def my(v: np.ndarray | float) -> np.ndarray:
        return ph - (np.asarray(v, dtype=np.float64) - y0) / (y1 - y0) * ph

    out = [f'<svg class="chart" width="{width}" '
           f'height="{height}" viewBox="0 0 {width} {height}" role="img">',
           f"<title>{esc(title)}</title>",
           f'<text x="{ml}" y="14" class="ct">{esc(title)}</text>']

    def tick_labels(ticks: Sequence[float], log: bool) -> list[str]:
        if log:
            return [fmt(10 ** v, 3) for v in ticks]
        step = min((b - a for a, b in zip(ticks, ticks[1:], strict=False)), default=1.0)
        decimals = max(0, math.ceil(-math.log10(step) - 1e-9)) if step > 0 else 0
        if decimals == 0:
            return [f"{v:.0f}" for v in ticks]
        labels = [f"{v:.{decimals + 1}f}".rstrip("0").rstrip(".") for v in ticks]
        return [lb if lb not in ("-0", "") else "0" for lb in labels]

    xticks = (_log_ticks(x0, x1) if xlog else nice_ticks(x0, x1, 8))
    yticks = (_log_ticks(y0, y1) if ylog else nice_ticks(y0, y1, 4))
    for v, label in zip(xticks, tick_labels(xticks, xlog), strict=True):
        px = ml + float(mx(v))
        out.append(f'<line x1="{px:.1f}" y1="{mt}" x2="{px:.1f}" y2="{mt + ph}" class="grid"/>'
                   f'<text x="{px:.1f}" y="{mt + ph + 13}" class="tick" text-anchor="middle">'
                   f"{esc(label)}</text>")
    for v, label in zip(yticks, tick_labels(yticks, ylog), strict=True):
        py = mt + float(my(v))
        out.append(f'<line x1="{ml}" y1="{py:.1f}" x2="{ml + pw}" y2="{py:.1f}" class="grid"/>'
                   f'<text x="{ml - 4}" y="{py + 3:.1f}" class="tick" text-anchor="end">'
                   f"{esc(label)}</text>")
    out.append(f'<rect x="{ml}" y="{mt}" width="{pw}" height="{ph}" class="frame"/>')
    out.append(f'<text x="{ml + pw}" y="{height - 3}" class="tick" text-anchor="end">'
               f"{esc(xlabel)}</text>")
    if ylabel:
        out.append(f'<text x="12" y="{mt + ph / 2:.0f}" class="tick" text-anchor="middle" '
                   f'transform="rotate(-90 12 {mt + ph / 2:.0f})">{esc(ylabel)}</text>')
    out.append(f'<svg x="{ml}" y="{mt}" width="{pw}" height="{ph}" viewBox="0 0 {pw} {ph}">')
    for value, colour, label in hlines:
        tv = float(tx(np.array([value]), ylog)[0])
        if math.isfinite(tv):
            py = float(my(tv))
            out.append(f'<line x1="0" y1="{py:.1f}" x2="{pw}" y2="{py:.1f}" stroke="{colour}" '
                       f'stroke-dasharray="5 3" stroke-width="1"><title>{esc(label)}</title>'
                       "</line>")
    for value, colour, label in vlines:
        tv = float(tx(np.array([value]), xlog)[0])
        if math.isfinite(tv):
            px = float(mx(tv))
            out.append(f'<line x1="{px:.1f}" y1="0" x2="{px:.1f}" y2="{ph}" stroke="{colour}" '
                       f'stroke-width="1.5"><title>{esc(label)}</title></line>')
    for s, sx, sy in data:
        d = _path(mx(sx), my(sy))
        if d:
            dash = ' stroke-dasharray="6 3"' if s.dash else ""
            out.append(f'<path d="{d}" fill="none" stroke="{s.colour}" '
                       f'stroke-width="{s.width}"{dash}><title>{esc(s.label)}</title></path>')
    out.append("</svg>")
    lx = width - mr
    for i, s in enumerate(reversed(series)):
        label = esc(s.label)
        if legend_inside:
            ly = mt + ph - 6 - 13 * i
            out.append(f'<text x="{ml + pw - 6}" y="{ly}" class="legend" text-anchor="end" '
                       f'fill="{s.colour}">{label}</text>')
            continue
        out.append(f'<text x="{lx}" y="14" class="legend" text-anchor="end" '
                   f'fill="{s.colour}">{label}</text>')
        lx -= 7 * len(s.label) + 14
    out.append("</svg>")
    return "".join(out)


def cdf_chart(samples: dict[str, np.ndarray], *, title: str, deadline_ms: float | None = None,
              width: int = 330, height: int = 230) -> str:
    """CDF of times [ms] per label (log x axis when the data spans > 1 decade)."""
    series = []
    allv = [v[np.isfinite(v) & (v > 0)] for v in samples.values()]
    allv = [v for v in allv if v.size]
    if not allv:
        return f'<div class="nodata">{esc(title)}: no data</div>'
    cat = np.concatenate(allv)
    xlog = bool(cat.max() / max(cat.min(), 1e-9) > 10)
    for i, (label, values) in enumerate(samples.items()):
        v = np.sort(values[np.isfinite(values) & (values > 0)])
        if not v.size:
            continue
        p = np.arange(1, v.size + 1) / v.size
        if v.size > MAX_POINTS:
            idx = np.unique(np.linspace(0, v.size - 1, MAX_POINTS).astype(int))
            v, p = v[idx], p[idx]
        series.append(Series(label, v, p, PALETTE[i % len(PALETTE)]))
    vlines = [(deadline_ms, "#dc2626", "control period")] if deadline_ms else []
    return line_chart(series, title=title, ylabel="fraction", xlabel="time [ms]", width=width,
                      height=height, xlog=xlog, vlines=vlines, legend_inside=True)


# --------------------------------------------------------------------------- failure marks


def failure_marks(run: RunEval) -> list[tuple[str, int, str]]:
    """(label, trace row, colour) for where each failure happened (first or worst step)."""
    rec = run.record
    if rec is None or len(rec.trace) == 0:
        return []
    marks: list[tuple[str, int, str]] = []
    t = column(rec, "t_s")
    names = [p[0] for p in (parse_failure(f) for f in run.failed) if p is not None]
    comfort = None
    comfort_keys = {"min_long_acc_mps2": ("long_acc", -1), "max_long_acc_mps2": ("long_acc", 1),
                    "max_abs_lat_acc_mps2": ("lat_acc", 0), "max_abs_yaw_rate_radps":
                    ("yaw_rate", 0), "max_abs_yaw_acc_radps2": ("yaw_acc", 0),
                    "max_abs_long_jerk_mps3": ("long_jerk", 0), "max_abs_jerk_mps3": ("jerk", 0)}

    def worst(values: np.ndarray, sign: int) -> int | None:
        v = np.asarray(values, dtype=np.float64)
        v = -v if sign < 0 else (np.abs(v) if sign == 0 else v)
        v = np.where(np.isfinite(v), v, -np.inf)
        return int(np.argmax(v)) if np.any(np.isfinite(v)) else None

    for name in names:
        row: int | None = None
        colour = "#9333ea"
        if name == "collision":
            rows = np.flatnonzero(collision_steps(rec))
            row, colour = (int(rows[0]) if rows.size else None), "#dc2626"
        elif name == "offroad_s":
            rows = np.flatnonzero(offroad_steps(rec))
            row, colour = (int(rows[0]) if rows.size else None), "#ea580c"
        elif name == "min_ttc_s":
            ttc = ttc_series(rec)
            row = int(np.argmin(ttc)) if np.any(np.isfinite(ttc)) else None
            colour = "#db2777"
        elif name == "min_gap_m":
            row = worst(column(rec, "min_gap_m"), -1)
        elif name == "min_ellipse_margin":
            row = worst(ellipse_margin_series(rec), -1)
        elif name in comfort_keys:
            comfort = comfort if comfort is not None else comfort_series(rec)
            key, sign = comfort_keys[name]
            row = worst(comfort[key], sign)
        if row is not None:
            marks.append((f"{name} at t={fmt(t[row], 4)} s", row, colour))
    if run.status in ("error", "timeout"):
        marks.append((f"{run.status} at t={fmt(t[-1], 4)} s", len(t) - 1, "#7c3aed"))
    return marks


# --------------------------------------------------------------------------- bird's-eye


def _viridis(frac: np.ndarray) -> list[str]:
    idx = np.clip(np.round(np.nan_to_num(frac) * (len(VIRIDIS) - 1)), 0, len(VIRIDIS) - 1)
    return [VIRIDIS[int(i)] for i in idx]


def _offset_polyline(shape: np.ndarray, offset: float) -> np.ndarray:
    """Polyline shifted sideways by ``offset`` (left +) using vertex normals."""
    if shape.shape[0] < 2:
        return shape
    d = np.gradient(shape, axis=0)
    norm = np.linalg.norm(d, axis=1, keepdims=True)
    d = d / np.maximum(norm, 1e-9)
    normal = np.stack([-d[:, 1], d[:, 0]], axis=1)
    return shape + offset * normal


ZOOM_HALF_LENGTH_M = 40.0
ZOOM_HALF_WIDTH_M = 12.0


def birdseye_svg(run: RunEval, marks: Sequence[tuple[str, int, str]], width: int = 860,
                 max_height: int = 280, zoom: tuple[int, str] | None = None) -> str:
    """Bird's-eye view of one run (see module doc); lateral scale exaggerated when the
    plotted stretch is long and thin (the factor is printed). With ``zoom=(row, label)``:
    a true-scale ±40 m window around the ego at that trace row, with every vehicle's box
    at that step."""
    rec = run.record
    if rec is None or len(rec.trace) == 0:
        return '<div class="nodata">bird\'s-eye: no trace</div>'
    x, y = column(rec, "x_m"), column(rec, "y_m")
    ok = np.isfinite(x) & np.isfinite(y)
    if not np.any(ok):
        return '<div class="nodata">bird\'s-eye: no pose</div>'
    xo, yo = x[ok], y[ok]
    origin = np.array([xo[0], yo[0]])
    chord = np.array([xo[-1] - xo[0], yo[-1] - yo[0]])
    psi = column(rec, "psi_rad")[ok]
    if np.isfinite(psi[0]) and np.isfinite(psi[-1]):
        # mean of start and end headings: the chord direction of an arc, and exactly the
        # road direction for lane changes on a straight road
        theta = math.atan2(math.sin(psi[0]) + math.sin(psi[-1]),
                           math.cos(psi[0]) + math.cos(psi[-1]))
    elif np.hypot(*chord) > 1.0:
        theta = math.atan2(chord[1], chord[0])
    else:
        theta = 0.0
    c, s = math.cos(theta), math.sin(theta)

    def to_local(px: np.ndarray, py: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        dx, dy = np.asarray(px) - origin[0], np.asarray(py) - origin[1]
        return dx * c + dy * s, -dx * s + dy * c

    ea, eb = to_local(xo, yo)
    a0, a1 = float(ea.min()) - 30.0, float(ea.max()) + 30.0
    b0, b1 = float(eb.min()) - 9.0, float(eb.max()) + 9.0
    focus_row = -1
    if zoom is not None and 0 <= zoom[0] < len(x) and np.isfinite(x[zoom[0]]) \
            and np.isfinite(y[zoom[0]]):
        focus_row = zoom[0]
        fa, fb = to_local(np.array([x[focus_row]]), np.array([y[focus_row]]))
        a0, a1 = float(fa[0]) - ZOOM_HALF_LENGTH_M, float(fa[0]) + ZOOM_HALF_LENGTH_M
        b0, b1 = float(fb[0]) - ZOOM_HALF_WIDTH_M, float(fb[0]) + ZOOM_HALF_WIDTH_M
    elif zoom is not None:
        return ""
    pad = 8
    pw = width - 2 * pad
    sx = pw / (a1 - a0)
    if (b1 - b0) * sx <= max_height - 2 * pad:
        sy = sx
        height = int(max((b1 - b0) * sx + 2 * pad, 120))
        # centre the band vertically when the min height adds room
        extra = (height - 2 * pad) / sy - (b1 - b0)
        b0, b1 = b0 - extra / 2, b1 + extra / 2
    else:
        height = max_height
        sy = (height - 2 * pad) / (b1 - b0)
    exaggeration = sy / sx

    def to_px(px: np.ndarray, py: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        la, lb = to_local(px, py)
        return pad + (la - a0) * sx, height - pad - (lb - b0) * sy

    def pts(px: np.ndarray, py: np.ndarray) -> str:
        u, v = to_px(px, py)
        return " ".join(f"{p:.1f},{q:.1f}" for p, q in zip(u, v, strict=True)
                        if math.isfinite(p) and math.isfinite(q))

    def in_view(px: np.ndarray, py: np.ndarray, margin: float = 60.0) -> np.ndarray:
        la, lb = to_local(px, py)
        return (la > a0 - margin) & (la < a1 + margin) & (lb > b0 - margin) & (lb < b1 + margin)

    def visible_part(px: np.ndarray, py: np.ndarray) -> slice:
        """The index range of a path that can show in a zoomed view (all of it otherwise)."""
        if focus_row < 0:
            return slice(0, len(px))
        idx = np.flatnonzero(in_view(px, py, 10.0))
        if idx.size == 0:
            return slice(0, 0)
        return slice(max(int(idx[0]) - 1, 0), min(int(idx[-1]) + 2, len(px)))

    out = [f'<svg class="bev" width="{width}" '
           f'height="{height}" viewBox="0 0 {width} {height}" role="img">',
           "<title>bird's-eye view</title>",
           f'<rect x="0" y="0" width="{width}" height="{height}" fill="#f8fafc"/>']
    allow_sh = shoulder_allowed(rec.meta)
    lanes = rec.road.get("lanes") or []
    edges: list[str] = []
    for lane in lanes:
        shape = np.asarray(lane.get("shape_xy_m") or [], dtype=np.float64).reshape(-1, 2)
        w = float(lane.get("width_m") or 0.0)
        if shape.shape[0] < 2 or w <= 0:
            continue
        view = in_view(shape[:, 0], shape[:, 1], 400.0)
        if not np.any(view):
            # long straight segments may have both ends out of view: keep if it crosses
            la, lb = to_local(shape[:, 0], shape[:, 1])
            if not (np.any(lb > b0 - 20) and np.any(lb < b1 + 20) and la.min() < a1
                    and la.max() > a0):
                continue
            view[:] = True
        idx = np.flatnonzero(view)
        lo, hi = max(int(idx[0]) - 1, 0), min(int(idx[-1]) + 2, shape.shape[0])
        part = shape[lo:hi]
        left, right = _offset_polyline(part, w / 2), _offset_polyline(part, -w / 2)
        ring = np.vstack([left, right[::-1]])
        if lane.get("is_shoulder"):
            fill = "#e9dcc0" if allow_sh else "#f0e4cc"
        elif lane_is_drivable(lane, allow_sh):
            fill = "#d4d8de"
        else:
            fill = "#f1c9c9"
        title = esc(f"{lane.get('id', '')}{' (shoulder)' if lane.get('is_shoulder') else ''}")
        out.append(f'<polygon points="{pts(ring[:, 0], ring[:, 1])}" fill="{fill}">'
                   f"<title>{title}</title></polygon>")
        for side in (left, right):
            edges.append(f'<polyline points="{pts(side[:, 0], side[:, 1])}" fill="none" '
                         'stroke="#ffffff" stroke-width="1" stroke-dasharray="8 6"/>')
    out.extend(edges)
    nb = rec.neighbours
    if len(nb) and {"id", "x_m", "y_m"} <= set(nb.columns):
        stalled_col = nb["stalled"] if "stalled" in nb.columns else pd.Series(False,
                                                                              index=nb.index)
        moving = nb.loc[~stalled_col.fillna(False).astype(bool)]
        for vid, grp in list(moving.groupby("id", sort=False))[:60]:
            gx, gy = grp["x_m"].to_numpy(float), grp["y_m"].to_numpy(float)
            span = visible_part(gx, gy)
            if span.stop - span.start < 2:
                continue
            gx, gy = gx[span], gy[span]
            if gx.size > 80:
                k = np.unique(np.linspace(0, gx.size - 1, 80).astype(int))
                gx, gy = gx[k], gy[k]
            out.append(f'<polyline points="{pts(gx, gy)}" fill="none" stroke="#334155" '
                       f'stroke-opacity="0.35" stroke-width="1.2"><title>{esc(vid)}</title>'
                       "</polyline>")
    for st in rec.meta.get("stalled") or []:
        try:
            corners = box_corners(float(st["x_m"]), float(st["y_m"]),
                                  float(st.get("heading_rad", 0.0)),
                                  float(st.get("length_m", 4.5)), float(st.get("width_m", 1.8)))
        except (KeyError, TypeError, ValueError):
            continue
        out.append(f'<polygon points="{pts(corners[:, 0], corners[:, 1])}" fill="#b91c1c" '
                   f'fill-opacity="0.85" stroke="#7f1d1d"><title>stalled {esc(st.get("id", ""))}'
                   "</title></polygon>")
    # obstacle ellipses the controller saw, at the step of the smallest margin
    ell = rec.arrays.get("ellipses")
    margins = ellipse_margin_series(rec)
    if ell is not None and np.any(np.isfinite(margins)):
        ell_row = int(np.nanargmin(margins))
        steps = column(rec, "step")
        ell_idx = ell_row
        if np.isfinite(steps[ell_row]) and 0 <= steps[ell_row] < len(ell):
            ell_idx = int(steps[ell_row])
        ang = np.linspace(0.0, 2 * np.pi, 37)
        for e in np.asarray(ell[min(ell_idx, len(ell) - 1)], dtype=np.float64).reshape(-1, 6):
            if not (np.all(np.isfinite(e[:5])) and e[5] > 0.5):
                continue
            ex = e[0] + e[3] * np.cos(ang) * math.cos(e[2]) - e[4] * np.sin(ang) * math.sin(e[2])
            ey = e[1] + e[3] * np.cos(ang) * math.sin(e[2]) + e[4] * np.sin(ang) * math.cos(e[2])
            out.append(f'<polygon points="{pts(ex, ey)}" fill="#f59e0b" fill-opacity="0.12" '
                       'stroke="#d97706" stroke-dasharray="4 3" stroke-width="1">'
                       f"<title>obstacle ellipse at t={fmt(column(rec, 't_s')[ell_row], 4)} s "
                       f"(min margin {fmt(margins[ell_row], 3)})</title></polygon>")
    # ego boxes every ~1/8 of the run (zoom: of the part in view), faint
    _, _, _, corners = ego_boxes(rec)
    n = len(rec.trace)
    box_rows = np.unique(np.linspace(0, n - 1, 9).astype(int))
    if focus_row >= 0:
        inside = np.flatnonzero(in_view(x, y, 0.0))
        box_rows = inside[np.unique(np.linspace(0, inside.size - 1, 10).astype(int))] \
            if inside.size else np.zeros(0, dtype=int)
        nbs = rec.neighbours
        if len(nbs) and "step" in nbs.columns:
            step_here = column(rec, "step")[focus_row]
            now = nbs[nbs["step"] == step_here]
            for _, nrow in now.iterrows():
                nc = box_corners(float(nrow["x_m"]), float(nrow["y_m"]),
                                 float(nrow.get("heading_rad", 0.0)),
                                 float(nrow.get("length_m", 4.5)),
                                 float(nrow.get("width_m", 1.8)))
                colour = "#b91c1c" if bool(nrow.get("stalled", False)) else "#475569"
                out.append(f'<polygon points="{pts(nc[:, 0], nc[:, 1])}" fill="{colour}" '
                           f'fill-opacity="0.55" stroke="{colour}"><title>{esc(nrow["id"])} '
                           f'{fmt(float(nrow.get("speed_mps", math.nan)), 3)} m/s</title>'
                           "</polygon>")
        fc = corners[focus_row]
        if np.all(np.isfinite(fc)):
            out.append(f'<polygon points="{pts(fc[:, 0], fc[:, 1])}" fill="#2563eb" '
                       'fill-opacity="0.45" stroke="#1d4ed8" stroke-width="1.5">'
                       "<title>ego at the focus step</title></polygon>")
    for i in box_rows:
        cb = corners[i]
        if np.all(np.isfinite(cb)):
            out.append(f'<polygon points="{pts(cb[:, 0], cb[:, 1])}" fill="#2563eb" '
                       'fill-opacity="0.10" stroke="#2563eb" stroke-opacity="0.5" '
                       'stroke-width="0.8"/>')
    # ego path coloured by speed (runs of equal colour share one polyline)
    speed = column(rec, "speed_mps")
    finite_speed = speed[np.isfinite(speed)]
    v0 = float(finite_speed.min()) if finite_speed.size else 0.0
    v1 = float(finite_speed.max()) if finite_speed.size else 1.0
    span = visible_part(x, y)
    px_all, py_all, speed_d = x[span], y[span], speed[span]
    if px_all.size > MAX_POINTS:
        k = np.unique(np.linspace(0, px_all.size - 1, MAX_POINTS).astype(int))
        px_all, py_all, speed_d = px_all[k], py_all[k], speed_d[k]
    colours = _viridis((speed_d - v0) / max(v1 - v0, 1e-6))
    start = 0
    for i in range(1, len(colours) + 1):
        if i == len(colours) or colours[i] != colours[start]:
            seg = slice(start, min(i + 1, len(colours)))
            out.append(f'<polyline points="{pts(px_all[seg], py_all[seg])}" fill="none" '
                       f'stroke="{colours[start]}" stroke-width="2.6" '
                       'stroke-linecap="round"/>')
            start = i
    sx0, sy0 = to_px(np.array([xo[0]]), np.array([yo[0]]))
    ex0, ey0 = to_px(np.array([xo[-1]]), np.array([yo[-1]]))
    out.append(f'<circle cx="{sx0[0]:.1f}" cy="{sy0[0]:.1f}" r="4" fill="#16a34a">'
               "<title>start</title></circle>")
    out.append(f'<rect x="{ex0[0] - 3.5:.1f}" y="{ey0[0] - 3.5:.1f}" width="7" height="7" '
               'fill="#111827"><title>end</title></rect>')
    for label, row, colour in marks:
        if not (0 <= row < n) or not (np.isfinite(x[row]) and np.isfinite(y[row])):
            continue
        mx_, my_ = to_px(np.array([x[row]]), np.array([y[row]]))
        cx, cy = float(mx_[0]), float(my_[0])
        out.append(f'<g class="mark"><title>{esc(label)}</title>'
                   f'<circle cx="{cx:.1f}" cy="{cy:.1f}" r="9" fill="none" stroke="{colour}" '
                   'stroke-width="2.5"/>'
                   f'<path d="M{cx - 6:.1f} {cy - 6:.1f}L{cx + 6:.1f} {cy + 6:.1f}M{cx - 6:.1f} '
                   f'{cy + 6:.1f}L{cx + 6:.1f} {cy - 6:.1f}" stroke="{colour}" '
                   'stroke-width="2.5"/></g>')
    note = (f"lateral scale ×{exaggeration:.1f}" if exaggeration > 1.05 else "true scale")
    if focus_row >= 0 and zoom is not None:
        note = f"zoom ±{ZOOM_HALF_LENGTH_M:.0f} m around {zoom[1]} · {note}"
    out.append(f'<text x="{width - 10}" y="{height - 10}" class="tick" text-anchor="end">'
               f"{esc(note)} · speed {fmt(v0, 3)}–{fmt(v1, 3)} m/s (dark→light)</text>")
    out.append("</svg>")
    return "".join(out)


# --------------------------------------------------------------------------- sections


def zoom_focus(run: RunEval, marks: Sequence[tuple[str, int, str]]) -> tuple[int, str] | None:
    """Where to zoom the bird's-eye view: the first failure mark, else the closest approach
    (smallest gap) when one was recorded."""
    if marks:
        return marks[0][1], marks[0][0].split(" at ")[0]
    rec = run.record
    if rec is None or len(rec.trace) == 0:
        return None
    gap = column(rec, "min_gap_m")
    if not np.any(np.isfinite(gap)):
        return None
    row = int(np.nanargmin(np.where(np.isfinite(gap), gap, np.nan)))
    return row, f"closest approach ({fmt(gap[row], 3)} m)"


def run_anchor(run: RunEval) -> str:
    """The element id of a run's section."""
    safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in run.run_id)
    return f"run-{safe}"


def badge(status: str) -> str:
    """Coloured status label."""
    return f'<span class="badge {esc(status)}">{esc(status)}</span>'


def time_series(run: RunEval, marks: Sequence[tuple[str, int, str]]) -> str:
    """The per-run time-series charts."""
    rec = run.record
    if rec is None or len(rec.trace) == 0:
        return '<div class="nodata">no trace</div>'
    t = column(rec, "t_s")
    vl = [(float(t[row]), colour, label) for label, row, colour in marks if 0 <= row < len(t)]
    crit = Criteria.from_overrides(rec.meta.get("criteria") or None) \
        if _criteria_ok(rec.meta.get("criteria")) else Criteria()
    charts = [line_chart([Series("speed", t, column(rec, "speed_mps"), PALETTE[0]),
                          Series("set-point", t, column(rec, "target_speed_mps"), "#64748b",
                                 dash=True)], title="speed", ylabel="m/s", vlines=vl)]
    charts.append(line_chart([Series("lateral deviation", t, column(rec, "lat_dev_m"),
                                     PALETTE[2])], title="lateral deviation from reference",
                             ylabel="m", vlines=vl, hlines=[(0.0, "#94a3b8", "reference")]))
    comfort = comfort_series(rec)
    hl: list[tuple[float, str, str]] = []
    for name, label in (("min_long_acc_mps2", "long acc min"),
                        ("max_long_acc_mps2", "long acc max")):
        limit = getattr(crit, name)
        if limit is not None:
            hl.append((limit, "#fca5a5", label))
    charts.append(line_chart([Series("long acc", t, comfort["long_acc"], PALETTE[0]),
                              Series("lat acc", t, comfort["lat_acc"], PALETTE[1])],
                             title="accelerations (SG-smoothed)", ylabel="m/s²", vlines=vl,
                             hlines=hl))
    steer = [Series("steer", t, column(rec, "steer_rad"), PALETTE[3])]
    for name, label, colour in (("steer_outer_rad", "outer", PALETTE[5]),
                                ("steer_corr_rad", "inner corr", PALETTE[4])):
        values = column(rec, name)
        if np.any(np.isfinite(values) & (values != 0)):
            steer.append(Series(label, t, values, colour, dash=True, width=1.2))
    charts.append(line_chart(steer, title="steering (front-wheel angle)", ylabel="rad",
                             vlines=vl))
    gap = column(rec, "min_gap_m")
    ttc = np.minimum(ttc_series(rec), 10.0)
    if np.any(np.isfinite(gap)) or np.any(ttc < 10.0):
        hl2 = [(crit.min_ttc_s, "#fca5a5", "TTC limit")] if crit.min_ttc_s is not None else []
        charts.append(line_chart([Series("gap [m]", t, np.where(np.isfinite(gap), gap, np.nan),
                                         PALETTE[6]),
                                  Series("TTC ahead [s] (≤10)", t, ttc, PALETTE[4])],
                                 title="gap and time to collision", ylabel="m / s",
                                 vlines=vl, hlines=hl2))
    residual = column(rec, "residual")
    if np.any(np.isfinite(residual)):
        pos = residual[np.isfinite(residual) & (residual > 0)]
        ylog = bool(pos.size and pos.max() / max(pos.min(), 1e-300) > 100)
        charts.append(line_chart([Series("residual E", t, residual, PALETTE[7])],
                                 title="outer-loop residual E = ‖F‖∞", ylabel="E",
                                 ylog=ylog, vlines=vl))
    return "".join(charts)


def _criteria_ok(overrides: object) -> bool:
    try:
        Criteria.from_overrides(overrides if isinstance(overrides, dict) else None)
        return True
    except ValueError:
        return False


def metrics_grid(run: RunEval) -> str:
    """Key metrics of a run, failed ones highlighted."""
    failed_metrics = {p[0] for p in (parse_failure(f) for f in run.failed) if p is not None}
    extra = ("progress_ratio", "max_offroad_m", "shoulder_s", "min_ttc_rear_s", "ssm_ttc_min_s",
             "outer_ms_p99", "inner_ms_p99", "guards", "steps")
    names = list(REQUIRED_METRICS) + [e for e in extra if e in run.metrics]
    cells = []
    for name in names:
        if name not in run.metrics:
            continue
        cls = ' class="bad"' if name in failed_metrics else ""
        cells.append(f"<div{cls}><span>{esc(name)}</span><b>{fmt(run.metrics[name])}</b></div>")
    return f'<div class="grid">{"".join(cells)}</div>'


def run_section(run: RunEval) -> str:
    """One collapsible run section."""
    marks = failure_marks(run)
    is_open = " open" if run.status != "pass" else ""
    failed = "; ".join(run.failed)
    head = (f'<summary>{badge(run.status)} <b>{esc(run.scenario)}</b> · '
            f'<span class="ctrl">{esc(run.controller)}</span> · '
            f'<span class="fam">{esc(run.family)}</span>'
            + (f' <span class="why">{esc(failed)}</span>' if failed else "")
            + "</summary>")
    body = [f'<p class="meta">run dir <code>{esc(run.run_dir)}</code> · sim '
            f"{fmt(run.meta.get('sim_time_s', math.nan))} s · wall "
            f"{fmt(run.meta.get('wall_s', math.nan))} s · seed {esc(run.meta.get('seed', '–'))}"
            "</p>"]
    if run.error:
        body.append(f"<pre class=\"err\">{esc(run.error)}</pre>")
    if marks:
        body.append("<p class=\"marks\">" + " · ".join(
            f'<span style="color:{c}">✖ {esc(label)}</span>' for label, _, c in marks) + "</p>")
    if run.metrics:
        body.append(metrics_grid(run))
    body.append(birdseye_svg(run, marks))
    focus = zoom_focus(run, marks)
    if focus is not None:
        body.append(birdseye_svg(run, marks, zoom=focus))
    body.append(time_series(run, marks))
    return (f'<details class="run" id="{run_anchor(run)}" data-status="{esc(run.status)}" '
            f'data-text="{esc((run.scenario + " " + run.controller + " " + run.family).lower())}"'
            f"{is_open}>{head}{''.join(body)}</details>")


def matrix_row(run: RunEval) -> str:
    """Scenario name without the controller part a controller sweep adds
    (``s3_stall__two_loop`` -> ``s3_stall``), so a row holds the same case for every
    controller."""
    ctrl = "".join(ch if ch.isalnum() or ch == "_" else "_" for ch in run.controller.lower())
    parts = [p for p in run.scenario.split("__") if p != ctrl]
    return "__".join(parts) or run.scenario


def matrix_tables(runs: Sequence[RunEval]) -> str:
    """Family × controller pass-rate matrix and scenario × controller status matrix."""
    controllers = sorted({r.controller for r in runs})
    families = sorted({r.family for r in runs})
    out = ['<h2 id="matrix">Pass/fail matrix</h2><table class="matrix"><thead><tr>'
           "<th>family</th>" + "".join(f"<th>{esc(c)}</th>" for c in controllers)
           + "</tr></thead><tbody>"]
    for fam in families:
        cells = []
        for ctrl in controllers:
            members = [r for r in runs if r.family == fam and r.controller == ctrl]
            if not members:
                cells.append('<td class="empty">–</td>')
                continue
            n_pass = sum(r.status == "pass" for r in members)
            rate = n_pass / len(members)
            hue = int(120 * rate)
            cells.append(f'<td class="rate" style="background:hsl({hue},65%,82%)" '
                         f'title="{n_pass} of {len(members)} pass">{n_pass}/{len(members)}</td>')
        out.append(f"<tr><th>{esc(fam)}</th>{''.join(cells)}</tr>")
    out.append("</tbody></table>")
    by_key = {(matrix_row(r), r.controller): r for r in runs}
    scenarios = sorted({(r.family, matrix_row(r)) for r in runs})
    out.append('<table class="matrix" id="scenario-matrix"><thead><tr><th>scenario</th>'
               + "".join(f"<th>{esc(c)}</th>" for c in controllers) + "</tr></thead><tbody>")
    last_family = None
    for fam, scn in scenarios:
        if fam != last_family:
            out.append(f'<tr class="famrow"><th colspan="{len(controllers) + 1}">{esc(fam)}'
                       "</th></tr>")
            last_family = fam
        cells = []
        for ctrl in controllers:
            run = by_key.get((scn, ctrl))
            if run is None:
                cells.append('<td class="empty">–</td>')
                continue
            err_lines = run.error.strip().splitlines()
            tip = "; ".join(run.failed) or (err_lines[-1] if err_lines else run.status)
            cells.append(f'<td class="cell {esc(run.status)}" title="{esc(tip)}">'
                         f'<a href="#{run_anchor(run)}">{esc(run.status)}</a></td>')
        out.append(f"<tr><th>{esc(scn)}</th>{''.join(cells)}</tr>")
    out.append("</tbody></table>")
    return "".join(out)


SUMMARY_COLUMNS = (("runs", "runs"), ("pass", "pass"), ("fail", "fail"), ("error", "error"),
                   ("timeout", "timeout"), ("pass_rate", "pass rate"),
                   ("sum_collision", "collisions"), ("min_min_gap_m", "min gap [m]"),
                   ("min_min_ttc_s", "min TTC [s]"), ("mean_progress_ratio", "progress ratio"),
                   ("max_max_abs_lat_acc_mps2", "max |lat acc|"),
                   ("max_max_abs_jerk_mps3", "max |jerk|"), ("mean_rms_lat_dev_m", "RMS lat dev"),
                   ("step_ms_p50", "step p50 [ms]"), ("step_ms_p99", "step p99 [ms]"),
                   ("outer_ms_p99", "outer p99 [ms]"), ("inner_ms_p99", "inner p99 [ms]"),
                   ("sum_deadline_misses", "deadline misses"), ("sum_fallbacks", "fallbacks"))


def summary_tables(summary: pd.DataFrame) -> str:
    """Per-controller summary tables (all runs, then per family)."""
    if summary.empty:
        return ""
    out = ['<h2 id="summary">Per-controller summary</h2>']
    for controller, grp in summary.groupby("controller", sort=True):
        grp = pd.concat([grp[grp["family"] == "ALL"], grp[grp["family"] != "ALL"]])
        out.append(f"<h3>{esc(controller)}</h3><table class=\"summary\"><thead><tr>"
                   "<th>family</th>" + "".join(f"<th>{esc(label)}</th>"
                                               for _, label in SUMMARY_COLUMNS)
                   + "</tr></thead><tbody>")
        for _, row in grp.iterrows():
            cls = ' class="all"' if row["family"] == "ALL" else ""
            cells = []
            for key, _ in SUMMARY_COLUMNS:
                value = row.get(key, math.nan)
                text = f"{100 * value:.0f}%" if key == "pass_rate" and pd.notna(value) \
                    else fmt(value)
                cells.append(f"<td>{text}</td>")
            out.append(f"<tr{cls}><th>{esc(row['family'])}</th>{''.join(cells)}</tr>")
        out.append("</tbody></table>")
    return "".join(out)


def timing_section(runs: Sequence[RunEval]) -> str:
    """CDF per loop (total, outer, inner, SUMO), one line per controller."""
    controllers = sorted({r.controller for r in runs})
    periods = [float(r.meta["step_s"]) * 1e3 for r in runs
               if isinstance(r.meta.get("step_s"), int | float)]
    deadline = float(np.median(periods)) if periods else None
    charts = []
    for loop, title in (("step", "whole controller step"), ("outer", "outer loop"),
                        ("inner", "inner loop"), ("sumo", "SUMO step")):
        samples = {}
        for ctrl in controllers:
            parts = [loop_times_s(r.record, loop) * 1e3 for r in runs
                     if r.controller == ctrl and r.record is not None]
            samples[ctrl] = np.concatenate(parts) if parts else np.zeros(0)
        charts.append(cdf_chart(samples, title=f"CDF: {title}",
                                deadline_ms=deadline if loop == "step" else None))
    return ('<h2 id="timing">Timing distributions</h2><div class="cdfs">' + "".join(charts)
            + "</div>")


CSS = """
:root{--pass:#15803d;--fail:#dc2626;--error:#7c3aed;--timeout:#d97706}
body{font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:0;
color:#0f172a;background:#f1f5f9}
header{background:#0f172a;color:#f8fafc;padding:14px 24px;position:sticky;top:0;z-index:5}
header h1{font-size:19px;margin:0 0 6px}
header .counts span{margin-right:12px}
main{padding:10px 24px 40px;max-width:1400px}
h2{margin:26px 0 8px;font-size:17px}h3{margin:14px 0 6px;font-size:15px}
table{border-collapse:collapse;background:#fff;margin:6px 0 12px}
th,td{border:1px solid #e2e8f0;padding:3px 8px;text-align:center;font-size:13px}
th{background:#f8fafc}tbody th{text-align:left}
.matrix td.cell a{color:#fff;text-decoration:none;display:block}
td.cell.pass{background:var(--pass)}td.cell.fail{background:var(--fail)}
td.cell.error{background:var(--error)}td.cell.timeout{background:var(--timeout)}
td.empty{color:#94a3b8}tr.famrow th{background:#e2e8f0;font-weight:600}
tr.all{font-weight:600;background:#f8fafc}
.badge{display:inline-block;min-width:54px;text-align:center;border-radius:4px;color:#fff;
padding:0 6px;font-size:12px;font-weight:600}
.badge.pass{background:var(--pass)}.badge.fail{background:var(--fail)}
.badge.error{background:var(--error)}.badge.timeout{background:var(--timeout)}
details.run{background:#fff;border:1px solid #e2e8f0;border-radius:6px;margin:8px 0;
padding:6px 12px}
details.run>summary{cursor:pointer;padding:4px 0}
.why{color:#b91c1c;font-size:12px;margin-left:8px}.ctrl{color:#1d4ed8}.fam{color:#64748b}
.grid{display:grid;grid-template-columns:repeat(auto-fill,minmax(210px,1fr));gap:2px 12px;
margin:8px 0;font-size:12px}
.grid div{display:flex;justify-content:space-between;border-bottom:1px dotted #e2e8f0}
.grid div.bad{color:#b91c1c;font-weight:600}
.grid span{color:#475569}.grid div.bad span{color:#b91c1c}
svg{display:block;margin:6px 0;background:#fff}
svg .ct{font-size:12px;font-weight:600;fill:#0f172a}
svg .tick{font-size:10px;fill:#475569}svg .legend{font-size:11px;font-weight:600}
svg .grid{stroke:#eef2f7}svg .frame{fill:none;stroke:#cbd5e1}
.cdfs{display:flex;flex-wrap:wrap;gap:8px}
pre.err{background:#1e1b4b;color:#e0e7ff;padding:8px;overflow:auto;max-height:260px;
font-size:12px}
.nodata{color:#94a3b8;font-style:italic;margin:4px 0}.meta{color:#475569;font-size:12px}
.controls{margin:10px 0}.controls input[type=search]{padding:3px 6px;width:240px}
.controls label{margin-left:10px}.controls button{margin-left:8px}
code{font-size:12px}
"""

JS = """
(function(){
  function openHash(){
    var id=decodeURIComponent(location.hash.slice(1));
    if(!id){return;}
    var el=document.getElementById(id);
    if(el&&el.tagName==='DETAILS'){el.open=true;el.scrollIntoView();}
  }
  window.addEventListener('hashchange',openHash);
  openHash();
  var q=document.getElementById('filter');
  var boxes=document.querySelectorAll('.controls input[type=checkbox]');
  function apply(){
    var text=(q&&q.value||'').toLowerCase();
    var allowed={};
    boxes.forEach(function(b){allowed[b.value]=b.checked;});
    var shown=0;
    document.querySelectorAll('details.run').forEach(function(d){
      var ok=allowed[d.dataset.status]!==false&&d.dataset.text.indexOf(text)>=0;
      d.style.display=ok?'':'none';
      if(ok){shown++;}
    });
    var c=document.getElementById('shown');
    if(c){c.textContent=shown;}
  }
  if(q){q.addEventListener('input',apply);}
  boxes.forEach(function(b){b.addEventListener('change',apply);});
  function setAll(v){document.querySelectorAll('details.run').forEach(function(d){d.open=v;});}
  var ex=document.getElementById('expand');
  if(ex){ex.addEventListener('click',function(){setAll(true);});}
  var co=document.getElementById('collapse');
  if(co){co.addEventListener('click',function(){setAll(false);});}
  apply();
})();
"""


def render_report(runs: Sequence[RunEval], title: str = "hwyeval report") -> str:
    """The whole HTML page as a string."""
    counts = {s: sum(1 for r in runs if r.status == s) for s in STATUSES}
    ordered = sorted(runs, key=lambda r: (STATUS_ORDER.get(r.status, 9), r.family, r.scenario,
                                          r.controller))
    catalogs = sorted({str(r.meta.get("catalog", "")) for r in runs if r.meta.get("catalog")})
    now = _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
    count_html = " ".join(f'<span>{badge(s)} {counts[s]}</span>' for s in STATUSES)
    checks = "".join(f'<label><input type="checkbox" value="{s}" checked> {s}</label>'
                     for s in STATUSES)
    parts = [
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">",
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        '<link rel="icon" href="data:,">',
        f"<title>{esc(title)}</title><style>{CSS}</style></head><body>",
        f"<header><h1>{esc(title)}</h1><div class=\"counts\"><span><b>{len(runs)}</b> runs"
        f"</span>{count_html}<span>catalog: {esc(', '.join(catalogs) or '–')}</span>"
        f"<span>generated {esc(now)}</span></div></header><main>",
        '<nav><a href="#matrix">matrix</a> · <a href="#summary">summary</a> · '
        '<a href="#timing">timing</a> · <a href="#runs">runs</a></nav>',
        matrix_tables(runs),
        summary_tables(summary_frame(runs)),
        timing_section(runs),
        '<h2 id="runs">Runs</h2><div class="controls">'
        '<input type="search" id="filter" placeholder="filter scenario / controller / family">'
        f'{checks}<button type="button" id="expand">expand all</button>'
        '<button type="button" id="collapse">collapse all</button> '
        f'<span class="meta"><span id="shown">{len(runs)}</span> shown</span></div>',
        "".join(run_section(r) for r in ordered),
        f"</main><script>{JS}</script></body></html>",
    ]
    return "\n".join(parts)


def write_html(runs: Sequence[RunEval], path: str | Path, title: str | None = None) -> Path:
    """Write report.html; returns its path."""
    path = Path(path)
    name = title or f"hwyeval report — {path.parent.name}"
    path.write_text(render_report(runs, name), encoding="utf-8")
    return path

