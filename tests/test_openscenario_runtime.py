"""The storyboard runtime (suite.world.storyboard) against known answers, on a straight
road of three 3.5 m lanes without SUMO: each action's motion and each condition's firing
step, edges and delays."""

from __future__ import annotations

import math
from dataclasses import dataclass

import pytest

from suite.catalog import storyboard as sb
from suite.world.storyboard.engine import StoryEngine
from suite.world.storyboard.profiles import lane_offset_duration_s, shape
from suite.world.storyboard.road import lane_centre_y, lane_of
from suite.world.storyboard.state import EntityView

DT = 0.02
W = 3.5


@dataclass
class StraightRoad:
    """Three lanes of width W; the route position is x, the lateral place y."""

    lanes: int = 3

    def widths(self, pos_m: float) -> tuple[float, ...]:
        del pos_m
        return (W,) * self.lanes

    def pose(self, pos_m: float, lane: int, lateral_m: float,
             heading_rad: float) -> tuple[float, float, float]:
        return pos_m, lane_centre_y(self, pos_m, lane) + lateral_m, heading_rad


CAR = sb.Entity("Car", "vehicle", 4.0, 2.0, 3.0)
EGO = sb.Entity("Ego", "vehicle", 5.0, 2.0, 3.9, ego=True)
ROAD = StraightRoad()
T0 = sb.Trigger((sb.ConditionGroup((sb.Condition(
    "t0", 0.0, "none", sb.SimulationTimeCondition(0.0, "greaterOrEqual")),)),))


def _when(check: object, edge: str = "none", delay: float = 0.0,
          triggering: tuple[str, ...] = ()) -> sb.Trigger:
    return sb.Trigger((sb.ConditionGroup((sb.Condition("c", delay, edge, check,
                                                       triggering),)),))


NEVER = sb.Trigger()


def _story(action: object, start: sb.Trigger = T0, speed: float = 20.0, lane: int = 0,
           pos: float = 100.0, stop: sb.Trigger = NEVER) -> sb.Storyboard:
    event = sb.Event("E", (("A", action),), start)
    group = sb.ManeuverGroup("G", ("Car",), (sb.Maneuver("M", (event,)),))
    return sb.Storyboard((EGO, CAR), (sb.EntityInit("Car", sb.RoutePosition(pos, lane), speed),),
                         (sb.Story("S", (sb.Act("Act", (group,), T0),)),), stop)


def _ego_view(t: float, pos0: float = 0.0, v: float = 20.0, lane: int = 0) -> EntityView:
    pos = pos0 + v * t
    y = lane_centre_y(ROAD, pos, lane)
    return EntityView(EGO, pos, y, pos, y, 0.0, v, v * t)


Row = tuple[float, float, float, float, int]


def _run(story: sb.Storyboard, seconds: float, ego: object = None
         ) -> tuple[StoryEngine, list[Row]]:
    """Step ``seconds``; rows (t after the step, pos, y, speed, lane) of the car."""
    eng = StoryEngine(story, ROAD)
    rows: list[Row] = []
    for k in range(int(round(seconds / DT))):
        t = k * DT
        eng.step(t, DT, ego(t) if callable(ego) else _ego_view(t))
        m = eng.motions["Car"]
        rows.append((t + DT, m.pos_m, m.y_m, m.speed_mps, lane_of(ROAD, m.pos_m, m.y_m)[0]))
    return eng, rows


# ---------------------------------------------------------------- actions

@pytest.mark.parametrize("v_y", [0.5, 1.0, 2.0, 3.0])
def test_a_lane_change_at_lateral_rate_v_y_across_width_w_ends_at_w_over_v_y(v_y: float) -> None:
    action = sb.LaneChangeAction("sinusoidal", "rate", v_y, lane=1)
    eng, rows = _run(_story(action), 12.0)
    done = eng.time_of("action", "A", "endTransition")
    assert abs(done - W / v_y) <= DT + 1e-9
    assert rows[-1][4] == 1 and abs(rows[-1][2] - lane_centre_y(ROAD, 0, 1)) < 1e-9
    before = [r for r in rows if r[0] < W / v_y - DT]
    assert all(r[2] < lane_centre_y(ROAD, 0, 1) for r in before)


def test_a_lane_change_by_time_and_by_distance() -> None:
    eng, _ = _run(_story(sb.LaneChangeAction("cubic", "time", 4.0, lane=2)), 6.0)
    assert abs(eng.time_of("action", "A", "endTransition") - 4.0) <= DT + 1e-9
    eng, rows = _run(_story(sb.LaneChangeAction("linear", "distance", 50.0, lane=1)), 6.0)
    t_end = eng.time_of("action", "A", "endTransition")
    assert abs(t_end - 50.0 / 20.0) <= DT + 1e-9  # 50 m at 20 m/s


def test_a_relative_lane_change_targets_the_reference_entitys_lane() -> None:
    rel = sb.RelativeLaneTarget("Ego", 0)
    _, rows = _run(_story(sb.LaneChangeAction("linear", "time", 2.0, relative=rel), lane=1),
                   3.0, ego=lambda t: _ego_view(t, lane=2))
    assert rows[-1][4] == 2


