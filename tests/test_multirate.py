"""Multi-rate stepping: the catalog's sumo_step_s, the stepping rule, the extrapolation
(known answers), and the SUMO world at 10 Hz under a 50 Hz loop (SUMO tests)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from controllers.behaviour.types import Traffic
from suite.catalog import CatalogError, load_catalog
from suite.catalog.specs import default_sumo_step, sumo_step_problem
from suite.world.multirate import MultiRate, extrapolate_traffic

CATALOG = """
[defaults]
controller = "lane_keep"
duration_s = 4.0
step_s = 0.02
seed = 2

[[scenario]]
name = "default_rate"
net = "straight_3lane"
ego = { lane = 1, pos_m = 100.0, speed_mps = 25.0 }
traffic = { vehicles_per_hour = 2400, seed = 3 }
"""


def _load(tmp_path: Path, extra: str = "") -> list:  # type: ignore[type-arg]
    path = tmp_path / "c.toml"
    path.write_text(CATALOG + extra)
    return list(load_catalog(path).scenarios)


def test_default_sumo_step_is_the_largest_multiple_up_to_100_ms() -> None:
    assert default_sumo_step(0.02) == pytest.approx(0.1)
    assert default_sumo_step(0.04) == pytest.approx(0.08)
    assert default_sumo_step(0.03) == pytest.approx(0.09)
    assert default_sumo_step(0.25) == pytest.approx(0.25)
    for step in (0.001, 0.02, 0.03, 0.07, 0.1, 0.3):
        assert sumo_step_problem(default_sumo_step(step), step) is None


def test_catalog_key(tmp_path: Path) -> None:
    (sc,) = _load(tmp_path)
    assert sc.sumo_step_s == pytest.approx(0.1) and sc.steps_per_world_step == 5
    assert sc.as_dict()["sumo_step_s"] == pytest.approx(0.1)
    (sc,) = _load(tmp_path, 'sumo_step_s = 0.02\n')
    assert sc.steps_per_world_step == 1
    (sc,) = _load(tmp_path, 'sumo_step_s = 0.2\n')
    assert sc.steps_per_world_step == 10
    for bad, why in ((0.03, "whole multiple"), (0.01, "whole multiple"),
                     (0.1005, "milliseconds"), ("fast", "milliseconds")):
        with pytest.raises(CatalogError, match=why) as info:
            _load(tmp_path, f'sumo_step_s = {bad!r}\n'.replace("'", '"'))
        assert "sumo_step_s" in str(info.value)


def test_stepping_rule() -> None:
    rate = MultiRate(5, 0.02)
    assert rate.world_step_s == pytest.approx(0.1)
    assert [rate.is_world_step(k) for k in range(1, 11)] == [False] * 4 + [True] + \
        [False] * 4 + [True]
    assert rate.since_world_step_s(7) == pytest.approx(0.04)
    assert rate.since_world_step_s(10) == 0.0
    assert all(MultiRate(1, 0.02).is_world_step(k) for k in range(1, 5))
    for bad in ((0, 0.02), (True, 0.02), (2.0, 0.02), (5, 0.0), (5, math.nan)):
        with pytest.raises(ValueError):
            MultiRate(*bad)  # type: ignore[arg-type]


def test_extrapolation_is_constant_speed_along_the_heading() -> None:
    tr = Traffic(ids=("a", "b", "c"), x_m=np.array([0.0, 10.0, 5.0]),
                 y_m=np.array([0.0, 3.5, -3.5]),
                 heading_rad=np.array([0.0, math.pi / 2, 0.1]),
                 speed_mps=np.array([20.0, 10.0, 0.0]), length_m=np.full(3, 4.5),
                 width_m=np.full(3, 1.8), lane_index=np.array([0, 1, 2]),
                 road_id=("e", "e", "e"), stalled=np.array([False, False, True]))
    out = extrapolate_traffic(tr, 0.08)
    np.testing.assert_allclose(out.x_m, [1.6, 10.0, 5.0], atol=1e-12)
    np.testing.assert_allclose(out.y_m, [0.0, 4.3, -3.5], atol=1e-12)
    assert out.ids == tr.ids and out.lane_index is tr.lane_index
    np.testing.assert_array_equal(tr.x_m, [0.0, 10.0, 5.0])  # the input is not changed
    assert extrapolate_traffic(tr, 0.0) is tr
    assert extrapolate_traffic(Traffic.empty(), 0.05).count == 0


@pytest.mark.sumo
def test_sumo_world_steps_at_its_own_rate(tmp_path: Path) -> None:
    """SUMO's clock moves every 5th call; in between the scene's time moves by step_s and
    the vehicles by v tau along their heading from SUMO's last state."""
    from controllers.plant.vehicle_model import VehicleParams
    from suite.road.network import RoadNetwork
    from suite.world.sumo import SumoWorld

    (sc,) = _load(tmp_path)
    world = SumoWorld(sc, RoadNetwork.load(sc.net_path), VehicleParams(), tmp_path / "sumo",
                      externally_driven=False)
    try:  # SUMO's driver drives this ego: SUMO is its plant and steps every step_s
        world.start(None)
        sumo_t = [world._time()]
        for _ in range(10):
            world.step(None)
            sumo_t.append(world._time())
        np.testing.assert_allclose(np.diff(sumo_t), 0.02)
    finally:
        world.close()

    world = SumoWorld(sc, RoadNetwork.load(sc.net_path), VehicleParams(), tmp_path / "sumo2",
                      externally_driven=True)
    from suite.world.protocol import EgoPose

    pose = EgoPose(100.0, -4.8, 0.0)
    try:
        held = world.start(pose)
        assert held.traffic.count > 0
        t0 = world._time()
        for k in range(1, 16):
            pose = EgoPose(pose.front_x_m + 0.5, pose.front_y_m, 0.0)
            scene = world.step(pose)
            if k % 5 == 0:
                assert world._time() == pytest.approx(t0 + 0.1 * (k // 5))
                held = scene
                continue
            assert world._time() == pytest.approx(t0 + 0.1 * (k // 5))
            tau = (k % 5) * 0.02
            assert scene.t_s == pytest.approx(held.t_s + tau)
            assert scene.ego is held.ego and scene.collisions == ()
            tr, base = scene.traffic, held.traffic
            assert tr.ids == base.ids
            np.testing.assert_allclose(tr.x_m - base.x_m,
                                       base.speed_mps * tau * np.cos(base.heading_rad))
            np.testing.assert_allclose(tr.y_m - base.y_m,
                                       base.speed_mps * tau * np.sin(base.heading_rad))
    finally:
        world.close()
