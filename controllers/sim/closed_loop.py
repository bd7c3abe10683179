"""Plant-only closed loop (no SUMO): a controller drives :class:`SingleTrackPlant` on a path.

Used by the tests and the benchmark. Other vehicles are given in the reference-path
Frenet frame (:class:`FrenetVehicle` or tuples (s, y, length, width[, v_s, v_y])), as a
static list or a function of time; every step they become world-frame
:class:`~controllers.behaviour.types.Traffic` and go through a
:class:`~controllers.behaviour.protocol.Behaviour`, exactly as in a SUMO run:

* with ``lanes`` (a :class:`LaneContext`, or a function of time giving one) the
  behaviour is SUMO's, :class:`~controllers.behaviour.decision.LaneBehaviour`: it picks
  the pass side from the lanes, sets the lateral reference and the follow speed;
* without, :class:`ScriptedBehaviour` takes the pass side and lateral reference from
  ``pass_side`` / ``lateral_fn`` (a controller unit test that forces a decision), with
  the same ellipse geometry.

Returned traces (dict of arrays, one row per control step, SI units): t_s, state
(K, 6), s_m, y_m (Frenet CG), steer_rad, torque_nm, lat_acc_mps2, long_acc_mps2,
yaw_rate_radps, speed_mps, lateral_reference_m (the raw reference given), side and
target_speed_mps (the decision), the controller's diagnostics (one array per field of
its diagnostics dataclass), plans (K, N+1, 3 Frenet states) and plan_tau_s (K, N+1)
when the controller exposes ``plan``, box_overlap (K,) bool (ego box vs any vehicle box,
separating axes), ellipse_c (K, n_vehicles) ellipse value of the ego CG for every
vehicle with the policy's semi-axes *without* margins (c < 0: CG inside the vehicles'
Minkowski-sum ellipse), ellipse_c_margin (the same with the policy's margins).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from controllers.behaviour.decision import EgoShape, LaneBehaviour
from controllers.behaviour.ellipses import FrenetVehicle, build_obstacles, ellipse_semi_axes
from controllers.behaviour.perception import project_traffic
from controllers.behaviour.protocol import Behaviour
from controllers.behaviour.types import (
    SIDE_FOLLOW,
    Decision,
    EgoFrenet,
    LaneContext,
    ObstaclePolicy,
    Side,
    Traffic,
)
from controllers.path.frenet import FrenetPath
from controllers.plant.vehicle_model import SingleTrackPlant, VehicleParams
from controllers.protocol import Controller, Observation, ScenarioContext

VehiclesFn = Callable[[float], Sequence[FrenetVehicle]]
# (t_s, s_m, y_m) of the ego CG -> (pass_side, lateral_reference_m): a scripted decision.
LateralFn = Callable[[float, float, float], tuple[int, float]]
VehicleLike = FrenetVehicle | tuple[float, ...]
# lateral_fn's pass side for "follow" (no side free), as the behaviour layer says it.
FOLLOW_SIDE = SIDE_FOLLOW


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


@dataclass
class ScriptedBehaviour:
    """A decision forced by the test (see the module docstring): pass side and lateral
    reference from ``lateral_fn(t, s_cg, y_cg)`` (else ``pass_side`` and 0), the speed
    set-point as given, ellipses for the vehicles within the detection distance.
    ``pass_side`` FOLLOW_SIDE emulates the follow mode: no offset, the ellipses in the
    ego lane ahead widened by 1.5 lane widths, Observation.pass_side 0.
    ``frenet_vehicles``, when set, are used instead of projecting the traffic."""

    path: FrenetPath
    policy: ObstaclePolicy
    vehicle: VehicleParams
    pass_side: int = 1
    lateral_fn: LateralFn | None = None
    lane_width_m: float = 3.5
    t_s: float = 0.0
    frenet_vehicles: Sequence[FrenetVehicle] | None = None

    def decide(self, ego: EgoFrenet, traffic: Traffic, lanes: LaneContext,
               set_speed_mps: float) -> Decision:
        del lanes
        side, y_ref = self.pass_side, 0.0
        if self.lateral_fn is not None:
            side, y_ref = self.lateral_fn(self.t_s, ego.s_m, ego.lat_m)
        vehicles = self.frenet_vehicles
        if vehicles is None:  # only world-frame traffic: project it
            fn = project_traffic(self.path, traffic, ego)
            vehicles = [FrenetVehicle(float(fn.s_m[i]), float(fn.y_m[i]),
                                      float(fn.length_m[i]), float(fn.width_m[i]),
                                      float(fn.v_s_mps[i]), float(fn.v_y_mps[i]))
                        for i in range(traffic.count)]
        follow = side == FOLLOW_SIDE
        obstacles = build_obstacles(ego.s_m, ego.lat_m, vehicles, self.policy, self.vehicle,
                                    0 if follow else side)
        if follow:
            blocking = (np.abs(obstacles.y_m) < 0.5 * self.lane_width_m) & (obstacles.s_m > ego.s_m)
            obstacles.semi_b_m[blocking] += 1.5 * self.lane_width_m
        pass_side = 0 if follow or not obstacles.count else side
        return Decision(obstacles=obstacles, side=SIDE_FOLLOW if follow else Side(pass_side),
                        target_speed_mps=set_speed_mps, lateral_reference_m=float(y_ref))


def traffic_from_frenet(path: FrenetPath, vehicles: Sequence[FrenetVehicle]) -> Traffic:
    """World-frame boxes of Frenet vehicles: centre at (s, y), heading along the path
    tangent turned by the velocity's angle, speed |(v_s, v_y)|; stalled when still."""
    if not vehicles:
        return Traffic.empty()
    s = np.array([v.s_m for v in vehicles])
    y = np.array([v.y_m for v in vehicles])
    vs = np.array([v.speed_s_mps for v in vehicles])
    vy = np.array([v.speed_y_mps for v in vehicles])
    x_w, y_w = path.to_global(s, y)
    speed = np.hypot(vs, vy)
    heading = np.asarray(path.gamma(s)) + np.where(speed > 1e-9, np.arctan2(vy, vs), 0.0)
    n = len(vehicles)
    return Traffic(ids=tuple(f"v{i}" for i in range(n)), x_m=np.asarray(x_w, dtype=np.float64),
                   y_m=np.asarray(y_w, dtype=np.float64), heading_rad=heading, speed_mps=speed,
                   length_m=np.array([v.length_m for v in vehicles]),
                   width_m=np.array([v.width_m for v in vehicles]),
                   lane_index=np.full(n, -1, dtype=np.int64), road_id=("",) * n,
                   stalled=speed < 0.5)


