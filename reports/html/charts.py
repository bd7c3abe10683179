"""Inline SVG charts for report.html: line charts and CDFs, decimated so that a page of
hundreds of runs stays small. No scripts, no external resources."""

from __future__ import annotations

import html
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

MAX_POINTS = 400
PALETTE = ("#2563eb", "#ea580c", "#059669", "#9333ea", "#db2777", "#0891b2", "#65a30d",
           "#b45309")
ESC = html.escape
Line = tuple[float, str, str]  # (value, colour, label) of a reference line


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




def _to_axis(values: np.ndarray | float, log: bool) -> np.ndarray:
    """Values in axis units: NaN where not finite (or ≤ 0 on a log axis), log10 if log."""
    v = np.asarray(values, dtype=np.float64)
    v = np.where(np.isfinite(v), v, np.nan)
    if log:
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(v > 0, np.log10(np.where(v > 0, v, 1.0)), np.nan)
    return v


def _tick_labels(ticks: Sequence[float], log: bool) -> list[str]:
    if log:
        return [fmt(10 ** v, 3) for v in ticks]
    step = min((b - a for a, b in zip(ticks, ticks[1:], strict=False)), default=1.0)
    decimals = max(0, math.ceil(-math.log10(step) - 1e-9)) if step > 0 else 0
    if decimals == 0:
        return [f"{v:.0f}" for v in ticks]
    labels = [f"{v:.{decimals + 1}f}".rstrip("0").rstrip(".") for v in ticks]
    return [lb if lb not in ("-0", "") else "0" for lb in labels]


@dataclass(frozen=True)
class _Plot:
    """The data range of a chart and its plot area inside the SVG [px]."""

    x0: float
    x1: float
    y0: float
    y1: float
    width: int
    height: int
    ml: int = 64
    mr: int = 12
    mt: int = 22
    mb: int = 30

    @property
    def pw(self) -> int:
        return self.width - self.ml - self.mr

    @property
    def ph(self) -> int:
        return self.height - self.mt - self.mb

    def mx(self, v: np.ndarray | float) -> np.ndarray:
        return (np.asarray(v, dtype=np.float64) - self.x0) / (self.x1 - self.x0) * self.pw

    def my(self, v: np.ndarray | float) -> np.ndarray:
        return self.ph - (np.asarray(v, dtype=np.float64) - self.y0) / (self.y1 - self.y0) \
            * self.ph


def _plot_range(xs: np.ndarray, ys: np.ndarray, hlines: Sequence[Line], ylog: bool,
                width: int, height: int) -> _Plot:
    """Data bounds widened to the reference lines, a flat signal given a band, 6 % pad."""
    x0, x1 = float(xs.min()), float(xs.max())
    y0, y1 = float(ys.min()), float(ys.max())
    for value, _, _ in hlines:
        tv = float(_to_axis(value, ylog))
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
    return _Plot(x0, x1, y0 - pad_y, y1 + pad_y, width, height)


def _axes(p: _Plot, xlog: bool, ylog: bool, xlabel: str, ylabel: str) -> list[str]:
    out = []
    xticks = _log_ticks(p.x0, p.x1) if xlog else nice_ticks(p.x0, p.x1, 8)
    yticks = _log_ticks(p.y0, p.y1) if ylog else nice_ticks(p.y0, p.y1, 4)
    for v, label in zip(xticks, _tick_labels(xticks, xlog), strict=True):
        px = p.ml + float(p.mx(v))
        out.append(f'<line x1="{px:.1f}" y1="{p.mt}" x2="{px:.1f}" y2="{p.mt + p.ph}" '
                   f'class="grid"/><text x="{px:.1f}" y="{p.mt + p.ph + 13}" class="tick" '
                   f'text-anchor="middle">{esc(label)}</text>')
    for v, label in zip(yticks, _tick_labels(yticks, ylog), strict=True):
        py = p.mt + float(p.my(v))
        out.append(f'<line x1="{p.ml}" y1="{py:.1f}" x2="{p.ml + p.pw}" y2="{py:.1f}" '
                   f'class="grid"/><text x="{p.ml - 4}" y="{py + 3:.1f}" class="tick" '
                   f'text-anchor="end">{esc(label)}</text>')
    out.append(f'<rect x="{p.ml}" y="{p.mt}" width="{p.pw}" height="{p.ph}" class="frame"/>')
    out.append(f'<text x="{p.ml + p.pw}" y="{p.height - 3}" class="tick" text-anchor="end">'
               f"{esc(xlabel)}</text>")
    if ylabel:
        mid = p.mt + p.ph / 2
        out.append(f'<text x="12" y="{mid:.0f}" class="tick" text-anchor="middle" '
                   f'transform="rotate(-90 12 {mid:.0f})">{esc(ylabel)}</text>')
    return out


