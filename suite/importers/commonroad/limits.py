"""Bounds on what a read CommonRoad file may hold: coordinates and times beyond them are
a unit or field error, not a recording (an :class:`~suite.importers.commonroad.errors.
ImportFailure` naming the file and the element). Non-finite numbers are refused where
they are read (:mod:`~suite.importers.commonroad.reader`); these are the finite values
that are still absurd.

* Every lanelet vertex, obstacle sample, the ego's initial position and its goal
  positions: |x|, |y| at most :data:`MAX_ABS_COORD_M`.
* Every time step k of an obstacle sample, of the ego's initial state and of its goal:
  |k| dt at most :data:`MAX_RECORDING_S`.
"""

from __future__ import annotations

import numpy as np

from suite.importers.commonroad.errors import ImportFailure
from suite.importers.commonroad.records import EgoStart, FloatArray, RecordedFile

__all__ = ["MAX_ABS_COORD_M", "MAX_RECORDING_S", "check_limits"]

MAX_ABS_COORD_M = 1.0e7
"""The largest |x| or |y| [m] a position may have. Projected coordinates stay
below it (UTM northings reach 1e7 m, with the southern hemisphere's false northing;
eastings 1e6 m), and float64's spacing there is 2e-9 m. Beyond it precision is the
coordinates' problem: at 1e15 m the spacing is 0.125 m, so boxes touch or miss by
rounding (a collision would be an artefact), and netconvert writes millimetres."""

MAX_RECORDING_S = 24.0 * 3600.0
"""The largest time [s] a time step k may stand for, |k| dt. Recordings last
minutes (highD: up to 17 min, NGSIM: 15 min per period), a run at most
:data:`suite.catalog.loader.MAX_STEPS` control steps (5.6 h at 20 ms); a day is no
recording's: a time stamp in a time-step field, or a typo."""


def _far(xy: FloatArray) -> bool:
    return bool(np.any(np.abs(xy) > MAX_ABS_COORD_M))


def _coords(x: float, y: float) -> str:
    return f"({x:.6g}, {y:.6g}) m"


def _coord_reason(what: str, x: float, y: float) -> str:
    return (f"{what} at {_coords(x, y)}: beyond the bound |x|, |y| <= "
            f"{MAX_ABS_COORD_M:g} m (limits.MAX_ABS_COORD_M)")


def _time_reason(what: str, step: int, dt_s: float) -> str:
    return (f"{what} at time step {step} = {step * dt_s:.6g} s: beyond the bound of "
            f"{MAX_RECORDING_S:g} s (limits.MAX_RECORDING_S)")


def _check_lanelets(rec: RecordedFile) -> None:
    for ll in rec.lanelets:
        for name, xy in (("left bound", ll.left_xy_m), ("right bound", ll.right_xy_m)):
            if _far(xy):
                k = int(np.argmax(np.max(np.abs(xy), axis=1)))
                raise ImportFailure(rec.path, f"lanelet {ll.label}", _coord_reason(
                    f"a {name} vertex", float(xy[k, 0]), float(xy[k, 1])))


def _check_obstacles(rec: RecordedFile) -> None:
    for ob in rec.obstacles:
        element = f"obstacle {ob.obstacle_id}"
        xy = np.column_stack([ob.x_m, ob.y_m])
        if _far(xy):
            k = int(np.argmax(np.max(np.abs(xy), axis=1)))
            raise ImportFailure(rec.path, element, _coord_reason(
                f"its sample of time step {int(ob.steps[k])}", float(xy[k, 0]),
                float(xy[k, 1])))
        late = np.abs(ob.steps.astype(np.float64)) * rec.dt_s > MAX_RECORDING_S
        if np.any(late):
            step = int(ob.steps[int(np.argmax(late))])
            raise ImportFailure(rec.path, element, _time_reason("a sample", step, rec.dt_s))


def _check_ego(rec: RecordedFile, ego: EgoStart) -> None:
    start = f"planningProblem {ego.problem_id} initialState"
    goal = f"planningProblem {ego.problem_id} goalState"
    if abs(ego.x_m) > MAX_ABS_COORD_M or abs(ego.y_m) > MAX_ABS_COORD_M:
        raise ImportFailure(rec.path, start, _coord_reason("the ego", ego.x_m, ego.y_m))
    if abs(ego.time_step) * rec.dt_s > MAX_RECORDING_S:
        raise ImportFailure(rec.path, start, _time_reason("the ego's start", ego.time_step,
                                                          rec.dt_s))
    for x, y in ego.goal_points_xy_m:
        if not (np.isfinite(x) and np.isfinite(y)):
            raise ImportFailure(rec.path, goal, f"a goal position at {_coords(x, y)}: not "
                                "a finite number")
        if abs(x) > MAX_ABS_COORD_M or abs(y) > MAX_ABS_COORD_M:
            raise ImportFailure(rec.path, goal, _coord_reason("a goal position", x, y))
    end = ego.goal_end_step
    if end is not None and abs(end) * rec.dt_s > MAX_RECORDING_S:
        raise ImportFailure(rec.path, goal, _time_reason("the goal's end", end, rec.dt_s))


def check_limits(rec: RecordedFile) -> None:
    """Refuse a coordinate or a time beyond its bound (module docstring), naming the
    lanelet, the obstacle or the planning problem."""
    _check_lanelets(rec)
    _check_obstacles(rec)
    _check_ego(rec, rec.ego)
