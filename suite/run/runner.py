"""Run one scenario: SUMO world + controller + plant, recorded into a run directory.

The control loop, one iteration per SUMO step of ``step_s``:

    neighbours (SUMO, after the last step) -> obstacles + side (suite/obstacles)
      -> controller.step(observation) -> plant (STVM, RK4) -> moveToXY -> SUMO step
      -> gap / collision checks on oriented boxes -> trace row

The plant is the ego's truth; SUMO mirrors its pose. For the ``sumo``
controller SUMO drives the ego and the runner reads it back instead.
A run stops at ``duration_s``, 0.5 s after the first collision, or when the ego
is within 30 m of the route's end. ``run_scenario`` never raises: a crash is
recorded as status ``error`` with its traceback, an exceeded wall-clock budget
as ``timeout``, and what was recorded until then is kept.
"""

from __future__ import annotations

import json
import math
import resource
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from controllers import registry
from controllers.path.frenet import FrenetPath
from controllers.plant.vehicle_model import SingleTrackPlant, VehicleParams
from controllers.protocol import Controller, Observation, ScenarioContext
from reports import run_record as rr
from reports.metrics.geometry import box_corners, box_distance, boxes_overlap, ego_box_centre
from suite.obstacles import (
    SIDE_NONE,
    LaneSlot,
    ObstacleBuilder,
    ellipses_in_world,
    to_frenet,
)
from suite.road.network import RoadNetwork
from suite.world.sumo import EGO_ID, Neighbours, SumoWorld, parse_ssm

_COLLISION_GRACE_S = 0.5
_END_OF_ROUTE_MARGIN_M = 30.0


class ScenarioTimeout(Exception):
    pass


@dataclass
class RunOptions:
    """How to run: Rerun logging on/off, catalog name for the recording id, wall budget."""

    write_rrd: bool = True
    catalog_name: str = ""
    timeout_s: float | None = None


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    if hasattr(obj, "items"):
        return dict(obj.items())
    raise TypeError(f"not JSON-serialisable: {type(obj)}")


def write_json(path: Path, data: dict[str, Any]) -> None:
    """Write atomically so a reader never sees half a file."""
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(data, indent=1, default=_json_default, allow_nan=True))
    tmp.replace(path)


class _Recorder:
    """Accumulates per-step rows and arrays; written once at the end."""

    def __init__(self) -> None:
        self.rows: list[dict[str, Any]] = []
        self.nb: dict[str, list[Any]] = {k: [] for k in rr.NEIGHBOUR_COLUMNS}
        self.plan: list[np.ndarray | None] = []
        self.preview: list[np.ndarray | None] = []
        self.ellipses: list[np.ndarray] = []

    def add_neighbours(self, step: int, t_s: float, nb: Neighbours, keep: np.ndarray) -> None:
        """Log the neighbours where ``keep`` (within the recording radius)."""
        if not np.any(keep):
            return
        idx = np.flatnonzero(keep)
        nb = Neighbours([nb.ids[i] for i in idx], nb.x_m[idx], nb.y_m[idx], nb.heading_rad[idx],
                        nb.speed_mps[idx], nb.length_m[idx], nb.width_m[idx],
                        nb.lane_index[idx], [nb.edge_id[i] for i in idx], nb.stalled[idx])
        n = nb.count
        self.nb["step"].extend([step] * n)
        self.nb["t_s"].extend([t_s] * n)
        self.nb["id"].extend(nb.ids)
        self.nb["x_m"].extend(nb.x_m.tolist())
        self.nb["y_m"].extend(nb.y_m.tolist())
        self.nb["heading_rad"].extend(nb.heading_rad.tolist())
        self.nb["speed_mps"].extend(nb.speed_mps.tolist())
        self.nb["length_m"].extend(nb.length_m.tolist())
        self.nb["width_m"].extend(nb.width_m.tolist())
        self.nb["lane_index"].extend(nb.lane_index.tolist())
        self.nb["stalled"].extend(nb.stalled.tolist())

    @staticmethod
    def _stack(items: list[np.ndarray | None], tail: tuple[int, ...]) -> np.ndarray:
        sizes = [a.shape[0] for a in items if a is not None]
        width = max(sizes) if sizes else 0
        out = np.full((len(items), width, *tail), np.nan)
        for i, a in enumerate(items):
            if a is not None and a.size:
                out[i, : a.shape[0]] = a
        return out

    def write(self, run_dir: Path, detection_radius_m: float) -> None:
        trace = pd.DataFrame(self.rows, columns=list(rr.TRACE_COLUMNS))
        trace.to_parquet(run_dir / rr.TRACE, index=False)
        pd.DataFrame(self.nb, columns=list(rr.NEIGHBOUR_COLUMNS)).to_parquet(
            run_dir / rr.NEIGHBOURS, index=False)
        np.savez_compressed(
            run_dir / rr.CONTROLLER_ARRAYS,
            plan_xy_m=self._stack(self.plan, (2,)),
            preview_xy_m=self._stack(self.preview, (2,)),
            ellipses=self._stack(list(self.ellipses), (6,)),
            detection_radius_m=np.array(detection_radius_m),
        )


