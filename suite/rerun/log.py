"""Write a run directory as a Rerun recording, ``DIR/<scenario>/run.rrd``.

The runner calls :func:`write_rrd` after the simulation; everything is logged from
the recorded arrays (``reports.run_record``) with columnar ``send_columns`` calls, one
per entity, so the cost is a handful of batches, not one call per step.

Recording
---------
* application id ``hwyeval`` (default), recording id :func:`recording_id_for`
  (catalog, scenario, seed): a UUID5 string, the same for the same run, so a re-run
  replaces the old recording in the viewer instead of piling up beside it.
* a per-run ``rr.RecordingStream`` (never the global one) saved to ``run.rrd`` with
  the default blueprint of ``suite.rerun.blueprint`` embedded.
* timelines: ``sim_time`` (duration, from ``t_s``) and ``step`` (sequence).

Entity paths (users and tests rely on them)
-------------------------------------------
World, bird's-eye, metres in SUMO's network frame (static = logged once):

``/world/road/lanes``          static LineStrips2D, left/right edges of the driving lanes
``/world/road/shoulders``      static LineStrips2D, edges of shoulder lanes (amber)
``/world/road/centrelines``    static LineStrips2D, lane centrelines (thin, dim)
``/world/reference_path``      static LineStrips2D, the controller's reference centreline
``/world/ego/driven_path``     static LineStrips2D, the whole path of the ego CG
``/world/ego/box``             per step, closed LineStrip2D of the ego box (label "ego")
``/world/ego/velocity``        per step, Arrows2D from the CG, length = 1 s of travel; labelled
                               with the pass side and its reason while a side is chosen
``/world/ego/frame``           per step, Transform3D translation = ego box centre, scale
                               (1, -1, 1); the "Follow ego" view renders in this frame, so it
                               follows the ego with world +Y (left) up on screen
``/world/view/north_up``       static Transform3D scale (1, -1, 1): frame of the "Whole road" view
``/world/vehicles``            per step, closed LineStrips2D of moving traffic, SUMO ids as labels
``/world/stalled``             stalled vehicles (red), static from run.json, else per step
``/world/ellipses``            per step, obstacle ellipses as the controller sees them
                               (polylines); colour = pass side (magenta left, orange right,
                               red follow, grey none)
``/world/plan``                per step, planned SPMM trajectory (``plan_xy_m``)
``/world/preview``             per step, STVM preview of the CG (``preview_xy_m``)
``/world/preview_error``       per step, Arrows2D from the preview end to the plan
``/world/detection``           per step, Ellipses2D circle of ``detection_radius_m`` at the CG

Scalars (``Scalars`` + static ``SeriesLines`` names/colours); NaN samples are left out:

``/safety/ttc_s``                SUMO SSM TTC [s]
``/safety/min_gap_m``            ego box to nearest box [m]
``/safety/collision``            1 on steps with a geometric or SUMO collision
``/comfort/accel_mps2/{long,lat}``  body accelerations [m/s^2]
``/comfort/jerk_mps3/{long,total}`` longitudinal jerk and |d a/dt| of the world-frame
                                 acceleration [m/s^3], the series the verdict uses
                                 (``reports.metrics.comfort``; local Savitzky-Golay fallback)
``/comfort/yaw_rate_radps``      yaw rate [rad/s]
``/controller/speed_mps/{actual,target}``
``/controller/lat_dev_m``, ``/controller/heading_err_deg``
``/controller/steer_deg/{total,outer,correction}``
``/controller/torque_nm/{total,outer,correction}``
``/controller/residual``         outer-loop residual E
``/controller/preview_err_m/{t,n}``  when the trace has ``preview_err_t_m``/``_n_m``
``/controller/side``             pass side (+1 left, -1 right, 0 none, 2 follow)
``/controller/fallback``, ``/controller/n_obstacles``
``/timing/step_ms/{outer,inner,obstacles,controller,sumo}``  time per loop [ms]

Text:

``/events``            TextLog at the step each happens: start, collisions (geometry and
                       SUMO, ERROR), failed criteria at their first violating step (WARN;
                       at the end when not derivable), fallback onsets (WARN), pass-side
                       changes (INFO), final status (INFO or ERROR)
``/docs/scenario``     static markdown: status, failed criteria, scenario parameters, seed,
                       criteria, metrics, full run.json
``/docs/controller``   static markdown: controller name, options and parameters (JSON)
"""

from __future__ import annotations

import json
import re
import uuid
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import rerun as rr

from reports.metrics.geometry import box_corners
from reports.run_record import RRD, RunRecord, load_run
from suite.rerun.blueprint import VIEW_FRAME_SCALE, default_blueprint, north_up_transform

__all__ = ["write_rrd", "recording_id_for", "lane_edges", "ENTITY_PATHS"]

# Stable namespace for recording ids (uuid5 of "hwyeval|catalog|scenario|seed").
_RECORDING_NAMESPACE = uuid.UUID("6f1d3c2a-9b7e-5d41-8c3a-2e6f0b9a7d15")

ENTITY_PATHS = {
    "lanes": "/world/road/lanes",
    "shoulders": "/world/road/shoulders",
    "centrelines": "/world/road/centrelines",
    "reference_path": "/world/reference_path",
    "driven_path": "/world/ego/driven_path",
    "ego_box": "/world/ego/box",
    "ego_velocity": "/world/ego/velocity",
    "ego_frame": "/world/ego/frame",
    "north_up": "/world/view/north_up",
    "vehicles": "/world/vehicles",
    "stalled": "/world/stalled",
    "ellipses": "/world/ellipses",
    "plan": "/world/plan",
    "preview": "/world/preview",
    "preview_error": "/world/preview_error",
    "detection": "/world/detection",
    "events": "/events",
    "scenario_doc": "/docs/scenario",
    "controller_doc": "/docs/controller",
}

