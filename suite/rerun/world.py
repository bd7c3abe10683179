"""The bird's-eye entities of a recording (``/world/...``), in SUMO's network frame [m].

Static: the road (lane edges, shoulders, centrelines, reference path), the driven path,
the stalled cars of the scenario. Per step: the ego box, velocity arrow (labelled with
the pass side and its reason) and follow frame, the other vehicles' boxes, the obstacle
ellipses the controller saw (coloured by pass side), its plan and preview polylines,
the preview-error arrow and the detection circle. Recorded vehicles (scenario
``replay``) have their own entities and colours, by the neighbours' ``agent`` column:
``/world/replayed`` (following the recording, labelled ``<id> (replayed)``) and
``/world/reactive`` (handed over to SUMO's driver, ``<id> (reactive)``).
"""

from __future__ import annotations

import numpy as np
import rerun as rr

from reports.geometry import box_corners, ego_box_centres
from reports.record import AGENT_NAMES, AGENT_REACTIVE, AGENT_REPLAYED
from suite.rerun.blueprint import VIEW_FRAME_SCALE, north_up_transform
from suite.rerun.paths import ENTITY_PATHS, RECORDED_PATHS
from suite.rerun.stream import Colour, FlatStrips, RunLog

# Colours chosen to read on the viewer's dark background.
C_LANE = (200, 200, 200, 255)
C_SHOULDER = (230, 160, 40, 255)
C_CENTRE = (110, 110, 120, 255)
C_REFERENCE = (80, 170, 255, 200)
C_EGO = (60, 230, 120, 255)
C_TRAFFIC = (150, 180, 230, 255)
C_STALLED = (255, 60, 60, 255)
C_REPLAYED = (20, 184, 166, 255)  # teal (as the HTML views): a recording, blind to the ego
C_REACTIVE = (200, 110, 255, 255)  # violet: a recorded car now driven by SUMO
C_PLAN = (60, 255, 200, 255)
C_PREVIEW = (255, 170, 40, 255)
C_ERR = (255, 80, 80, 255)
C_DETECT = (90, 120, 200, 120)
C_SIDE = {1: (230, 80, 230, 255), -1: (255, 150, 40, 255), 2: (255, 60, 60, 255),
          0: (160, 160, 160, 255)}
SIDE_NAME = {1: "pass left", -1: "pass right", 2: "follow", 0: "no side"}
ELLIPSE_SEGMENTS = 36


def _polyline_normals(xy: np.ndarray) -> np.ndarray:
    """Unit left normals at the vertices of a polyline (M, 2), averaging adjacent segments."""
    d = np.diff(xy, axis=0)
    seg_len = np.linalg.norm(d, axis=1, keepdims=True)
    t_seg = d / np.maximum(seg_len, 1e-9)
    t = np.empty_like(xy)
    t[0] = t_seg[0]
    t[-1] = t_seg[-1]
    if len(xy) > 2:
        mid = t_seg[:-1] + t_seg[1:]
        t[1:-1] = mid / np.maximum(np.linalg.norm(mid, axis=1, keepdims=True), 1e-9)
    return np.stack([-t[:, 1], t[:, 0]], axis=1)


