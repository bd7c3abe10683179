"""A criterion switched off from a catalog: ``criteria = { name = "off" }`` is accepted,
kept through the Scenario and the run record's info, and judged as no limit; anything
else that is not a finite number is refused naming the key."""

from __future__ import annotations

from pathlib import Path

import pytest

from suite.catalog import CatalogError, load_catalog

HEADER = """
[defaults]
controller = "lane_keep"
duration_s = 5.0
step_s = 0.02
criteria = { max_abs_jerk_mps3 = "off" }

[[scenario]]
name = "a"
net = "straight_2lane"
ego = { lane = 0, pos_m = 50.0, speed_mps = 20.0 }
"""


def test_off_reaches_the_scenario_and_the_run_info(tmp_path: Path) -> None:
    from controllers.plant.vehicle_model import VehicleParams
    from reports.metrics.criteria import Criteria
    from suite.run.info import scenario_info

    path = tmp_path / "c.toml"
    path.write_text(HEADER + 'criteria = { min_gap_m = 0.5 }\n')
    sc = load_catalog(path, known_controllers={"lane_keep"}).scenarios[0]
    # Merged name by name: the default's "off" and the scenario's number.
    assert dict(sc.criteria) == {"max_abs_jerk_mps3": "off", "min_gap_m": 0.5}
    info_criteria = scenario_info(sc, "c", VehicleParams()).criteria
    assert info_criteria == {"max_abs_jerk_mps3": "off", "min_gap_m": 0.5}
    limits = Criteria.from_overrides(info_criteria)
    assert limits.max_abs_jerk_mps3 is None and limits.min_gap_m == 0.5


@pytest.mark.parametrize("bad", ['"of"', "true", "[1.0]"])
def test_anything_else_is_refused_by_key(tmp_path: Path, bad: str) -> None:
    path = tmp_path / "c.toml"
    path.write_text(HEADER + f"criteria = {{ min_gap_m = {bad} }}\n")
    with pytest.raises(CatalogError) as exc:
        load_catalog(path, known_controllers={"lane_keep"})
    assert "criteria.min_gap_m" in str(exc.value) and 'or "off"' in str(exc.value)
