"""Catalog key ``actors`` (scripted vehicles): validation messages, the specs it builds,
and the route file lines it writes (no SUMO; tests/test_behaviour_sumo.py drives them)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from controllers.plant.vehicle_model import VehicleParams
from suite.catalog import (
    ActorEventSpec,
    ActorSpec,
    ActorWhenSpec,
    CatalogError,
    SpecError,
    load_catalog,
)
from suite.road.network import RoadNetwork
from suite.world.actors import EgoAndActor, _Ramp
from suite.world.routes import RouteFile

KNOWN = {"lane_keep", "two_loop"}
HEADER = """
[defaults]
controller = "lane_keep"
duration_s = 20.0
step_s = 0.02

[[scenario]]
name = "a"
net = "straight_3lane"
ego = { lane = 1, pos_m = 50.0, speed_mps = 25.0 }
"""


def _load(tmp_path: Path, body: str) -> object:
    path = tmp_path / "c.toml"
    path.write_text(HEADER + body)
    return load_catalog(path, known_controllers=KNOWN)


def _problems(tmp_path: Path, body: str) -> str:
    with pytest.raises(CatalogError) as exc:
        _load(tmp_path, body)
    return str(exc.value)


def test_actors_build_their_specs_and_route_lines(tmp_path: Path) -> None:
    cat = _load(tmp_path, """
[[scenario.actors]]
id = "cutter"
lane = 0
pos_m = 90.0
speed_mps = 20.0
events = [ { t_s = 1.0, lane_change = 1 }, { t_s = 4.0, speed_mps = 10.0, accel_mps2 = 3 } ]
""")
    sc = cat.scenarios[0]  # type: ignore[attr-defined]
    (actor,) = sc.actors
    assert actor == ActorSpec("cutter", 0, 90.0, 20.0, events=(
        ActorEventSpec(1.0, lane_change=1), ActorEventSpec(4.0, speed_mps=10.0,
                                                           accel_mps2=3.0)))
    assert actor.sumo_id == "actor_cutter" and isinstance(actor.events[1].accel_mps2, float)
    assert sc.as_dict()["actors"][0]["events"][1]["speed_mps"] == 10.0
    xml = RouteFile(sc, RoadNetwork.load(sc.net_path), VehicleParams(),
                    tmp_path / "ssm.xml").xml()
    root = ET.fromstring(xml)
    veh = root.find("vehicle[@id='actor_cutter']")
    assert veh is not None
    assert (veh.get("departLane"), veh.get("departSpeed")) == ("0", "20.000")
    vtype = root.find("vType[@id='t_actor_cutter']")
    assert vtype is not None and vtype.get("sigma") == "0"  # no dawdling


def test_bad_actors_are_reported_by_key(tmp_path: Path) -> None:
    text = _problems(tmp_path, """
actors = [
  { id = "x", lane = 5, pos_m = 100.0, speed_mps = 20.0 },
  { id = "y", lane = 1, pos_m = 52.0, speed_mps = 20.0 },
  { id = "Bad id", lane = 0, pos_m = 200.0, speed_mps = 20.0, colour = 1 },
  { id = "z", lane = 0, pos_m = 300.0, speed_mps = 20.0, events = [
    { t_s = 3.0 }, { t_s = 1.0, speed_mps = -2.0 } ] },
]
""")
    assert "scenario[0].actors.0.lane (scenario 'a'): expected a lane index in 0..2" in text
    assert "actors.1.pos_m" in text and "clear of ego" in text
    assert "actors.2.id" in text and "actors.2.colour" in text
    assert "actors.3.events.0.lane_change" in text and "it does nothing" in text
    assert "actors.3.events.1.speed_mps" in text


def test_events_in_time_order_and_distinct_ids() -> None:
    with pytest.raises(SpecError, match="time order"):
        ActorSpec("a", 0, 10.0, 5.0, events=(ActorEventSpec(2.0, 1), ActorEventSpec(1.0, 1)))
    with pytest.raises(SpecError, match="lane change"):
        ActorEventSpec(1.0, lane_change=0)


def test_speed_ramp_is_linear_then_held() -> None:
    up = _Ramp(t0_s=2.0, v0_mps=25.0, v1_mps=45.0, accel_mps2=4.0)
    assert up.speed(1.0) == 25.0 and up.speed(3.0) == pytest.approx(29.0)
    assert up.speed(7.0) == 45.0 and up.speed(100.0) == 45.0
    down = _Ramp(t0_s=0.0, v0_mps=20.0, v1_mps=10.0, accel_mps2=2.0)
    assert down.speed(2.5) == pytest.approx(15.0) and down.speed(6.0) == 10.0


def test_triggers_and_relative_starts_build_their_specs(tmp_path: Path) -> None:
    cat = _load(tmp_path, """