@pytest.mark.parametrize("shape_name", ["linear", "cubic", "sinusoidal"])
def test_a_speed_action_over_t_seconds_reaches_its_target_at_t(shape_name: str) -> None:
    eng, rows = _run(_story(sb.SpeedAction(10.0, shape_name, "time", 4.0)), 6.0)
    assert abs(eng.time_of("action", "A", "endTransition") - 4.0) <= DT + 1e-9
    at = {round(r[0], 6): r[3] for r in rows}
    assert at[4.0] == pytest.approx(10.0)
    assert at[2.0] == pytest.approx(20.0 - 10.0 * shape(shape_name, 0.5))
    assert all(v > 10.0 for t, v in at.items() if t < 4.0 - 1e-9)


def test_a_speed_action_at_a_rate_and_a_step() -> None:
    eng, rows = _run(_story(sb.SpeedAction(8.0, "linear", "rate", 3.0)), 6.0)
    assert abs(eng.time_of("action", "A", "endTransition") - 4.0) <= DT + 1e-9  # 12 / 3
    _, rows = _run(_story(sb.SpeedAction(5.0, "step", "time", 0.0)), 0.1)
    assert rows[0][3] == 5.0


def test_a_speed_action_over_a_distance_and_relative_to_an_entity() -> None:
    eng, rows = _run(_story(sb.SpeedAction(0.0, "linear", "distance", 40.0)), 6.0)
    t_end = eng.time_of("action", "A", "endTransition")
    stop_row = next(r for r in rows if r[0] >= t_end - 1e-9)
    assert stop_row[1] - 100.0 == pytest.approx(40.0, abs=20.0 * DT)
    _, rows = _run(_story(sb.SpeedAction(-3.0, "step", "time", 0.0, relative_to="Ego")), 0.1,
                   ego=lambda t: _ego_view(t, v=30.0))
    assert rows[0][3] == pytest.approx(27.0)


def test_a_lane_offset_with_a_peak_lateral_acceleration() -> None:
    action = sb.LaneOffsetAction(0.8, "sinusoidal", 0.5)
    eng, rows = _run(_story(action), 6.0)
    expected = math.pi * math.sqrt(0.8 / (2 * 0.5))
    assert lane_offset_duration_s("sinusoidal", 0.8, 0.5) == pytest.approx(expected)
    assert abs(eng.time_of("action", "A", "endTransition") - expected) <= DT + 1e-9
    assert rows[-1][2] - lane_centre_y(ROAD, 0, 0) == pytest.approx(0.8)


def test_a_relative_teleport_lands_where_it_says() -> None:
    action = sb.TeleportAction(relative_to="Ego", ds_m=30.0, dlane=1, lateral_m=0.2)
    eng, rows = _run(_story(action, speed=0.0), 0.02, ego=lambda t: _ego_view(t, pos0=50.0))
    m = eng.motions["Car"]
    # the Ego's reference point is at 50 - 3.9; the car's is 30 m ahead of it
    assert m.pos_m - CAR.front_m == pytest.approx(50.0 - EGO.front_m + 30.0)
    assert m.y_m == pytest.approx(lane_centre_y(ROAD, 0, 1) + 0.2)


def test_a_trajectory_is_followed_in_time() -> None:
    verts = (sb.TrajectoryVertex(0.0, sb.RoutePosition(200.0, 0, -1.0)),
             sb.TrajectoryVertex(4.0, sb.RoutePosition(200.0, 0, 6.0)))
    eng, rows = _run(_story(sb.FollowTrajectoryAction(verts), speed=0.0), 5.0)
    at = {round(r[0], 6): r for r in rows}
    assert at[2.0][2] == pytest.approx(lane_centre_y(ROAD, 0, 0) + 2.5)
    assert at[2.0][3] == pytest.approx(7.0 / 4.0)
    assert abs(eng.time_of("action", "A", "endTransition") - 4.0) <= DT + 1e-9


def test_a_continuous_distance_keeps_the_gap() -> None:
    action = sb.LongitudinalDistanceAction("Ego", True, True, True, distance_m=20.0)
    _, rows = _run(_story(action), 2.0, ego=lambda t: _ego_view(t, v=25.0))
    pos, ego = rows[-1][1], _ego_view(2.0 - DT, v=25.0)
    assert pos - CAR.length_m - ego.pos_m == pytest.approx(20.0, abs=25.0 * DT + 1e-6)


# ---------------------------------------------------------------- conditions

def _fired(check: object, seconds: float, ego: object = None, edge: str = "none",
           delay: float = 0.0, speed: float = 20.0, pos: float = 100.0) -> float:
    trig = _when(check, edge, delay, () if isinstance(
        check, sb.SimulationTimeCondition | sb.StateCondition) else ("Ego",))
    eng, _ = _run(_story(sb.ActivateControllerAction(), trig, speed=speed, pos=pos),
                  seconds, ego)
    return eng.time_of("event", "E", "startTransition")


