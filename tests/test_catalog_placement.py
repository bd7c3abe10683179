"""Catalog checks of what SUMO would refuse: overlapping placements, steps off SUMO's clock."""

from __future__ import annotations

from pathlib import Path

import pytest

from suite.catalog import CatalogError, load_catalog

BASE = """
[defaults]
controller = "lane_keep"
duration_s = 10.0
step_s = 0.02
"""


def load(tmp_path: Path, body: str) -> CatalogError | None:
    path = tmp_path / "c.toml"
    path.write_text(BASE + body)
    try:
        load_catalog(path)
    except CatalogError as exc:
        return exc
    return None


def test_two_stalled_cars_at_one_spot_are_refused(tmp_path: Path) -> None:
    err = load(tmp_path, """
[[scenario]]
name = "pile"
net = "straight_3lane"
ego = { lane = 1, pos_m = 100.0, speed_mps = 25.0 }
stalled = [ { lane = 1, pos_m = 300.0 }, { lane = 1, pos_m = 303.0 } ]
""")
    assert err is not None and len(err.issues) == 1
    issue = err.issues[0]
    assert issue.key == "scenario[0].stalled.1.pos_m" and "clear of stalled.0" in issue.expected


def test_a_stalled_car_on_the_egos_spot_is_refused(tmp_path: Path) -> None:
    err = load(tmp_path, """
[[scenario]]
name = "on_me"
net = "straight_2lane"
ego = { lane = 0, pos_m = 200.0, speed_mps = 25.0 }
stalled = [ { lane = 0, pos_m = 198.0 } ]
""")
    assert err is not None and err.issues[0].key == "scenario[0].stalled.0.pos_m"
    assert "clear of ego" in err.issues[0].expected


def test_close_but_clear_and_other_lanes_are_fine(tmp_path: Path) -> None:
    # 40 m ahead in the ego's lane (a realistic test) and side by side in two lanes.
    assert load(tmp_path, """
[[scenario]]
name = "close"
net = "straight_3lane"
ego = { lane = 1, pos_m = 100.0, speed_mps = 25.0 }
stalled = [ { lane = 1, pos_m = 140.0 }, { lane = 2, pos_m = 140.0 }, { lane = 2, pos_m = 146.0 } ]
""") is None


@pytest.mark.parametrize(("step", "ok"), [(0.02, True), (0.001, True), (0.1, True),
                                          (1e-5, False), (0.0025, False), (0.0, False)])
def test_the_step_is_on_sumos_millisecond_clock(tmp_path: Path, step: float, ok: bool) -> None:
    err = load(tmp_path, f"""
[[scenario]]
name = "s"
net = "straight_2lane"
step_s = {step!r}
ego = {{ lane = 0, pos_m = 100.0, speed_mps = 25.0 }}
""")
    assert (err is None) == ok
    if err is not None:
        assert err.issues[0].key == "scenario[0].step_s"
        assert "whole number of milliseconds" in err.issues[0].expected