[[scenario.actors]]
id = "cutter"
lane = 2
ahead_of_ego_m = 40.0
speed_mps = 20.0
events = [ { when = { ahead_gap_m = 15.0, delay_s = 0.5 }, lane_change = -1 },
           { t_s = 2.0, when = { ttc_s = 3 }, speed_mps = 10.0 } ]
""")
    sc = cat.scenarios[0]  # type: ignore[attr-defined]
    (actor,) = sc.actors
    assert actor.pos_m == 90.0  # the ego's 50 m + 40 m, front bumpers along the route
    first, second = actor.events
    assert first.t_s is None and first.earliest_s == 0.0
    assert first.when == ActorWhenSpec(ahead_gap_m=15.0, delay_s=0.5)
    assert second.earliest_s == 2.0 and second.when is not None and second.when.ttc_s == 3.0
    events = sc.as_dict()["actors"][0]["events"]
    assert events[0]["when"] == {"ahead_gap_m": 15.0, "delay_s": 0.5}
    # an event without a trigger reads as it always did (no "when" key)
    plain = ActorEventSpec(1.0, lane_change=1).as_dict()
    assert plain == {"t_s": 1.0, "lane_change": 1, "speed_mps": None, "accel_mps2": 2.0}


@pytest.mark.parametrize(("body", "key"), [
    ('{ id = "a", lane = 0, pos_m = 90.0, ahead_of_ego_m = 10.0, speed_mps = 20.0 }',
     "actors.0.ahead_of_ego_m"),
    ('{ id = "a", lane = 0, ahead_of_ego_m = -80.0, speed_mps = 20.0 }',
     "actors.0.ahead_of_ego_m"),
    ('{ id = "a", lane = 0, ahead_of_ego_m = "far", speed_mps = 20.0 }',
     "actors.0.ahead_of_ego_m"),
    ('{ id = "a", lane = 0, pos_m = 90.0, speed_mps = 20.0, events = [ { lane_change = 1 } ] }',
     "actors.0.events.0.t_s"),
    ('{ id = "a", lane = 0, pos_m = 90.0, speed_mps = 20.0, events = [ { when = { delay_s = 1 },'
     ' lane_change = 1 } ] }', "actors.0.events.0.when"),
    ('{ id = "a", lane = 0, pos_m = 90.0, speed_mps = 20.0, events = [ { when = { ttc_s = 0 },'
     ' lane_change = 1 } ] }', "actors.0.events.0.when"),
    ('{ id = "a", lane = 0, pos_m = 90.0, speed_mps = 20.0, events = [ { when = { gap = 3 },'
     ' lane_change = 1 } ] }', "actors.0.events.0.when"),
])
def test_bad_triggers_and_relative_starts_are_reported_by_key(tmp_path: Path, body: str,
                                                              key: str) -> None:
    assert f"scenario[0].{key} (scenario 'a')" in _problems(tmp_path, f"actors = [ {body} ]\n")


def test_when_conditions_known_answers() -> None:
    # ego front at 100 m, 25 m/s; actor front at 130 m, 4.5 m long, 20 m/s: gap 25.5 m,
    # headway 25.5 / 25 = 1.02 s, time to collision 25.5 / 5 = 5.1 s
    view = EgoAndActor(100.0, 25.0, 130.0, 20.0, 4.5)
    assert view.gap_m == pytest.approx(25.5)
    assert view.holds(ActorWhenSpec(ahead_gap_m=25.5))
    assert not view.holds(ActorWhenSpec(ahead_gap_m=25.4))
    assert view.holds(ActorWhenSpec(time_headway_s=1.02 + 1e-9))
    assert not view.holds(ActorWhenSpec(time_headway_s=1.01))
    assert view.holds(ActorWhenSpec(ttc_s=5.1 + 1e-9)) and not view.holds(ActorWhenSpec(ttc_s=5.0))
    assert view.holds(ActorWhenSpec(ego_pos_m=100.0))
    assert not view.holds(ActorWhenSpec(ego_pos_m=101.0))
    # all conditions given must hold
    assert not view.holds(ActorWhenSpec(ahead_gap_m=30.0, ttc_s=5.0))
    # not closing: no time to collision; behind the ego: no gap, headway or TTC holds
    assert not EgoAndActor(100.0, 20.0, 130.0, 25.0, 4.5).holds(ActorWhenSpec(ttc_s=100.0))
    behind = EgoAndActor(100.0, 25.0, 90.0, 20.0, 4.5)
    assert not behind.holds(ActorWhenSpec(ahead_gap_m=100.0))
    assert not behind.holds(ActorWhenSpec(time_headway_s=100.0))
    # an unknown position (a junction) holds nothing
    assert not EgoAndActor(float("nan"), 25.0, 130.0, 20.0, 4.5).holds(
        ActorWhenSpec(ahead_gap_m=100.0))