def _lane_slots(network: RoadNetwork, route: tuple[str, ...]) -> dict[str, dict[int, LaneSlot]]:
    slots: dict[str, dict[int, LaneSlot]] = {}
    for li in network.lane_info(route):
        slots.setdefault(li.edge_id, {})[li.index] = LaneSlot(
            li.index, li.width_m, li.allows_passenger, li.is_shoulder)
    return slots


def _initial_state(path: FrenetPath, front_pos_m: float, speed_mps: float,
                   vehicle: VehicleParams) -> np.ndarray:
    s_cg = max(front_pos_m - vehicle.cg_to_front_bumper_m, 0.0)
    x, y = path.point(s_cg)
    psi = float(path.gamma(s_cg))
    return np.array([float(x), float(y), psi, speed_mps, 0.0, 0.0])


def _ego_box(state: np.ndarray, vehicle: VehicleParams) -> np.ndarray:
    cx, cy = ego_box_centre(state[0], state[1], state[2], vehicle.cg_to_box_centre_m)
    return box_corners(cx, cy, state[2], vehicle.length_m, vehicle.width_m)


def _gap_and_collision(ego_box: np.ndarray, nb: Neighbours) -> tuple[float, str, bool]:
    if nb.count == 0:
        return math.inf, "", False
    boxes = box_corners(nb.x_m, nb.y_m, nb.heading_rad, nb.length_m, nb.width_m)
    dist = box_distance(ego_box[None], boxes)
    i = int(np.argmin(dist))
    overlap = bool(np.any(boxes_overlap(ego_box[None], boxes)))
    return float(dist[i]), nb.ids[i], overlap


