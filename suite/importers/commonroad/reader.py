"""Read one CommonRoad XML file into :mod:`~suite.importers.commonroad.records` (the one
module that imports commonroad-io, lazily).

commonroad-io's ``CommonRoadFileReader`` imports its protobuf reader, which fails with
the protobuf >= 5 that the ``cluster`` extra needs; ``XMLFileReader`` does not, and XML
is the only format imported here (docs/recorded.md).

Uncertain states (2018b: a position given as a shape, an orientation or a velocity as an
interval) are replaced by their centres and counted (:class:`UncertainCount`). The box
centre of an obstacle is its position moved back by the shape's ``origin_x_shift`` (the
reference point's offset from the box centre along the heading, 0 in XML files).

Speed limits: a traffic sign element whose commonroad-io id (``TrafficSignIDGermany``
``274``, ``TrafficSignIDUsa`` ``R2-1``, ... per the scenario's country) is named
``MAX_SPEED`` gives its first ``additionalValue`` in m/s (CommonRoad's unit); a lanelet
takes the lowest such sign it references. Values outside (0, :data:`MAX_PLAUSIBLE_MPS`]
or not numbers are ignored, with a warning note.

Bounds: CommonRoad's centre line is the mean of the i-th left and i-th right vertex, which
is the centre only where those vertices are opposite (exiD's are not). Bounds whose
interior vertex pairs lie more than ``PAIR_SKEW_TOL_M`` apart along the road, or that have
different vertex counts, are re-paired (:func:`~suite.importers.commonroad.geometry.
pair_bounds`; a note names them); others are kept as they are.

Checks: the file's structure first (:mod:`~suite.importers.commonroad.structure`:
well-formed XML, unique ids, goal lanelets that exist); then every number read: a
position, orientation or velocity of a state, an obstacle's size, a lanelet vertex or
the ego's initial state given as a number that is not finite (``nan``, ``inf``) names
its element (an orientation or velocity the file does not give is no error: a missing
orientation is 0, a missing speed NaN, derived later from the positions); last the
bounds of :mod:`~suite.importers.commonroad.limits` (coordinates, times).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from suite.importers.commonroad.errors import ImportFailure
from suite.importers.commonroad.geometry import PAIR_SKEW_TOL_M, pair_bounds, pair_skew_m
from suite.importers.commonroad.limits import check_limits
from suite.importers.commonroad.records import (
    EgoStart,
    FloatArray,
    LaneletRecord,
    ObstacleRecord,
    RecordedFile,
    UncertainCount,
)
from suite.importers.commonroad.structure import check_structure

__all__ = ["MAX_PLAUSIBLE_MPS", "read_file"]

MAX_PLAUSIBLE_MPS = 70.0
"""A ``MAX_SPEED`` value above this [m/s] (252 km/h) is not taken as a speed limit in
m/s (likely km/h or mph): ignored with a warning."""

INSTALL_HINT = ("commonroad-io is not installed: install hwyeval[commonroad] (pip install "
                "'hwyeval[commonroad]', or in a cluster venv pip install --no-deps "
                "'commonroad-io>=2024.1', see docs/recorded.md)")


def _xml_reader() -> Any:
    try:
        from commonroad.common.reader.file_reader_xml import XMLFileReader
    except ImportError as exc:
        raise ImportError(f"{INSTALL_HINT} ({exc})") from exc
    return XMLFileReader


def _float(value: Any) -> tuple[float, bool]:
    """A number, or the centre of an interval (``start``/``end``); (value, uncertain)."""
    if value is None:
        return math.nan, False
    if hasattr(value, "start") and hasattr(value, "end"):
        return 0.5 * (float(value.start) + float(value.end)), True
    return float(value), False


def _position(value: Any) -> tuple[float, float, bool]:
    """A point, or the centre of a position shape; (x, y, uncertain)."""
    if value is None:
        raise ValueError("a state without a position")
    if hasattr(value, "center") and not isinstance(value, np.ndarray):
        c = value.center
        c = np.asarray([c.x, c.y] if hasattr(c, "x") else c, dtype=np.float64).reshape(-1)
        return float(c[0]), float(c[1]), True
    p = np.asarray(value, dtype=np.float64).reshape(-1)
    return float(p[0]), float(p[1]), False


def _box(shape: Any) -> tuple[float, float, float]:
    """(length, width, origin_x_shift) [m] of an obstacle shape: a rectangle's own, a
    circle's diameter, else the extent of its vertices; ValueError unless finite (and
    the box > 0)."""
    shift = float(getattr(shape, "origin_x_shift", 0.0) or 0.0)
    length = getattr(shape, "length", None)
    width = getattr(shape, "width", None)
    radius = getattr(shape, "radius", None)
    if length is not None and width is not None:
        length, width = float(length), float(width)
    elif radius is not None:
        length = width = 2.0 * float(radius)
    else:
        verts = np.asarray(shape.vertices, dtype=np.float64).reshape(-1, 2)
        ext = np.ptp(verts, axis=0)
        length, width = float(max(ext)), float(min(ext))
    if not all(math.isfinite(v) for v in (length, width, shift)):
        raise ValueError(f"its shape: a size that is not a finite number ({length} x "
                         f"{width} m, origin shift {shift} m)")
    if not (length > 0.0 and width > 0.0):
        raise ValueError(f"a box of {length} x {width} m")
    return length, width, shift


def _states(obstacle: Any) -> list[Any]:
    states = [obstacle.initial_state]
    prediction = getattr(obstacle, "prediction", None)
    trajectory = getattr(prediction, "trajectory", None)
    if trajectory is not None:
        states += list(trajectory.state_list)
    by_step: dict[int, Any] = {}
    for st in states:
        step = st.time_step
        by_step.setdefault(int(step.start if hasattr(step, "start") else step), st)
    return [by_step[k] for k in sorted(by_step)]


def _given(value: Any, what: str, step: int) -> tuple[float, bool]:
    """:func:`_float` of a state's field; NaN when the file gives none, ValueError when
    it gives one that is not a finite number."""
    number, uncertain = _float(value)
    if value is not None and not math.isfinite(number):
        raise ValueError(f"its {what} at time step {step} is not a finite number ({number})")
    return number, uncertain


def _state_row(st: Any, shift: float) -> tuple[tuple[float, ...], bool]:
    """(time step, box centre x, y, heading, speed) of one state, and whether it was
    uncertain; a position, orientation or velocity given as a non-finite number is a
    ValueError."""
    step_value = st.time_step
    step = int(step_value.start if hasattr(step_value, "start") else step_value)
    x, y, u_pos = _position(st.position)
    if not (math.isfinite(x) and math.isfinite(y)):
        raise ValueError(f"its position at time step {step} is not a finite number "
                         f"({x}, {y})")
    heading, u_head = _given(getattr(st, "orientation", None), "orientation", step)
    speed, u_speed = _given(getattr(st, "velocity", None), "velocity", step)
    if not math.isfinite(heading):  # none given
        heading = 0.0
    return ((step, x - shift * math.cos(heading), y - shift * math.sin(heading), heading,
             speed), bool(u_pos or u_head or u_speed))


def _obstacle(obstacle: Any, static: bool) -> tuple[ObstacleRecord, int]:
    """The record of one obstacle and how many of its states were uncertain."""
    length, width, shift = _box(obstacle.obstacle_shape)
    rows = []
    uncertain = 0
    for st in _states(obstacle):
        row, was_uncertain = _state_row(st, shift)
        rows.append(row)
        uncertain += int(was_uncertain)
    arr = np.asarray(rows, dtype=np.float64)
    kind = getattr(obstacle.obstacle_type, "value", str(obstacle.obstacle_type))
    return ObstacleRecord(
        obstacle_id=int(obstacle.obstacle_id), kind=str(kind), static=static,
        length_m=length, width_m=width, steps=arr[:, 0].astype(np.int64),
        x_m=arr[:, 1].copy(), y_m=arr[:, 2].copy(), heading_rad=arr[:, 3].copy(),
        speed_mps=np.abs(arr[:, 4])), uncertain


def _speed_signs(network: Any) -> tuple[dict[int, float], list[str]]:
    """Sign id -> its lowest ``MAX_SPEED`` value [m/s] (module docstring), and notes."""
    out: dict[int, float] = {}
    bad: list[str] = []
    for sign in getattr(network, "traffic_signs", None) or ():
        for el in getattr(sign, "traffic_sign_elements", None) or ():
            ident = getattr(el, "traffic_sign_element_id", None)
            if getattr(ident, "name", None) != "MAX_SPEED":
                continue
            values = list(getattr(el, "additional_values", None) or ())
            try:
                v = float(values[0])
            except (IndexError, TypeError, ValueError):
                bad.append(f"{sign.traffic_sign_id} ({values!r})")
                continue
            if not (math.isfinite(v) and 0.0 < v <= MAX_PLAUSIBLE_MPS):
                bad.append(f"{sign.traffic_sign_id} ({v:g})")
                continue
            sid = int(sign.traffic_sign_id)
            out[sid] = min(v, out.get(sid, math.inf))
    notes = [f"WARNING {len(bad)} MAX_SPEED signs ignored (no value in (0, "
             f"{MAX_PLAUSIBLE_MPS:g}] m/s): {', '.join(bad[:10])}"] if bad else []
    return out, notes


def _bounds(ll: Any) -> tuple[FloatArray, FloatArray, bool]:
    """The lanelet's left and right bounds (n, 2) [m] with opposite vertices, and
    whether they had to be re-paired (module docstring)."""
    left = np.asarray(ll.left_vertices, dtype=np.float64).reshape(-1, 2)
    right = np.asarray(ll.right_vertices, dtype=np.float64).reshape(-1, 2)
    if min(left.shape[0], right.shape[0]) < 2:
        raise ValueError(f"left/right bounds of {left.shape[0]}/{right.shape[0]} points "
                         "(expected at least 2 each)")
    if not (np.all(np.isfinite(left)) and np.all(np.isfinite(right))):
        raise ValueError("a bound vertex that is not a finite number")
    if pair_skew_m(left, right) <= PAIR_SKEW_TOL_M:
        return left, right, False
    left, right = pair_bounds(left, right)
    return left, right, True


def _lanelet(ll: Any, limits: dict[int, float]) -> tuple[LaneletRecord, bool]:
    """The record of one lanelet, and whether its bounds were re-paired."""
    left, right, repaired = _bounds(ll)
    same_left = bool(ll.adj_left_same_direction) if ll.adj_left is not None else False
    same_right = bool(ll.adj_right_same_direction) if ll.adj_right is not None else False
    return LaneletRecord(
        lanelet_id=int(ll.lanelet_id), left_xy_m=left, right_xy_m=right,
        adj_left=int(ll.adj_left) if same_left else None,
        adj_right=int(ll.adj_right) if same_right else None,
        opposite_left=ll.adj_left is not None and not same_left,
        successors=tuple(int(s) for s in ll.successor or ()),
        predecessors=tuple(int(p) for p in ll.predecessor or ()),
        types=tuple(sorted(str(getattr(t, "value", t)) for t in ll.lanelet_type or ())),
        speed_limit_mps=min((limits[int(i)] for i in ll.traffic_signs or () if int(i) in limits),
                            default=None)), repaired


def _goal(problem: Any) -> tuple[tuple[int, ...], tuple[tuple[float, float], ...], int | None]:
    goal = problem.goal
    lanelets: list[int] = []
    for ids in (getattr(goal, "lanelets_of_goal_position", None) or {}).values():
        lanelets += [int(i) for i in ids]
    points = []
    end: int | None = None
    for st in getattr(goal, "state_list", None) or ():
        pos = getattr(st, "position", None)
        if pos is not None:
            try:
                x, y, _ = _position(pos)
                points.append((x, y))
            except (ValueError, TypeError, AttributeError):
                pass
        step = getattr(st, "time_step", None)
        if step is not None:
            last = int(step.end if hasattr(step, "end") else step)
            end = last if end is None else max(end, last)
    return tuple(lanelets), tuple(points), end


def _ego(path: str, problems: Any) -> tuple[EgoStart, list[str]]:
    items = sorted(getattr(problems, "planning_problem_dict", {}).items())
    if not items:
        raise ImportFailure(path, "planningProblem", "no planning problem in the file")
    notes = []
    if len(items) > 1:
        notes.append(f"{len(items)} planning problems: the first (id {items[0][0]}) is the ego")
    pid, problem = items[0]
    st = problem.initial_state
    try:
        x, y, _ = _position(st.position)
        heading, _ = _float(st.orientation)
        speed, _ = _float(st.velocity)
    except (ValueError, TypeError, AttributeError) as exc:
        raise ImportFailure(path, f"planningProblem {pid} initialState", str(exc)) from exc
    if not all(math.isfinite(v) for v in (x, y, heading, speed)):
        raise ImportFailure(path, f"planningProblem {pid} initialState",
                            "expected a finite position, orientation and velocity")
    lanelets, points, end = _goal(problem)
    return EgoStart(int(pid), int(st.time_step), x, y, heading, abs(speed), lanelets,
                    points, end), notes


def _open(path: Path) -> tuple[Any, Any]:
    """commonroad-io's scenario and planning problems of ``path``, its structure checked
    first (:mod:`~suite.importers.commonroad.structure`: well-formed, unique ids, goal
    lanelets that exist)."""
    name = str(path)
    reader = _xml_reader()
    check_structure(path)
    try:
        scenario, problems = reader(name).open()
    except Exception as exc:  # commonroad-io raises whatever its parsing hits
        raise ImportFailure(name, "commonRoad (commonroad-io's reader)",
                            f"{type(exc).__name__}: {exc}") from exc
    if not scenario.lanelet_network.lanelets:
        raise ImportFailure(name, "lanelet", "commonroad-io read no lanelet: a road is needed")
    return scenario, problems


def _read_lanelets(name: str, network: Any) -> tuple[list[LaneletRecord], list[str]]:
    """The lanelet records and the notes (ignored speed signs, re-paired bounds)."""
    limits, read_notes = _speed_signs(network)
    lanelets = []
    repaired = []
    for ll in network.lanelets:
        try:
            lanelet, was_repaired = _lanelet(ll, limits)
        except (ValueError, TypeError) as exc:
            raise ImportFailure(name, f"lanelet {ll.lanelet_id}", str(exc)) from exc
        lanelets.append(lanelet)
        if was_repaired:
            repaired.append(lanelet.lanelet_id)
    if repaired:
        read_notes.append(f"{len(repaired)} lanelets' bounds re-paired (their i-th left and "
                          f"right vertices were more than {PAIR_SKEW_TOL_M:g} m apart along "
                          f"the road): lanelets {', '.join(map(str, repaired[:20]))}"
                          f"{' ...' if len(repaired) > 20 else ''}")
    return lanelets, read_notes


def _read_obstacles(name: str, scenario: Any) -> tuple[list[ObstacleRecord], UncertainCount]:
    obstacles = []
    n_states = n_obstacles = 0
    for static, group in ((False, scenario.dynamic_obstacles), (True, scenario.static_obstacles)):
        for obs in group:
            try:
                record, uncertain = _obstacle(obs, static)
            except (ValueError, TypeError, AttributeError, IndexError) as exc:
                raise ImportFailure(name, f"obstacle {obs.obstacle_id}", str(exc)) from exc
            obstacles.append(record)
            n_states += uncertain
            n_obstacles += int(uncertain > 0)
    return obstacles, UncertainCount(n_states, n_obstacles)


def read_file(path: Path) -> RecordedFile:
    """Read ``path`` (CommonRoad XML, 2018b/2020a/...); :class:`ImportFailure` names the
    file and the element that is wrong (also a non-finite number, and a coordinate or a
    time beyond :mod:`~suite.importers.commonroad.limits`'s bounds); ``ImportError`` if
    commonroad-io is missing."""
    name = str(path)
    scenario, problems = _open(path)
    lanelets, read_notes = _read_lanelets(name, scenario.lanelet_network)
    obstacles, uncertain = _read_obstacles(name, scenario)
    ego, notes = _ego(name, problems)
    dt_s = float(scenario.dt)
    if not (math.isfinite(dt_s) and dt_s > 0.0):
        raise ImportFailure(name, "commonRoad timeStepSize", f"expected > 0, got {dt_s}")
    country = str(getattr(getattr(scenario, "scenario_id", None), "country_id", "") or "ZAM")
    rec = RecordedFile(name, dt_s, tuple(lanelets), tuple(obstacles), ego, uncertain,
                       (*notes, *read_notes), country.upper())
    check_limits(rec)
    return rec