def _reference_lines(p: _Plot, hlines: Sequence[Line], vlines: Sequence[Line], xlog: bool,
                     ylog: bool) -> list[str]:
    out = []
    for value, colour, label in hlines:
        tv = float(_to_axis(value, ylog))
        if math.isfinite(tv):
            py = float(p.my(tv))
            out.append(f'<line x1="0" y1="{py:.1f}" x2="{p.pw}" y2="{py:.1f}" stroke="{colour}" '
                       f'stroke-dasharray="5 3" stroke-width="1"><title>{esc(label)}</title>'
                       "</line>")
    for value, colour, label in vlines:
        tv = float(_to_axis(value, xlog))
        if math.isfinite(tv):
            px = float(p.mx(tv))
            out.append(f'<line x1="{px:.1f}" y1="0" x2="{px:.1f}" y2="{p.ph}" stroke="{colour}" '
                       f'stroke-width="1.5"><title>{esc(label)}</title></line>')
    return out


def _legend(p: _Plot, series: Sequence[Series], inside: bool) -> list[str]:
    out = []
    lx = p.width - p.mr
    for i, s in enumerate(reversed(series)):
        label = esc(s.label)
        if inside:
            ly = p.mt + p.ph - 6 - 13 * i
            out.append(f'<text x="{p.ml + p.pw - 6}" y="{ly}" class="legend" '
                       f'text-anchor="end" fill="{s.colour}">{label}</text>')
            continue
        out.append(f'<text x="{lx}" y="14" class="legend" text-anchor="end" '
                   f'fill="{s.colour}">{label}</text>')
        lx -= 7 * len(s.label) + 14
    return out


def line_chart(series: Sequence[Series], *, title: str, ylabel: str = "",
               xlabel: str = "t [s]", width: int = 860, height: int = 170,
               xlog: bool = False, ylog: bool = False, hlines: Iterable[Line] = (),
               vlines: Iterable[Line] = (), legend_inside: bool = False) -> str:
    """Inline SVG line chart. hlines/vlines: (value, colour, label). The legend runs along
    the top edge, or (``legend_inside``) stacked in the plot's lower-right corner."""
    hl, vl = list(hlines), list(vlines)
    data = [(s, *decimate(_to_axis(s.x, xlog), _to_axis(s.y, ylog))) for s in series]
    xs = np.concatenate([d[1] for d in data]) if data else np.zeros(0)
    ys = np.concatenate([d[2] for d in data]) if data else np.zeros(0)
    xs, ys = xs[np.isfinite(xs)], ys[np.isfinite(ys)]
    if xs.size == 0 or ys.size == 0:
        return f'<div class="nodata">{esc(title)}: no data</div>'
    p = _plot_range(xs, ys, hl, ylog, width, height)
    out = [f'<svg class="chart" width="{width}" height="{height}" '
           f'viewBox="0 0 {width} {height}" role="img">', f"<title>{esc(title)}</title>",
           f'<text x="{p.ml}" y="14" class="ct">{esc(title)}</text>']
    out += _axes(p, xlog, ylog, xlabel, ylabel)
    out.append(f'<svg x="{p.ml}" y="{p.mt}" width="{p.pw}" height="{p.ph}" '
               f'viewBox="0 0 {p.pw} {p.ph}">')
    out += _reference_lines(p, hl, vl, xlog, ylog)
    for s, sx, sy in data:
        d = _path(p.mx(sx), p.my(sy))
        if d:
            dash = ' stroke-dasharray="6 3"' if s.dash else ""
            out.append(f'<path d="{d}" fill="none" stroke="{s.colour}" '
                       f'stroke-width="{s.width}"{dash}><title>{esc(s.label)}</title></path>')
    out.append("</svg>")
    out += _legend(p, series, legend_inside)
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
