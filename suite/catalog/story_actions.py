"""The storyboard's actions (:mod:`suite.catalog.storyboard`, docs/openscenario.md):
speed, lane change and offset, teleport, controller activation, distance keeping, a
trajectory to follow and a stop; each checks its fields in ``__post_init__``."""

from __future__ import annotations

from dataclasses import dataclass

from suite.catalog.story_conditions import (
    DIMENSIONS,
    SHAPES,
    RoutePosition,
    StoryError,
    _finite,
    _one_of,
)

# ---------------------------------------------------------------- actions

@dataclass(frozen=True)
class SpeedAction:
    """To a speed target: absolute ``target_mps``, or relative to ``relative_to``
    (``relative_kind`` delta: its speed + target, factor: its speed x target;
    ``continuous``: keep following it), along ``shape`` over ``dimension`` (time [s],
    distance [m] or rate [m/s²]) of ``value``."""

    target: float
    shape: str
    dimension: str
    value: float
    relative_to: str | None = None
    relative_kind: str = "delta"
    continuous: bool = False

    def __post_init__(self) -> None:
        _finite(self, "target", "value")
        _one_of(self, "shape", SHAPES)
        _one_of(self, "dimension", DIMENSIONS)
        _one_of(self, "relative_kind", ("delta", "factor"))
        if self.value < 0.0:
            raise StoryError(f"SpeedAction.value: expected >= 0, got {self.value}")


@dataclass(frozen=True)
class RelativeLaneTarget:
    """A lane ``value`` lanes left (+) of ``entity``'s lane."""

    entity: str
    value: int


@dataclass(frozen=True)
class LaneChangeAction:
    """Into ``lane`` (absolute index) or ``relative`` lane, ending ``target_offset_m``
    [m] off its centre, along ``shape`` over ``dimension`` (time [s], distance [m],
    rate: mean lateral speed [m/s], duration = lateral distance / rate)."""

    shape: str
    dimension: str
    value: float
    lane: int | None = None
    relative: RelativeLaneTarget | None = None
    target_offset_m: float = 0.0

    def __post_init__(self) -> None:
        _finite(self, "value", "target_offset_m")
        _one_of(self, "shape", SHAPES)
        _one_of(self, "dimension", DIMENSIONS)
        if (self.lane is None) == (self.relative is None):
            raise StoryError("LaneChangeAction: expected exactly one of lane, relative")
        if self.value < 0.0 or (self.value == 0.0 and self.shape != "step"):
            raise StoryError(f"LaneChangeAction.value: expected > 0, got {self.value}")


@dataclass(frozen=True)
class LaneOffsetAction:
    """To ``offset_m`` [m, left +] from the lane's centre (``relative_to``: from that
    entity's offset), along ``shape`` with at most ``max_lateral_acc_mps2`` [m/s²]."""

    offset_m: float
    shape: str
    max_lateral_acc_mps2: float
    relative_to: str | None = None
    continuous: bool = False

    def __post_init__(self) -> None:
        _finite(self, "offset_m", "max_lateral_acc_mps2")
        _one_of(self, "shape", SHAPES)
        if self.max_lateral_acc_mps2 <= 0.0:
            raise StoryError("LaneOffsetAction.max_lateral_acc_mps2: expected > 0")


@dataclass(frozen=True)
class TeleportAction:
    """To ``position`` (absolute) or relative to ``relative_to``: ``ds_m`` [m] along the
    route, ``dlane`` lanes left, ``lateral_m`` [m] off that lane's centre."""

    position: RoutePosition | None = None
    relative_to: str | None = None
    ds_m: float = 0.0
    dlane: int = 0
    lateral_m: float = 0.0

    def __post_init__(self) -> None:
        _finite(self, "ds_m", "lateral_m")
        if (self.position is None) == (self.relative_to is None):
            raise StoryError("TeleportAction: expected exactly one of position, relative_to")


@dataclass(frozen=True)
class ActivateControllerAction:
    """The ego's controller takes over (it drives the ego from t = 0 in hwyeval: the
    action is recorded as done, nothing else changes)."""

    lateral: bool = True
    longitudinal: bool = True


@dataclass(frozen=True)
class LongitudinalDistanceAction:
    """Keep (``continuous``) or take once the gap [m] (``distance_m``, or ``time_gap_s``
    x the reference's speed) to ``entity_ref``, ahead of it (``ahead``) or behind;
    ``freespace``: bumper to bumper, else reference points."""

    entity_ref: str
    freespace: bool
    ahead: bool
    continuous: bool
    distance_m: float | None = None
    time_gap_s: float | None = None

    def __post_init__(self) -> None:
        if (self.distance_m is None) == (self.time_gap_s is None):
            raise StoryError("LongitudinalDistanceAction: expected one of distance_m, "
                             "time_gap_s")


@dataclass(frozen=True)
class TrajectoryVertex:
    """A polyline vertex: time ``t_s`` [s] from the action's start and a place."""

    t_s: float
    position: RoutePosition

    def __post_init__(self) -> None:
        _finite(self, "t_s")


@dataclass(frozen=True)
class FollowTrajectoryAction:
    """Follow a polyline in time (following mode position): ``vertices`` in time order,
    linear between them, ``scale`` x (vertex time) + ``offset_s`` [s]."""

    vertices: tuple[TrajectoryVertex, ...]
    scale: float = 1.0
    offset_s: float = 0.0

    def __post_init__(self) -> None:
        _finite(self, "scale", "offset_s")
        object.__setattr__(self, "vertices", tuple(self.vertices))
        times = [v.t_s for v in self.vertices]
        if len(times) < 2 or times != sorted(times) or self.scale <= 0.0:
            raise StoryError("FollowTrajectoryAction: expected two vertices or more in time "
                             "order and a scale > 0")


@dataclass(frozen=True)
class StopAction:
    """The storyboard's own end (its stop trigger fired): nothing moves any more by the
    story; kept for the record."""


ACTION_TYPES: tuple[type, ...] = (
    SpeedAction, LaneChangeAction, LaneOffsetAction, TeleportAction,
    ActivateControllerAction, LongitudinalDistanceAction, FollowTrajectoryAction)
