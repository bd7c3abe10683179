"""The values the lane behaviour (:mod:`controllers.behaviour.decision`) works with: the
ego's shape, its parameters, the lane plan it holds between steps (``_Plan``) and a
wanted change (``_Want``)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from controllers.behaviour.following import FollowParams
from controllers.behaviour.lane_change import (
    LaneChangeParams,
)
from controllers.behaviour.types import (
    Reason,
)


@dataclass(frozen=True)
class EgoShape:
    """The ego's box [m] and whether it may use a hard shoulder."""

    length_m: float
    width_m: float
    allow_shoulder: bool = False


@dataclass(frozen=True)
class BehaviourParams:
    """Car following and lane changing (see their modules for the units)."""

    follow: FollowParams = field(default_factory=FollowParams)
    lane_change: LaneChangeParams = field(default_factory=LaneChangeParams)


@dataclass(frozen=True)
class _Plan:
    """The lane plan: ``lane`` held (``origin == lane``) or moved into from ``origin``,
    since ``since_s``; ``passing``: the vehicle being passed ('' none); ``end_s_m``: the
    path position where the change's stretch ends (what its gap rules were checked
    over, and are re-checked over until the commit point)."""

    lane: int
    origin: int
    since_s: float
    passing: str = ""
    evasive: bool = False
    end_s_m: float = math.nan

    @property
    def changing(self) -> bool:
        return self.lane != self.origin


@dataclass(frozen=True)
class _Want:
    """A wanted change: target lane, where the manoeuvre ends (path s), why (text), whether
    it may skip the hold time, the vehicle it passes ('' none), whether it evades a
    stopped vehicle that the ego cannot stop for comfortably, and why (the code)."""

    target: int
    end_s_m: float
    why: str
    urgent: bool
    passing: str = ""
    evasive: bool = False
    kind: Reason = Reason.PASS
