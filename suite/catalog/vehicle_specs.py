"""The specs of the vehicles on the road at the start (:mod:`suite.catalog.specs`): the
ego (:class:`EgoSpec`), stalled cars (:class:`StalledSpec`), SUMO's traffic on the main
road (:class:`TrafficSpec`) and from the on-ramps (:class:`RampTrafficSpec`). Each checks
its own fields on construction (``_RULES``)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any, ClassVar

from suite.catalog import rules
from suite.catalog.errors import SpecError
from suite.catalog.frozen import FrozenMap, thaw
from suite.catalog.rules import Rule


def _plain_dataclass(obj: Any) -> dict[str, Any]:
    return {f.name: thaw(getattr(obj, f.name)) for f in fields(obj)}


MAX_EGO_LATERAL_OFFSET_M = 5.0
"""An ego start further than this [m] from its lane's centre line is in another lane:
``ego.lane`` says which."""


MAX_EGO_HEADING_RAD = 0.5 * math.pi
"""An ego start must point along its lane: less than this [rad] from its direction."""


def _lateral_offset(v: Any) -> str | None:
    """None (unset), or a finite offset [m] of at most MAX_EGO_LATERAL_OFFSET_M."""
    if v is None or (rules.is_number(v) and abs(v) <= MAX_EGO_LATERAL_OFFSET_M):
        return None
    return (f"a finite number in [-{MAX_EGO_LATERAL_OFFSET_M:g}, "
            f"{MAX_EGO_LATERAL_OFFSET_M:g}] (m left of the lane's centre line; further is "
            "another lane: set ego.lane)")


def _heading(v: Any) -> str | None:
    """None (unset), or a finite angle [rad] of magnitude below MAX_EGO_HEADING_RAD."""
    if v is None or (rules.is_number(v) and abs(v) < MAX_EGO_HEADING_RAD):
        return None
    return (f"a finite number in (-{MAX_EGO_HEADING_RAD:.4f}, {MAX_EGO_HEADING_RAD:.4f}) "
            "(rad from the lane's direction, counter-clockwise +: the ego points along "
            "its lane)")


@dataclass(frozen=True)
class EgoSpec:
    """Ego start: lane index (0 = rightmost), route position, speed, cruise set-point.

    ``target_speed_mps`` defaults to ``speed_mps`` (NaN on input means "unset").

    ``lateral_offset_m`` [m, left +] and ``heading_rad`` [rad, counter-clockwise +]: the
    start pose in the lane's own frame (:mod:`suite.road.lane_pose`): the front bumper's
    centre lies ``lateral_offset_m`` left of lane ``lane``'s centre line at route
    position ``pos_m``, the ego heads ``heading_rad`` from the lane's direction there (a
    recorded ego mid lane change). ``None`` (unset, both): the run starts the ego on its
    reference path as it always did; one of them set, the other is 0.
    """

    lane: int
    pos_m: float
    speed_mps: float
    target_speed_mps: float = math.nan
    lateral_offset_m: float | None = None
    heading_rad: float | None = None

    _RULES: ClassVar[dict[str, Rule]] = {
        "lane": rules.integer(0), "pos_m": rules.num(0.0), "speed_mps": rules.num(0.0),
        "target_speed_mps": rules.num(0.0), "lateral_offset_m": _lateral_offset,
        "heading_rad": _heading,
    }
    _REQUIRED: ClassVar[tuple[str, ...]] = ("lane", "pos_m", "speed_mps")
    _POSE: ClassVar[tuple[str, ...]] = ("lateral_offset_m", "heading_rad")

    def __post_init__(self) -> None:
        if isinstance(self.target_speed_mps, float) and math.isnan(self.target_speed_mps):
            object.__setattr__(self, "target_speed_mps", self.speed_mps)
        rules.check_fields(self)
        rules.as_float(self, "pos_m", "speed_mps", "target_speed_mps",
                       *(k for k in self._POSE if getattr(self, k) is not None))

    @property
    def start_pose(self) -> tuple[float, float] | None:
        """(lateral_offset_m, heading_rad) when either is set (the other 0), else
        ``None``: the ego starts on its reference path."""
        if self.lateral_offset_m is None and self.heading_rad is None:
            return None
        return (float(self.lateral_offset_m or 0.0), float(self.heading_rad or 0.0))

    def as_dict(self) -> dict[str, Any]:
        """Every field, the start-pose keys only when set (a scenario without them keeps
        the dict, and the identity, it had)."""
        return {k: v for k, v in _plain_dataclass(self).items()
                if not (k in self._POSE and v is None)}


@dataclass(frozen=True)
class StalledSpec:
    """A stopped vehicle at route position ``pos_m`` on lane ``lane``."""

    lane: int
    pos_m: float
    length_m: float = 4.8
    width_m: float = 1.9

    _RULES: ClassVar[dict[str, Rule]] = {
        "lane": rules.integer(0), "pos_m": rules.num(0.0),
        "length_m": rules.num(0.0, strict=True), "width_m": rules.num(0.0, strict=True),
    }
    _REQUIRED: ClassVar[tuple[str, ...]] = ("lane", "pos_m")

    def __post_init__(self) -> None:
        rules.check_fields(self)
        rules.as_float(self, "pos_m", "length_m", "width_m")


@dataclass(frozen=True)
class TrafficSpec:
    """Background traffic. ``lanes`` None = every lane admitting passenger cars;
    ``speed_mps`` None = the lane speed limit; ``speed_factor_dev`` = SUMO speedDev;
    ``lane_speeds_mps`` (lane index of the first route edge -> speed [m/s]): the traffic
    of those lanes drives at most that fast and keeps its lane (None: no lane has its own
    speed). Its keys are kept as canonical decimal strings (``"2"``), as TOML and JSON
    write them; :meth:`lane_speed_mps` and :meth:`own_speed_lanes` take and give ints."""

    vehicles_per_hour: float
    seed: int
    speed_mps: float | None = None
    lanes: tuple[int, ...] | None = None
    speed_factor_dev: float = 0.1
    lane_speeds_mps: Mapping[str, float] | None = None

    _RULES: ClassVar[dict[str, Rule]] = {
        "vehicles_per_hour": rules.num(0.0), "seed": rules.integer(0, rules.MAX_SEED),
        "speed_mps": rules.num(0.0, strict=True, optional=True), "lanes": rules.lanes,
        "speed_factor_dev": rules.num(0.0), "lane_speeds_mps": rules.lane_speeds,
    }
    _REQUIRED: ClassVar[tuple[str, ...]] = ("vehicles_per_hour",)

    def __post_init__(self) -> None:
        rules.check_fields(self)
        if self.lanes is not None:
            object.__setattr__(self, "lanes", tuple(self.lanes))
        rules.as_float(self, "vehicles_per_hour", "speed_factor_dev")
        if self.speed_mps is not None:
            rules.as_float(self, "speed_mps")
        if self.lane_speeds_mps is not None:
            speeds = {rules.lane_key(k): float(v) for k, v in self.lane_speeds_mps.items()}
            if len(speeds) != len(self.lane_speeds_mps):
                raise SpecError("lane_speeds_mps", "distinct lane indices",
                                dict(self.lane_speeds_mps))
            object.__setattr__(self, "lane_speeds_mps", FrozenMap(
                (str(lane), speed) for lane, speed in sorted(
                    (int(lane or 0), speed) for lane, speed in speeds.items())))

    def own_speed_lanes(self) -> tuple[int, ...]:
        """The lanes with their own traffic speed, ascending."""
        return tuple(int(k) for k in self.lane_speeds_mps or {})

    def lane_speed_mps(self, lane: int) -> float | None:
        """The lane's own traffic speed [m/s], None if it has none."""
        if self.lane_speeds_mps is None:
            return None
        speed = self.lane_speeds_mps.get(str(lane))
        return None if speed is None else float(speed)


@dataclass(frozen=True)
class RampTrafficSpec:
    """Traffic entering the route from ``edge``, an edge off the route (an on-ramp):
    a Poisson flow of ``vehicles_per_hour`` that drives from ``edge`` onto the route and
    along it to its end, plus cars spread over the ramp at t = 0. ``speed_mps``: their
    speed (departure and maximum) [m/s]; None = the lanes' limits."""

    edge: str
    vehicles_per_hour: float
    speed_mps: float | None = None

    _RULES: ClassVar[dict[str, Rule]] = {
        "edge": rules.edge_id, "vehicles_per_hour": rules.num(0.0),
        "speed_mps": rules.num(0.0, strict=True, optional=True),
    }
    _REQUIRED: ClassVar[tuple[str, ...]] = ("edge", "vehicles_per_hour")

    def __post_init__(self) -> None:
        rules.check_fields(self)
        rules.as_float(self, "vehicles_per_hour")
        if self.speed_mps is not None:
            rules.as_float(self, "speed_mps")
