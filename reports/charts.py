"""Inline SVG charts for every page hwyeval writes (report, run pages, compare, search,
paper): line charts and CDFs, decimated so that a page of hundreds of runs stays small.
No scripts, no external resources. Below the renderers in the layers, so that each of
them draws with the same charts."""

from __future__ import annotations

import html
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

MAX_POINTS = 100
PALETTE = ("#2563eb", "#ea580c", "#059669", "#9333ea", "#db2777", "#0891b2", "#65a30d",
           "#b45309")
ESC = html.escape
Line = tuple[float, str, str]  # (value, colour, label) of a reference line
# The charts' classes (frame, grid, ticks, legend): every page that embeds a chart
# carries this stylesheet. Without it an SVG <rect>/<path> fills black by default, and
# the plot area of a chart is one black block.
CHART_CSS = """
svg{display:block;margin:6px 0;background:#fff}
svg .ct{font-size:12px;font-weight:600;fill:#0f172a}
svg .tick,svg .xt,svg .yt{font-size:10px;fill:#475569}svg .xt{text-anchor:middle}
svg .yt{text-anchor:end}svg .legend{font-size:11px;font-weight:600}
svg .lane{stroke:#fff;stroke-width:1;stroke-dasharray:8 6}
svg .grid{stroke:#e8edf3;fill:none}svg .frame{fill:none;stroke:#cbd5e1}
"""


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
    """At most ``max_points`` samples of (x, y): per bucket of consecutive samples the
    min and the max of y, in order (extremes survive; a bucket without a finite y
    keeps its first sample)."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    n = y.size
    if n <= max_points:
        return x, y
    buckets = max(1, max_points // 2)
    edges = np.linspace(0, n, buckets + 1).astype(int)
    starts, size = edges[:-1], int(np.max(np.diff(edges)))
    idx = np.minimum(starts[:, None] + np.arange(size)[None, :], n - 1)
    inside = np.arange(size)[None, :] < np.diff(edges)[:, None]
    vals = np.where(inside, y[idx], np.nan)
    finite = np.isfinite(vals)
    lo = np.argmin(np.where(finite, vals, np.inf), axis=1)
    hi = np.argmax(np.where(finite, vals, -np.inf), axis=1)
    none = ~finite.any(axis=1)
    lo[none] = 0
    hi[none] = 0
    keep = np.unique(np.concatenate([idx[np.arange(buckets), lo], idx[np.arange(buckets), hi]]))
    return x[keep], y[keep]


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
    """Round tick values in [lo, hi]: steps of 1, 2, 2.5 or 5 × 10^k, the smallest one
    giving at most n + 1 ticks, or a finer one when that leaves fewer than 3."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return [lo] if math.isfinite(lo) else []
    mag = 10 ** math.floor(math.log10((hi - lo) / n))
    steps = [m * mag * f for f in (0.1, 1.0, 10.0) for m in (1, 2, 2.5, 5)]

    def ticks_for(step: float) -> list[float]:
        start = math.ceil(lo / step - 1e-9) * step
        out, k = [], 0
        while start + k * step <= hi + step * 1e-9:
            v = round(start + k * step, 12)
            out.append(0.0 if abs(v) < step * 1e-9 else v)
            k += 1
        return out

    chosen: list[float] = []
    for step in steps:
        ticks = ticks_for(step)
        if len(ticks) <= n + 1:
            if len(ticks) >= 3 or not chosen:
                chosen = ticks
            break
        chosen = ticks if len(ticks) <= n + 3 else chosen
    return chosen


def _log_ticks(lo: float, hi: float, n: int = 6) -> list[float]:
    """Whole decades in [lo, hi] (log10 units), thinned to at most ``n``."""
    decades = list(range(math.ceil(lo), math.floor(hi) + 1))
    step = max(1, math.ceil(len(decades) / n))
    return [float(v) for v in decades[::step]]


