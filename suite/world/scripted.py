"""A scripted, plant-only World (no SUMO): a reference road, lanes beside it, and
vehicles that are pure functions of time.

The road is the reference path (a straight or curved polyline, the Frenet frame of
:class:`~controllers.path.frenet.FrenetPath`) with ``lane_count`` parallel lanes of
``lane_width_m``; lane ``i`` (0 = rightmost) has its centre at the offset

    y_i = (i - reference_lane) * lane_width_m                               [m, left +]

so the reference path is the centre of ``reference_lane``. A :class:`ScriptedVehicle`
drives its lane at a constant speed v along the path:

    s(t) = s_0 + v t,   y(t) = y_lane + offset_m                           [m]

(v = 0: a stalled car), from t = 0 until ``leaves_at_s`` (then it is no longer in the
scene, as a vehicle SUMO removes). Every step the vehicles become the same typed
:class:`~controllers.behaviour.types.Traffic` the SUMO world gives (box centre in the
world frame, heading along the path tangent, speed, box size, lane index on the one
road ``ROAD_ID``), so production's behaviour, safety monitor and recorder run
unchanged on it; :meth:`ScriptedRoad.lanes` is the matching
:class:`~controllers.behaviour.types.LaneContext` (the loop's lane source).

The world does not move the ego: the loop's plant does (``start`` / ``step`` take its
pose, as SUMO takes an externally driven ego's).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from controllers.behaviour.types import LaneContext, LaneSlot, Traffic
from controllers.path.frenet import FrenetPath
from suite.world.protocol import EgoPose, Scene, WorldEgo, WorldSummary

FloatArray = npt.NDArray[np.float64]
ROAD_ID = "scripted"


def _finite(owner: str, **values: float) -> None:
    for name, v in values.items():
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise ValueError(f"{owner}.{name} must be a finite number, got {v!r}")


@dataclass(frozen=True)
class ScriptedRoad:
    """The reference polyline (M, 2) [m] and the lanes beside it: ``lane_count`` lanes of
    ``lane_width_m`` [m], the reference path on the centre of ``reference_lane``."""

    reference_xy_m: FloatArray
    lane_count: int = 1
    reference_lane: int = 0
    lane_width_m: float = 3.5

    def __post_init__(self) -> None:
        ref = np.asarray(self.reference_xy_m, dtype=np.float64)
        if ref.ndim != 2 or ref.shape[1] != 2 or ref.shape[0] < 2 or not np.all(np.isfinite(ref)):
            raise ValueError(f"ScriptedRoad.reference_xy_m must be a finite (M>=2, 2) array, "
                             f"got shape {ref.shape}")
        object.__setattr__(self, "reference_xy_m", ref)
        if isinstance(self.lane_count, bool) or not isinstance(self.lane_count, int) \
                or self.lane_count < 1:
            raise ValueError(f"ScriptedRoad.lane_count must be an integer >= 1, "
                             f"got {self.lane_count!r}")
        if not (isinstance(self.reference_lane, int) and 0 <= self.reference_lane
                < self.lane_count):
            raise ValueError(f"ScriptedRoad.reference_lane must be in [0, {self.lane_count}), "
                             f"got {self.reference_lane!r}")
        _finite("ScriptedRoad", lane_width_m=self.lane_width_m)
        if self.lane_width_m <= 0.0:
            raise ValueError(f"ScriptedRoad.lane_width_m must be > 0, got {self.lane_width_m}")

    def lane_offset_m(self, lane: int) -> float:
        """y_i [m, left +] of lane ``lane``'s centre from the reference path."""
        return (lane - self.reference_lane) * self.lane_width_m

    def lanes(self) -> LaneContext:
        """The lane context everywhere on the road (no lane ends, no shoulder)."""
        slots = {i: LaneSlot(i, self.lane_width_m, True, False, self.lane_offset_m(i))
                 for i in range(self.lane_count)}
        return LaneContext(slots, self.reference_lane, {ROAD_ID: self.reference_lane})

    def at(self, s_m: float) -> LaneContext:
        """The loop's lane source: the same lanes at every ``s_m``."""
        del s_m
        return self._context

    @property
    def _context(self) -> LaneContext:
        cached: LaneContext | None = self.__dict__.get("_lanes")
        if cached is None:
            cached = self.lanes()
            object.__setattr__(self, "_lanes", cached)
        return cached


@dataclass(frozen=True)
class ScriptedVehicle:
    """Another vehicle: id, centre at ``s_m`` [m] along the path at t = 0 in lane ``lane``
    (``offset_m`` [m, left +] off its centre), constant speed ``speed_mps`` [m/s] along
    the path (0: stalled), box ``length_m`` x ``width_m`` [m], in the scene until
    ``leaves_at_s`` [s] (inf: the whole run)."""

    id: str
    s_m: float
    lane: int = 0
    speed_mps: float = 0.0
    length_m: float = 4.8
    width_m: float = 1.9
    offset_m: float = 0.0
    leaves_at_s: float = math.inf

    def __post_init__(self) -> None:
        if not self.id:
            raise ValueError("ScriptedVehicle.id must not be empty")
        _finite("ScriptedVehicle", s_m=self.s_m, speed_mps=self.speed_mps,
                length_m=self.length_m, width_m=self.width_m, offset_m=self.offset_m)
        if self.length_m <= 0.0 or self.width_m <= 0.0 or self.speed_mps < 0.0:
            raise ValueError(f"ScriptedVehicle {self.id}: box sizes must be > 0 and the "
                             f"speed >= 0, got {self.length_m}, {self.width_m}, "
                             f"{self.speed_mps}")
        if isinstance(self.lane, bool) or not isinstance(self.lane, int):
            raise ValueError(f"ScriptedVehicle.lane must be an integer, got {self.lane!r}")
        if math.isnan(self.leaves_at_s) or self.leaves_at_s < 0.0:
            raise ValueError(f"ScriptedVehicle.leaves_at_s must be >= 0, got "
                             f"{self.leaves_at_s!r}")


