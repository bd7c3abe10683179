"""Bird's-eye SVG of one run: lanes, other vehicles' paths, stalled cars, the obstacle
ellipses the controller saw, the ego path coloured by speed and the failure marks.
Recorded vehicles (scenario ``replay``) have their own colours by the neighbours'
``agent``: replayed teal, reactive (handed over to SUMO) violet, with legend entries.

The view is the run's bounding box in a frame along the mean of the start and end
headings (the chord of an arc; exactly the road direction for a lane change on a
straight road). A long thin stretch gets its lateral scale exaggerated (the factor is
printed). A zoomed view is a true-scale ±40 m × ±12 m window around the ego at one
trace row, with every vehicle's box at that step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from reports.charts import esc, fmt
from reports.geometry import box_corners, ego_box_corners
from reports.html.marks import Mark
from reports.record import (
    AGENT_NAMES,
    AGENT_REACTIVE,
    AGENT_REPLAYED,
    AGENT_SUMO,
    RunRecord,
    Verdict,
)

VIRIDIS = ("#440154", "#414487", "#2a788e", "#22a884", "#7ad151", "#fde725")
ZOOM_HALF_LENGTH_M = 40.0
ZOOM_HALF_WIDTH_M = 12.0
MAX_NEIGHBOUR_PATHS = 10
MAX_LANE_POINTS = 60
EGO_PATH_POINTS = 90  # points of the ego path drawn  # points per lane outline drawn


def _viridis(frac: np.ndarray) -> list[str]:
    idx = np.clip(np.round(np.nan_to_num(frac) * (len(VIRIDIS) - 1)), 0, len(VIRIDIS) - 1)
    return [VIRIDIS[int(i)] for i in idx]


def _offset_polyline(shape: np.ndarray, offset: float) -> np.ndarray:
    """Polyline shifted sideways by ``offset`` [m] (left +) using vertex normals."""
    if shape.shape[0] < 2:
        return shape
    d = np.gradient(shape, axis=0)
    norm = np.linalg.norm(d, axis=1, keepdims=True)
    d = d / np.maximum(norm, 1e-9)
    normal = np.stack([-d[:, 1], d[:, 0]], axis=1)
    out: np.ndarray = shape + offset * normal
    return out


@dataclass(frozen=True)
class _View:
    """World → local frame (origin, angle θ) → pixels; the visible window [a0, a1] ×
    [b0, b1] in local metres; ``focus_row`` ≥ 0 for a zoomed view."""

    origin: tuple[float, float]
    theta: float
    a0: float
    a1: float
    b0: float
    b1: float
    sx: float
    sy: float
    width: int
    height: int
    focus_row: int = -1
    pad: int = 8

    def local(self, px: np.ndarray, py: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        c, s = math.cos(self.theta), math.sin(self.theta)
        dx, dy = np.asarray(px) - self.origin[0], np.asarray(py) - self.origin[1]
        return dx * c + dy * s, -dx * s + dy * c

    def to_px(self, px: np.ndarray, py: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        la, lb = self.local(px, py)
        return self.pad + (la - self.a0) * self.sx, self.height - self.pad - (lb - self.b0) * \
            self.sy

    def pts(self, px: np.ndarray, py: np.ndarray) -> str:
        """SVG points in whole pixels, a repeated pixel dropped (a page per run stays
        small; the view is drawn at 1 px per unit)."""
        u, v = self.to_px(px, py)
        out: list[str] = []
        last = ""
        for p, q in zip(u, v, strict=True):
            if not (math.isfinite(p) and math.isfinite(q)):
                continue
            text = f"{int(round(p))},{int(round(q))}"
            if text != last:
                out.append(text)
                last = text
        return " ".join(out)

    def in_view(self, px: np.ndarray, py: np.ndarray, margin: float = 60.0) -> np.ndarray:
        la, lb = self.local(px, py)
        return ((la > self.a0 - margin) & (la < self.a1 + margin) & (lb > self.b0 - margin)
                & (lb < self.b1 + margin))

    def visible_part(self, px: np.ndarray, py: np.ndarray) -> slice:
        """The index range of a path that can show in a zoomed view (all of it otherwise)."""
        if self.focus_row < 0:
            return slice(0, len(px))
        idx = np.flatnonzero(self.in_view(px, py, 10.0))
        if idx.size == 0:
            return slice(0, 0)
        return slice(max(int(idx[0]) - 1, 0), min(int(idx[-1]) + 2, len(px)))

    @property
    def exaggeration(self) -> float:
        return self.sy / self.sx


def _view(rec: RunRecord, width: int, max_height: int, zoom_row: int | None) -> _View | None:
    x, y = rec.trace.ego.x_m, rec.trace.ego.y_m
    ok = np.isfinite(x) & np.isfinite(y)
    xo, yo = x[ok], y[ok]
    psi = rec.trace.ego.psi_rad[ok]
    chord = np.array([xo[-1] - xo[0], yo[-1] - yo[0]])
    if np.isfinite(psi[0]) and np.isfinite(psi[-1]):
        theta = math.atan2(math.sin(psi[0]) + math.sin(psi[-1]),
                           math.cos(psi[0]) + math.cos(psi[-1]))
    elif np.hypot(*chord) > 1.0:
        theta = math.atan2(chord[1], chord[0])
    else:
        theta = 0.0
    frame = _View((float(xo[0]), float(yo[0])), theta, 0, 1, 0, 1, 1, 1, width, max_height)
    ea, eb = frame.local(xo, yo)
    a0, a1 = float(ea.min()) - 30.0, float(ea.max()) + 30.0
    b0, b1 = float(eb.min()) - 9.0, float(eb.max()) + 9.0
    focus = -1
    if zoom_row is not None:
        if not (0 <= zoom_row < len(x) and ok[zoom_row]):
            return None
        focus = zoom_row
        fa, fb = frame.local(np.array([x[focus]]), np.array([y[focus]]))
        a0, a1 = float(fa[0]) - ZOOM_HALF_LENGTH_M, float(fa[0]) + ZOOM_HALF_LENGTH_M
        b0, b1 = float(fb[0]) - ZOOM_HALF_WIDTH_M, float(fb[0]) + ZOOM_HALF_WIDTH_M
    pad = frame.pad
    sx = (width - 2 * pad) / (a1 - a0)
    if (b1 - b0) * sx <= max_height - 2 * pad:
        sy = sx
        height = int(max((b1 - b0) * sx + 2 * pad, 120))
        # centre the band vertically when the minimum height adds room
        extra = (height - 2 * pad) / sy - (b1 - b0)
        b0, b1 = b0 - extra / 2, b1 + extra / 2
    else:
        height = max_height
        sy = (height - 2 * pad) / (b1 - b0)
    return _View(frame.origin, theta, a0, a1, b0, b1, sx, sy, width, height, focus)


def _lanes(rec: RunRecord, v: _View) -> list[str]:
    allow = rec.info.allow_shoulder
    out: list[str] = []
    for lane in rec.road.lanes:
        shape = np.asarray(lane.shape_xy_m, dtype=np.float64).reshape(-1, 2)
        if shape.shape[0] < 2:
            continue
        view = v.in_view(shape[:, 0], shape[:, 1], 400.0)
        if not np.any(view):
            # long straight segments may have both ends out of view: keep if it crosses
            la, lb = v.local(shape[:, 0], shape[:, 1])
            if not (np.any(lb > v.b0 - 20) and np.any(lb < v.b1 + 20) and la.min() < v.a1
                    and la.max() > v.a0):
                continue
            view[:] = True
        idx = np.flatnonzero(view)
        part = shape[max(int(idx[0]) - 1, 0):min(int(idx[-1]) + 2, shape.shape[0])]
        if part.shape[0] > MAX_LANE_POINTS:
            keep = np.unique(np.linspace(0, part.shape[0] - 1, MAX_LANE_POINTS).astype(int))
            part = part[keep]
        left = _offset_polyline(part, lane.width_m / 2)
        right = _offset_polyline(part, -lane.width_m / 2)
        ring = np.vstack([left, right[::-1]])
        if lane.is_shoulder:
            fill = "#e9dcc0" if allow else "#f0e4cc"
        else:
            fill = "#d4d8de" if lane.drivable(allow) else "#f1c9c9"
        title = esc(f"{lane.id}{' (shoulder)' if lane.is_shoulder else ''}")
        # the outline's white dashes are the lane markings (no separate edge lines)
        out.append(f'<polygon points="{v.pts(ring[:, 0], ring[:, 1])}" fill="{fill}" '
                   f'class="lane"><title>{title}</title></polygon>')
    return out


# Recorded vehicles (neighbours' ``agent``): replayed from the recording, or handed over
# to SUMO's driver (reactive replay); their paths and boxes have these colours.
C_AGENT = {AGENT_SUMO: "#475569", AGENT_REPLAYED: "#0d9488", AGENT_REACTIVE: "#9333ea"}
AGENT_LEGEND = {AGENT_REPLAYED: ("replayed car (recording)", C_AGENT[AGENT_REPLAYED], "box"),
                AGENT_REACTIVE: ("reactive car (handed over to SUMO)", C_AGENT[AGENT_REACTIVE],
                                 "box")}


def _neighbour_paths(rec: RunRecord, v: _View) -> list[str]:
    """Each moving neighbour's path, in the colour of its agent kind (the highest it
    had: a handed-over car is drawn as reactive)."""
    nb = rec.neighbours
    moving = nb.take(~nb.stalled)
    out: list[str] = []
    ids = list(dict.fromkeys(moving.id.tolist()))[:MAX_NEIGHBOUR_PATHS]  # first-seen order
    for vid in ids:
        mine = moving.id == vid
        gx, gy = moving.x_m[mine], moving.y_m[mine]
        span = v.visible_part(gx, gy)
        if span.stop - span.start < 2:
            continue
        gx, gy = gx[span], gy[span]
        if gx.size > 16:
            k = np.unique(np.linspace(0, gx.size - 1, 16).astype(int))
            gx, gy = gx[k], gy[k]
        agent = int(moving.agent[mine].max()) if mine.any() else AGENT_SUMO
        colour, opacity = ("#334155", "0.35") if agent == AGENT_SUMO else (
            C_AGENT.get(agent, "#334155"), "0.6")
        kind = f" ({AGENT_NAMES[agent]})" if agent in AGENT_LEGEND else ""
        out.append(f'<polyline points="{v.pts(gx, gy)}" fill="none" stroke="{colour}" '
                   f'stroke-opacity="{opacity}" stroke-width="1.2"><title>{esc(vid)}{kind}'
                   "</title></polyline>")
    return out


def _stalled(rec: RunRecord, v: _View) -> list[str]:
    out = []
    for st in rec.outcome.stalled:
        corners = box_corners(st.x_m, st.y_m, st.heading_rad, st.length_m, st.width_m)
        out.append(f'<polygon points="{v.pts(corners[:, 0], corners[:, 1])}" fill="#b91c1c" '
                   f'fill-opacity="0.85" stroke="#7f1d1d"><title>stalled {esc(st.id)}'
                   "</title></polygon>")
    return out


def _ellipses(rec: RunRecord, verdict: Verdict | None, v: _View) -> list[str]:
    """The obstacle ellipses the controller saw at the step of the smallest margin."""
    metric = verdict.metric("min_ellipse_margin") if verdict is not None else None
    ell = np.asarray(rec.arrays.ellipses, dtype=np.float64)
    if metric is None or metric.worst_step is None or ell.ndim != 3 or ell.shape[0] == 0:
        return []
    row = metric.worst_step
    step = int(rec.trace.step[row]) if row < len(rec.trace) else row
    idx = step if 0 <= step < len(ell) else row
    ang = np.linspace(0.0, 2 * np.pi, 37)
    out = []
    at = min(idx, len(ell) - 1)
    for slot, e in enumerate(ell[at].reshape(-1, ell.shape[-1])):
        if e.size < 6 or not (np.all(np.isfinite(e[:5])) and e[5] > 0.5):
            continue
        ex = e[0] + e[3] * np.cos(ang) * math.cos(e[2]) - e[4] * np.sin(ang) * math.sin(e[2])
        ey = e[1] + e[3] * np.cos(ang) * math.sin(e[2]) + e[4] * np.sin(ang) * math.cos(e[2])
        vid = rec.arrays.ellipse_id(at, slot)
        of = f" of {esc(vid)}" if vid else ""
        out.append(f'<polygon points="{v.pts(ex, ey)}" fill="#f59e0b" fill-opacity="0.12" '
                   f'stroke="#d97706" stroke-dasharray="4 3" stroke-width="1" '
                   f'data-vehicle="{esc(vid)}">'
                   f"<title>obstacle ellipse{of} at t={fmt(rec.trace.t_s[row], 4)} s "
                   f"(min margin {fmt(metric.value, 3)})</title></polygon>")
    return out


def _focus_boxes(rec: RunRecord, v: _View, corners: np.ndarray) -> list[str]:
    """Every vehicle's box at the focus step of a zoomed view, and the ego's."""
    out = []
    nb = rec.neighbours
    now = nb.take(nb.step == rec.trace.step[v.focus_row])
    now = now.take(v.in_view(now.x_m, now.y_m, 5.0))  # only the boxes inside the window
    for i in range(len(now)):
        nc = box_corners(now.x_m[i], now.y_m[i], now.heading_rad[i], now.length_m[i],
                         now.width_m[i])
        colour = "#b91c1c" if bool(now.stalled[i]) else C_AGENT.get(int(now.agent[i]),
                                                                      "#475569")
        out.append(f'<polygon points="{v.pts(nc[:, 0], nc[:, 1])}" fill="{colour}" '
                   f'fill-opacity="0.55" stroke="{colour}"><title>{esc(now.id[i])} '
                   f'{fmt(float(now.speed_mps[i]), 3)} m/s</title></polygon>')
    fc = corners[v.focus_row]
    if np.all(np.isfinite(fc)):
        out.append(f'<polygon points="{v.pts(fc[:, 0], fc[:, 1])}" fill="#2563eb" '
                   'fill-opacity="0.45" stroke="#1d4ed8" stroke-width="1.5">'
                   "<title>ego at the focus step</title></polygon>")
    return out


def _ego(rec: RunRecord, v: _View) -> list[str]:
    """Faint ego boxes every ~1/8 of the run (zoom: of the part in view), the focus
    boxes of a zoomed view, then the ego path coloured by speed."""
    ego = rec.trace.ego
    x, y = ego.x_m, ego.y_m
    corners = ego_box_corners(x, y, ego.psi_rad, rec.info.ego)
    n = len(rec.trace)
    rows = np.unique(np.linspace(0, n - 1, 9).astype(int))
    out: list[str] = []
    if v.focus_row >= 0:
        inside = np.flatnonzero(v.in_view(x, y, 0.0))
        rows = inside[np.unique(np.linspace(0, inside.size - 1, 10).astype(int))] \
            if inside.size else np.zeros(0, dtype=int)
        out += _focus_boxes(rec, v, corners)
    for i in rows:
        cb = corners[i]
        if np.all(np.isfinite(cb)):
            out.append(f'<polygon points="{v.pts(cb[:, 0], cb[:, 1])}" fill="#2563eb" '
                       'fill-opacity="0.10" stroke="#2563eb" stroke-opacity="0.5" '
                       'stroke-width="0.8"/>')
    return out + _speed_path(rec, v)


def _speed_range(speed: np.ndarray) -> tuple[float, float]:
    finite = speed[np.isfinite(speed)]
    return (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)


def _speed_path(rec: RunRecord, v: _View) -> list[str]:
    """The ego path coloured by speed (runs of equal colour share one polyline)."""
    ego = rec.trace.ego
    x, y, speed = ego.x_m, ego.y_m, ego.speed_mps
    v0, v1 = _speed_range(speed)
    span = v.visible_part(x, y)
    px, py, sp = x[span], y[span], speed[span]
    if px.size > EGO_PATH_POINTS:
        k = np.unique(np.linspace(0, px.size - 1, EGO_PATH_POINTS).astype(int))
        px, py, sp = px[k], py[k], sp[k]
    colours = _viridis((sp - v0) / max(v1 - v0, 1e-6))
    out = []
    start = 0
    for i in range(1, len(colours) + 1):
        if i == len(colours) or colours[i] != colours[start]:
            seg = slice(start, min(i + 1, len(colours)))
            out.append(f'<polyline points="{v.pts(px[seg], py[seg])}" fill="none" '
                       f'stroke="{colours[start]}" stroke-width="2.6" '
                       'stroke-linecap="round"/>')
            start = i
    return out


def _ends_and_marks(rec: RunRecord, v: _View, marks: list[Mark]) -> list[str]:
    x, y = rec.trace.ego.x_m, rec.trace.ego.y_m
    ok = np.flatnonzero(np.isfinite(x) & np.isfinite(y))
    sx0, sy0 = v.to_px(x[ok[:1]], y[ok[:1]])
    ex0, ey0 = v.to_px(x[ok[-1:]], y[ok[-1:]])
    out = [f'<circle cx="{sx0[0]:.1f}" cy="{sy0[0]:.1f}" r="4" fill="#16a34a">'
           "<title>start</title></circle>",
           f'<rect x="{ex0[0] - 3.5:.1f}" y="{ey0[0] - 3.5:.1f}" width="7" height="7" '
           'fill="#111827"><title>end</title></rect>']
    for m in marks:
        if not (0 <= m.row < len(x)) or not (np.isfinite(x[m.row]) and np.isfinite(y[m.row])):
            continue
        mx_, my_ = v.to_px(x[m.row:m.row + 1], y[m.row:m.row + 1])
        cx, cy = float(mx_[0]), float(my_[0])
        out.append(f'<g class="mark"><title>{esc(m.label)}</title>'
                   f'<circle cx="{cx:.1f}" cy="{cy:.1f}" r="9" fill="none" stroke="{m.colour}" '
                   'stroke-width="2.5"/>'
                   f'<path d="M{cx - 6:.1f} {cy - 6:.1f}L{cx + 6:.1f} {cy + 6:.1f}M{cx - 6:.1f} '
                   f'{cy + 6:.1f}L{cx + 6:.1f} {cy - 6:.1f}" stroke="{m.colour}" '
                   'stroke-width="2.5"/></g>')
    return out


def birdseye_svg(rec: RunRecord | None, verdict: Verdict | None, marks: list[Mark],
                 width: int = 860, max_height: int = 280,
                 zoom: tuple[int, str] | None = None) -> str:
    """The bird's-eye view of one run (see the module doc); ``zoom=(row, label)`` for the
    zoomed view around the ego at a trace row ('' if that row has no pose)."""
    if rec is None or len(rec.trace) == 0:
        return '<div class="nodata">bird\'s-eye: no trace</div>'
    if not np.any(np.isfinite(rec.trace.ego.x_m) & np.isfinite(rec.trace.ego.y_m)):
        return '<div class="nodata">bird\'s-eye: no pose</div>'
    v = _view(rec, width, max_height, zoom[0] if zoom is not None else None)
    if v is None:
        return ""
    out = [f'<svg class="bev" width="{width}" height="{v.height}" '
           f'viewBox="0 0 {width} {v.height}" role="img">', "<title>bird's-eye view</title>",
           f'<rect x="0" y="0" width="{width}" height="{v.height}" fill="#f8fafc"/>']
    out += _lanes(rec, v) + _neighbour_paths(rec, v) + _stalled(rec, v)
    out += _ellipses(rec, verdict, v) + _ego(rec, v) + _ends_and_marks(rec, v, marks)
    v0, v1 = _speed_range(rec.trace.ego.speed_mps)
    note = f"lateral scale ×{v.exaggeration:.1f}" if v.exaggeration > 1.05 else "true scale"
    if zoom is not None:
        note = f"zoom ±{ZOOM_HALF_LENGTH_M:.0f} m around {zoom[1]} · {note}"
    out.append(f'<text x="{width - 10}" y="{v.height - 10}" class="tick" text-anchor="end">'
               f"{esc(note)} · speed {fmt(v0, 3)}–{fmt(v1, 3)} m/s (dark→light)</text>")
    # the legend once a page (the whole-run view); the zoom below it has the same glyphs
    out += _scale_bar(v) + (_glyph_legend(v, rec) if zoom is None else [])
    out.append("</svg>")
    return "".join(out)


SCALE_STEPS_M = (1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0)


def _scale_bar(v: _View) -> list[str]:
    """A bar of a round length (about a sixth of the view) along the driving direction,
    bottom left, labelled in metres; the lateral scale differs when exaggerated (the
    note says by how much)."""
    want = (v.a1 - v.a0) / 6.0
    length = max((m for m in SCALE_STEPS_M if m <= want), default=SCALE_STEPS_M[0])
    px = length * v.sx
    x0, y0 = v.pad + 4, v.height - v.pad - 18
    return [f'<g class="scale"><line x1="{x0}" y1="{y0}" x2="{x0 + px:.1f}" y2="{y0}" '
            'stroke="#111827" stroke-width="2"/>'
            f'<line x1="{x0}" y1="{y0 - 4}" x2="{x0}" y2="{y0 + 4}" stroke="#111827"/>'
            f'<line x1="{x0 + px:.1f}" y1="{y0 - 4}" x2="{x0 + px:.1f}" y2="{y0 + 4}" '
            'stroke="#111827"/>'
            f'<text x="{x0 + px / 2:.1f}" y="{y0 - 6}" class="tick" text-anchor="middle">'
            f"{length:g} m</text></g>"]


LEGEND = (("ego path (speed: dark slow, light fast)", "#440154", "line"),
          ("ego box", "#2563eb", "box"), ("stalled car", "#b91c1c", "box"),
          ("other vehicle", "#475569", "box"), ("obstacle ellipse", "#d97706", "dash"),
          ("start", "#16a34a", "dot"), ("end", "#111827", "square"))


def _glyph_legend(v: _View, rec: RunRecord | None = None) -> list[str]:
    """What each glyph means, in one line of text along the top edge (a coloured
    symbol before each label: one element, a page per run stays small); the recorded
    vehicles' entries only when the run has such vehicles."""
    symbol = {"line": "━", "box": "■", "dash": "▭", "dot": "●", "square": "▪"}
    agents = set(np.unique(rec.neighbours.agent).tolist()) if rec is not None else set()
    entries = [*LEGEND, *(AGENT_LEGEND[a] for a in sorted(agents) if a in AGENT_LEGEND)]
    parts = "".join(f'<tspan fill="{colour}">{symbol[kind]}</tspan> {esc(label)}   '
                    for label, colour, kind in entries)
    return [f'<text x="{v.pad + 4}" y="14" class="tick" xml:space="preserve">{parts}</text>']
