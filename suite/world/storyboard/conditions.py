"""A condition's test at one instant (before edges and delays, which
:mod:`~suite.world.storyboard.triggers` applies)."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping

from suite.catalog import storyboard as sb
from suite.world.storyboard.state import (
    EntityView,
    headway_s,
    longitudinal_gap_m,
    relative_distance_m,
    ttc_s,
)

__all__ = ["test_condition"]

StateTest = Callable[[sb.StateCondition], bool]
PlaceY = Callable[[sb.RoutePosition], float]


def _entity_value(check: object, me: EntityView, views: Mapping[str, EntityView],
                  place_y: PlaceY) -> float:
    """The measured value of an entity condition for triggering entity ``me`` (NaN for
    a condition on another entity that is not there)."""
    own = _own_value(check, me, place_y)
    if own is not None:
        return own
    ref = views.get(getattr(check, "entity_ref", ""), None)
    if ref is None:
        return math.nan
    return _relative_value(check, me, ref)


def _own_value(check: object, me: EntityView, place_y: PlaceY) -> float | None:
    """The value of a condition on ``me`` alone: its speed [m/s], the distance it
    travelled [m], its distance to a position [m]; None for any other condition."""
    if isinstance(check, sb.SpeedCondition):
        return me.speed_mps
    if isinstance(check, sb.TraveledDistanceCondition):
        return me.travelled_m
    if isinstance(check, sb.ReachPositionCondition):
        return math.hypot(me.pos_m - check.position.pos_m,
                          me.y_m - place_y(check.position))
    return None


def _relative_value(check: object, me: EntityView, ref: EntityView) -> float:
    """The value of a condition on ``me`` relative to entity ``ref``: their distance
    [m], headway [s], time to collision [s] or speed difference [m/s]."""
    if isinstance(check, sb.RelativeDistanceCondition):
        return relative_distance_m(me, ref, check.distance_type, check.freespace)
    if isinstance(check, sb.TimeHeadwayCondition):
        return headway_s(me, ref, check.freespace)
    if isinstance(check, sb.TimeToCollisionCondition):
        return ttc_s(me, ref, check.freespace)
    if isinstance(check, sb.RelativeSpeedCondition):
        return me.speed_mps - ref.speed_mps
    return longitudinal_gap_m(me, ref, False)  # pragma: no cover - all kinds above


def _entity_holds(check: object, value: float) -> bool:
    if math.isnan(value):
        return False
    if isinstance(check, sb.TraveledDistanceCondition):
        return value >= check.value_m
    if isinstance(check, sb.ReachPositionCondition):
        return value <= check.tolerance_m
    threshold = float(getattr(check, "value_m", getattr(check, "value_s",
                                                           getattr(check, "value_mps", 0.0))))
    return sb.compare(value, str(getattr(check, "rule", "equalTo")), threshold)


def test_condition(cond: sb.Condition, t_s: float, views: Mapping[str, EntityView],
                   state_test: StateTest, place_y: PlaceY) -> bool:
    """Whether ``cond``'s test holds now (run time ``t_s`` [s], the entities' views;
    ``state_test`` answers storyboard element state conditions, ``place_y`` gives a
    route position's lateral place [m])."""
    check = cond.check
    if isinstance(check, sb.SimulationTimeCondition):
        return sb.compare(t_s, check.rule, check.value_s)
    if isinstance(check, sb.StateCondition):
        return state_test(check)
    results = [_entity_holds(check, _entity_value(check, views[n], views, place_y))
               for n in cond.triggering if n in views]
    if not results:
        return False
    return any(results) if cond.any_entity else all(results)