def _path(px: np.ndarray, py: np.ndarray) -> str:
    """SVG path data through the finite points, in whole pixels: an absolute move at
    each start, then relative steps between the rounded positions (no drift), repeated
    pixels dropped; a gap (non-finite point) lifts the pen."""
    parts: list[str] = []
    last: tuple[int, int] | None = None
    pending = (0, 0)  # a relative step not written yet (collinear steps merge into it)

    def flush() -> None:
        if pending != (0, 0):
            parts.append(f"l{pending[0]} {pending[1]}")

    for a, b in zip(px, py, strict=True):
        if not (math.isfinite(a) and math.isfinite(b)):
            flush()
            pending, last = (0, 0), None
            continue
        point = (int(round(a)), int(round(b)))
        if last is None:
            parts.append(f"M{point[0]} {point[1]}")
        elif point != last:
            step = (point[0] - last[0], point[1] - last[1])
            cross = pending[0] * step[1] - pending[1] * step[0]
            if pending != (0, 0) and cross == 0 and pending[0] * step[0] + pending[1] * step[1] > 0:
                pending = (pending[0] + step[0], pending[1] + step[1])
            else:
                flush()
                pending = step
        last = point
    flush()
    return "".join(parts)



def _to_axis(values: np.ndarray | float, log: bool) -> np.ndarray:
    """Values in axis units: NaN where not finite (or ≤ 0 on a log axis), log10 if log."""
    v = np.asarray(values, dtype=np.float64)
    v = np.where(np.isfinite(v), v, np.nan)
    if log:
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(v > 0, np.log10(np.where(v > 0, v, 1.0)), np.nan)
    return v


def tick_decimals(ticks: Sequence[float]) -> int:
    """The fewest decimals that print every tick exactly (2.5-steps need one more than
    their magnitude: 17.5, not 18)."""
    for decimals in range(0, 13):
        if all(abs(round(v, decimals) - v) <= 1e-9 * max(1.0, abs(v)) for v in ticks):
            return decimals
    return 12


def tick_labels(ticks: Sequence[float], log: bool = False) -> list[str]:
    """Labels equal to the tick values (log axes: 10^v with 3 digits)."""
    if log:
        return [fmt(10 ** v, 3) for v in ticks]
    decimals = tick_decimals(ticks)
    labels = [f"{v:.{decimals}f}" for v in ticks]
    return ["0" if float(lb) == 0 else lb.replace("-", "−") for lb in labels]


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
                width: int, height: int, min_span: float = 0.0) -> _Plot:
    """Data bounds widened to the reference lines and to at least ``min_span`` (in the
    quantity's unit, around the data's middle: noise of 0.015 m/s never fills a speed
    axis), a flat signal given a band, 6 % pad."""
    x0, x1 = float(xs.min()), float(xs.max())
    y0, y1 = float(ys.min()), float(ys.max())
    for value, _, _ in hlines:
        tv = float(_to_axis(value, ylog))
        if math.isfinite(tv):
            y0, y1 = min(y0, tv), max(y1, tv)
    if x1 <= x0:
        x0, x1 = x0 - 0.5, x1 + 0.5
    if not ylog and y1 - y0 < min_span:
        mid = 0.5 * (y0 + y1)
        y0, y1 = mid - 0.5 * min_span, mid + 0.5 * min_span
    flat = 0.5 if ylog else max(1e-12, 1e-6 * max(abs(y0), abs(y1)))
    if y1 - y0 < flat:  # flat (or numerically flat) signal: show a sensible band
        mid = 0.5 * (y0 + y1)
        pad = max(abs(mid) * 0.1, 0.1) if not ylog else 0.5
        y0, y1 = mid - pad, mid + pad
    pad_y = 0.06 * (y1 - y0)
    return _Plot(x0, x1, y0 - pad_y, y1 + pad_y, width, height)


def _axes(p: _Plot, xlog: bool, ylog: bool, xlabel: str, ylabel: str) -> list[str]:
    """Gridlines as one path (vertical ``M x top v h``, horizontal ``M left y h w``)
    and tick labels: a y label sits 3 px below its gridline (``y = line + 3``)."""
    out = []
    grid: list[str] = []
    xticks = _log_ticks(p.x0, p.x1) if xlog else nice_ticks(p.x0, p.x1, 6)
    yticks = _log_ticks(p.y0, p.y1) if ylog else nice_ticks(p.y0, p.y1, 4)
    for v, label in zip(xticks, tick_labels(xticks, xlog), strict=True):
        px = p.ml + float(p.mx(v))
        grid.append(f"M{px:.1f} {p.mt}v{p.ph}")
        out.append(f'<text x="{px:.1f}" y="{p.mt + p.ph + 13}" class="xt">{esc(label)}</text>')
    for v, label in zip(yticks, tick_labels(yticks, ylog), strict=True):
        py = p.mt + float(p.my(v))
        grid.append(f"M{p.ml} {py:.2f}h{p.pw}")
        out.append(f'<text x="{p.ml - 4}" y="{py + 3:.2f}" class="yt">{esc(label)}</text>')
    out.insert(0, f'<path d="{"".join(grid)}" class="grid"/>')
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


