"""The run directory: the one contract between the runner, metrics, Rerun logs and reports.

``DIR/<scenario>/`` holds, for one scenario run:

``run.json``  (dict)
    scenario, controller, controller_options, controller_params, catalog, seed,
    net (path), duration_s, step_s, target_speed_mps, criteria (dict of limits),
    status ('pass'|'fail'|'error'|'timeout'), error (traceback text or null),
    wall_s, sim_time_s, ego ({length_m, width_m, cg_to_front_bumper_m,
    cg_to_box_centre_m}), stalled (list of {id, x_m, y_m, heading_rad, length_m,
    width_m, lane_index}), sumo_collisions (list of {t_s, collider, victim, type}),
    ssm (dict of SUMO SSM figures for the ego, may be empty), metrics (dict),
    failed_criteria (list of "name=value>limit" strings).
``road.json``  (dict)
    lanes: list of {id, edge_id, index, width_m, shape_xy_m [[x, y], ...],
    allowed [vclass...], is_shoulder, on_route}; reference_xy_m [[x, y], ...]
    (the controller's reference centreline), reference_length_m, route [edge ids].
``trace.parquet``  one row per control step, columns (``TRACE_COLUMNS``).
``neighbours.parquet``  one row per (step, other vehicle) within the
    recording radius, columns (``NEIGHBOUR_COLUMNS``).
``controller_arrays.npz``  optional per-step arrays, NaN-padded, first axis = step:
    plan_xy_m (T, N+1, 2), preview_xy_m (T, Np+1, 2),
    ellipses (T, K, 6) = [cx_m, cy_m, heading_rad, semi_a_m, semi_b_m, active]
    in the world frame, detection_radius_m (scalar array).
``traceback.txt``  only for status 'error'.

Headings are radians counter-clockwise from +X (math convention); positions are
vehicle *box centres* for neighbours and the ego's CG for the ego (its box centre
is ``cg_to_box_centre_m`` ahead of the CG).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

# name -> meaning [unit]
TRACE_COLUMNS: dict[str, str] = {
    "step": "control step index [-]",
    "t_s": "simulation time at the end of the step [s]",
    "x_m": "ego CG X [m]",
    "y_m": "ego CG Y [m]",
    "psi_rad": "ego yaw, CCW from +X [rad]",
    "u_mps": "body longitudinal speed [m/s]",
    "v_mps": "body lateral speed [m/s]",
    "r_radps": "yaw rate [rad/s]",
    "speed_mps": "speed magnitude [m/s]",
    "target_speed_mps": "speed set-point given to the controller [m/s]",
    "long_acc_mps2": "body longitudinal acceleration u' - r v [m/s^2]",
    "lat_acc_mps2": "body lateral acceleration v' + r u [m/s^2]",
    "steer_rad": "applied front-wheel angle [rad]",
    "torque_nm": "applied drive torque [N m]",
    "steer_outer_rad": "outer-loop steering part [rad] (NaN if n/a)",
    "steer_corr_rad": "inner-loop steering correction [rad] (NaN if n/a)",
    "torque_outer_nm": "outer-loop torque part [N m] (NaN if n/a)",
    "torque_corr_nm": "inner-loop torque correction [N m] (NaN if n/a)",
    "s_m": "progress along the reference path [m]",
    "lat_dev_m": "signed offset of the CG from the reference centreline, left + [m]",
    "heading_err_rad": "yaw minus reference tangent angle [rad]",
    "lane_index": "SUMO lane index under the ego (-1 if off the net)",
    "sumo_front_x_m": "ego front bumper X as SUMO has it after the step [m]",
    "sumo_front_y_m": "ego front bumper Y as SUMO has it after the step [m]",
    "sumo_heading_rad": "ego heading as SUMO has it after the step, CCW from +X [rad]",
    "min_gap_m": "distance between the ego box and the nearest other box (0 on contact) [m]",
    "gap_vehicle": "id of that vehicle ('' if none)",
    "geom_collision": "ego box overlaps another box (bool)",
    "sumo_collision": "SUMO reported a collision involving the ego this step (bool)",
    "ssm_ttc_s": "SUMO SSM device's current TTC for the ego [s] (NaN if none)",
    "side": "pass side chosen: +1 left, -1 right, 0 none, 2 follow (no side free)",
    "side_reason": "why that side (text)",
    "n_obstacles": "obstacles given to the controller [-]",
    "lat_ref_m": "lateral reference given to the controller (pass lane centre), left + [m]",
    "lat_ref_smoothed_m": "the controller's smoothed lateral reference [m] (NaN if n/a)",
    "residual": "outer-loop residual E = ||F||inf (NaN if n/a)",
    "fallback": "a safe fallback replaced the plan this step (bool)",
    "guard_fired": "barrier guard count this step [-]",
    "outer_s": "outer-loop time this step [s] (NaN if n/a)",
    "inner_s": "inner-loop time this step [s] (NaN if n/a)",
    "obstacles_s": "obstacle building and side choice time [s]",
    "controller_s": "whole controller step time incl. obstacles [s]",
    "sumo_s": "SUMO step time [s]",
}

NEIGHBOUR_COLUMNS: dict[str, str] = {
    "step": "control step index [-]",
    "t_s": "simulation time [s]",
    "id": "SUMO vehicle id",
    "x_m": "box centre X [m]",
    "y_m": "box centre Y [m]",
    "heading_rad": "CCW from +X [rad]",
    "speed_mps": "speed [m/s]",
    "length_m": "box length [m]",
    "width_m": "box width [m]",
    "lane_index": "SUMO lane index",
    "stalled": "stalled vehicle (bool)",
}

RUN_JSON = "run.json"
ROAD_JSON = "road.json"
TRACE = "trace.parquet"
NEIGHBOURS = "neighbours.parquet"
CONTROLLER_ARRAYS = "controller_arrays.npz"
TRACEBACK = "traceback.txt"
RRD = "run.rrd"


@dataclass
class RunRecord:
    """One run directory, loaded. ``trace``/``neighbours`` may be empty for errors."""

    run_dir: Path
    meta: dict[str, Any]
    road: dict[str, Any]
    trace: pd.DataFrame
    neighbours: pd.DataFrame
    arrays: dict[str, np.ndarray]

    @property
    def name(self) -> str:
        return str(self.meta.get("scenario", self.run_dir.name))


def load_run(run_dir: str | Path, with_arrays: bool = True) -> RunRecord:
    """Read a run directory written by the runner."""
    run_dir = Path(run_dir)
    meta_path = run_dir / RUN_JSON
    if not meta_path.is_file():
        raise FileNotFoundError(f"{meta_path}: no run.json, not a run directory")
    meta = json.loads(meta_path.read_text())
    road_path = run_dir / ROAD_JSON
    road = json.loads(road_path.read_text()) if road_path.is_file() else {}
    trace_path = run_dir / TRACE
    trace = pd.read_parquet(trace_path) if trace_path.is_file() else pd.DataFrame(
        columns=list(TRACE_COLUMNS))
    nb_path = run_dir / NEIGHBOURS
    neighbours = pd.read_parquet(nb_path) if nb_path.is_file() else pd.DataFrame(
        columns=list(NEIGHBOUR_COLUMNS))
    arrays: dict[str, np.ndarray] = {}
    arr_path = run_dir / CONTROLLER_ARRAYS
    if with_arrays and arr_path.is_file():
        with np.load(arr_path) as npz:
            arrays = {k: npz[k] for k in npz.files}
    return RunRecord(run_dir, meta, road, trace, neighbours, arrays)


def iter_run_dirs(out_dir: str | Path) -> list[Path]:
    """Scenario run directories under a catalog output directory, sorted by name."""
    out_dir = Path(out_dir)
    return sorted(p.parent for p in out_dir.glob(f"*/{RUN_JSON}"))
