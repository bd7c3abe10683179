"""Plant-only closed loop (no SUMO): a controller drives :class:`SingleTrackPlant` on a path.

Used by the tests and the benchmark. Obstacles are other vehicles given in the
reference-path Frenet frame (:class:`FrenetVehicle` or tuples (s, y, length, width),
e.g. stalled cars), either a static list or a function of time; every step they
are turned into the controller's ellipses with its ``obstacle_policy``
(``controllers.behaviour.ellipses``), exactly as the SUMO runner does from SUMO data.

Returned traces (dict of arrays, one row per control step, SI units): t_s, state
(K, 6), s_m, y_m (Frenet CG), steer_rad, torque_nm, lat_acc_mps2, long_acc_mps2,
yaw_rate_radps, speed_mps, lateral_reference_m (the raw reference given), the
controller's diagnostics (one array per key), plans
(K, N+1, 3 Frenet states) and plan_tau_s (K, N+1) when the controller exposes
``plan``, box_overlap (K,) bool (ego box vs any obstacle box, separating axes),
ellipse_c (K, n_obstacles) ellipse value of the ego CG for every vehicle with the
policy's semi-axes *without* margins (c < 0: CG inside the vehicles' Minkowski-sum
ellipse), ellipse_c_margin (the same with the policy's margins, no offset).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from controllers.behaviour.ellipses import FrenetVehicle, build_obstacles, ellipse_semi_axes
from controllers.path.frenet import FrenetPath
from controllers.plant.vehicle_model import SingleTrackPlant, VehicleParams
from controllers.protocol import Controller, Observation, ObstaclePolicy, ScenarioContext

VehiclesFn = Callable[[float], Sequence[FrenetVehicle]]
# (t_s, s_m, y_m) of the ego CG -> (pass_side, lateral_reference_m), as the runner decides.
LateralFn = Callable[[float, float, float], tuple[int, float]]
VehicleLike = FrenetVehicle | tuple[float, ...]
# lateral_fn's pass side for "follow" (suite.obstacles.SIDE_FOLLOW): no free side.
FOLLOW_SIDE = 2


def _as_vehicle(v: VehicleLike) -> FrenetVehicle:
    """FrenetVehicle or a tuple (s, y, length, width[, speed_s, speed_y])."""
    return v if isinstance(v, FrenetVehicle) else FrenetVehicle(*(float(x) for x in v))


def _box(cx: float, cy: float, heading: float, length: float, width: float) -> np.ndarray:
    c, s = math.cos(heading), math.sin(heading)
    hl, hw = 0.5 * length, 0.5 * width
    pts = np.array([[hl, hw], [hl, -hw], [-hl, -hw], [-hl, hw]])
    return np.column_stack([cx + pts[:, 0] * c - pts[:, 1] * s, cy + pts[:, 0] * s + pts[:, 1] * c])


def boxes_overlap(a: np.ndarray, b: np.ndarray) -> bool:
    """Separating-axis test for two convex quadrilaterals (4, 2)."""
    for poly in (a, b):
        for i in range(4):
            e = poly[(i + 1) % 4] - poly[i]
            axis = np.array([-e[1], e[0]])
            pa = a @ axis
            pb = b @ axis
            if pa.max() < pb.min() or pb.max() < pa.min():
                return False
    return True


def pass_reference(obstacle_s_m: float, pass_side: int = 1, lane_offset_m: float = 3.5,
                   detect_m: float = 80.0, release_past_m: float = 15.0) -> LateralFn:
    """A ``lateral_fn`` emulating the runner for one stalled car in the ego lane.

    (pass_side, pass_side * lane_offset_m) from the moment the ego CG is within
    ``detect_m`` before the car until it is ``release_past_m`` past it, (pass_side, 0)
    afterwards (latched: the reference steps out once and back once).
    """
    state = {"released": False}

    def fn(t_s: float, s_m: float, y_m: float) -> tuple[int, float]:
        if state["released"] or s_m > obstacle_s_m + release_past_m:
            state["released"] = True
            return pass_side, 0.0
        if obstacle_s_m - s_m <= detect_m:
            return pass_side, pass_side * lane_offset_m
        return pass_side, 0.0

    return fn


def simulate(controller: Controller, path_xy: np.ndarray,
             vehicles: Sequence[VehicleLike] | VehiclesFn = (), duration_s: float = 10.0,
             dt: float = 0.02, initial_speed_mps: float = 25.0, target_speed_mps: float = 25.0,
             pass_side: int = 1, initial_s_m: float = 0.0, initial_y_m: float = 0.0,
             target_speed_fn: Callable[[float, float], float] | None = None,
             vehicle: VehicleParams | None = None, lane_width_m: float = 3.5,
             lateral_fn: LateralFn | None = None,
             ) -> dict[str, Any]:
    """Run ``controller`` for ``duration_s``; see module docstring for the traces.

    ``lateral_fn(t, s_cg, y_cg) -> (pass_side, lateral_reference_m)`` emulates the
    runner's lane context every step (it overrides ``pass_side``); without it the
    lateral reference is 0. The raw reference is traced as ``lateral_reference_m``.
    pass_side ``FOLLOW_SIDE`` (2) emulates the runner's follow mode: no offset, the
    ellipses in the ego lane ahead widened by 1.5 lane widths, Observation.pass_side 0.
    """
    vp = vehicle or VehicleParams()
    path = FrenetPath.cached(path_xy)
    x0, y0 = path.to_global(initial_s_m, initial_y_m)
    psi0 = float(path.gamma(initial_s_m))
    state0 = np.array([float(x0), float(y0), psi0, initial_speed_mps, 0.0, 0.0])
    ctx = ScenarioContext(reference_xy_m=np.asarray(path_xy, dtype=np.float64),
                          lane_width_m=lane_width_m, target_speed_mps=target_speed_mps,
                          control_period_s=dt, vehicle=vp, initial_state=state0)
    controller.reset(ctx)
    plant = SingleTrackPlant(vp, state0)
    policy: ObstaclePolicy = getattr(controller, "obstacle_policy", ObstaclePolicy())
    n_steps = int(round(duration_s / dt))
    rec: dict[str, list[Any]] = {k: [] for k in (
        "t_s", "state", "s_m", "y_m", "steer_rad", "torque_nm", "lat_acc_mps2",
        "long_acc_mps2", "yaw_rate_radps", "speed_mps", "box_overlap", "ellipse_c",
        "ellipse_c_margin", "plans", "plan_tau_s", "lateral_reference_m")}
    diags: dict[str, list[float]] = {}
    s_hint = initial_s_m
    no_margin = ObstaclePolicy(margin_long_m=0.0, margin_lat_m=0.0)
    for k in range(n_steps):
        t = k * dt
        st = plant.state
        s_arr, y_arr = path.project(st[0], st[1], s_hint)
        s_cg, y_cg = float(s_arr), float(y_arr)
        s_hint = s_cg
        vehs = [_as_vehicle(v) for v in (vehicles(t) if callable(vehicles) else vehicles)]
        side, y_ref = pass_side, 0.0
        if lateral_fn is not None:
            side, y_ref = lateral_fn(t, s_cg, y_cg)
        follow = side == FOLLOW_SIDE
        obstacles = build_obstacles(s_cg, y_cg, vehs, policy, vp, 0 if follow else side)
        if follow and obstacles.count:
            # The runner's follow mode (suite.obstacles): the blocking ellipse in the ego
            # lane ahead is widened across the lane so that no way round exists.
            blocking = (np.abs(obstacles.y_m) < 0.5 * lane_width_m) & (obstacles.s_m > s_cg)
            obstacles.semi_b_m[blocking] += 1.5 * lane_width_m
            side = 0
        vt = target_speed_fn(t, s_cg) if target_speed_fn is not None else target_speed_mps
        obs = Observation(t_s=t, state=st.copy(), target_speed_mps=vt, obstacles=obstacles,
                          pass_side=side if obstacles.count else 0,
                          lateral_reference_m=float(y_ref))
        cmd = controller.step(obs)
        if not (math.isfinite(cmd.steer_rad) and math.isfinite(cmd.torque_nm)):
            raise AssertionError(f"non-finite command at t={t}")
        # Safety bookkeeping at this state.
        ego_c = vp.cg_to_box_centre_m
        ego_box = _box(st[0] + ego_c * math.cos(st[2]), st[1] + ego_c * math.sin(st[2]), st[2],
                       vp.length_m, vp.width_m)
        overlap = False
        cs, cm = [], []
        for veh in vehs:
            ox, oy = path.to_global(veh.s_m, veh.y_m)
            ob = _box(float(ox), float(oy), float(path.gamma(veh.s_m)), veh.length_m,
                      veh.width_m)
            overlap = overlap or boxes_overlap(ego_box, ob)
            a0, b0 = ellipse_semi_axes(veh.length_m, veh.width_m, vp.length_m, vp.width_m,
                                       no_margin)
            a1, b1 = ellipse_semi_axes(veh.length_m, veh.width_m, vp.length_m, vp.width_m,
                                       policy)
            cs.append((s_cg - veh.s_m) ** 2 / a0**2 + (y_cg - veh.y_m) ** 2 / b0**2 - 1.0)
            cm.append((s_cg - veh.s_m) ** 2 / a1**2 + (y_cg - veh.y_m) ** 2 / b1**2 - 1.0)
        plant.step(cmd.steer_rad, cmd.torque_nm, dt)
        rec["t_s"].append(t)
        rec["state"].append(st.copy())
        rec["s_m"].append(s_cg)
        rec["y_m"].append(y_cg)
        rec["steer_rad"].append(plant.saturate(cmd.steer_rad, cmd.torque_nm)[0])
        rec["torque_nm"].append(plant.saturate(cmd.steer_rad, cmd.torque_nm)[1])
        rec["lat_acc_mps2"].append(plant.lat_acc_mps2)
        rec["long_acc_mps2"].append(plant.long_acc_mps2)
        rec["yaw_rate_radps"].append(float(plant.state[5]))
        rec["speed_mps"].append(float(math.hypot(st[3], st[4])))
        rec["box_overlap"].append(overlap)
        rec["lateral_reference_m"].append(float(y_ref))
        rec["ellipse_c"].append(cs)
        rec["ellipse_c_margin"].append(cm)
        plan = getattr(controller, "plan", None)
        if plan is not None:
            rec["plans"].append(np.asarray(plan.states, dtype=np.float64).copy())
            rec["plan_tau_s"].append(np.asarray(plan.stage_times_s, dtype=np.float64).copy())
        for f in dataclasses.fields(cmd.diagnostics):
            diags.setdefault(f.name, []).append(float(getattr(cmd.diagnostics, f.name)))
    out: dict[str, Any] = {}
    for key, vals in rec.items():
        if key in ("ellipse_c", "ellipse_c_margin"):
            width = max((len(v) for v in vals), default=0)
            arr = np.full((len(vals), width), np.inf)
            for i, v in enumerate(vals):
                arr[i, :len(v)] = v
            out[key] = arr
        elif key in ("plans", "plan_tau_s") and not vals:
            out[key] = np.zeros((0,))
        else:
            out[key] = np.asarray(vals)
    for key, vals in diags.items():
        out[key] = np.asarray(vals)
    out["path"] = path
    return out


def plan_tracking_error(trace: dict[str, Any], tau_s: float = 0.5) -> np.ndarray:
    """Lateral (Frenet y) error between each plan's point at tau_s and where the car was then.

    For step k: y_actual(t_k + tau) - y_plan_k(tau), with both interpolated linearly.
    Steps whose t_k + tau is past the end, or whose plan horizon is shorter than
    tau, are NaN. This is the paper's Fig. 12 "lateral tracking error".
    """
    t = trace["t_s"]
    y = trace["y_m"]
    plans = trace["plans"]
    taus = trace["plan_tau_s"]
    out = np.full(t.shape[0], np.nan)
    for k in range(t.shape[0]):
        if taus[k][-1] < tau_s or t[k] + tau_s > t[-1]:
            continue
        y_plan = float(np.interp(tau_s, taus[k], plans[k][:, 1]))
        out[k] = float(np.interp(t[k] + tau_s, t, y)) - y_plan
    return out


def steering_chatter(steer_rad: np.ndarray, dt_s: float, mask: np.ndarray | None = None) -> float:
    """High-frequency steering measure: RMS of the second difference of delta over dt² [rad/s²].

    For a smooth steering signal delta(t) this is the RMS of delta''; a command that
    flips from step to step (the paper's J1 chatter, Fig. 10) makes it large because
    the second difference of a period-2 oscillation of amplitude a is 4a/dt².
    ``mask`` (bool, same length) restricts it to a window, e.g. obstacle in view.
    """
    d2 = np.diff(np.asarray(steer_rad, dtype=np.float64), 2) / dt_s**2
    if mask is not None:
        d2 = d2[np.asarray(mask)[1:-1]]
    return float(np.sqrt(np.mean(d2**2))) if d2.size else 0.0
