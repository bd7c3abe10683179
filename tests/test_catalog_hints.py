"""Bad input names every problem and the closest valid name (#26): misspelt keys, nets
and controllers get a "did you mean", an unknown controller with no close name points
at --plugin, and every bad key and value of a controller's options table is reported,
not only the first."""

from __future__ import annotations

from pathlib import Path

import pytest

from suite.catalog import CatalogError, load_catalog

HEAD = '[defaults]\ncontroller = "two_loop"\nduration_s = 5.0\nstep_s = 0.02\n'


def issues(tmp_path: Path, body: str) -> dict[str, str]:
    path = tmp_path / "cat.toml"
    path.write_text(HEAD + body)
    with pytest.raises(CatalogError) as info:
        load_catalog(path)
    return {i.key: i.expected for i in info.value.issues}


def test_misspelt_names_get_the_closest_valid_one(tmp_path: Path) -> None:
    found = issues(tmp_path, '[[scenario]]\nname = "a"\nnet = "straight_3lan"\n'
                   'ego = { lane = 1, pos_m = 60.0, speeed_mps = 25.0 }\n'
                   '[[scenario]]\nname = "b"\nnet = "straight_3lane"\n'
                   'ego = { lane = 1, pos_m = 60.0, speed_mps = 25.0 }\n'
                   'controller = { name = "two_lop" }\n')
    assert "'straight_3lane'" in found["scenario[0].net"].rsplit(";", 1)[1]
    assert "'speed_mps'" in found["scenario[0].ego.speeed_mps"].rsplit(";", 1)[1]
    assert "'two_loop'" in found["scenario[1].controller.name"].rsplit(";", 1)[1]


def test_an_unknown_controller_far_from_any_name_points_at_plugins(tmp_path: Path) -> None:
    found = issues(tmp_path, '[[scenario]]\nname = "a"\nnet = "straight_3lane"\n'
                   'ego = { lane = 1, pos_m = 60.0, speed_mps = 25.0 }\n'
                   'controller = "my_company_mpc"\n')
    assert "--plugin" in found["scenario[0].controller.name"]


def test_every_bad_option_of_a_controller_table_is_reported(tmp_path: Path) -> None:
    found = issues(tmp_path, '[[scenario]]\nname = "a"\nnet = "straight_3lane"\n'
                   'ego = { lane = 1, pos_m = 60.0, speed_mps = 25.0 }\n'
                   'controller = { name = "two_loop", outer = { horizn_s = 1.0, c_yy = 2.0 },'
                   ' lateral = { rate_mps = -1.0 } }\n')
    assert {"scenario[0].controller.outer.horizn_s", "scenario[0].controller.outer.c_yy",
            "scenario[0].controller.lateral.rate_mps"} <= set(found)
    assert "'horizon_s'" in found["scenario[0].controller.outer.horizn_s"]
