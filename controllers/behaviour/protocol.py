"""The Behaviour role: traffic and lane context in, a :class:`Decision` out, every step."""

from __future__ import annotations

from typing import Protocol

from controllers.behaviour.types import Decision, EgoFrenet, LaneContext, Traffic


class Behaviour(Protocol):
    """Stateful per run (a decision may hold across steps). ``set_speed_mps`` is the
    scenario's cruise set-point; the decision's ``target_speed_mps`` may be lower."""

    def decide(self, ego: EgoFrenet, traffic: Traffic, lanes: LaneContext,
               set_speed_mps: float) -> Decision: ...


class CruiseBehaviour:
    """For controllers that take no obstacles: keep the lane at the set speed."""

    def decide(self, ego: EgoFrenet, traffic: Traffic, lanes: LaneContext,
               set_speed_mps: float) -> Decision:
        del ego, traffic, lanes
        return Decision(target_speed_mps=set_speed_mps)
