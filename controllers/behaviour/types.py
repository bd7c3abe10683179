"""Neutral array types of the behaviour layer: what the world hands over, what is decided.

The behaviour layer sits between the world (SUMO, or the scripted plant-only world) and
the controller: other vehicles and lane context in, obstacle ellipses, a pass side, a
lateral reference and a speed target out. These types carry no SUMO object; the SUMO
adapter (``suite.world.sumo``) and the scripted world (``suite.world.scripted``) both
produce them.

Frames: world = network coordinates [m], headings CCW from +X [rad]; Frenet = arc
length ``s`` along the controller's reference path [m] and lateral offset ``y``, left
positive [m].
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from enum import IntEnum, StrEnum

import numpy as np
import numpy.typing as npt

from controllers.behaviour.ellipse_fit import leave_ego_outside

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]
Int8Array = npt.NDArray[np.int8]


def _no_agents() -> Int8Array:
    return np.zeros(0, dtype=np.int8)

class Side(IntEnum):
    """The behaviour's side for the plan; the integer is the trace's ``side`` code.

    LEFT / RIGHT: pass (or move) on that side; KEEP: keep the lane, nothing to pass;
    FOLLOW: no side is free, follow the lead (the controller passes on no side).
    """

    KEEP = 0
    LEFT = 1
    RIGHT = -1
    FOLLOW = 2

    @property
    def pass_side(self) -> int:
        """+1 / -1 when passing on that side, else 0 (the controller's pass side)."""
        return int(self) if self in (Side.LEFT, Side.RIGHT) else 0


SIDE_NONE = Side.KEEP
SIDE_LEFT = Side.LEFT
SIDE_RIGHT = Side.RIGHT
SIDE_FOLLOW = Side.FOLLOW


class LaneCheck(StrEnum):
    """Why a wanted lane change was or was not taken, per target lane (the decision's
    ``lane_checks``; its ``reason`` text says it with the vehicles and numbers).

    FREE: the lane (or shoulder) is free; NO_LANE: there is none; SHOULDER_NOT_ALLOWED:
    it is a shoulder and the scenario forbids it; BARS_PASSENGER: passenger cars may not
    use it; ENDS: it ends before the change would; STOPPED_VEHICLE: a stopped vehicle
    stands where the change would go; FRONT_GAP / REAR_GAP: the time gap to the vehicle
    ahead / behind in it is too short; CLOSING_AHEAD / CLOSING_FROM_BEHIND: that vehicle
    would need harder braking than the bound; CURVE: the curve leaves too little lateral
    acceleration for a change that is not urgent; MERGE_CONFLICT: a vehicle merges into it;
    HOLDING: the last change is too recent (the hold time).
    """

    FREE = "free"
    NO_LANE = "no_lane"
    SHOULDER_NOT_ALLOWED = "shoulder_not_allowed"
    BARS_PASSENGER = "bars_passenger"
    ENDS = "ends"
    STOPPED_VEHICLE = "stopped_vehicle"
    FRONT_GAP = "front_gap"
    REAR_GAP = "rear_gap"
    CLOSING_AHEAD = "closing_ahead"
    CLOSING_FROM_BEHIND = "closing_from_behind"
    CURVE = "curve"
    MERGE_CONFLICT = "merge_conflict"
    HOLDING = "holding"

    @property
    def gap_too_short(self) -> bool:
        """A vehicle in the target lane is too close or closing too fast."""
        return self in (LaneCheck.FRONT_GAP, LaneCheck.REAR_GAP, LaneCheck.CLOSING_AHEAD,
                        LaneCheck.CLOSING_FROM_BEHIND)


class Reason(StrEnum):
    """What kind of decision the behaviour took (the trace's ``reason_code``); the
    decision's ``reason`` text says it with the vehicles and numbers.

    NONE: no lane behaviour (a controller that takes no obstacles); KEEP: keep the lane
    (free, or no change possible that is not needed); FOLLOW: a slower lead holds the
    ego and no faster lane can be taken; PASS / RETURN / LANE_ENDS / MAKE_ROOM: a lane
    change starts, to pass a vehicle, back towards the home lane, out of a lane that
    ends, to make room for a merging vehicle; PASSING / CHANGING: a change under way
    (passing a vehicle, or not); IN_LANE: a change complete; ABORT: a change aborted
    (back to the origin lane).
    """

    NONE = "none"
    KEEP = "keep"
    FOLLOW = "follow"
    PASS = "pass"
    RETURN = "return"
    LANE_ENDS = "lane_ends"
    MAKE_ROOM = "make_room"
    PASSING = "passing"
    CHANGING = "changing"
    IN_LANE = "in_lane"
    ABORT = "abort"


def require_numbers(obj: object, names: tuple[str, ...], *, low: float = 0.0,
                    strict: bool = False) -> None:
    """Raise ValueError naming ``Class.field`` unless each of ``names`` is a finite
    number (never a bool) ``>= low`` (``> low`` if ``strict``)."""
    for name in names:
        v = getattr(obj, name)
        ok = (isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
              and (v > low if strict else v >= low))
        if not ok:
            op = ">" if strict else ">="
            raise ValueError(f"{type(obj).__name__}.{name} must be a finite number "
                             f"{op} {low:g}, got {v!r}")


@dataclass(frozen=True)
class Traffic:
    """Other vehicles at one instant, every array of shape (n,), world frame.

    x_m, y_m: box centre [m]; heading_rad; speed_mps along the heading; length_m,
    width_m: box size [m]; lane_index: lane index on its road (0 = rightmost, -1
    unknown); road_id: the road (edge) it is on ('' unknown); stalled: a stalled
    vehicle of the scenario (never moves); agent: what moves it (0 = the simulator's
    traffic or a scripted actor, 1 = replayed from a recording, 2 = a recorded vehicle
    handed over to the simulator's driver; all 0 when not given).
    """

    ids: tuple[str, ...]
    x_m: FloatArray
    y_m: FloatArray
    heading_rad: FloatArray
    speed_mps: FloatArray
    length_m: FloatArray
    width_m: FloatArray
    lane_index: IntArray
    road_id: tuple[str, ...]
    stalled: BoolArray
    agent: Int8Array = field(default_factory=_no_agents)

    def __post_init__(self) -> None:
        n = len(self.ids)
        if n and np.shape(self.agent) == (0,):
            object.__setattr__(self, "agent", np.zeros(n, dtype=np.int8))
        for name in ("x_m", "y_m", "heading_rad", "speed_mps", "length_m", "width_m",
                     "lane_index", "stalled", "agent"):
            if np.shape(getattr(self, name)) != (n,):
                raise ValueError(f"Traffic.{name} must have shape ({n},), "
                                 f"got {np.shape(getattr(self, name))}")
        if len(self.road_id) != n:
            raise ValueError(f"Traffic.road_id must have {n} entries, got {len(self.road_id)}")

    @property
    def count(self) -> int:
        return len(self.ids)

    def moved(self, x_m: FloatArray, y_m: FloatArray) -> Traffic:
        """These vehicles with box centres ``x_m``, ``y_m`` [m] (shape (n,), as this
        one's), everything else shared. The shapes are checked against this (already
        checked) instance only: no full re-validation, the extrapolation between SUMO
        steps makes one of these every control step."""
        n = len(self.ids)
        if x_m.shape != (n,) or y_m.shape != (n,):
            raise ValueError(f"Traffic.moved: positions must have shape ({n},), got "
                             f"{x_m.shape} and {y_m.shape}")
        out = object.__new__(Traffic)
        fields = dict(self.__dict__)
        fields["x_m"], fields["y_m"] = x_m, y_m
        out.__dict__.update(fields)
        return out

    @staticmethod
    def empty() -> Traffic:
        z = np.zeros(0)
        return Traffic((), z, z, z, z, z, z, np.zeros(0, dtype=np.int64), (),
                       np.zeros(0, dtype=bool))

    def take(self, index: npt.NDArray[np.intp] | BoolArray) -> Traffic:
        """The vehicles at ``index`` (integer positions or a boolean mask)."""
        idx = np.flatnonzero(index) if np.asarray(index).dtype == bool else np.asarray(index)
        return Traffic(tuple(self.ids[i] for i in idx), self.x_m[idx], self.y_m[idx],
                       self.heading_rad[idx], self.speed_mps[idx], self.length_m[idx],
                       self.width_m[idx], self.lane_index[idx],
                       tuple(self.road_id[i] for i in idx), self.stalled[idx],
                       self.agent[idx])


@dataclass(frozen=True)
class LaneSlot:
    """A lane of the road under a point of the route: index (0 = rightmost of its road),
    width [m], passenger cars allowed, hard shoulder; its centre's offset from the
    reference path there [m, left +] (NaN: unknown, lanes are then assumed side by side
    at their widths) and how far ahead along the route it continues [m] (inf: to the
    route's end; an exit or a lane that ends has a finite value)."""

    index: int
    width_m: float
    allows_passenger: bool
    is_shoulder: bool
    offset_m: float = math.nan
    continues_m: float = math.inf


@dataclass(frozen=True)
class LaneContext:
    """The lanes at the ego's position, by lane index, and the index of the lane the
    reference path follows there (``reference_index``); ``reference_index_by_road``
    gives that index on every road (edge) of the route near the ego, so that a vehicle
    whose road and lane index the world reports is placed in its lane exactly.

    ``ending_lanes_by_road``: road -> lane index -> (route position [m] where that lane
    ends, the side its traffic merges to: +1 left, -1 right) for the lanes of the route
    that end without leaving it (acceleration lanes, lane drops; exits are not there);
    ``route_pos_m``: the ego's route position [m] (NaN unknown)."""

    slots: Mapping[int, LaneSlot]
    reference_index: int
    reference_index_by_road: Mapping[str, int] = field(default_factory=dict)
    ending_lanes_by_road: Mapping[str, Mapping[int, tuple[float, int]]] = field(
        default_factory=dict)
    route_pos_m: float = math.nan

    def slot(self, index: int) -> LaneSlot | None:
        return self.slots.get(index)

    @property
    def reference_width_m(self) -> float:
        ref = self.slots.get(self.reference_index)
        return ref.width_m if ref is not None else math.nan

    def offset_of(self, index: int, fallback_width_m: float) -> float:
        """Offset [m] of lane ``index``'s centre from the reference path (left +): the
        slot's own when known, else the half widths of the lanes in between."""
        slot = self.slots.get(index)
        if slot is not None and math.isfinite(slot.offset_m):
            return slot.offset_m
        ref = self.slots.get(self.reference_index)
        ref_off = ref.offset_m if ref is not None and math.isfinite(ref.offset_m) else 0.0
        step = 1 if index > self.reference_index else -1
        total = 0.0
        for i in range(self.reference_index, index, step):
            a, b = self.slots.get(i), self.slots.get(i + step)
            total += 0.5 * ((a.width_m if a else fallback_width_m)
                            + (b.width_m if b else fallback_width_m))
        return ref_off + step * total if index != self.reference_index else ref_off


@dataclass(frozen=True)
class EgoFrenet:
    """The ego as the behaviour sees it: CG in the world [m] and on the reference path
    (s_m, lat_m) [m], speed [m/s], and the run's time [s] (decisions hold for a while)."""

    x_m: float
    y_m: float
    s_m: float
    lat_m: float
    speed_mps: float
    t_s: float = 0.0


@dataclass(frozen=True)
class Obstacles:
    """Obstacle ellipses as the controller sees them, all arrays of shape (K,).

    Reference-path Frenet frame: centre ``(s_m, y_m)`` now (the offset OS already
    applied, away from the pass side), velocity ``(speed_s_mps, speed_y_mps)`` for the
    constant-velocity prediction s_j(tau) = s_m + speed_s_mps tau, semi-axes
    ``semi_a_m`` (along the path) and ``semi_b_m`` (across), ego allowance and
    margins included. ``vehicle_ids``: the vehicle behind each ellipse (K entries), or
    () when not known (the planner then re-identifies obstacles by position).
    ``half_length_m``: the box-sum half length a_j = (obstacle length + ego length) / 2
    [m] of each ellipse's vehicle (K entries), the centre distance at which the two
    boxes touch end to end; or an empty array when not known (then it is inferred from
    the semi-axes, which only holds for an ellipse built by ``ellipse_semi_axes`` and
    never reshaped: not for a followed lead's wall or a shrunk ellipse).
    ``accel_s_mps2``: each vehicle's estimated acceleration along the path [m/s²] (K
    entries; :mod:`controllers.behaviour.tracking`), or an empty array when not known:
    the braking an obstacle needs counts a lead's own braking
    (:func:`controllers.two_loop.fallback.most_urgent_obstacle`); the ellipses' motion
    stays the constant-velocity prediction.
    """

    s_m: FloatArray
    y_m: FloatArray
    speed_s_mps: FloatArray
    speed_y_mps: FloatArray
    semi_a_m: FloatArray
    semi_b_m: FloatArray
    vehicle_ids: tuple[str, ...] = ()
    half_length_m: FloatArray = field(default_factory=lambda: np.zeros(0))
    accel_s_mps2: FloatArray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self) -> None:
        if self.vehicle_ids and len(self.vehicle_ids) != self.count:
            raise ValueError(f"Obstacles.vehicle_ids must have {self.count} entries (or "
                             f"none), got {len(self.vehicle_ids)}")
        for name in ("half_length_m", "accel_s_mps2"):
            n = int(np.asarray(getattr(self, name)).shape[0])
            if n not in (0, self.count):
                raise ValueError(f"Obstacles.{name} must have {self.count} entries (or "
                                 f"none), got {n}")

    @staticmethod
    def empty() -> Obstacles:
        z = np.zeros(0)
        return Obstacles(z, z, z, z, z, z)

    @property
    def count(self) -> int:
        return int(self.s_m.shape[0])

    def ahead(self, tau_s: float) -> Obstacles:
        """The same ellipses ``tau_s`` [s] later by their own constant-velocity
        prediction: centres s + speed_s tau, y + speed_y tau; speeds, semi-axes, ids,
        half lengths and accelerations held (the controller's prediction over its
        horizon, started tau later). ``tau_s = 0`` or no obstacle: ``self``."""
        if tau_s == 0.0 or self.count == 0:
            return self
        return replace(self, s_m=self.s_m + self.speed_s_mps * tau_s,
                       y_m=self.y_m + self.speed_y_mps * tau_s)

    def around_ego(self, ego_s_m: float, ego_lat_m: float) -> Obstacles:
        """The same ellipses with every one that would contain the ego's CG at
        (``ego_s_m``, ``ego_lat_m``) [m] narrowed to leave it outside
        (:func:`controllers.behaviour.ellipse_fit.leave_ego_outside`; A not below the
        box-sum half length where known); ``self`` when none does."""
        a, b = self.semi_a_m.copy(), self.semi_b_m.copy()
        known = self.half_length_m.shape[0] == self.count
        narrowed = False
        for k in range(self.count):
            a_k, b_k = float(a[k]), float(b[k])
            a[k], b[k] = leave_ego_outside(
                ego_s_m - float(self.s_m[k]), ego_lat_m - float(self.y_m[k]), a_k, b_k,
                float(self.half_length_m[k]) if known else 0.0)
            # != as np.array_equal compared: a NaN semi-axis counts as changed
            narrowed = narrowed or a[k] != a_k or b[k] != b_k
        if not narrowed:
            return self
        return replace(self, semi_a_m=a, semi_b_m=b)