def run_scenario(scenario: Any, out_dir: Path, options: RunOptions | None = None) -> dict[str, Any]:
    """Run one scenario into ``out_dir/<name>/`` and return its ``run.json`` dict."""
    options = options or RunOptions()
    run_dir = Path(out_dir) / scenario.name
    run_dir.mkdir(parents=True, exist_ok=True)
    for stale in (rr.TRACE, rr.NEIGHBOURS, rr.CONTROLLER_ARRAYS, rr.TRACEBACK, rr.RRD):
        (run_dir / stale).unlink(missing_ok=True)
    vehicle = VehicleParams()
    meta: dict[str, Any] = {
        "scenario": scenario.name,
        "family": scenario.family,
        "controller": scenario.controller.name,
        "controller_options": dict(scenario.controller.options),
        "catalog": str(scenario.catalog_path),
        "catalog_name": options.catalog_name,
        "seed": int(scenario.seed),
        "net": str(scenario.net_path),
        "net_name": scenario.net,
        "duration_s": float(scenario.duration_s),
        "step_s": float(scenario.step_s),
        "target_speed_mps": float(scenario.ego.target_speed_mps),
        "allow_shoulder": bool(scenario.allow_shoulder),
        "criteria": dict(scenario.criteria),
        "scenario_spec": scenario.as_dict(),
        "ego": {"length_m": vehicle.length_m, "width_m": vehicle.width_m,
                "cg_to_front_bumper_m": vehicle.cg_to_front_bumper_m,
                "cg_to_box_centre_m": vehicle.cg_to_box_centre_m},
        "status": "error", "error": None, "stalled": [], "sumo_collisions": [], "ssm": {},
    }
    recorder = _Recorder()
    detection_m = 0.0
    wall0 = time.perf_counter()
    world: SumoWorld | None = None
    try:
        world, detection_m = _simulate(scenario, run_dir, vehicle, meta, recorder, options, wall0)
        meta["status"] = "ok"
    except ScenarioTimeout as exc:
        meta["status"] = "timeout"
        meta["error"] = str(exc)
    except Exception:  # noqa: BLE001 - one scenario's crash must not stop the catalog
        meta["status"] = "error"
        meta["error"] = traceback.format_exc()
        (run_dir / rr.TRACEBACK).write_text(meta["error"])
    finally:
        if world is not None:
            meta["sumo_collisions"] = list(world.collisions)
            world.close()
            _attach_ssm(world, meta, recorder)
    meta["wall_s"] = time.perf_counter() - wall0
    # Linux reports ru_maxrss in KiB: the scenario process's peak memory.
    meta["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    meta["sim_time_s"] = float(recorder.rows[-1]["t_s"]) if recorder.rows else 0.0
    try:
        recorder.write(run_dir, detection_m)
    except Exception:  # noqa: BLE001
        meta["status"] = "error"
        meta["error"] = ((meta["error"] or "") + "\nwhile writing the trace:\n"
                         + traceback.format_exc())
    _finish(run_dir, meta, options)
    return meta


def _attach_ssm(world: SumoWorld, meta: dict[str, Any], rec: _Recorder) -> None:
    """SUMO writes the SSM log on close: fill ``ssm_ttc_s`` per step from it."""
    try:
        times, ttcs, summary = parse_ssm(world.ssm_file)
    except Exception:  # noqa: BLE001 - a malformed SSM log must not lose the run
        meta["ssm"] = {"error": traceback.format_exc()}
        return
    meta["ssm"] = summary
    if times.size == 0:
        return
    lookup = dict(zip(np.round(times, 6).tolist(), ttcs.tolist(), strict=True))
    t_origin = meta.get("sumo_t_origin_s", 0.0)
    for row in rec.rows:
        value = lookup.get(round(row["t_s"] + t_origin, 6))
        if value is not None:
            row["ssm_ttc_s"] = value


def _finish(run_dir: Path, meta: dict[str, Any], options: RunOptions) -> None:
    """Evaluate metrics and criteria, write run.json, then the Rerun log."""
    from reports.metrics.evaluate import evaluate_run

    write_json(run_dir / rr.RUN_JSON, meta)
    try:
        record = rr.load_run(run_dir)
        result = evaluate_run(record, meta.get("criteria") or None)
        meta["metrics"] = result.metrics
        meta["failed_criteria"] = list(result.failed)
        if meta["status"] == "ok":
            meta["status"] = result.status
    except Exception:  # noqa: BLE001
        meta["metrics"] = {}
        meta["failed_criteria"] = []
        if meta["status"] == "ok":
            meta["status"] = "error"
        meta["error"] = ((meta["error"] or "") + "\nwhile evaluating metrics:\n"
                         + traceback.format_exc())
    write_json(run_dir / rr.RUN_JSON, meta)
    if options.write_rrd:
        t0 = time.perf_counter()
        try:
            from suite.rerun.log import write_rrd

            write_rrd(run_dir, catalog_name=options.catalog_name or None)
            meta["log_s"] = time.perf_counter() - t0
        except Exception:  # noqa: BLE001 - a broken log must not lose the verdict
            meta["log_error"] = traceback.format_exc()
        write_json(run_dir / rr.RUN_JSON, meta)
    if meta.get("error") and not (run_dir / rr.TRACEBACK).exists():
        (run_dir / rr.TRACEBACK).write_text(str(meta["error"]))


def _simulate(scenario: Any, run_dir: Path, vehicle: VehicleParams, meta: dict[str, Any],
              rec: _Recorder, options: RunOptions, wall0: float) -> tuple[SumoWorld, float]:
    network = RoadNetwork.load(scenario.net_path)
    route = tuple(scenario.route)
    controller: Controller = registry.make(scenario.controller.name, scenario.controller.options)
    meta["controller_params"] = dict(controller.parameters())
    reference = network.lane_centreline(route, scenario.ego.lane)
    path = FrenetPath.cached(reference)
    lane_slots = _lane_slots(network, route)
    route_len_m = network.route_length_m(route)
    start_edge, _ = network.locate(route, scenario.ego.pos_m)
    lane_width = network.lane_width_m(start_edge, scenario.ego.lane)
    write_json(run_dir / rr.ROAD_JSON, {
        "lanes": [li.as_dict() for li in network.lane_info(route)],
        "reference_xy_m": reference.tolist(),
        "reference_length_m": float(path.length_m),
        "route": list(route),
    })
    dt = float(scenario.step_s)
    target = float(scenario.ego.target_speed_mps)
    state0 = _initial_state(path, scenario.ego.pos_m, scenario.ego.speed_mps, vehicle)
    context = ScenarioContext(reference, lane_width, target, dt, vehicle, state0)
    controller.reset(context)
    external = not controller.simulated_by_sumo
    plant = SingleTrackPlant(vehicle, state0) if external else None
    policy = getattr(controller, "obstacle_policy", None)
    builder = (ObstacleBuilder(policy, vehicle.length_m, vehicle.width_m, scenario.ego.lane,
                               scenario.allow_shoulder) if policy is not None else None)
    detection_m = float(policy.detection_distance_m) if policy is not None else 0.0

    world = SumoWorld(scenario, network, vehicle, run_dir / "sumo", externally_driven=external)
    world.start()
    if plant is not None:
        fx, fy = plant.front_bumper_xy()
        world.move_ego(fx, fy, float(plant.state[2]))
        world.step()
    t_origin = world.time_s
    meta["sumo_t_origin_s"] = t_origin
    meta["stalled"] = world.stalled_vehicles()
    nb = world.neighbours()
    state = state0.copy()
    prev_psi = state[2]
    prev_speed = float(state[3])
    # The pose projected at the end of one step is the next step's input: project once.
    s_now, y_now, _ = path.project_pose(state[0], state[1], state[2])
    s_hint = float(s_now)
    n_steps = int(round(scenario.duration_s / dt))
    first_collision_t: float | None = None
    end_s = path.length_m - _END_OF_ROUTE_MARGIN_M
    timeout = options.timeout_s
    record_radius_m = float(scenario.record_radius_m)
    for step in range(n_steps):
        if timeout is not None and time.perf_counter() - wall0 > timeout:
            raise ScenarioTimeout(f"wall-clock budget of {timeout} s exceeded at step {step}")
        t_s = step * dt
        speed = math.hypot(state[3], state[4])
        tc0 = time.perf_counter()
        side, reason, n_obs, lat_ref = SIDE_NONE, "", 0, 0.0
        step_target = target
        ellipses = np.zeros((0, 6))
        obs_kwargs: dict[str, Any] = {}
        if builder is not None:
            fn = to_frenet(path, nb, s_hint, float(state[0]), float(state[1]))
            edge, _ = network.locate(route, min(max(s_hint, 0.0), route_len_m - 1e-3))
            decision = builder.build(s_hint, float(y_now), speed, target, nb, fn,
                                     lane_slots.get(edge, {}), lane_width)
            side, reason, step_target = decision.side, decision.reason, decision.target_speed_mps
            n_obs = decision.obstacles.count
            ellipses = ellipses_in_world(path, decision.obstacles)
            lat_ref = decision.lateral_reference_m
            obs_kwargs = {"obstacles": decision.obstacles,
                          "pass_side": side if side in (-1, 1) else 0,
                          "lateral_reference_m": lat_ref}
        t_obs = time.perf_counter() - tc0
        command = controller.step(Observation(t_s, state.copy(), step_target, **obs_kwargs))
        t_ctrl = time.perf_counter() - tc0
        ts0 = time.perf_counter()
        if plant is not None:
            steer, torque = plant.saturate(command.steer_rad, command.torque_nm)
            state = plant.step(steer, torque, dt)
            fx, fy = plant.front_bumper_xy()
            world.move_ego(fx, fy, float(state[2]))
            hits = world.step()
            long_acc, lat_acc = plant.long_acc_mps2, plant.lat_acc_mps2
            ego_sumo = world.ego_state() if world.ego_in_sim() else None
        else:
            steer, torque = math.nan, math.nan
            hits = world.step()
            if not world.ego_in_sim():
                break
            es = ego_sumo = world.ego_state()
            d = vehicle.cg_to_front_bumper_m
            psi = es.heading_rad
            r = math.remainder(psi - prev_psi, 2 * math.pi) / dt
            state = np.array([es.front_x_m - d * math.cos(psi), es.front_y_m - d * math.sin(psi),
                              prev_psi + math.remainder(psi - prev_psi, 2 * math.pi),
                              es.speed_mps, 0.0, r])
            long_acc, lat_acc = (es.speed_mps - prev_speed) / dt, es.speed_mps * r
        t_sumo = time.perf_counter() - ts0
        prev_psi, prev_speed = state[2], math.hypot(state[3], state[4])
        nb = world.neighbours()
        t_end = world.time_s - t_origin
        gap, gap_id, overlap = _gap_and_collision(_ego_box(state, vehicle), nb)
        s_new, y_new, e_new = path.project_pose(state[0], state[1], state[2], s_hint=s_hint)
        y_now, s_hint = y_new, float(s_new)
        lane_idx = ego_sumo.lane_index if ego_sumo is not None else -1
        diag = command.diagnostics
        rec.rows.append({
            "step": step, "t_s": t_end, "x_m": state[0], "y_m": state[1], "psi_rad": state[2],
            "u_mps": state[3], "v_mps": state[4], "r_radps": state[5],
            "speed_mps": math.hypot(state[3], state[4]), "target_speed_mps": step_target,
            "long_acc_mps2": long_acc, "lat_acc_mps2": lat_acc, "steer_rad": steer,
            "torque_nm": torque,
            "steer_outer_rad": diag.get("steer_outer_rad", math.nan),
            "steer_corr_rad": diag.get("steer_corr_rad", math.nan),
            "torque_outer_nm": diag.get("torque_outer_nm", math.nan),
            "torque_corr_nm": diag.get("torque_corr_nm", math.nan),
            "s_m": float(s_new), "lat_dev_m": float(y_new), "heading_err_rad": float(e_new),
            "lane_index": lane_idx,
            "sumo_front_x_m": ego_sumo.front_x_m if ego_sumo is not None else math.nan,
            "sumo_front_y_m": ego_sumo.front_y_m if ego_sumo is not None else math.nan,
            "sumo_heading_rad": ego_sumo.heading_rad if ego_sumo is not None else math.nan,
            "min_gap_m": gap, "gap_vehicle": gap_id,
            "geom_collision": overlap, "sumo_collision": bool(hits),
            "ssm_ttc_s": math.nan, "side": side, "side_reason": reason,
            "n_obstacles": n_obs, "lat_ref_m": lat_ref,
            "lat_ref_smoothed_m": diag.get("lateral_ref_m", math.nan),
            "residual": diag.get("residual", math.nan),
            "fallback": bool(diag.get("fallback", 0.0)),
            "guard_fired": int(diag.get("guard_fired", 0)),
            "outer_s": diag.get("outer_s", math.nan), "inner_s": diag.get("inner_s", math.nan),
            "obstacles_s": t_obs, "controller_s": t_ctrl, "sumo_s": t_sumo,
        })
        rec.add_neighbours(step, t_end, nb,
                           np.hypot(nb.x_m - state[0], nb.y_m - state[1]) <= record_radius_m)
        rec.plan.append(command.arrays.get("plan_xy_m"))
        rec.preview.append(command.arrays.get("preview_xy_m"))
        rec.ellipses.append(ellipses)
        if (overlap or hits) and first_collision_t is None:
            first_collision_t = t_end
        if first_collision_t is not None and t_end - first_collision_t >= _COLLISION_GRACE_S:
            break
        if float(s_new) >= end_s:
            break
    meta["ego_id"] = EGO_ID
    return world, detection_m