@dataclass(frozen=True)
class FrenetTracks:
    """The vehicles on the path at given times, arrays (K, n): centre s_m, y_m [m] and
    present (False once a vehicle has left; its s_m, y_m are then NaN)."""

    s_m: FloatArray
    y_m: FloatArray
    present: npt.NDArray[np.bool_]


@dataclass
class ScriptedWorld:
    """The :class:`~suite.world.protocol.World` of the module docstring, one run;
    ``step_s`` [s] is the loop's period (the world's clock advances by it per step)."""

    road: ScriptedRoad
    vehicles: tuple[ScriptedVehicle, ...] = ()
    step_s: float = 0.02
    _step: int = field(default=0, init=False)
    _path: FrenetPath = field(init=False)
    _last_pose: EgoPose | None = field(default=None, init=False)

    def __post_init__(self) -> None:
        _finite("ScriptedWorld", step_s=self.step_s)
        if self.step_s <= 0.0:
            raise ValueError(f"ScriptedWorld.step_s must be > 0, got {self.step_s}")
        ids = [v.id for v in self.vehicles]
        if len(set(ids)) != len(ids):
            raise ValueError(f"ScriptedWorld: vehicle ids must be unique, got {ids}")
        for v in self.vehicles:
            if not 0 <= v.lane < self.road.lane_count:
                raise ValueError(f"ScriptedVehicle {v.id}: lane {v.lane} is not one of the "
                                 f"road's {self.road.lane_count}")
        self._path = FrenetPath.cached(self.road.reference_xy_m)

    def tracks(self, t_s: FloatArray) -> FrenetTracks:
        """Where the vehicles are at times ``t_s`` (K,) [s] (the module's s(t), y(t))."""
        t = np.asarray(t_s, dtype=np.float64)[:, None]
        n = len(self.vehicles)
        s0 = np.array([v.s_m for v in self.vehicles]).reshape(1, n)
        v = np.array([v.speed_mps for v in self.vehicles]).reshape(1, n)
        y0 = np.array([self.road.lane_offset_m(v.lane) + v.offset_m
                       for v in self.vehicles]).reshape(1, n)
        leaves = np.array([v.leaves_at_s for v in self.vehicles]).reshape(1, n)
        present = np.broadcast_to(t < leaves, (t.shape[0], n)).copy()
        s = np.where(present, s0 + v * t, np.nan)
        y = np.where(present, np.broadcast_to(y0, s.shape), np.nan)
        return FrenetTracks(s, y, present)

    def traffic_at(self, t_s: float) -> Traffic:
        """The vehicles at ``t_s`` [s] as world-frame Traffic (only those present)."""
        keep = [v for v in self.vehicles if t_s < v.leaves_at_s]
        if not keep:
            return Traffic.empty()
        s = np.array([v.s_m + v.speed_mps * t_s for v in keep])
        y = np.array([self.road.lane_offset_m(v.lane) + v.offset_m for v in keep])
        x_w, y_w = self._path.to_global(s, y)
        speed = np.array([v.speed_mps for v in keep])
        n = len(keep)
        return Traffic(ids=tuple(v.id for v in keep), x_m=np.asarray(x_w, dtype=np.float64),
                       y_m=np.asarray(y_w, dtype=np.float64),
                       heading_rad=np.asarray(self._path.gamma(s), dtype=np.float64),
                       speed_mps=speed, length_m=np.array([v.length_m for v in keep]),
                       width_m=np.array([v.width_m for v in keep]),
                       lane_index=np.array([v.lane for v in keep], dtype=np.int64),
                       road_id=(ROAD_ID,) * n, stalled=speed == 0.0)

    def _scene(self, pose: EgoPose | None) -> Scene:
        t_s = self._step * self.step_s
        ego = None
        if pose is not None:
            speed = math.nan
            if self._last_pose is not None:
                speed = math.hypot(pose.front_x_m - self._last_pose.front_x_m,
                                   pose.front_y_m - self._last_pose.front_y_m) / self.step_s
            s, y = self._path.project(pose.front_x_m, pose.front_y_m)
            lane = int(np.clip(round(float(y) / self.road.lane_width_m)
                               + self.road.reference_lane, 0, self.road.lane_count - 1))
            ego = WorldEgo(pose.front_x_m, pose.front_y_m, pose.heading_rad, speed, math.nan,
                           lane, ROAD_ID, float(self._path.gamma(float(s))))
            self._last_pose = pose
        return Scene(t_s, self.traffic_at(t_s), ego)

    def start(self, ego_pose: EgoPose | None) -> Scene:
        self._step = 0
        self._last_pose = None
        return self._scene(ego_pose)

    def step(self, ego_pose: EgoPose | None) -> Scene:
        self._step += 1
        return self._scene(ego_pose)

    def close(self) -> WorldSummary:
        return WorldSummary()