def _vehicle_boxes(path: FrenetPath, vehicles: Sequence[FrenetVehicle]) -> list[np.ndarray]:
    out = []
    for veh in vehicles:
        ox, oy = path.to_global(veh.s_m, veh.y_m)
        out.append(_box(float(ox), float(oy), float(path.gamma(veh.s_m)), veh.length_m,
                        veh.width_m))
    return out


def _ellipse_values(s_cg: float, y_cg: float, vehicles: Sequence[FrenetVehicle],
                    vp: VehicleParams, policy: ObstaclePolicy) -> tuple[list[float], list[float]]:
    """Ellipse value of the CG for each vehicle, without and with the policy's margins."""
    no_margin = ObstaclePolicy(margin_long_m=0.0, margin_lat_m=0.0)
    cs, cm = [], []
    for veh in vehicles:
        a0, b0 = ellipse_semi_axes(veh.length_m, veh.width_m, vp.length_m, vp.width_m, no_margin)
        a1, b1 = ellipse_semi_axes(veh.length_m, veh.width_m, vp.length_m, vp.width_m, policy)
        cs.append((s_cg - veh.s_m) ** 2 / a0**2 + (y_cg - veh.y_m) ** 2 / b0**2 - 1.0)
        cm.append((s_cg - veh.s_m) ** 2 / a1**2 + (y_cg - veh.y_m) ** 2 / b1**2 - 1.0)
    return cs, cm


_REC_KEYS = ("t_s", "state", "s_m", "y_m", "steer_rad", "torque_nm", "lat_acc_mps2",
             "long_acc_mps2", "yaw_rate_radps", "speed_mps", "box_overlap", "ellipse_c",
             "ellipse_c_margin", "plans", "plan_tau_s", "lateral_reference_m", "side",
             "target_speed_mps")