# Colours chosen to read on the viewer's dark background.
_C_LANE = (200, 200, 200, 255)
_C_SHOULDER = (230, 160, 40, 255)
_C_CENTRE = (110, 110, 120, 255)
_C_REFERENCE = (80, 170, 255, 200)
_C_EGO = (60, 230, 120, 255)
_C_TRAFFIC = (150, 180, 230, 255)
_C_STALLED = (255, 60, 60, 255)
_C_PLAN = (60, 255, 200, 255)
_C_PREVIEW = (255, 170, 40, 255)
_C_ERR = (255, 80, 80, 255)
_C_DETECT = (90, 120, 200, 120)
_C_SIDE = {1: (230, 80, 230, 255), -1: (255, 150, 40, 255), 2: (255, 60, 60, 255),
           0: (160, 160, 160, 255)}
_SIDE_NAME = {1: "pass left", -1: "pass right", 2: "follow", 0: "no side"}

_ELLIPSE_SEGMENTS = 36


def _catalog_name(catalog: Any) -> str:
    """A catalog name from a name or a catalog file path ('catalogs/smoke.yaml' -> 'smoke')."""
    if catalog is None:
        return ""
    text = str(catalog)
    path = Path(text)
    if path.suffix.lower() in {".yaml", ".yml", ".toml", ".json"}:
        return path.stem
    return path.name if "/" in text else text


def recording_id_for(catalog: str | None, scenario: str, seed: int | str | None) -> str:
    """Stable recording id of a run: UUID5 of (catalog name, scenario, seed)."""
    key = f"hwyeval|{_catalog_name(catalog)}|{scenario}|{'' if seed is None else seed}"
    return str(uuid.uuid5(_RECORDING_NAMESPACE, key))


# --------------------------------------------------------------------------- geometry


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
    """Left and right edges of a lane from its centreline (M, 2) and width."""
    xy = np.asarray(shape_xy, dtype=np.float64).reshape(-1, 2)
    if len(xy) < 2:
        return xy.copy(), xy.copy()
    n = _polyline_normals(xy)
    half = 0.5 * float(width_m)
    return xy + half * n, xy - half * n


def _closed_boxes(cx: np.ndarray, cy: np.ndarray, heading: np.ndarray, length: np.ndarray,
                  width: np.ndarray) -> np.ndarray:
    """Closed box outlines (N, 5, 2) for LineStrips2D."""
    corners = box_corners(cx, cy, heading, length, width)
    return np.concatenate([corners, corners[..., :1, :]], axis=-2)


def _ellipse_polylines(ell: np.ndarray) -> np.ndarray:
    """Closed polylines (M, S+1, 2) of ellipses rows [cx, cy, heading, A, B, ...]."""
    th = np.linspace(0.0, 2.0 * np.pi, _ELLIPSE_SEGMENTS + 1)
    a = ell[:, 3:4] * np.cos(th)[None, :]
    b = ell[:, 4:5] * np.sin(th)[None, :]
    c, s = np.cos(ell[:, 2:3]), np.sin(ell[:, 2:3])
    x = ell[:, 0:1] + c * a - s * b
    y = ell[:, 1:2] + s * a + c * b
    return np.stack([x, y], axis=-1)


# --------------------------------------------------------------------------- helpers


def _col(df: pd.DataFrame, name: str, default: float = np.nan) -> np.ndarray:
    if name in df.columns:
        return pd.to_numeric(df[name], errors="coerce").to_numpy(dtype=np.float64)
    return np.full(len(df), default, dtype=np.float64)


def _bool_col(df: pd.DataFrame, name: str) -> np.ndarray:
    if name in df.columns:
        return df[name].fillna(False).to_numpy().astype(bool)
    return np.zeros(len(df), dtype=bool)


def _jerk(acc: np.ndarray, t: np.ndarray, window_s: float = 0.5) -> np.ndarray:
    """d(acc)/dt by a Savitzky-Golay derivative (quadratic fit over ~window_s).

    For the first derivative the quadratic and linear SG kernels coincide:
    w_k = k / (dt * sum k^2), k = -m..m. The m samples at each end use np.gradient.
    NaN samples count as 0 (they are rare: the trace is complete for finished steps).
    """
    n = len(acc)
    if n < 3:
        return np.zeros(n)
    dt = float(np.median(np.diff(t)))
    if not np.isfinite(dt) or dt <= 0:
        dt = 1.0
    a = np.where(np.isfinite(acc), acc, 0.0)
    out = np.gradient(a, dt)
    m = max(2, int(round(0.5 * window_s / dt)))
    if n > 2 * m:
        k = np.arange(-m, m + 1, dtype=np.float64)
        kernel = k / (dt * float(np.sum(k * k)))
        out[m:n - m] = np.convolve(a, kernel[::-1], mode="valid")
    return out


def _comfort_series(run: RunRecord, t: np.ndarray) -> dict[str, np.ndarray]:
    """Per-step comfort signals, the same ones the verdict uses when reports.metrics is there.

    Keys: long_acc, lat_acc, yaw_rate, yaw_acc, long_jerk, jerk (|d a/dt| of the world-frame
    acceleration vector). Falls back to a local Savitzky-Golay derivative.
    """
    n = len(run.trace)
    try:
        from reports.metrics.comfort import comfort_series

        series = comfort_series(run)
        if all(len(np.asarray(series.get(k, []))) == n
               for k in ("long_acc", "lat_acc", "long_jerk", "jerk")):
            return {k: np.asarray(v, dtype=np.float64) for k, v in series.items()}
    except Exception:  # noqa: BLE001 - metrics are optional here; the log must not fail
        pass
    tr = run.trace
    psi = np.unwrap(np.nan_to_num(_col(tr, "psi_rad", 0.0)))
    a_long, a_lat = _col(tr, "long_acc_mps2"), _col(tr, "lat_acc_mps2")
    r = _col(tr, "r_radps")
    c, s_ = np.cos(psi), np.sin(psi)
    ax = np.nan_to_num(a_long) * c - np.nan_to_num(a_lat) * s_
    ay = np.nan_to_num(a_long) * s_ + np.nan_to_num(a_lat) * c
    return {"long_acc": a_long, "lat_acc": a_lat, "yaw_rate": r, "yaw_acc": _jerk(r, t),
            "long_jerk": _jerk(a_long, t), "jerk": np.hypot(_jerk(ax, t), _jerk(ay, t))}