def test_a_time_headway_trigger_fires_at_the_step_the_headway_crosses() -> None:
    # ego 30 m/s from 0, car 20 m/s ahead from 100: freespace gap 100 - 4 - 10 t - 0
    # (the ego's front at 30 t, the car's rear at 100 - 4 + 20 t); headway gap / 30
    t_cross = (96.0 - 2.0 * 30.0) / 10.0  # headway 2 s when 96 - 10 t = 60
    t = _fired(sb.TimeHeadwayCondition("Car", True, 2.0, "lessThan"), 6.0,
               ego=lambda t: _ego_view(t, v=30.0), edge="rising")
    first = math.ceil(t_cross / DT + 1e-9) * DT
    assert t == pytest.approx(first, abs=1e-9)


def test_a_relative_distance_and_ttc_fire_where_they_cross() -> None:
    t = _fired(sb.RelativeDistanceCondition("Car", "longitudinal", True, 30.0, "lessThan"),
               10.0, ego=lambda t: _ego_view(t, v=30.0), edge="rising")
    assert t == pytest.approx(math.ceil((96.0 - 30.0) / 10.0 / DT + 1e-9) * DT, abs=1e-9)
    t = _fired(sb.TimeToCollisionCondition("Car", True, 3.0, "lessThan"), 10.0,
               ego=lambda t: _ego_view(t, v=30.0))
    assert t == pytest.approx(math.ceil((96.0 - 30.0) / 10.0 / DT + 1e-9) * DT, abs=1e-9)
    t = _fired(sb.RelativeDistanceCondition("Car", "lateral", False, 3.0, "greaterThan"), 1.0,
               ego=lambda t: _ego_view(t, lane=1))
    assert t == 0.0


def test_speed_travelled_relative_speed_and_reach_position() -> None:
    assert _fired(sb.SpeedCondition(25.0, "greaterThan"), 1.0,
                  ego=lambda t: _ego_view(t, v=30.0)) == 0.0
    t = _fired(sb.TraveledDistanceCondition(50.0), 4.0)
    assert t == pytest.approx(50.0 / 20.0, abs=DT + 1e-9)
    assert _fired(sb.RelativeSpeedCondition("Car", 5.0, "greaterOrEqual"), 1.0,
                  ego=lambda t: _ego_view(t, v=25.0)) == 0.0
    t = _fired(sb.ReachPositionCondition(sb.RoutePosition(40.0, 0), 1.0), 4.0)
    assert t == pytest.approx((40.0 - 1.0) / 20.0, abs=DT + 1e-9)


def test_simulation_time_edges_and_delays() -> None:
    check = sb.SimulationTimeCondition(1.0, "greaterOrEqual")
    assert _fired(check, 3.0) == pytest.approx(1.0)
    assert _fired(check, 3.0, edge="rising") == pytest.approx(1.0)
    assert _fired(check, 3.0, delay=0.5) == pytest.approx(1.5)
    assert math.isnan(_fired(check, 3.0, edge="falling"))
    assert _fired(sb.SimulationTimeCondition(1.0, "lessThan"), 3.0,
                  edge="falling") == pytest.approx(1.0)


def test_a_storyboard_element_state_condition_follows_the_other_event() -> None:
    first = sb.Event("First", (("Slow", sb.SpeedAction(10.0, "linear", "time", 2.0)),), T0)
    after = sb.Event("Second", (("Change", sb.LaneChangeAction("linear", "time", 1.0, lane=1)),),
                     _when(sb.StateCondition("action", "Slow", "endTransition"), "rising",
                           delay=1.0), priority="parallel")
    group = sb.ManeuverGroup("G", ("Car",), (sb.Maneuver("M", (first, after)),))
    story = sb.Storyboard((EGO, CAR), (sb.EntityInit("Car", sb.RoutePosition(100.0, 0), 20.0),),
                          (sb.Story("S", (sb.Act("Act", (group,), T0),)),))
    eng, _ = _run(story, 6.0)
    slow_end = eng.time_of("action", "Slow", "endTransition")
    assert slow_end == pytest.approx(2.0, abs=DT + 1e-9)
    assert eng.time_of("event", "Second", "startTransition") == pytest.approx(
        slow_end + 1.0, abs=DT + 1e-9)


def test_the_stop_trigger_ends_the_storyboard() -> None:
    stop = _when(sb.SimulationTimeCondition(1.0, "greaterOrEqual"))
    eng, rows = _run(_story(sb.SpeedAction(0.0, "linear", "time", 4.0), stop=stop), 3.0)
    assert eng.stopped_at_s == pytest.approx(1.0)
    assert eng.time_of("action", "A", "stopTransition") == pytest.approx(1.0)
    assert rows[-1][3] == pytest.approx(rows[int(1.0 / DT)][3])  # speed held after it


def test_the_story_json_round_trips() -> None:
    story = _story(sb.LaneChangeAction("sinusoidal", "rate", 2.0,
                                       relative=sb.RelativeLaneTarget("Ego", 1)))
    assert sb.story_from_json(sb.story_to_json(story)) == story
    with pytest.raises(sb.StoryError, match="Storyboard"):
        sb.story_from_json('{"type": "Trigger", "groups": []}')
    with pytest.raises(sb.StoryError, match="rule"):
        sb.SpeedCondition(1.0, "about")