def simulate(controller: Controller, path_xy: np.ndarray,
             vehicles: Sequence[VehicleLike] | VehiclesFn = (), duration_s: float = 10.0,
             dt: float = 0.02, initial_speed_mps: float = 25.0, target_speed_mps: float = 25.0,
             pass_side: int = 1, initial_s_m: float = 0.0, initial_y_m: float = 0.0,
             target_speed_fn: Callable[[float, float], float] | None = None,
             vehicle: VehicleParams | None = None, lane_width_m: float = 3.5,
             lateral_fn: LateralFn | None = None,
             lanes: LaneContext | Callable[[float], LaneContext] | None = None,
             allow_shoulder: bool = False) -> dict[str, Any]:
    """Run ``controller`` for ``duration_s``; see the module docstring for the traces.

    ``target_speed_fn(t, s_cg)`` replaces the set speed; with ``lanes`` the behaviour may
    lower it further (follow).
    """
    vp = vehicle or VehicleParams()
    path = FrenetPath.cached(path_xy)
    x0, y0 = path.to_global(initial_s_m, initial_y_m)
    state0 = np.array([float(x0), float(y0), float(path.gamma(initial_s_m)), initial_speed_mps,
                       0.0, 0.0])
    controller.reset(ScenarioContext(reference_xy_m=np.asarray(path_xy, dtype=np.float64),
                                     lane_width_m=lane_width_m, target_speed_mps=target_speed_mps,
                                     control_period_s=dt, vehicle=vp, initial_state=state0))
    plant = SingleTrackPlant(vp, state0)
    policy = controller.obstacle_policy or ObstaclePolicy()
    behaviour: Behaviour
    scripted: ScriptedBehaviour | None = None
    if lanes is None:
        scripted = ScriptedBehaviour(path, policy, vp, pass_side, lateral_fn, lane_width_m)
        behaviour = scripted
    else:
        behaviour = LaneBehaviour(path, policy, EgoShape(vp.length_m, vp.width_m, allow_shoulder),
                                  lane_width_m)
    rec: dict[str, list[Any]] = {k: [] for k in _REC_KEYS}
    diags: dict[str, list[float]] = {}
    s_hint = initial_s_m
    for k in range(int(round(duration_s / dt))):
        t = k * dt
        st = plant.state
        s_arr, y_arr = path.project(st[0], st[1], s_hint)
        s_cg, y_cg = float(s_arr), float(y_arr)
        s_hint = s_cg
        vehs = [_as_vehicle(v) for v in (vehicles(t) if callable(vehicles) else vehicles)]
        vt = target_speed_fn(t, s_cg) if target_speed_fn is not None else target_speed_mps
        if scripted is not None:
            # The test's vehicles are given in the Frenet frame: use them as given (a
            # round trip through the world frame would perturb them by ~1e-8 m).
            scripted.t_s, scripted.frenet_vehicles = t, vehs
        lane_ctx = (lanes(t) if callable(lanes) else lanes) if lanes is not None \
            else LaneContext({}, 0)
        ego = EgoFrenet(float(st[0]), float(st[1]), s_cg, y_cg, math.hypot(st[3], st[4]), t)
        decision = behaviour.decide(ego, traffic_from_frenet(path, vehs), lane_ctx, vt)
        cmd = controller.step(Observation(
            t_s=t, state=st.copy(), target_speed_mps=decision.target_speed_mps,
            obstacles=decision.obstacles, pass_side=decision.pass_side,
            lateral_reference_m=decision.lateral_reference_m, evasive=decision.evasive,
            side=decision.side))
        if not (math.isfinite(cmd.steer_rad) and math.isfinite(cmd.torque_nm)):
            raise ValueError(f"non-finite command at t={t}")
        ego_c = vp.cg_to_box_centre_m
        ego_box = _box(st[0] + ego_c * math.cos(st[2]), st[1] + ego_c * math.sin(st[2]), st[2],
                       vp.length_m, vp.width_m)
        overlap = any(boxes_overlap(ego_box, ob) for ob in _vehicle_boxes(path, vehs))
        cs, cm = _ellipse_values(s_cg, y_cg, vehs, vp, policy)
        steer, torque = plant.saturate(cmd.steer_rad, cmd.torque_nm)
        plant.step(cmd.steer_rad, cmd.torque_nm, dt)
        for key, value in (("t_s", t), ("state", st.copy()), ("s_m", s_cg), ("y_m", y_cg),
                           ("steer_rad", steer), ("torque_nm", torque),
                           ("lat_acc_mps2", plant.lat_acc_mps2),
                           ("long_acc_mps2", plant.long_acc_mps2),
                           ("yaw_rate_radps", float(plant.state[5])),
                           ("speed_mps", float(math.hypot(st[3], st[4]))),
                           ("box_overlap", overlap),
                           ("lateral_reference_m", decision.lateral_reference_m),
                           ("side", decision.side),
                           ("target_speed_mps", decision.target_speed_mps),
                           ("ellipse_c", cs), ("ellipse_c_margin", cm)):
            rec[key].append(value)
        plan = getattr(controller, "plan", None)
        if plan is not None:
            rec["plans"].append(np.asarray(plan.states, dtype=np.float64).copy())
            rec["plan_tau_s"].append(np.asarray(plan.stage_times_s, dtype=np.float64).copy())
        for f in dataclasses.fields(cmd.diagnostics):
            diags.setdefault(f.name, []).append(float(getattr(cmd.diagnostics, f.name)))
    return _collect(rec, diags, path)


def _collect(rec: dict[str, list[Any]], diags: dict[str, list[float]],
             path: FrenetPath) -> dict[str, Any]:
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
    for key, dvals in diags.items():
        out[key] = np.asarray(dvals)
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