@dataclass(frozen=True)
class ObstaclePolicy:
    """How other vehicles become the controller's ellipses (docs/method.md §4).

    Semi-axes: the ellipse contains the box-sum rectangle of the obstacle and the ego
    (the point-mass planner is a point at the ego CG) plus margins, see
    :func:`controllers.behaviour.ellipses.ellipse_semi_axes`. Vehicles whose box centre
    is within ``detection_distance_m`` [m] of the ego CG and at most ``rear_range_m``
    [m] behind it enter the problem, nearest first, at most ``max_obstacles``.
    ``offset_m`` [m] shifts the ellipse away from the pass side; ``margin_long_m``,
    ``margin_lat_m`` [m] are the safety margins along and across the path.
    ``moving_obstacles`` feeds traffic with its speed (constant-velocity prediction);
    without it only stalled vehicles become obstacles.
    """

    detection_distance_m: float = field(default=100.0, metadata={
        "unit": "m", "doc": "a vehicle closer than this to the ego CG becomes an obstacle"})
    rear_range_m: float = field(default=10.0, metadata={
        "unit": "m", "doc": "and no more than this behind the ego CG"})
    margin_long_m: float = field(default=2.0, metadata={
        "unit": "m", "doc": "safety margin added to the ellipse along the path"})
    margin_lat_m: float = field(default=0.4, metadata={
        "unit": "m", "doc": "safety margin added to the ellipse across the path"})
    offset_m: float = field(default=0.3, metadata={
        "unit": "m", "doc": "ellipse centre shift away from the pass side"})
    max_obstacles: int = field(default=3, metadata={
        "unit": "-", "doc": "obstacle slots of the planner (nearest first)"})
    moving_obstacles: bool = field(default=True, metadata={
        "unit": "-", "doc": "moving traffic as obstacles (constant-velocity prediction)"})

    def __post_init__(self) -> None:
        require_numbers(self, ("detection_distance_m", "rear_range_m", "margin_long_m",
                               "margin_lat_m", "offset_m"))
        if isinstance(self.max_obstacles, bool) or not (
                isinstance(self.max_obstacles, int) and 0 <= self.max_obstacles <= 16):
            raise ValueError(
                f"ObstaclePolicy.max_obstacles must be an integer in [0, 16], "
                f"got {self.max_obstacles!r}")
        if not isinstance(self.moving_obstacles, bool):
            raise ValueError(f"ObstaclePolicy.moving_obstacles must be true or false, "
                             f"got {self.moving_obstacles!r}")