def _time_columns(steps: np.ndarray, t_s: np.ndarray) -> list[rr.TimeColumn]:
    return [rr.TimeColumn("step", sequence=np.asarray(steps, dtype=np.int64)),
            rr.TimeColumn("sim_time", duration=np.asarray(t_s, dtype=np.float64))]


def _md_json(obj: Any) -> str:
    return "```json\n" + json.dumps(obj, indent=2, sort_keys=True, default=str) + "\n```\n"


class _Writer:
    """Logs one RunRecord to a recording stream."""

    def __init__(self, rec: rr.RecordingStream, run: RunRecord) -> None:
        self.rec = rec
        self.run = run
        self.meta = run.meta
        tr = run.trace
        if "step" in tr.columns and len(tr):
            tr = tr.sort_values("step", kind="stable").reset_index(drop=True)
        self.trace = tr
        self.T = len(tr)
        self.steps = (tr["step"].to_numpy(dtype=np.int64) if self.T else np.zeros(0, np.int64))
        self.t = _col(tr, "t_s") if self.T else np.zeros(0)
        if self.T and not np.all(np.isfinite(self.t)):
            dt = float(self.meta.get("step_s") or 0.1)
            self.t = np.where(np.isfinite(self.t), self.t, self.steps * dt)
        self.idx = _time_columns(self.steps, self.t)
        ego = self.meta.get("ego") or {}
        self.ego_len = float(ego.get("length_m", 4.5))
        self.ego_wid = float(ego.get("width_m", 1.8))
        self.ego_off = float(ego.get("cg_to_box_centre_m", 0.0))
        self.events: list[tuple[int, str, str]] = []  # (row in trace, level, text)
        self._comfort: dict[str, np.ndarray] | None = None

    def comfort(self) -> dict[str, np.ndarray]:
        if self._comfort is None:
            self._comfort = _comfort_series(self.run, self.t)
        return self._comfort

    # -------------------------------------------------------------- sending helpers
    def send(self, path: str, columns: Any, idx: Sequence[rr.TimeColumn] | None = None) -> None:
        self.rec.send_columns(path, indexes=self.idx if idx is None else idx, columns=columns)

    def static(self, path: str, *archetypes: Any) -> None:
        self.rec.log(path, *archetypes, static=True)

    def strips_per_step(self, path: str, strips: np.ndarray | list[np.ndarray],
                        lengths: np.ndarray, labels: list[str] | None = None,
                        label_lengths: np.ndarray | None = None,
                        colors: np.ndarray | None = None) -> None:
        """Per-step LineStrips2D: row i holds lengths[i] strips (0 clears the entity)."""
        lengths = np.asarray(lengths, dtype=np.int64)
        cols = list(rr.LineStrips2D.columns(strips=strips).partition(lengths))
        if labels is not None:
            ll = lengths if label_lengths is None else np.asarray(label_lengths, np.int64)
            cols += list(rr.LineStrips2D.columns(labels=labels).partition(ll))
        if colors is not None:
            cols += list(rr.LineStrips2D.columns(colors=colors).partition(lengths))
        self.send(path, cols)

    def scalar(self, path: str, values: np.ndarray, name: str,
               color: tuple[int, int, int, int] | None = None) -> None:
        values = np.asarray(values, dtype=np.float64)
        ok = np.isfinite(values)
        if not ok.any():
            return
        self.static(path, rr.SeriesLines(names=[name],
                                         colors=[color] if color is not None else None))
        self.send(path, rr.Scalars.columns(scalars=values[ok]),
                  idx=_time_columns(self.steps[ok], self.t[ok]))

    # -------------------------------------------------------------- static content
    def log_road(self) -> None:
        self.static(ENTITY_PATHS["north_up"], north_up_transform())
        road = self.run.road
        lanes: list[np.ndarray] = []
        shoulders: list[np.ndarray] = []
        centres: list[np.ndarray] = []
        for lane in road.get("lanes", []):
            shape = np.asarray(lane.get("shape_xy_m", []), dtype=np.float64).reshape(-1, 2)
            if len(shape) < 2:
                continue
            left, right = lane_edges(shape, float(lane.get("width_m", 3.2)))
            (shoulders if lane.get("is_shoulder") else lanes).extend([left, right])
            centres.append(shape)
        if lanes:
            self.static(ENTITY_PATHS["lanes"], rr.LineStrips2D(
                lanes, colors=_C_LANE, radii=rr.components.Radius.ui_points(0.75),
                draw_order=1.0))
        if shoulders:
            self.static(ENTITY_PATHS["shoulders"], rr.LineStrips2D(
                shoulders, colors=_C_SHOULDER, radii=rr.components.Radius.ui_points(1.0),
                draw_order=1.5))
        if centres:
            self.static(ENTITY_PATHS["centrelines"], rr.LineStrips2D(
                centres, colors=_C_CENTRE, radii=rr.components.Radius.ui_points(0.4),
                draw_order=0.5))
        ref = np.asarray(road.get("reference_xy_m", []), dtype=np.float64).reshape(-1, 2)
        if len(ref) >= 2:
            self.static(ENTITY_PATHS["reference_path"], rr.LineStrips2D(
                [ref], colors=_C_REFERENCE, radii=rr.components.Radius.ui_points(1.0),
                draw_order=2.0))

    def log_docs(self) -> None:
        m = self.meta
        status = str(m.get("status", "?"))
        failed = list(m.get("failed_criteria") or [])
        head = [f"# {m.get('scenario', self.run.name)}",
                "",
                f"**status: {status.upper()}**" + (f" — failed: {', '.join(failed)}" if failed
                                                    else ""),
                ""]
        if m.get("error"):
            head += ["```", str(m["error"]).strip().splitlines()[-1], "```", ""]
        facts = [("controller", m.get("controller")), ("catalog", m.get("catalog")),
                 ("seed", m.get("seed")), ("net", m.get("net")),
                 ("duration_s", m.get("duration_s")), ("step_s", m.get("step_s")),
                 ("target_speed_mps", m.get("target_speed_mps")),
                 ("sim_time_s", m.get("sim_time_s")), ("wall_s", m.get("wall_s"))]
        head += ["| parameter | value |", "|---|---|"]
        head += [f"| {k} | {v} |" for k, v in facts if v is not None]
        body = ["", "## Criteria", _md_json(m.get("criteria", {})),
                "## Metrics", _md_json(m.get("metrics", {})),
                "## Stalled vehicles", _md_json(m.get("stalled", [])),
                "## SUMO collisions", _md_json(m.get("sumo_collisions", [])),
                "## SSM", _md_json(m.get("ssm", {})),
                "## run.json", _md_json({k: v for k, v in m.items() if k != "error"})]
        self.static(ENTITY_PATHS["scenario_doc"], rr.TextDocument(
            "\n".join(head + body), media_type=rr.MediaType.MARKDOWN))
        ctrl = ["# Controller: " + str(m.get("controller", "?")), "",
                "## Options", _md_json(m.get("controller_options", {})),
                "## Parameters", _md_json(m.get("controller_params", {}))]
        self.static(ENTITY_PATHS["controller_doc"], rr.TextDocument(
            "\n".join(ctrl), media_type=rr.MediaType.MARKDOWN))

    # -------------------------------------------------------------- per-step world
    def log_ego(self) -> None:
        tr = self.trace
        x, y, psi = _col(tr, "x_m"), _col(tr, "y_m"), _col(tr, "psi_rad", 0.0)
        psi = np.where(np.isfinite(psi), psi, 0.0)
        cx = x + self.ego_off * np.cos(psi)
        cy = y + self.ego_off * np.sin(psi)
        boxes = _closed_boxes(cx, cy, psi, np.full(self.T, self.ego_len),
                              np.full(self.T, self.ego_wid))
        ok = np.all(np.isfinite(boxes), axis=(1, 2))
        path = ENTITY_PATHS["ego_box"]
        self.static(path, rr.LineStrips2D.from_fields(
            colors=[_C_EGO], radii=rr.components.Radius.ui_points(2.0), labels=["ego"],
            show_labels=True, draw_order=30.0))
        self.strips_per_step(path, boxes[ok], ok.astype(np.int64))

        speed = _col(tr, "speed_mps")
        u, v = _col(tr, "u_mps"), _col(tr, "v_mps", 0.0)
        if not np.isfinite(speed).any():
            speed = np.hypot(u, np.where(np.isfinite(v), v, 0.0))
        beta = np.arctan2(np.where(np.isfinite(v), v, 0.0), np.where(np.isfinite(u), u, 1.0))
        vec = np.stack([speed * np.cos(psi + beta), speed * np.sin(psi + beta)], axis=1)
        okv = ok & np.all(np.isfinite(vec), axis=1)
        vpath = ENTITY_PATHS["ego_velocity"]
        self.static(vpath, rr.Arrows2D.from_fields(colors=[_C_EGO], draw_order=31.0,
                                                   radii=rr.components.Radius.ui_points(1.0)))
        origins = np.stack([x, y], axis=1)
        cols = list(rr.Arrows2D.columns(vectors=vec[okv], origins=origins[okv])
                    .partition(okv.astype(np.int64)))
        side = np.nan_to_num(_col(tr, "side", 0.0)).astype(np.int64)
        reason = (tr["side_reason"].fillna("").astype(str).tolist()
                  if "side_reason" in tr.columns else [""] * self.T)
        has_label = okv & (side != 0)
        if has_label.any():  # the pass side next to the ego, where the eye already is
            labels = [_SIDE_NAME.get(int(side[i]), str(side[i]))
                      + (f": {reason[i]}" if reason[i] else "") for i in np.flatnonzero(has_label)]
            cols += list(rr.Arrows2D.columns(labels=labels).partition(has_label.astype(np.int64)))
        self.send(vpath, cols)

        # Follow frame: translation only, so the bird's-eye view keeps world axes.
        fpath = ENTITY_PATHS["ego_frame"]
        cxy = np.stack([cx, cy], axis=1)
        last = np.array([0.0, 0.0])
        trans = np.zeros((self.T, 3))
        for i in range(self.T):  # carry the last finite pose over NaN gaps
            if np.all(np.isfinite(cxy[i])):
                last = cxy[i]
            trans[i, :2] = last
        scale = np.tile(np.asarray(VIEW_FRAME_SCALE, dtype=np.float64), (self.T, 1))
        self.send(fpath, rr.Transform3D.columns(translation=trans, scale=scale))

        driven = np.stack([x, y], axis=1)[np.all(np.isfinite(np.stack([x, y], 1)), axis=1)]
        if len(driven) >= 2:
            self.static(ENTITY_PATHS["driven_path"], rr.LineStrips2D(
                [driven], colors=(60, 230, 120, 110), radii=rr.components.Radius.ui_points(0.75),
                draw_order=3.0))

    def _row_of_step(self, steps: np.ndarray) -> np.ndarray:
        """Row position in the trace of each given step (-1 if not a trace step)."""
        pos = np.searchsorted(self.steps, steps)
        pos = np.clip(pos, 0, max(self.T - 1, 0))
        ok = (self.T > 0) & (self.steps[pos] == steps) if self.T else np.zeros(len(steps), bool)
        return np.where(ok, pos, -1)

    def log_vehicles(self) -> None:
        nb = self.run.neighbours
        stalled_meta = list(self.meta.get("stalled") or [])
        stalled_ids = {str(s.get("id")) for s in stalled_meta}
        if len(nb) and self.T:
            rows = self._row_of_step(nb["step"].to_numpy(dtype=np.int64))
            nb = nb.assign(_row=rows)
            nb = nb[nb["_row"] >= 0]
            is_stalled = (_bool_col(nb, "stalled")
                          | nb["id"].astype(str).isin(stalled_ids).to_numpy())
        else:
            nb = nb.iloc[0:0]
            is_stalled = np.zeros(0, dtype=bool)

        groups: list[tuple[str, pd.DataFrame, tuple[int, int, int, int], float]] = [
            (ENTITY_PATHS["vehicles"], nb[~is_stalled], _C_TRAFFIC, 20.0)]
        if stalled_meta:
            s = pd.DataFrame(stalled_meta)
            boxes = _closed_boxes(_col(s, "x_m"), _col(s, "y_m"), _col(s, "heading_rad", 0.0),
                                  _col(s, "length_m", 4.5), _col(s, "width_m", 1.8))
            self.static(ENTITY_PATHS["stalled"], rr.LineStrips2D(
                boxes, colors=_C_STALLED, radii=rr.components.Radius.ui_points(2.0),
                labels=[f"{i} (stalled)" for i in s["id"].astype(str)], show_labels=True,
                draw_order=21.0))
        else:
            groups.append((ENTITY_PATHS["stalled"], nb[is_stalled], _C_STALLED, 21.0))

        for path, df, color, order in groups:
            if not len(df) or not self.T:
                continue
            df = df.sort_values(["_row", "id"], kind="stable")
            boxes = _closed_boxes(_col(df, "x_m"), _col(df, "y_m"), _col(df, "heading_rad", 0.0),
                                  _col(df, "length_m", 4.5), _col(df, "width_m", 1.8))
            ok = np.all(np.isfinite(boxes), axis=(1, 2))
            df, boxes = df[ok], boxes[ok]
            counts = np.bincount(df["_row"].to_numpy(dtype=np.int64), minlength=self.T)
            self.static(path, rr.LineStrips2D.from_fields(
                colors=[color], radii=rr.components.Radius.ui_points(1.25), draw_order=order,
                show_labels=True))
            self.strips_per_step(path, boxes, counts, labels=df["id"].astype(str).tolist())

    def _array(self, name: str) -> np.ndarray | None:
        a = self.run.arrays.get(name)
        if a is None or not self.T:
            return None
        a = np.asarray(a, dtype=np.float64)
        if a.ndim < 1 or a.shape[0] == 0:
            return None
        if a.shape[0] < self.T:  # pad missing trailing steps with NaN
            pad = np.full((self.T - a.shape[0],) + a.shape[1:], np.nan)
            a = np.concatenate([a, pad])
        return a[: self.T]

    def log_ellipses(self) -> None:
        ell = self._array("ellipses")
        if ell is None or ell.ndim != 3 or ell.shape[2] < 5:
            return
        active = np.all(np.isfinite(ell[:, :, :5]), axis=2)
        if ell.shape[2] >= 6:
            active &= np.nan_to_num(ell[:, :, 5]) > 0.5
        counts = active.sum(axis=1)
        if not counts.any():
            return
        side = np.nan_to_num(_col(self.trace, "side", 0.0)).astype(np.int64)
        flat = ell[active]
        strips = _ellipse_polylines(flat) if len(flat) else np.zeros((0, 2, 2))
        row_side = np.repeat(side, counts)
        colors = np.array([_C_SIDE.get(int(s), _C_SIDE[0]) for s in row_side],
                          dtype=np.uint8).reshape(-1, 4)
        path = ENTITY_PATHS["ellipses"]
        self.static(path, rr.LineStrips2D.from_fields(
            radii=rr.components.Radius.ui_points(1.25), draw_order=15.0))
        self.strips_per_step(path, strips, counts, colors=colors)

    def _polyline_per_step(self, name: str) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
        """Valid points of a (T, P, 2) array per step -> (strips, lengths, last point (T, 2))."""
        arr = self._array(name)
        last = np.full((self.T, 2), np.nan)
        if arr is None or arr.ndim != 3 or arr.shape[2] != 2:
            return [], np.zeros(self.T, np.int64), last
        ok = np.all(np.isfinite(arr), axis=2)
        strips: list[np.ndarray] = []
        lengths = np.zeros(self.T, np.int64)
        for i in range(self.T):
            pts = arr[i][ok[i]]
            if len(pts) >= 2:
                strips.append(pts)
                lengths[i] = 1
            if len(pts):
                last[i] = pts[-1]
        return strips, lengths, last

    def log_plan_preview(self) -> None:
        plan_strips, plan_len, _ = self._polyline_per_step("plan_xy_m")
        if plan_len.any():
            path = ENTITY_PATHS["plan"]
            self.static(path, rr.LineStrips2D.from_fields(
                colors=[_C_PLAN], radii=rr.components.Radius.ui_points(1.5), draw_order=25.0))
            self.strips_per_step(path, plan_strips, plan_len)
        prev_strips, prev_len, prev_end = self._polyline_per_step("preview_xy_m")
        if prev_len.any():
            path = ENTITY_PATHS["preview"]
            self.static(path, rr.LineStrips2D.from_fields(
                colors=[_C_PREVIEW], radii=rr.components.Radius.ui_points(1.5), draw_order=26.0))
            self.strips_per_step(path, prev_strips, prev_len)
        self._log_preview_error(prev_end)

    def _log_preview_error(self, prev_end: np.ndarray) -> None:
        """Arrow from the preview end to the plan point it should be at.

        Trace ``preview_err_t_m``/``preview_err_n_m`` (plan minus preview, along/left of
        the preview's end tangent) when recorded; otherwise the plan point at the
        preview's index when both have the same sampling (N == Np), else the nearest
        plan point to the preview end.
        """
        prev = self._array("preview_xy_m")
        plan = self._array("plan_xy_m")
        if prev is None or prev.ndim != 3:
            return
        vec = np.full((self.T, 2), np.nan)
        et, en = _col(self.trace, "preview_err_t_m"), _col(self.trace, "preview_err_n_m")
        if np.isfinite(et).any() and np.isfinite(en).any():
            for i in range(self.T):
                pts = prev[i][np.all(np.isfinite(prev[i]), axis=1)]
                if len(pts) < 2:
                    continue
                d = pts[-1] - pts[-2]
                d = d / max(float(np.hypot(*d)), 1e-9)
                nrm = np.array([-d[1], d[0]])
                vec[i] = et[i] * d + en[i] * nrm
        elif plan is not None and plan.ndim == 3:
            same = plan.shape[1] == prev.shape[1]
            for i in range(self.T):
                if not np.all(np.isfinite(prev_end[i])):
                    continue
                pts = plan[i]
                if same and np.all(np.isfinite(pts[-1])):
                    target = pts[-1]
                else:
                    good = pts[np.all(np.isfinite(pts), axis=1)]
                    if not len(good):
                        continue
                    target = good[np.argmin(np.linalg.norm(good - prev_end[i], axis=1))]
                vec[i] = target - prev_end[i]
        ok = np.all(np.isfinite(vec), axis=1) & np.all(np.isfinite(prev_end), axis=1)
        if not ok.any():
            return
        path = ENTITY_PATHS["preview_error"]
        self.static(path, rr.Arrows2D.from_fields(
            colors=[_C_ERR], radii=rr.components.Radius.ui_points(1.0), draw_order=27.0))
        self.send(path, list(rr.Arrows2D.columns(vectors=vec[ok], origins=prev_end[ok])
                             .partition(ok.astype(np.int64))))

    def log_detection(self) -> None:
        r = self.run.arrays.get("detection_radius_m")
        if r is None or not self.T:
            return
        radius = float(np.asarray(r, dtype=np.float64).reshape(-1)[0])
        if not np.isfinite(radius) or radius <= 0:
            return
        xy = np.stack([_col(self.trace, "x_m"), _col(self.trace, "y_m")], axis=1)
        ok = np.all(np.isfinite(xy), axis=1)
        path = ENTITY_PATHS["detection"]
        self.static(path, rr.Ellipses2D.from_fields(
            half_sizes=[(radius, radius)], colors=[_C_DETECT],
            line_radii=rr.components.Radius.ui_points(0.75), draw_order=5.0))
        self.send(path, list(rr.Ellipses2D.columns(centers=xy[ok]).partition(ok.astype(np.int64))))

    # -------------------------------------------------------------- scalars
    def log_scalars(self) -> None:
        tr = self.trace
        if not self.T:
            return
        s = self.scalar
        ttc = _col(tr, "ssm_ttc_s")
        s("/safety/ttc_s", ttc, "TTC [s]", (255, 90, 90, 255))
        s("/safety/min_gap_m", _col(tr, "min_gap_m"), "min gap [m]", (255, 200, 60, 255))
        coll = (_bool_col(tr, "geom_collision") | _bool_col(tr, "sumo_collision")).astype(float)
        s("/safety/collision", coll, "collision", (255, 0, 0, 255))

        along, alat = _col(tr, "long_acc_mps2"), _col(tr, "lat_acc_mps2")
        s("/comfort/accel_mps2/long", along, "long acc [m/s²]", (90, 170, 255, 255))
        s("/comfort/accel_mps2/lat", alat, "lat acc [m/s²]", (255, 150, 60, 255))
        cs = self.comfort()
        s("/comfort/jerk_mps3/long", cs["long_jerk"], "long jerk [m/s³]", (90, 170, 255, 255))
        s("/comfort/jerk_mps3/total", cs["jerk"], "|jerk| [m/s³]", (255, 150, 60, 255))
        if "yaw_rate" in cs:
            s("/comfort/yaw_rate_radps", cs["yaw_rate"], "yaw rate [rad/s]", (160, 120, 255, 255))

        s("/controller/speed_mps/actual", _col(tr, "speed_mps"), "speed [m/s]", _C_EGO)
        s("/controller/speed_mps/target", _col(tr, "target_speed_mps"), "target [m/s]",
          (200, 200, 200, 255))
        s("/controller/lat_dev_m", _col(tr, "lat_dev_m"), "lateral deviation [m]",
          (80, 170, 255, 255))
        s("/controller/heading_err_deg", np.degrees(_col(tr, "heading_err_rad")),
          "heading error [deg]", (160, 120, 255, 255))
        s("/controller/steer_deg/total", np.degrees(_col(tr, "steer_rad")), "steer total [deg]",
          (255, 255, 255, 255))
        s("/controller/steer_deg/outer", np.degrees(_col(tr, "steer_outer_rad")),
          "steer outer [deg]", (80, 170, 255, 255))
        s("/controller/steer_deg/correction", np.degrees(_col(tr, "steer_corr_rad")),
          "steer correction [deg]", (255, 150, 60, 255))
        s("/controller/torque_nm/total", _col(tr, "torque_nm"), "torque total [N m]",
          (255, 255, 255, 255))
        s("/controller/torque_nm/outer", _col(tr, "torque_outer_nm"), "torque outer [N m]",
          (80, 170, 255, 255))
        s("/controller/torque_nm/correction", _col(tr, "torque_corr_nm"),
          "torque correction [N m]", (255, 150, 60, 255))
        s("/controller/residual", _col(tr, "residual"), "residual E", (230, 80, 230, 255))
        s("/controller/preview_err_m/t", _col(tr, "preview_err_t_m"), "preview err t [m]",
          (80, 170, 255, 255))
        s("/controller/preview_err_m/n", _col(tr, "preview_err_n_m"), "preview err n [m]",
          (255, 150, 60, 255))
        s("/controller/side", _col(tr, "side"), "pass side (+1 L, -1 R, 2 follow)",
          (230, 80, 230, 255))
        s("/controller/fallback", _bool_col(tr, "fallback").astype(float), "fallback",
          (255, 60, 60, 255))
        s("/controller/n_obstacles", _col(tr, "n_obstacles"), "obstacles", (200, 200, 200, 255))
        timing = [("outer", "outer_s", (80, 170, 255, 255)),
                  ("inner", "inner_s", (255, 150, 60, 255)),
                  ("obstacles", "obstacles_s", (160, 120, 255, 255)),
                  ("controller", "controller_s", (255, 255, 255, 255)),
                  ("sumo", "sumo_s", (60, 230, 120, 255))]
        for name, col, color in timing:
            s(f"/timing/step_ms/{name}", 1e3 * _col(tr, col), f"{name} [ms]", color)

    # -------------------------------------------------------------- events
    def _event(self, row: int, level: str, text: str) -> None:
        self.events.append((int(row), level, text))

    def _rising(self, flag: np.ndarray) -> np.ndarray:
        prev = np.concatenate([[False], flag[:-1]])
        return np.flatnonzero(flag & ~prev)

    def collect_events(self) -> None:
        m, tr, T = self.meta, self.trace, self.T
        end = max(T - 1, 0)
        self._event(0, "INFO", f"start: {m.get('scenario', self.run.name)} — controller "
                    f"{m.get('controller', '?')}, seed {m.get('seed', '?')}")
        if T:
            geom = _bool_col(tr, "geom_collision")
            gap_id = (tr["gap_vehicle"].fillna("").astype(str).tolist()
                      if "gap_vehicle" in tr.columns else [""] * T)
            for i in self._rising(geom):
                who = f" with {gap_id[i]}" if gap_id[i] else ""
                self._event(i, "ERROR", f"COLLISION (geometry){who} at t={self.t[i]:.2f} s")
            sumo_list = list(m.get("sumo_collisions") or [])
            for i, c, n_rep in self._collision_episodes(sumo_list):
                ts = float(c.get("t_s", self.t[end]))
                more = f" (reported on {n_rep} steps)" if n_rep > 1 else ""
                self._event(i, "ERROR", f"COLLISION (SUMO, {c.get('type', '?')}): "
                            f"{c.get('collider', '?')} -> {c.get('victim', '?')} "
                            f"at t={ts:.2f} s{more}")
            if not sumo_list:
                for i in self._rising(_bool_col(tr, "sumo_collision")):
                    self._event(i, "ERROR", f"COLLISION (SUMO) at t={self.t[i]:.2f} s")
            fb = _bool_col(tr, "fallback")
            for i in self._rising(fb):
                run_len = int(np.argmin(np.append(fb[i:], False)))
                self._event(i, "WARN", f"fallback: safe fallback replaced the plan "
                            f"({run_len} step{'s' if run_len != 1 else ''})")
            side = np.nan_to_num(_col(tr, "side", 0.0)).astype(np.int64)
            reason = (tr["side_reason"].fillna("").astype(str).tolist()
                      if "side_reason" in tr.columns else [""] * T)
            prev = 0
            for i in range(T):
                if side[i] != prev:
                    why = f" ({reason[i]})" if reason[i] else ""
                    self._event(i, "INFO", f"side: {_SIDE_NAME.get(prev, prev)} -> "
                                f"{_SIDE_NAME.get(int(side[i]), int(side[i]))}{why}")
                    prev = int(side[i])
        for crit in m.get("failed_criteria") or []:
            row = self._first_violation(str(crit))
            where = (f"first at t={self.t[row]:.2f} s" if row is not None
                     else "aggregate, logged at the end")
            self._event(end if row is None else row, "WARN",
                        f"criterion violated: {crit} ({where})")
        status = str(m.get("status", "?"))
        text = f"status: {status.upper()}"
        if m.get("failed_criteria"):
            text += " — failed: " + ", ".join(map(str, m["failed_criteria"]))
        if m.get("error"):
            text += " — error: " + str(m["error"]).strip().splitlines()[-1]
        self._event(end, "INFO" if status == "pass" else "ERROR", text)

    def _collision_episodes(self, collisions: list[dict[str, Any]]
                            ) -> list[tuple[int, dict[str, Any], int]]:
        """SUMO reports a lasting collision every step: one (row, first report, count)
        per run of reports of the same pair on consecutive steps."""
        end = max(self.T - 1, 0)
        dt = float(self.meta.get("step_s") or 0.0) or (
            float(np.median(np.diff(self.t))) if self.T > 1 else 0.1)
        episodes: list[tuple[int, dict[str, Any], int]] = []
        last: dict[tuple[str, str, str], tuple[int, float]] = {}  # key -> (episode idx, t)
        for c in sorted(collisions, key=lambda c: float(c.get("t_s", 0.0))):
            ts = float(c.get("t_s", self.t[end] if self.T else 0.0))
            key = (str(c.get("collider")), str(c.get("victim")), str(c.get("type")))
            prev = last.get(key)
            if prev is not None and ts - prev[1] <= 1.5 * dt + 1e-9:
                row, first, count = episodes[prev[0]]
                episodes[prev[0]] = (row, first, count + 1)
                last[key] = (prev[0], ts)
                continue
            i = int(np.clip(np.searchsorted(self.t, ts - 1e-9), 0, end)) if self.T else 0
            episodes.append((i, c, 1))
            last[key] = (len(episodes) - 1, ts)
        return episodes

    _CRIT_RE = re.compile(r"^\s*([A-Za-z0-9_.\-]+)\s*=\s*([^<>]*?)\s*([<>]=?)\s*([-+0-9.eE]+|inf)")

    def _first_violation(self, crit: str) -> int | None:
        """First trace row where criterion 'name=value>limit' is violated, if derivable."""
        match = self._CRIT_RE.match(crit)
        if not match or not self.T:
            return None
        name, op, limit_s = match.group(1).lower(), match.group(3), match.group(4)
        try:
            limit = float(limit_s)
        except ValueError:
            return None
        tr = self.trace
        series: np.ndarray | None = None
        if "collision" in name:
            flag = _bool_col(tr, "geom_collision") | _bool_col(tr, "sumo_collision")
            hits = np.flatnonzero(flag)
            return int(hits[0]) if len(hits) else None
        cs = self.comfort()
        if "ttc" in name:
            series = _col(tr, "ssm_ttc_s")
        elif "gap" in name:
            series = _col(tr, "min_gap_m")
        elif "long_jerk" in name:
            series = cs["long_jerk"]
        elif "jerk" in name:
            series = cs["jerk"]
        elif "lat_acc" in name:
            series = cs["lat_acc"]
        elif "long_acc" in name or "decel" in name:
            series = cs["long_acc"]
        elif "yaw_acc" in name and "yaw_acc" in cs:
            series = cs["yaw_acc"]
        elif "yaw_rate" in name and "yaw_rate" in cs:
            series = cs["yaw_rate"]
        elif "rms" in name:
            return None  # aggregate over the run
        elif "lat_dev" in name or "deviation" in name:
            series = _col(tr, "lat_dev_m")
        elif "heading" in name:
            series = _col(tr, "heading_err_rad")
        elif "residual" in name:
            series = _col(tr, "residual")
        elif "fallback" in name:
            series = _bool_col(tr, "fallback").astype(float)
            op, limit = ">", 0.5
        elif "steer" in name:
            series = _col(tr, "steer_rad")
        elif "max_speed" in name:
            series = _col(tr, "speed_mps")
        if series is not None and "abs" in name:
            series = np.abs(series)
        if series is None:
            return None
        with np.errstate(invalid="ignore"):
            bad = series > limit if op.startswith(">") else series < limit
        bad &= np.isfinite(series)
        hits = np.flatnonzero(bad)
        return int(hits[0]) if len(hits) else None

    def log_events(self) -> None:
        if not self.events:
            return
        self.events.sort(key=lambda e: e[0])
        rows = np.array([e[0] for e in self.events], dtype=np.int64)
        if self.T:
            steps, t = self.steps[rows], self.t[rows]
        else:
            steps, t = np.zeros(len(rows), np.int64), np.zeros(len(rows))
        self.send(ENTITY_PATHS["events"],
                  rr.TextLog.columns(text=[e[2] for e in self.events],
                                     level=[e[1] for e in self.events]),
                  idx=_time_columns(steps, t))

    def write(self) -> None:
        self.log_road()
        self.log_docs()
        if self.T:
            self.log_ego()
            self.log_vehicles()
            self.log_ellipses()
            self.log_plan_preview()
            self.log_detection()
            self.log_scalars()
        elif self.meta.get("stalled"):
            self.log_vehicles()
        self.collect_events()
        self.log_events()