LEGEND_CHAR_PX = 6.5  # width of a legend character at 11 px bold (for fitting labels)


def _fitted(label: str, room_px: float) -> str:
    """``label`` cut with an ellipsis to fit ``room_px`` (the full text is the title)."""
    fits = max(int(room_px / LEGEND_CHAR_PX), 4)
    return label if len(label) <= fits else label[: fits - 1] + "…"


def _legend(p: _Plot, series: Sequence[Series], inside: bool | str) -> list[str]:
    """The legend: along the top edge; ``True`` stacked in the plot's lower-right
    corner; ``"upper-left"`` stacked in its upper-left corner (where a CDF has no
    curve: small times, fractions near 1). Inside, labels are cut to the plot's width."""
    out = []
    lx = p.width - p.mr
    if inside == "upper-left":
        for i, s in enumerate(series):
            ly = p.mt + 14 + 13 * i
            out.append(f'<text x="{p.ml + 6}" y="{ly}" class="legend" fill="{s.colour}">'
                       f"<title>{esc(s.label)}</title>{esc(_fitted(s.label, p.pw - 12))}"
                       "</text>")
        return out
    for i, s in enumerate(reversed(series)):
        label = esc(s.label)
        if inside:
            ly = p.mt + p.ph - 6 - 13 * i
            out.append(f'<text x="{p.ml + p.pw - 6}" y="{ly}" class="legend" '
                       f'text-anchor="end" fill="{s.colour}"><title>{label}</title>'
                       f"{esc(_fitted(s.label, p.pw - 12))}</text>")
            continue
        out.append(f'<text x="{lx}" y="14" class="legend" text-anchor="end" '
                   f'fill="{s.colour}">{label}</text>')
        lx -= 7 * len(s.label) + 14
    return out


def line_chart(series: Sequence[Series], *, title: str, ylabel: str = "",  # noqa: PLR0913 - keyword display options of one chart
               xlabel: str = "t [s]", width: int = 860, height: int = 170,
               xlog: bool = False, ylog: bool = False, hlines: Iterable[Line] = (),
               vlines: Iterable[Line] = (), legend_inside: bool | str = False,
               min_span: float = 0.0) -> str:
    """Inline SVG line chart of one quantity (``ylabel`` names its unit). hlines/vlines:
    (value, colour, label). ``min_span``: the smallest y range shown [unit]. The legend
    runs along the top edge, or (``legend_inside``) stacked in the plot's lower-right
    corner. The svg carries its y axis as ``data-y0``/``data-y1`` (bottom/top value,
    log10 on a log axis), ``data-top``/``data-h`` (plot area [px]) so that a reader
    can map a gridline's pixel back to its value."""
    hl, vl = list(hlines), list(vlines)
    data = [(s, *decimate(_to_axis(s.x, xlog), _to_axis(s.y, ylog))) for s in series]
    xs = np.concatenate([d[1] for d in data]) if data else np.zeros(0)
    ys = np.concatenate([d[2] for d in data]) if data else np.zeros(0)
    xs, ys = xs[np.isfinite(xs)], ys[np.isfinite(ys)]
    if xs.size == 0 or ys.size == 0:
        return f'<div class="nodata">{esc(title)}: no data</div>'
    p = _plot_range(xs, ys, hl, ylog, width, height, min_span)
    out = [f'<svg class="chart" width="{width}" height="{height}" '
           f'viewBox="0 0 {width} {height}" role="img" data-y0="{p.y0!r}" data-y1="{p.y1!r}" '
           f'data-top="{p.mt}" data-h="{p.ph}" data-log="{int(ylog)}">',
           f"<title>{esc(title)}</title>",
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
                      height=height, xlog=xlog, vlines=vlines, legend_inside="upper-left")
