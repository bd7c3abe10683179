"""Synthetic run records for tests, built, judged and written exactly as the runner does.

Each ``*_trace`` builds a typed :class:`reports.record.Trace` from a kinematic path with
analytic velocities and accelerations; :func:`make_record` assembles a
:class:`reports.record.RunRecord`, :func:`judge` evaluates it once
(:func:`reports.metrics.evaluate`) and :func:`write_run` writes the run directory with
:func:`reports.record.write_run`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from reports.metrics import evaluate
from reports.record import (
    ControllerArrays,
    EgoBox,
    LaneRecord,
    NeighbourColumns,
    RoadRecord,
    RunInfo,
    RunOutcome,
    RunRecord,
    StalledVehicle,
    SumoCollision,
    Trace,
)
from reports.record import write_run as write_record

EGO_LENGTH_M = 4.6
EGO_WIDTH_M = 1.8
LANE_WIDTH_M = 3.5
EGO = EgoBox(length_m=EGO_LENGTH_M, width_m=EGO_WIDTH_M, cg_to_front_bumper_m=2.3,
             cg_to_box_centre_m=0.0)
# the two-loop controller's split of its command (controller-specific diagnostics)
DEFAULT_EXTRA = ("steer_outer_rad", "steer_corr_rad", "torque_outer_nm", "torque_corr_nm")


# --------------------------------------------------------------------------- road


def _lane(lane_id: str, index: int, width_m: float, shape: np.ndarray, *,
          allowed: tuple[str, ...] = ("passenger", "truck"), shoulder: bool = False) -> LaneRecord:
    return LaneRecord(id=lane_id, edge_id=lane_id.split("_")[0], index=index, width_m=width_m,
                      shape_xy_m=np.asarray(shape, dtype=np.float64), allowed=allowed,
                      is_shoulder=shoulder,
                      allows_passenger=(not allowed) or "passenger" in allowed)


def straight_road(length_m: float = 2000.0, n_lanes: int = 3, width_m: float = LANE_WIDTH_M,
                  shoulder: bool = False, x0_m: float = -100.0) -> RoadRecord:
    """Straight edge along +X; lane i's centre at y = i·width (0 is the rightmost regular
    lane); a shoulder (emergency vehicles only) at y = −width if asked."""
    lanes = [_lane(f"E0_{i + int(shoulder)}", i + int(shoulder), width_m,
                   np.array([[x0_m, i * width_m], [x0_m + length_m, i * width_m]]))
             for i in range(n_lanes)]
    if shoulder:
        lanes.append(_lane("E0_0", 0, width_m,
                           np.array([[x0_m, -width_m], [x0_m + length_m, -width_m]]),
                           allowed=("emergency",), shoulder=True))
    return RoadRecord(lanes=tuple(lanes),
                      reference_xy_m=np.array([[x0_m, 0.0], [x0_m + length_m, 0.0]]),
                      reference_length_m=length_m, route=("E0",))


def with_lane(road: RoadRecord, index: int, **changes: Any) -> RoadRecord:
    """``road`` with lane ``index`` changed (e.g. ``allowed=("bus",)``)."""
    lanes = list(road.lanes)
    lanes[index] = dataclasses.replace(lanes[index], **changes)
    return dataclasses.replace(road, lanes=tuple(lanes))


def circle_road(radius_m: float = 100.0, width_m: float = LANE_WIDTH_M) -> RoadRecord:
    """One lane on a circle of ``radius_m`` centred at (0, radius) (starts at the origin
    heading +X)."""
    a = np.linspace(-0.2, 2 * np.pi + 0.2, 400)
    shape = np.stack([radius_m * np.sin(a), radius_m * (1 - np.cos(a))], axis=-1)
    return RoadRecord(lanes=(_lane("C_0", 0, width_m, shape, allowed=()),),
                      reference_xy_m=shape, reference_length_m=float(radius_m * (2 * np.pi + 0.4)),
                      route=("C",))


# --------------------------------------------------------------------------- traces


def fill_timing(trace: Trace, seed: int = 0, outer_ms: float = 3.0, inner_ms: float = 1.0,
                scale: float = 1.0) -> None:
    """Plausible per-step times [s] (lognormal around the medians), controller times × scale."""
    n = len(trace)
    rng = np.random.default_rng(seed)
    outer = outer_ms * 1e-3 * rng.lognormal(0.0, 0.25, n)
    inner = inner_ms * 1e-3 * rng.lognormal(0.0, 0.25, n)
    obstacles = 0.2e-3 * rng.lognormal(0.0, 0.2, n)
    trace.controller.outer_s = outer * scale
    trace.controller.inner_s = inner * scale
    trace.timing.obstacles_s = obstacles * scale
    trace.timing.controller_s = (outer + inner + obstacles) * scale
    trace.timing.sumo_s = 0.5e-3 * rng.lognormal(0.0, 0.2, n)


def kinematic_trace(t: np.ndarray, x: np.ndarray, y: np.ndarray, psi: np.ndarray,
                    u: np.ndarray, *, v: np.ndarray | None = None, r: np.ndarray | None = None,
                    long_acc: np.ndarray | None = None, lat_acc: np.ndarray | None = None,
                    target_speed_mps: float | np.ndarray = 20.0, s_m: np.ndarray | None = None,
                    lat_dev_m: np.ndarray | None = None, seed: int = 0,
                    extra: Mapping[str, np.ndarray] | None = None) -> Trace:
    """A full trace along a path; missing kinematics are 0 or derived (r = dψ/dt,
    lat acc = r·u, s = arc length). ``extra``: controller diagnostics beyond the
    defaults (:data:`DEFAULT_EXTRA`)."""
    n = len(t)
    zeros = np.zeros(n)
    names = tuple(dict.fromkeys((*DEFAULT_EXTRA, *(extra or {}))))
    tr = Trace.allocate(n, names)
    v = zeros if v is None else v
    r = np.gradient(np.unwrap(psi), t) if r is None and n > 1 else (zeros if r is None else r)
    tr.t_s[:] = t
    ego = tr.ego
    ego.x_m[:], ego.y_m[:], ego.psi_rad[:], ego.u_mps[:] = x, y, psi, u
    ego.v_mps[:], ego.r_radps[:], ego.speed_mps[:] = v, r, np.hypot(u, v)
    ego.long_acc_mps2[:] = zeros if long_acc is None else long_acc
    ego.lat_acc_mps2[:] = r * u if lat_acc is None else lat_acc
    ego.steer_rad[:] = np.arctan(2.8 * r / np.maximum(u, 0.1))
    ego.torque_nm[:] = 300.0
    ego.s_m[:] = (np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))])
                  if s_m is None else s_m)
    ego.lat_dev_m[:] = zeros if lat_dev_m is None else lat_dev_m
    ego.heading_err_rad[:] = 0.0
    ego.lane_index[:] = 0
    tr.decision.target_speed_mps[:] = target_speed_mps
    tr.decision.side[:] = 0
    tr.decision.side_reason[:] = "none"
    tr.decision.n_obstacles[:] = 0
    tr.safety.min_gap_m[:] = np.inf
    tr.controller.residual[:] = 1e-4 * (1 + np.abs(np.sin(t)))
    tr.controller.guard_fired[:] = 0
    tr.extra["steer_outer_rad"][:] = 0.0
    tr.extra["steer_corr_rad"][:] = 0.0
    tr.extra["torque_outer_nm"][:] = 300.0
    tr.extra["torque_corr_nm"][:] = 0.0
    for name, values in (extra or {}).items():
        tr.extra[name][:] = values
    fill_timing(tr, seed)
    return tr


def times(duration_s: float, dt_s: float) -> np.ndarray:
    """t = dt, 2 dt, …, duration (t_s is the time at the end of a step)."""
    n = int(round(duration_s / dt_s))
    return dt_s * np.arange(1, n + 1)


def straight_trace(duration_s: float = 10.0, dt_s: float = 0.05, speed_mps: float = 20.0,
                   y_m: float = 0.0, x0_m: float = 0.0, **kw: Any) -> Trace:
    """Constant speed along +X at lateral position y_m."""
    t = times(duration_s, dt_s)
    n = len(t)
    return kinematic_trace(t, x0_m + speed_mps * t, np.full(n, y_m), np.zeros(n),
                           np.full(n, speed_mps), lat_dev_m=np.full(n, y_m), **kw)


def turn_trace(radius_m: float = 100.0, speed_mps: float = 20.0, duration_s: float = 10.0,
               dt_s: float = 0.05, **kw: Any) -> Trace:
    """Constant-radius left turn: yaw rate v/R, lateral acceleration v²/R."""
    t = times(duration_s, dt_s)
    w = speed_mps / radius_m
    n = len(t)
    return kinematic_trace(t, radius_m * np.sin(w * t), radius_m * (1 - np.cos(w * t)), w * t,
                           np.full(n, speed_mps), r=np.full(n, w),
                           lat_acc=np.full(n, speed_mps * w), **kw)


def accel_ramp_trace(jerk_mps3: float = 2.0, duration_s: float = 2.0, dt_s: float = 0.02,
                     speed0_mps: float = 10.0, **kw: Any) -> Trace:
    """Straight line with a(t) = jerk·t (constant longitudinal jerk)."""
    t = times(duration_s, dt_s)
    n = len(t)
    return kinematic_trace(t, speed0_mps * t + jerk_mps3 * t ** 3 / 6, np.zeros(n), np.zeros(n),
                           speed0_mps + 0.5 * jerk_mps3 * t ** 2, long_acc=jerk_mps3 * t, **kw)


def lane_change_trace(width_m: float = LANE_WIDTH_M, speed_mps: float = 20.0,
                      duration_s: float = 12.0, change_s: float = 4.0, start_s: float = 3.0,
                      dt_s: float = 0.05, **kw: Any) -> Trace:
    """Lane change to the left (y 0 → width) with a cosine lateral profile."""
    t = times(duration_s, dt_s)
    tau = np.clip((t - start_s) / change_s, 0.0, 1.0)
    y = width_m * 0.5 * (1 - np.cos(np.pi * tau))
    vy = np.where((tau > 0) & (tau < 1), width_m * 0.5 * np.pi / change_s * np.sin(np.pi * tau), 0)
    psi = np.arctan2(vy, speed_mps)
    return kinematic_trace(t, speed_mps * t, y, psi, np.hypot(speed_mps, vy), lat_dev_m=y, **kw)


def lead_vehicle(trace: Trace, x_m: np.ndarray, y_m: float, speed_mps: float,
                 vid: str = "lead", length_m: float = 4.6, width_m: float = 1.8,
                 stalled: bool = False, heading_rad: float = 0.0) -> NeighbourColumns:
    """Neighbour rows for one vehicle at every trace step."""
    n = len(trace)
    nb = NeighbourColumns.allocate(n)
    nb.step[:], nb.t_s[:] = trace.step, trace.t_s
    nb.id[:] = vid
    nb.x_m[:], nb.y_m[:], nb.heading_rad[:] = x_m, y_m, heading_rad
    nb.speed_mps[:], nb.length_m[:], nb.width_m[:] = speed_mps, length_m, width_m
    nb.lane_index[:] = 0
    nb.stalled[:] = stalled
    return nb


def approach_run_parts(gap_end_m: float = 20.0, ego_speed_mps: float = 20.0,
                       lead_speed_mps: float = 10.0, duration_s: float = 3.0,
                       dt_s: float = 0.05, seed: int = 0) -> tuple[Trace, NeighbourColumns]:
    """Ego at ego_speed behind a slower lead in the same lane; the bumper gap shrinks to
    ``gap_end_m`` at the last step, so min TTC = gap_end / (ego − lead speed)."""
    trace = straight_trace(duration_s, dt_s, ego_speed_mps, seed=seed)
    t = trace.t_s
    gap = gap_end_m + (ego_speed_mps - lead_speed_mps) * (t[-1] - t)
    lead_x = trace.ego.x_m + EGO_LENGTH_M + gap  # centre distance = gap + half lengths
    trace.safety.min_gap_m[:] = gap
    trace.safety.gap_vehicle[:] = "lead"
    return trace, lead_vehicle(trace, lead_x, 0.0, lead_speed_mps)


def ellipse_arrays(trace: Trace, centre_xy: Sequence[float], semi_a_m: float,
                   semi_b_m: float, heading_rad: float = 0.0, vehicle_id: str = ""
                   ) -> ControllerArrays:
    """Controller arrays with one static active ellipse (of two slots) at every step,
    of vehicle ``vehicle_id`` ('' unknown)."""
    n = len(trace)
    ell = np.full((n, 2, 6), np.nan)
    ell[:, 0] = [centre_xy[0], centre_xy[1], heading_rad, semi_a_m, semi_b_m, 1.0]
    ids = np.full((n, 2), "", dtype="<U32")
    ids[:, 0] = vehicle_id
    return ControllerArrays(plan_xy_m=np.full((n, 3, 2), np.nan),
                            preview_xy_m=np.full((n, 3, 2), np.nan), ellipses=ell,
                            detection_radius_m=80.0, ellipse_ids=ids)


# --------------------------------------------------------------------------- records


def base_info(scenario: str, controller: str = "ctrl_a", **changes: Any) -> RunInfo:
    """A RunInfo with every field set (``changes`` replace fields)."""
    info = RunInfo(scenario=scenario, family="", controller=controller, catalog="synthetic",
                   catalog_name="synthetic", seed=0, net="synthetic.net.xml",
                   net_name="synthetic", duration_s=10.0, step_s=0.05, target_speed_mps=20.0,
                   allow_shoulder=False, ego=EGO)
    return dataclasses.replace(info, **changes)


def make_record(trace: Trace | None, *, info: RunInfo | None = None,
                outcome: RunOutcome | None = None, road: RoadRecord | None = None,
                neighbours: NeighbourColumns | None = None,
                arrays: ControllerArrays | None = None, name: str = "run") -> RunRecord:
    """A record (not judged); defaults: a straight road, no neighbours, a run that ended
    'ok' with sim time = the last ``t_s`` and 5 s of wall time."""
    tr = trace if trace is not None else Trace.empty()
    if outcome is None:
        outcome = RunOutcome(wall_s=5.0, sim_time_s=float(tr.t_s[-1]) if len(tr) else 0.0,
                             steps=len(tr))
    return RunRecord(info=info if info is not None else base_info(name), outcome=outcome,
                     road=road if road is not None else straight_road(), trace=tr,
                     neighbours=neighbours if neighbours is not None
                     else NeighbourColumns.allocate(0),
                     arrays=arrays if arrays is not None else ControllerArrays())


def judge(record: RunRecord, criteria_overrides: Mapping[str, Any] | None = None) -> RunRecord:
    """The record with its verdict and series, as the runner stores them."""
    return evaluate(record, criteria_overrides).apply(record)


def write_judged(record: RunRecord, run_dir: str | Path) -> Path:
    """Judge ``record`` and write it to ``run_dir``; returns the directory."""
    run_dir = Path(run_dir)
    write_record(judge(record), run_dir)
    return run_dir


def write_run(run_dir: str | Path, trace: Trace | None, **kw: Any) -> Path:
    """Build (:func:`make_record` keywords), judge and write one run directory."""
    return write_judged(make_record(trace, name=Path(run_dir).name, **kw), run_dir)


def catalog_records(controllers: Sequence[str] = ("ctrl_a", "ctrl_b"),
                    speedup: float = 1.0) -> list[tuple[str, RunRecord]]:
    """(directory name, unjudged record) of a small mixed catalog: per controller a passing
    cruise, a lane change, a stalled-car pass, a sharp turn (fails comfort for the first
    controller only), a rear-end collision (fail) and, for the second controller, an
    error run and a timeout run. Directories are ``<scenario>__<ctrl>``.

    ``speedup`` scales every controller time (to fake a timing regression)."""
    out: list[tuple[str, RunRecord]] = []
    for ci, ctrl in enumerate(controllers):
        seed = ci

        def info(scn: str, family: str, _ctrl: str = ctrl, **kw: Any) -> RunInfo:
            return base_info(scn, _ctrl, family=family, **kw)

        def ok(sim_s: float, wall_s: float, **kw: Any) -> RunOutcome:
            return RunOutcome(sim_time_s=sim_s, wall_s=wall_s, **kw)

        def timed(tr: Trace, _seed: int = seed) -> Trace:
            fill_timing(tr, _seed, scale=speedup)
            return tr

        tr = timed(straight_trace(20.0, 0.05, 20.0, seed=seed))
        out.append((f"cruise_straight__{ctrl}", make_record(
            tr, info=info("cruise_straight", "cruise"), outcome=ok(20.0, 4.0))))

        tr = timed(lane_change_trace(seed=seed))
        nb = lead_vehicle(tr, 30.0 + 25.0 * tr.t_s, LANE_WIDTH_M * 2, 25.0, vid="car1")
        out.append((f"lane_change_left__{ctrl}", make_record(
            tr, neighbours=nb, info=info("lane_change_left", "lane_change"),
            outcome=ok(12.0, 3.0))))

        tr = timed(lane_change_trace(start_s=2.0, duration_s=10.0, seed=seed))
        stalled = StalledVehicle(id="stalled0", x_m=150.0, y_m=0.0, heading_rad=0.0,
                                 length_m=4.6, width_m=1.8, lane_index=0)
        nb = lead_vehicle(tr, np.full(len(tr), 150.0), 0.0, 0.0, vid="stalled0", stalled=True)
        tr.safety.min_gap_m[:] = np.maximum(np.abs(150.0 - tr.ego.x_m) - EGO_LENGTH_M, 0.5)
        out.append((f"stalled_pass_left__{ctrl}", make_record(
            tr, neighbours=nb, arrays=ellipse_arrays(tr, (150.0, 0.3), 6.6, 2.2,
                                                 vehicle_id="stalled0"),
            info=info("stalled_pass_left", "stalled"),
            outcome=ok(10.0, 2.5, stalled=(stalled,)))))

        radius = 60.0 if ci == 0 else 200.0
        tr = timed(turn_trace(radius_m=radius, speed_mps=20.0, seed=seed))
        out.append((f"sharp_curve__{ctrl}", make_record(
            tr, road=circle_road(radius), info=info("sharp_curve", "curve"),
            outcome=ok(10.0, 2.0))))

        tr, nb = approach_run_parts(gap_end_m=0.0, duration_s=4.0, seed=seed)
        tr = timed(tr)
        k = len(tr) - 5
        tr.safety.geom_collision[k:] = True
        tr.safety.sumo_collision[k:] = True
        hit = SumoCollision(t_s=3.8, collider="ego", victim="lead", type="collision")
        out.append((f"rear_end__{ctrl}", make_record(
            tr, neighbours=nb, info=info("rear_end", "cut_in"),
            outcome=ok(4.0, 1.0, sumo_collisions=(hit,)))))
        if ci == 1:
            tb = ('Traceback (most recent call last):\n  File "runner.py", line 1\n'
                  'RuntimeError: solver diverged <&> "quoted"\n')
            tr = timed(straight_trace(1.0, 0.05, 20.0, seed=seed))
            out.append((f"crash_case__{ctrl}", make_record(
                tr, info=info("crash_case", "cruise"),
                outcome=RunOutcome(end="error", error=tb, sim_time_s=1.0, wall_s=0.5))))
            out.append((f"slow_case__{ctrl}", make_record(
                None, info=info("slow_case", "cruise"),
                outcome=RunOutcome(end="timeout", error="timed out after 600 s",
                                   sim_time_s=0.0, wall_s=600.0))))
    return out


def make_catalog(out_dir: str | Path, controllers: Sequence[str] = ("ctrl_a", "ctrl_b"),
                 speedup: float = 1.0) -> Path:
    """Judge and write :func:`catalog_records` under ``out_dir``; returns ``out_dir``."""
    out_dir = Path(out_dir)
    for name, record in catalog_records(controllers, speedup):
        write_judged(record, out_dir / name)
    return out_dir