@dataclass(frozen=True)
class Decision:
    """The behaviour layer's output for one step.

    obstacles: the controller's ellipses (with the vehicle behind each: ``obstacle_ids``);
    side: :class:`Side` (LEFT / RIGHT pass, FOLLOW no side free, KEEP);
    reason_code: the kind of decision (:class:`Reason`), reason: why, as text (for logs
    and the trace); target_speed_mps: the speed set-point (lowered while
    following); lateral_reference_m: where the plan should settle across the reference
    path [m, left +] (the neighbour lane's centre while passing, 0 otherwise);
    evasive: the lane change under way evades a stopped vehicle the ego could not stop
    for at the comfortable deceleration (the controller may move sideways faster).
    """

    obstacles: Obstacles = field(default_factory=Obstacles.empty)
    side: Side = Side.KEEP
    reason: str = ""
    target_speed_mps: float = math.nan
    lateral_reference_m: float = 0.0
    evasive: bool = False
    reason_code: Reason = Reason.NONE
    # (relative target lane, check) of every lane change this decision weighed, in order
    lane_checks: tuple[tuple[int, LaneCheck], ...] = ()

    def __post_init__(self) -> None:
        # Side(...) / Reason(...) raise ValueError for a value that is none of theirs
        object.__setattr__(self, "side", Side(self.side))
        object.__setattr__(self, "reason_code", Reason(self.reason_code))

    @property
    def obstacle_ids(self) -> tuple[str, ...]:
        """The vehicle behind each ellipse (() when the obstacles carry no ids)."""
        return self.obstacles.vehicle_ids

    def lane_check(self, rel_lane: int) -> LaneCheck | None:
        """The last check of a change into relative lane ``rel_lane`` (+1 left, -1 right)
        this decision weighed; None when it weighed none."""
        found = [check for lane, check in self.lane_checks if lane == rel_lane]
        return found[-1] if found else None

    @property
    def pass_side(self) -> int:
        """+1 / -1 when passing on that side, else 0 (the controller's view)."""
        return self.side.pass_side

    def ahead(self, tau_s: float, ego_s_m: float, ego_lat_m: float) -> Decision:
        """This decision ``tau_s`` [s] after it was taken, before the next scene, for the
        ego's CG now at (``ego_s_m``, ``ego_lat_m``) [m]: the obstacles moved by their
        constant-velocity prediction (:meth:`Obstacles.ahead`) and narrowed where the ego
        has moved into one (:func:`controllers.behaviour.ellipse_fit.leave_ego_outside`,
        as the behaviour does when it decides), everything else held. What the loop hands
        the controller between two decisions."""
        if tau_s == 0.0 or self.obstacles.count == 0:
            return self
        return replace(self, obstacles=self.obstacles.ahead(tau_s).around_ego(ego_s_m,
                                                                             ego_lat_m))
