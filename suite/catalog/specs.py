"""The resolved, validated values a catalog yields: the specs of one scenario run
(:class:`EgoSpec`, :class:`StalledSpec`, :class:`ActorSpec` with its
:class:`ActorEventSpec`, :class:`TrafficSpec`, :class:`RampTrafficSpec`,
:class:`ReplaySpec`, :class:`ControllerSpec`),
the :class:`Scenario` itself and the :class:`Catalog` of them.

Each spec checks its own fields on construction (``_RULES``) and raises
:class:`~suite.catalog.errors.SpecError`; the loader checks raw values with the same rules
first, so that a catalog reports all of its problems.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, ClassVar

from suite.catalog import rules
from suite.catalog.actors import ActorEventSpec, ActorSpec, ActorWhenSpec
from suite.catalog.errors import SpecError
from suite.catalog.frozen import FrozenMap, thaw, thaw_map
from suite.catalog.rules import Rule
from suite.catalog.storyboard import Storyboard
from suite.catalog.tracks import TRACK_ID_PREFIX

__all__ = ["REPLAY_LANE_CHANGES", "REPLAY_MODES", "ActorEventSpec", "ActorSpec",
           "ActorWhenSpec", "Catalog",
           "ControllerSpec", "EgoSpec", "RampTrafficSpec", "ReplaySpec", "Scenario",
           "StalledSpec", "TrafficSpec", "XfailSpec", "default_sumo_step", "sumo_step_problem"]

DEFAULT_SUMO_STEP_S = 0.1  # SUMO's own step by default: the field's usual 10 Hz


def _ticks(t_s: float) -> int:
    """``t_s`` in SUMO's milliseconds (the catalog's steps are whole milliseconds)."""
    return int(round(t_s / rules.SUMO_TICK_S))


def default_sumo_step(step_s: float) -> float:
    """SUMO's step [s] when the catalog sets none: the largest whole multiple of ``step_s``
    [s] that is at most 0.1 s (``step_s`` itself when that is longer), in whole ms."""
    ticks = max(_ticks(step_s), 1)
    return max(_ticks(DEFAULT_SUMO_STEP_S) // ticks, 1) * ticks * rules.SUMO_TICK_S


def sumo_step_problem(sumo_step_s: Any, step_s: float) -> str | None:
    """Why ``sumo_step_s`` is no SUMO step for control period ``step_s`` (None: it is):
    a whole number of ms and a whole multiple (>= 1) of ``step_s``."""
    problem = rules.sumo_step(sumo_step_s)
    if problem:
        return problem
    ticks, base = _ticks(float(sumo_step_s)), max(_ticks(step_s), 1)
    if ticks < base or ticks % base:
        return f"a whole multiple (1, 2, ...) of step_s = {step_s:g} s"
    return None


def _optional_sumo_step(v: Any) -> str | None:
    return None if v is None else rules.sumo_step(v)


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


REPLAY_MODES = ("replay", "reactive")
# Lane changes of a reactive (handed-over) recorded vehicle -> SUMO lane-change mode:
# none at all, only those its route needs (where a lane ends), or SUMO's default set.
REPLAY_LANE_CHANGES: Mapping[str, int] = FrozenMap({"none": 0, "strategic": 1, "all": 1621})


def _choice(options: tuple[str, ...]) -> Rule:
    what = f"one of {list(options)}"

    def check(v: Any) -> str | None:
        return None if isinstance(v, str) and v in options else what

    return check


def _tracks_name(v: Any) -> str | None:
    problem = rules.nameable_path(v)
    if not isinstance(v, str) or not v:
        return "a tracks file path (Parquet, suite.catalog.tracks), relative to the catalog"
    return problem


def _ego_track_id(v: Any) -> str | None:
    """None (no recorded ego), or a track id as the tracks file has them."""
    if v is None or (isinstance(v, str) and v.startswith(TRACK_ID_PREFIX)
                     and len(v) > len(TRACK_ID_PREFIX)):
        return None
    return (f"the id of the recorded ego's track in the tracks file "
            f"('{TRACK_ID_PREFIX}<id in the recording>')")


@dataclass(frozen=True)
class ReplaySpec:
    """Recorded traffic around the ego (:mod:`suite.world.replay`, docs/replay.md).

    ``tracks``: the tracks file (:mod:`suite.catalog.tracks`) as the catalog names it,
    relative to the catalog file (or absolute); ``tracks_path`` its resolved path (set by
    the loader; ``None`` until then). ``mode``: ``"replay"`` (every recorded vehicle
    follows its recording, blind to the ego) or ``"reactive"`` (a recorded vehicle hands
    over to SUMO's car-following driver once its time gap behind the ego, gap / its speed
    [s], is below ``handover_time_gap_s`` [s] (> 0) with the ego in its lane or about to
    be, or whenever it is behind the ego in the ego's lane). ``lane_changes``: what a
    handed-over vehicle may change lanes for: ``"none"``, ``"strategic"`` (only to stay
    on its route) or ``"all"`` (SUMO's default lane-change model).

    ``ego_track``: the id of the ego's own recorded track in the tracks file (None: the
    recording has no recorded ego). That track is never replayed as traffic (it would
    sit on the ego); the controller ``recorded`` drives the ego along it. The loader
    checks it exists, has two samples or more and starts at run time 0
    (:func:`suite.catalog.tracks.ego_track_problem`)."""

    tracks: str
    mode: str = "replay"
    handover_time_gap_s: float = 1.0
    lane_changes: str = "strategic"
    tracks_path: Path | None = None
    ego_track: str | None = None

    _RULES: ClassVar[dict[str, Rule]] = {
        "tracks": _tracks_name, "mode": _choice(REPLAY_MODES),
        "handover_time_gap_s": rules.num(0.0, strict=True),
        "lane_changes": _choice(tuple(REPLAY_LANE_CHANGES)),
        "ego_track": _ego_track_id,
    }
    _REQUIRED: ClassVar[tuple[str, ...]] = ("tracks",)

    def __post_init__(self) -> None:
        rules.check_fields(self)
        rules.as_float(self, "handover_time_gap_s")
        if self.tracks_path is not None:
            object.__setattr__(self, "tracks_path", Path(self.tracks_path))

    @property
    def reactive(self) -> bool:
        return self.mode == "reactive"

    @property
    def lane_change_mode(self) -> int:
        """SUMO's lane-change mode of a handed-over vehicle (``REPLAY_LANE_CHANGES``)."""
        return int(REPLAY_LANE_CHANGES[self.lane_changes])

    def as_dict(self) -> dict[str, Any]:
        """The catalog's keys (``tracks_path`` is machine-specific, as ``net_path``;
        ``ego_track`` only when set, so that a scenario without a recorded ego keeps the
        dict, and the identity, it had)."""
        out: dict[str, Any] = {"tracks": self.tracks, "mode": self.mode,
                               "handover_time_gap_s": self.handover_time_gap_s,
                               "lane_changes": self.lane_changes}
        if self.ego_track is not None:
            out["ego_track"] = self.ego_track
        return out


@dataclass(frozen=True)
class ControllerSpec:
    """A registered controller and its (immutable, JSON-able) options."""

    name: str
    options: Mapping[str, Any] = field(default_factory=lambda: FrozenMap())

    def __post_init__(self) -> None:
        if rules.name_rule(self.name):
            raise SpecError("name", "a controller name matching [a-z0-9_]+", self.name)
        if not isinstance(self.options, Mapping):
            raise SpecError("options", "a table of options", self.options)
        bad = rules.non_json_path(self.options)
        if bad is not None:
            raise SpecError(bad[0] or "options", "a JSON-able value (string, number, bool, "
                            "list, table)", bad[1])
        if not isinstance(self.options, FrozenMap):
            object.__setattr__(self, "options", FrozenMap(copy.deepcopy(dict(self.options))))

    def options_dict(self) -> dict[str, Any]:
        """A deep, mutable copy of the options (what the factory gets)."""
        return thaw_map(self.options)

    def as_dict(self) -> dict[str, Any]:
        return {"name": self.name, "options": self.options_dict()}


# ---------------------------------------------------------------- known failures (xfail)


def _reason(v: Any) -> str | None:
    return None if isinstance(v, str) and v.strip() else "a non-empty string: why it fails"


@dataclass(frozen=True)
class XfailSpec:
    """A known failure (pytest's ``xfail``; :mod:`reports.expectation`): the scenario is
    expected to fail its criteria, for ``reason``; with ``strict`` an unexpected pass
    fails the night. It is no part of the test: it changes what a result means, not the
    run."""

    reason: str
    strict: bool = False

    _RULES: ClassVar[dict[str, Rule]] = {"reason": _reason, "strict": rules.boolean}
    _REQUIRED: ClassVar[tuple[str, ...]] = ("reason",)

    def __post_init__(self) -> None:
        rules.check_fields(self)


# ---------------------------------------------------------------- criteria

CRITERION_OFF = "off"  # reports.metrics.criteria.OFF: switches a criterion off


def _criteria_map(v: Any) -> str | None:
    """A table of criterion name -> finite number or "off"."""
    what = 'a table of name -> finite number or "off"'
    if not isinstance(v, Mapping):
        return what
    if any(not isinstance(k, str) or not (rules.is_number(x) or x == CRITERION_OFF)
           for k, x in v.items()):
        return what
    return None


@dataclass(frozen=True)
class Scenario:
    """One fully resolved, validated scenario run."""

    name: str
    family: str
    catalog_path: Path
    net: str
    net_path: Path
    route: tuple[str, ...]
    ego: EgoSpec
    stalled: tuple[StalledSpec, ...]
    traffic: TrafficSpec | None
    controller: ControllerSpec
    duration_s: float
    step_s: float
    seed: int
    allow_shoulder: bool = False
    criteria: Mapping[str, float | str] = field(default_factory=lambda: FrozenMap())
    sweep_values: Mapping[str, Any] = field(default_factory=lambda: FrozenMap())
    record_radius_m: float = 150.0
    timeout_s: float | None = None
    friction: float = 1.0
    ramp_traffic: tuple[RampTrafficSpec, ...] = ()
    actors: tuple[ActorSpec, ...] = ()
    sumo_step_s: float | None = None  # SUMO's step [s]; None: default_sumo_step(step_s)
    replay: ReplaySpec | None = None  # recorded traffic (suite.world.replay); None: none
    xfail: XfailSpec | None = None  # a known failure; None: expected to pass
    # an OpenSCENARIO storyboard (suite.catalog.storyboard, docs/openscenario.md): the
    # file as the catalog names it and its resolved content; None: none
    storyboard: str | None = None
    story: Storyboard | None = None

    _RULES: ClassVar[dict[str, Rule]] = {
        "name": rules.name_rule, "family": rules.name_rule,
        "duration_s": rules.num(0.0, strict=True), "step_s": rules.sumo_step,
        "seed": rules.integer(0, rules.MAX_SEED), "allow_shoulder": rules.boolean,
        "criteria": _criteria_map, "record_radius_m": rules.num(0.0, strict=True),
        "timeout_s": rules.num(0.0, strict=True, optional=True), "friction": rules.friction,
        "sumo_step_s": _optional_sumo_step,
    }

    def __post_init__(self) -> None:
        rules.check_fields(self)
        if self.step_s > self.duration_s:
            raise SpecError("step_s", f"a step <= duration_s ({self.duration_s})", self.step_s)
        if self.sumo_step_s is None:
            object.__setattr__(self, "sumo_step_s", default_sumo_step(float(self.step_s)))
        problem = sumo_step_problem(self.sumo_step_s, float(self.step_s))
        if problem:
            raise SpecError("sumo_step_s", problem, self.sumo_step_s)
        object.__setattr__(self, "sumo_step_s", float(self.sumo_step_s))  # type: ignore[arg-type]
        if not isinstance(self.ego, EgoSpec):
            raise SpecError("ego", "an EgoSpec", self.ego)
        if not isinstance(self.controller, ControllerSpec):
            raise SpecError("controller", "a ControllerSpec", self.controller)
        if self.traffic is not None and not isinstance(self.traffic, TrafficSpec):
            raise SpecError("traffic", "a TrafficSpec or None", self.traffic)
        if self.replay is not None and not isinstance(self.replay, ReplaySpec):
            raise SpecError("replay", "a ReplaySpec or None", self.replay)
        if self.xfail is not None and not isinstance(self.xfail, XfailSpec):
            raise SpecError("xfail", "an XfailSpec or None", self.xfail)
        _check_story(self.storyboard, self.story)
        stalled = tuple(self.stalled)
        if any(not isinstance(s, StalledSpec) for s in stalled):
            raise SpecError("stalled", "a sequence of StalledSpec", self.stalled)
        ramps = tuple(self.ramp_traffic)
        if any(not isinstance(r, RampTrafficSpec) for r in ramps):
            raise SpecError("ramp_traffic", "a sequence of RampTrafficSpec", self.ramp_traffic)
        object.__setattr__(self, "ramp_traffic", ramps)
        actors = tuple(self.actors)
        if any(not isinstance(a, ActorSpec) for a in actors):
            raise SpecError("actors", "a sequence of ActorSpec", self.actors)
        ids = [a.id for a in actors]
        if len(set(ids)) != len(ids):
            raise SpecError("actors", "actors with distinct ids", ids)
        object.__setattr__(self, "actors", actors)
        route = tuple(self.route)
        if not route or any(not isinstance(e, str) for e in route):
            raise SpecError("route", "a non-empty sequence of edge ids", self.route)
        object.__setattr__(self, "stalled", stalled)
        object.__setattr__(self, "route", route)
        object.__setattr__(self, "catalog_path", Path(self.catalog_path))
        object.__setattr__(self, "net_path", Path(self.net_path))
        object.__setattr__(self, "criteria", FrozenMap(
            {k: (v if v == CRITERION_OFF else float(v)) for k, v in self.criteria.items()}))
        object.__setattr__(self, "sweep_values", FrozenMap(self.sweep_values))
        rules.as_float(self, "duration_s", "step_s", "record_radius_m", "friction")
        if self.timeout_s is not None:
            rules.as_float(self, "timeout_s")

    @property
    def steps(self) -> int:
        """Number of simulation steps (``round(duration_s / step_s)``)."""
        return int(round(self.duration_s / self.step_s))

    @property
    def world_step_s(self) -> float:
        """SUMO's step [s] (``sumo_step_s``, resolved in ``__post_init__``)."""
        return float(self.sumo_step_s if self.sumo_step_s is not None else self.step_s)

    @property
    def steps_per_world_step(self) -> int:
        """Control steps per SUMO step (``sumo_step_s / step_s``, a whole number >= 1)."""
        return max(_ticks(self.world_step_s) // max(_ticks(self.step_s), 1), 1)

    def as_dict(self) -> dict[str, Any]:
        """JSON-serialisable dict of every field (``replay`` only when set, so that a
        scenario without recorded traffic keeps the dict, and the identity, it had)."""
        out = self._as_dict()
        if self.replay is not None:
            out["replay"] = self.replay.as_dict()
        if self.xfail is not None:  # likewise: an unmarked scenario keeps its identity
            out["xfail"] = _plain_dataclass(self.xfail)
        if self.story is not None:  # likewise; its content, not only its file name
            from suite.catalog.storyboard import story_to_json

            out["storyboard"] = {"file": self.storyboard,
                                 "sha256": _sha256(story_to_json(self.story))}
        return out

    def _as_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "family": self.family,
            "catalog_path": str(self.catalog_path),
            "net": self.net,
            "net_path": str(self.net_path),
            "route": list(self.route),
            "ego": self.ego.as_dict(),
            "stalled": [_plain_dataclass(s) for s in self.stalled],
            "traffic": None if self.traffic is None else _plain_dataclass(self.traffic),
            "controller": self.controller.as_dict(),
            "duration_s": self.duration_s,
            "step_s": self.step_s,
            "sumo_step_s": self.sumo_step_s,
            "seed": self.seed,
            "allow_shoulder": self.allow_shoulder,
            "criteria": thaw(self.criteria),
            "sweep_values": thaw(self.sweep_values),
            "record_radius_m": self.record_radius_m,
            "timeout_s": self.timeout_s,
            "friction": self.friction,
            "ramp_traffic": [_plain_dataclass(r) for r in self.ramp_traffic],
            "actors": [a.as_dict() for a in self.actors],
        }


def _check_story(storyboard: str | None, story: Storyboard | None) -> None:
    """A storyboard file name and its :class:`Storyboard`, or neither."""
    if (storyboard is None) != (story is None) or (
            story is not None and not isinstance(story, Storyboard)):
        raise SpecError("storyboard", "a storyboard file and its Storyboard, or neither",
                        storyboard)


def _sha256(text: str) -> str:
    import hashlib

    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _plain_dataclass(obj: Any) -> dict[str, Any]:
    return {f.name: thaw(getattr(obj, f.name)) for f in fields(obj)}


@dataclass(frozen=True)
class Catalog:
    """A loaded catalog: its path and its scenarios in file order, sweeps expanded."""

    path: Path
    scenarios: tuple[Scenario, ...]

    def names(self) -> list[str]:
        return [s.name for s in self.scenarios]

    def get(self, name: str) -> Scenario:
        for s in self.scenarios:
            if s.name == name:
                return s
        raise KeyError(f"{self.path}: no scenario {name!r}")

    def __len__(self) -> int:
        return len(self.scenarios)

    def __iter__(self) -> Iterator[Scenario]:
        return iter(self.scenarios)