def lane_edges(shape_xy: np.ndarray, width_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Left and right edges of a lane from its centreline (M, 2) [m] and width [m]."""
    xy = np.asarray(shape_xy, dtype=np.float64).reshape(-1, 2)
    if len(xy) < 2:
        return xy.copy(), xy.copy()
    n = _polyline_normals(xy)
    half = 0.5 * float(width_m)
    return xy + half * n, xy - half * n


def closed_boxes(cx: np.ndarray, cy: np.ndarray, heading: np.ndarray, length: np.ndarray,
                 width: np.ndarray) -> np.ndarray:
    """Closed box outlines (N, 5, 2) [m] for LineStrips2D."""
    corners = box_corners(cx, cy, heading, length, width)
    return np.concatenate([corners, corners[..., :1, :]], axis=-2)


def ellipse_polylines(ell: np.ndarray) -> np.ndarray:
    """Closed polylines (M, S+1, 2) of ellipse rows [cx, cy, heading, A, B, ...]."""
    th = np.linspace(0.0, 2.0 * np.pi, ELLIPSE_SEGMENTS + 1)
    a = ell[:, 3:4] * np.cos(th)[None, :]
    b = ell[:, 4:5] * np.sin(th)[None, :]
    c, s = np.cos(ell[:, 2:3]), np.sin(ell[:, 2:3])
    return np.stack([ell[:, 0:1] + c * a - s * b, ell[:, 1:2] + s * a + c * b], axis=-1)


def _static_strips(log: RunLog, key: str, strips: list[np.ndarray], colour: Colour,
                   radius: float, order: float) -> None:
    if strips:
        log.static(ENTITY_PATHS[key], rr.LineStrips2D(
            strips, colors=colour, radii=rr.components.Radius.ui_points(radius),
            draw_order=order))


def log_road(log: RunLog) -> None:
    """Lane edges, shoulder edges, centrelines and the reference path (static)."""
    log.static(ENTITY_PATHS["north_up"], north_up_transform())
    lanes: list[np.ndarray] = []
    shoulders: list[np.ndarray] = []
    centres: list[np.ndarray] = []
    for lane in log.record.road.lanes:
        shape = np.asarray(lane.shape_xy_m, dtype=np.float64).reshape(-1, 2)
        if len(shape) < 2:
            continue
        left, right = lane_edges(shape, lane.width_m)
        (shoulders if lane.is_shoulder else lanes).extend([left, right])
        centres.append(shape)
    _static_strips(log, "lanes", lanes, C_LANE, 0.75, 1.0)
    _static_strips(log, "shoulders", shoulders, C_SHOULDER, 1.0, 1.5)
    _static_strips(log, "centrelines", centres, C_CENTRE, 0.4, 0.5)
    ref = np.asarray(log.record.road.reference_xy_m, dtype=np.float64).reshape(-1, 2)
    if len(ref) >= 2:
        _static_strips(log, "reference_path", [ref], C_REFERENCE, 1.0, 2.0)


def _ego_velocity(log: RunLog, ok: np.ndarray, psi: np.ndarray) -> None:
    ego, decision = log.record.trace.ego, log.record.trace.decision
    speed = ego.speed_mps
    u, v = ego.u_mps, np.where(np.isfinite(ego.v_mps), ego.v_mps, 0.0)
    if not np.isfinite(speed).any():
        speed = np.hypot(u, v)
    beta = np.arctan2(v, np.where(np.isfinite(u), u, 1.0))
    vec = np.stack([speed * np.cos(psi + beta), speed * np.sin(psi + beta)], axis=1)
    okv = ok & np.all(np.isfinite(vec), axis=1)
    path = ENTITY_PATHS["ego_velocity"]
    log.static(path, rr.Arrows2D.from_fields(colors=[C_EGO], draw_order=31.0,
                                            radii=rr.components.Radius.ui_points(1.0)))
    origins = np.stack([ego.x_m, ego.y_m], axis=1)
    cols = list(rr.Arrows2D.columns(vectors=vec[okv], origins=origins[okv])
                .partition(okv.astype(np.int64)))
    side = np.asarray(decision.side, dtype=np.int64)
    labelled = okv & (side != 0)
    if labelled.any():  # the pass side next to the ego, where the eye already is
        labels = [SIDE_NAME.get(int(side[i]), str(side[i]))
                  + (f": {decision.side_reason[i]}" if decision.side_reason[i] else "")
                  for i in np.flatnonzero(labelled)]
        cols += list(rr.Arrows2D.columns(labels=labels).partition(labelled.astype(np.int64)))
    log.send(path, cols)


def _follow_frame(log: RunLog, cx: np.ndarray, cy: np.ndarray) -> None:
    """Translation only, so the follow view keeps world axes; NaN poses keep the last."""
    cxy = np.stack([cx, cy], axis=1)
    last = np.array([0.0, 0.0])
    trans = np.zeros((log.n, 3))
    for i in range(log.n):
        if np.all(np.isfinite(cxy[i])):
            last = cxy[i]
        trans[i, :2] = last
    scale = np.tile(np.asarray(VIEW_FRAME_SCALE, dtype=np.float64), (log.n, 1))
    log.send(ENTITY_PATHS["ego_frame"], rr.Transform3D.columns(translation=trans, scale=scale))


def log_ego(log: RunLog) -> None:
    """Ego box, velocity arrow, follow frame (per step) and driven path (static)."""
    ego, box = log.record.trace.ego, log.record.info.ego
    x, y = ego.x_m, ego.y_m
    psi = np.where(np.isfinite(ego.psi_rad), ego.psi_rad, 0.0)
    cx, cy = ego_box_centres(x, y, psi, box)
    boxes = closed_boxes(cx, cy, psi, np.full(log.n, box.length_m), np.full(log.n, box.width_m))
    ok = np.all(np.isfinite(boxes), axis=(1, 2))
    path = ENTITY_PATHS["ego_box"]
    log.static(path, rr.LineStrips2D.from_fields(
        colors=[C_EGO], radii=rr.components.Radius.ui_points(2.0), labels=["ego"],
        show_labels=True, draw_order=30.0))
    log.strips_per_step(path, boxes[ok], ok.astype(np.int64))
    _ego_velocity(log, ok, psi)
    _follow_frame(log, cx, cy)
    xy = np.stack([x, y], axis=1)
    driven = xy[np.all(np.isfinite(xy), axis=1)]
    if len(driven) >= 2:
        log.static(ENTITY_PATHS["driven_path"], rr.LineStrips2D(
            [driven], colors=(60, 230, 120, 110), radii=rr.components.Radius.ui_points(0.75),
            draw_order=3.0))


def _boxes_per_step(log: RunLog, path: str, rows: np.ndarray, take: np.ndarray,
                    colour: Colour, order: float, suffix: str = "") -> None:
    """Boxes of the neighbour rows ``take`` (with trace rows ``rows``), one batch per step."""
    nb = log.record.neighbours.take(take)
    rows = rows[take]
    if not len(nb):
        return
    sort = np.lexsort((np.asarray(nb.id, dtype=str), rows))  # by step, then id
    nb, rows = nb.take(sort), rows[sort]
    boxes = closed_boxes(nb.x_m, nb.y_m, np.nan_to_num(nb.heading_rad), nb.length_m,
                         nb.width_m)
    ok = np.all(np.isfinite(boxes), axis=(1, 2))
    counts = np.bincount(rows[ok], minlength=log.n)
    log.static(path, rr.LineStrips2D.from_fields(
        colors=[colour], radii=rr.components.Radius.ui_points(1.25), draw_order=order,
        show_labels=True))
    log.strips_per_step(path, boxes[ok], counts, labels=[str(i) + suffix for i in nb.id[ok]])


def log_vehicles(log: RunLog) -> None:
    """Moving traffic per step; stalled cars static from the outcome (else per step)."""
    nb = log.record.neighbours
    stalled = log.record.outcome.stalled
    rows = log.rows_of_steps(nb.step) if len(nb) else np.zeros(0, dtype=np.int64)
    on_trace = rows >= 0
    stalled_ids = {s.id for s in stalled}
    is_stalled = nb.stalled | np.isin(np.asarray(nb.id, dtype=str), list(stalled_ids))
    recorded = np.zeros(len(nb), dtype=bool)
    for agent, colour in ((AGENT_REPLAYED, C_REPLAYED), (AGENT_REACTIVE, C_REACTIVE)):
        mine = nb.agent == agent
        recorded |= mine
        if mine.any():
            name = AGENT_NAMES[agent]
            _boxes_per_step(log, RECORDED_PATHS[name], rows, on_trace & mine, colour, 20.5,
                            f" ({name})")
    _boxes_per_step(log, ENTITY_PATHS["vehicles"], rows, on_trace & ~is_stalled & ~recorded,
                    C_TRAFFIC, 20.0)
    if not stalled:
        _boxes_per_step(log, ENTITY_PATHS["stalled"], rows, on_trace & is_stalled, C_STALLED,
                        21.0)
        return
    boxes = closed_boxes(np.array([s.x_m for s in stalled]), np.array([s.y_m for s in stalled]),
                         np.array([s.heading_rad for s in stalled]),
                         np.array([s.length_m for s in stalled]),
                         np.array([s.width_m for s in stalled]))
    log.static(ENTITY_PATHS["stalled"], rr.LineStrips2D(
        boxes, colors=C_STALLED, radii=rr.components.Radius.ui_points(2.0),
        labels=[f"{s.id} (stalled)" for s in stalled], show_labels=True, draw_order=21.0))


def per_step_array(log: RunLog, values: np.ndarray) -> np.ndarray | None:
    """A controller array (first axis = step) cut or NaN-padded to the trace rows."""
    a = np.asarray(values, dtype=np.float64)
    if not log.n or a.ndim < 1 or a.shape[0] == 0:
        return None
    if a.shape[0] < log.n:  # pad missing trailing steps with NaN
        a = np.concatenate([a, np.full((log.n - a.shape[0],) + a.shape[1:], np.nan)])
    return a[: log.n]


def _ellipse_labels(log: RunLog, active: np.ndarray) -> list[str] | None:
    """The vehicle id of each active ellipse, in ``ell[active]`` order (None when the
    record has none: an older run, or a controller whose ellipses carry no ids)."""
    ids = log.record.arrays.ellipse_ids
    if ids is None or ids.ndim != 2 or not np.any(ids != ""):
        return None
    t, k = active.shape
    padded = np.full((t, k), "", dtype=ids.dtype)
    rows, cols = min(t, ids.shape[0]), min(k, ids.shape[1])
    padded[:rows, :cols] = ids[:rows, :cols]
    return [str(v) for v in padded[active]]


def log_ellipses(log: RunLog) -> None:
    """Active obstacle ellipses per step, coloured by the pass side of that step and
    labelled with the vehicle behind each (when the record has the ids)."""
    ell = per_step_array(log, log.record.arrays.ellipses)
    if ell is None or ell.ndim != 3 or ell.shape[2] < 5:
        return
    active = np.all(np.isfinite(ell[:, :, :5]), axis=2)
    if ell.shape[2] >= 6:
        active &= np.nan_to_num(ell[:, :, 5]) > 0.5
    counts = active.sum(axis=1)
    if not counts.any():
        return
    side = np.asarray(log.record.trace.decision.side, dtype=np.int64)
    strips = ellipse_polylines(ell[active])
    colors = np.array([C_SIDE.get(int(s), C_SIDE[0]) for s in np.repeat(side, counts)],
                      dtype=np.uint8).reshape(-1, 4)
    path = ENTITY_PATHS["ellipses"]
    log.static(path, rr.LineStrips2D.from_fields(
        radii=rr.components.Radius.ui_points(1.25), draw_order=15.0))
    log.strips_per_step(path, strips, counts, labels=_ellipse_labels(log, active),
                        colors=colors)


def _polyline_per_step(log: RunLog, values: np.ndarray
                       ) -> tuple[FlatStrips, np.ndarray, np.ndarray]:
    """Valid points of a (T, P, 2) array per step -> (the strips of the steps with two
    or more, strips per step (T,) 0 or 1, last valid point (T, 2), NaN where none)."""
    arr = per_step_array(log, values)
    last = np.full((log.n, 2), np.nan)
    if arr is None or arr.ndim != 3 or arr.shape[2] != 2:
        return FlatStrips(np.zeros((0, 2)), np.zeros(0, np.int64)), np.zeros(log.n, np.int64), \
            last
    ok = np.all(np.isfinite(arr), axis=2)
    valid = ok.sum(axis=1)
    strip = valid >= 2
    # boolean indexing walks rows in order: each step's valid points, in point order
    strips = FlatStrips(arr[ok & strip[:, None]], valid[strip].astype(np.int64))
    rows = np.flatnonzero(valid > 0)
    last[rows] = arr[rows, _last_true(ok[rows])]
    return strips, strip.astype(np.int64), last


def _last_true(mask: np.ndarray) -> np.ndarray:
    """Column of the last True of each row of a (T, P) mask (rows with one at least).

    A controller that returns no plan records (T, 0, 2) arrays: with no columns there
    is no row with a True either, and the answer is the empty (0,) index array (numpy's
    argmax refuses an empty axis)."""
    if mask.shape[0] == 0 or mask.shape[1] == 0:
        return np.zeros(mask.shape[0], dtype=np.int64)
    out: np.ndarray = mask.shape[1] - 1 - np.argmax(mask[:, ::-1], axis=1)
    return out


def log_plan_preview(log: RunLog) -> None:
    """The planned trajectory and the preview of the CG per step, then the error arrow."""
    arrays = log.record.arrays
    for key, values, colour, order in (("plan", arrays.plan_xy_m, C_PLAN, 25.0),
                                       ("preview", arrays.preview_xy_m, C_PREVIEW, 26.0)):
        strips, lengths, _ = _polyline_per_step(log, values)
        if lengths.any():
            log.static(ENTITY_PATHS[key], rr.LineStrips2D.from_fields(
                colors=[colour], radii=rr.components.Radius.ui_points(1.5), draw_order=order))
            log.strips_per_step(ENTITY_PATHS[key], strips, lengths)
    log_preview_error(log)


def _recorded_preview_error(log: RunLog, prev: np.ndarray, along: np.ndarray,
                            normal: np.ndarray) -> np.ndarray:
    """Error vectors (T, 2) [m] from the recorded components along / left of the
    preview's end tangent (plan minus preview): with d the unit vector from the last
    but one valid preview point to the last, along d + normal (-d_y, d_x); NaN rows
    where a step has fewer than two valid points."""
    vec = np.full((log.n, 2), np.nan)
    ok = np.all(np.isfinite(prev), axis=2)
    rows = np.flatnonzero(ok.sum(axis=1) >= 2)
    if rows.size == 0:
        return vec
    mask = ok[rows]
    end = _last_true(mask)
    mask[np.arange(rows.size), end] = False
    d = prev[rows, end] - prev[rows, _last_true(mask)]
    d = d / np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-9)[:, None]
    left = np.column_stack([-d[:, 1], d[:, 0]])
    vec[rows] = np.asarray(along)[rows, None] * d + np.asarray(normal)[rows, None] * left
    return vec


def _approximate_preview_error(log: RunLog, prev_end: np.ndarray) -> np.ndarray:
    """Without recorded components: the plan point at the preview's index when both have
    the same sampling, else the plan point nearest to the preview end, minus that end."""
    vec = np.full((log.n, 2), np.nan)
    plan = per_step_array(log, log.record.arrays.plan_xy_m)
    prev = per_step_array(log, log.record.arrays.preview_xy_m)
    if plan is None or plan.ndim != 3 or prev is None:
        return vec
    same = plan.shape[1] == prev.shape[1]
    for i in range(log.n):
        if not np.all(np.isfinite(prev_end[i])):
            continue
        pts = plan[i]
        if same and np.all(np.isfinite(pts[-1])):
            vec[i] = pts[-1] - prev_end[i]
            continue
        good = pts[np.all(np.isfinite(pts), axis=1)]
        if len(good):
            vec[i] = good[np.argmin(np.linalg.norm(good - prev_end[i], axis=1))] - prev_end[i]
    return vec


def log_preview_error(log: RunLog) -> None:
    """Arrow from the preview end to the plan point it should be at: from the trace's
    ``preview_err_t_m``/``preview_err_n_m`` when the controller records them, an
    approximation from the plan only for controllers that do not."""
    prev = per_step_array(log, log.record.arrays.preview_xy_m)
    if prev is None or prev.ndim != 3:
        return
    extra = log.record.trace.extra
    along, normal = extra.get("preview_err_t_m"), extra.get("preview_err_n_m")
    _, _, prev_end = _polyline_per_step(log, log.record.arrays.preview_xy_m)
    if along is not None and normal is not None:
        vec = _recorded_preview_error(log, prev, along, normal)
    else:
        vec = _approximate_preview_error(log, prev_end)
    ok = np.all(np.isfinite(vec), axis=1) & np.all(np.isfinite(prev_end), axis=1)
    if not ok.any():
        return
    path = ENTITY_PATHS["preview_error"]
    log.static(path, rr.Arrows2D.from_fields(
        colors=[C_ERR], radii=rr.components.Radius.ui_points(1.0), draw_order=27.0))
    log.send(path, list(rr.Arrows2D.columns(vectors=vec[ok], origins=prev_end[ok])
                        .partition(ok.astype(np.int64))))


def log_detection(log: RunLog) -> None:
    """The controller's detection circle around the CG per step."""
    radius = float(log.record.arrays.detection_radius_m)
    if not log.n or not np.isfinite(radius) or radius <= 0:
        return
    ego = log.record.trace.ego
    xy = np.stack([ego.x_m, ego.y_m], axis=1)
    ok = np.all(np.isfinite(xy), axis=1)
    path = ENTITY_PATHS["detection"]
    log.static(path, rr.Ellipses2D.from_fields(
        half_sizes=[(radius, radius)], colors=[C_DETECT],
        line_radii=rr.components.Radius.ui_points(0.75), draw_order=5.0))
    log.send(path, list(rr.Ellipses2D.columns(centers=xy[ok]).partition(ok.astype(np.int64))))