def _view_geometry(run: RunRecord) -> dict[str, Any]:
    """Where the bird's-eye views should look: ego start, heading sign, road bounds."""
    tr = run.trace
    start: tuple[float, float] | None = None
    heading = 0.0
    if len(tr) and "x_m" in tr.columns:
        x0, y0 = float(tr["x_m"].iloc[0]), float(tr["y_m"].iloc[0])
        if np.isfinite(x0) and np.isfinite(y0):
            start = (x0, y0)
        if "psi_rad" in tr.columns and np.isfinite(float(tr["psi_rad"].iloc[0])):
            heading = float(tr["psi_rad"].iloc[0])
    pts = [np.asarray(lane.get("shape_xy_m", []), dtype=np.float64).reshape(-1, 2)
           for lane in run.road.get("lanes", [])]
    pts = [p for p in pts if len(p)]
    bounds = None
    if pts:
        allp = np.concatenate(pts)
        bounds = (float(allp[:, 0].min()), float(allp[:, 0].max()),
                  float(allp[:, 1].min()), float(allp[:, 1].max()))
    return {"ego_start_xy": start, "ego_heading_rad": heading, "road_bounds": bounds}


def write_rrd(run_dir: Path, *, catalog_name: str | None = None,
              application_id: str = "hwyeval") -> Path:
    """Write ``run_dir/run.rrd`` for a run directory; returns its path.

    Uses its own ``rr.RecordingStream`` with a stable recording id
    (:func:`recording_id_for`) and embeds the default blueprint.
    """
    run_dir = Path(run_dir)
    run = load_run(run_dir)
    meta = run.meta
    scenario = str(meta.get("scenario", run_dir.name))
    catalog = catalog_name if catalog_name is not None else meta.get("catalog")
    rid = recording_id_for(catalog, scenario, meta.get("seed"))
    out = run_dir / RRD
    rec = rr.RecordingStream(application_id, recording_id=rid)
    try:
        rec.save(out, default_blueprint=default_blueprint(**_view_geometry(run)))
        rec.send_recording_name(f"{scenario} · seed {meta.get('seed', '?')} · "
                                f"{str(meta.get('status', '?')).upper()}")
        _Writer(rec, run).write()
        rec.flush()
    finally:
        rec.disconnect()
    return out
