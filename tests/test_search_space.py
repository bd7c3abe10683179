"""[scenario.search] tables: what is refused (exit 2 naming file, scenario and key before
anything runs), what run and list do with them (the nominal scenario), and how a drawn
point becomes a scenario (the catalog's own checks)."""

from __future__ import annotations

from pathlib import Path

import pytest

from suite.catalog import CatalogError, load_catalog
from suite.cli import main
from suite.search.space import CHOICE, FLOAT, INT, Refused, build_point, load_search_catalog

HEAD = """
[defaults]
controller = "lane_keep"
duration_s = 5.0
step_s = 0.02
[[scenario]]
name = "fam"
net = "straight_3lane"
ego = { lane = 1, pos_m = 50.0, speed_mps = 25.0 }
stalled = [ { lane = 1, pos_m = 400.0 } ]
traffic = { vehicles_per_hour = 600, seed = 3 }
"""


def write(tmp_path: Path, search: str, extra: str = "") -> Path:
    path = tmp_path / "cat.toml"
    path.write_text(HEAD + extra + "[scenario.search]\n" + search + "\n")
    return path


BAD = {
    "unknown_path": ('"stalled.3.pos_m" = { min = 60.0, max = 400.0 }', "stalled.3.pos_m"),
    "not_sweepable": ('"name" = { choices = ["a", "b"] }', "name"),
    "min_above_max": ('"ego.speed_mps" = { min = 30.0, max = 20.0 }', "ego.speed_mps"),
    "empty_range": ('"ego.speed_mps" = { min = 20.0, max = 20.0 }', "ego.speed_mps"),
    "missing_max": ('"ego.speed_mps" = { min = 20.0 }', "ego.speed_mps"),
    "unknown_spec_key": ('"ego.speed_mps" = { min = 20.0, max = 30.0, step = 1.0 }',
                         "ego.speed_mps"),
    "bool_bound": ('"ego.speed_mps" = { min = true, max = 30.0 }', "ego.speed_mps"),
    "float_int_bound": ('"traffic.seed" = { min = 0.5, max = 9.0, int = true }', "traffic.seed"),
    "int_not_bool": ('"traffic.seed" = { min = 0, max = 9, int = 1 }', "traffic.seed"),
    "empty_choices": ('"controller" = { choices = [] }', "controller"),
    "choices_and_range": ('"controller" = { choices = ["lane_keep"], min = 1, max = 2 }',
                          "controller"),
    "duplicate_choices": ('"controller" = { choices = ["lane_keep", "lane_keep"] }',
                          "controller"),
    "not_a_table": ('"ego.speed_mps" = [20.0, 30.0]', "ego.speed_mps"),
    "end_refused": ('"ego.lane" = { min = 0, max = 5, int = true }', "ego.lane"),
    "end_off_the_route": ('"stalled.0.pos_m" = { min = 60.0, max = 99000.0 }',
                          "stalled.0.pos_m"),
    "nested_inside": ('"stalled.0" = { choices = [{ lane = 0, pos_m = 300.0 }] }\n'
                      '"stalled.0.pos_m" = { min = 100.0, max = 300.0 }', "stalled.0"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_search_tables_exit_2_naming_file_scenario_and_key(
        tmp_path: Path, case: str, capsys: pytest.CaptureFixture[str]) -> None:
    search, key = BAD[case]
    path = write(tmp_path, search)
    out = tmp_path / "out"
    code = main(["search", str(path), "--out", str(out), "--budget", "3"])
    assert code == 2
    err = capsys.readouterr().err
    assert str(path) in err and "fam" in err and key in err
    assert not out.exists()  # nothing was written


def test_a_search_table_and_a_sweep_together_are_refused(tmp_path: Path) -> None:
    path = write(tmp_path, '"ego.speed_mps" = { min = 20.0, max = 30.0 }',
                 extra='sweep = { "ego.pos_m" = [40.0, 60.0] }\n')
    with pytest.raises(CatalogError) as info:
        load_search_catalog(path)
    assert any(i.key.endswith(".sweep") for i in info.value.issues)


def test_a_catalog_without_a_search_table_is_bad_input(tmp_path: Path) -> None:
    path = tmp_path / "plain.toml"
    path.write_text(HEAD)
    assert main(["search", str(path), "--out", str(tmp_path / "o"), "--budget", "2"]) == 2


def test_run_and_list_use_the_nominal_scenario(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path, '"stalled.0.pos_m" = { min = 100.0, max = 600.0 }')
    cat = load_catalog(path)
    assert [sc.name for sc in cat.scenarios] == ["fam"]
    assert cat.scenarios[0].stalled[0].pos_m == 400.0
    assert main(["list", str(path)]) == 0
    assert capsys.readouterr().out.split() == ["fam"]


def test_kinds_nominal_values_and_dotted_keys(tmp_path: Path) -> None:
    path = write(tmp_path, '"ego.speed_mps" = { min = 18.0, max = 33.0 }\n'
                           '"traffic.seed" = { min = 0, max = 999, int = true }\n'
                           'controller = { choices = ["lane_keep", { name = "lane_keep" }] }\n'
                           'stalled.0.lane = { choices = [0, 1, 2] }\n')
    fam = load_search_catalog(path).families[0]
    assert [p.path for p in fam.params] == ["ego.speed_mps", "traffic.seed", "controller",
                                            "stalled.0.lane"]
    assert [p.kind for p in fam.params] == [FLOAT, INT, CHOICE, CHOICE]
    assert fam.nominal == (25.0, 3, "lane_keep", 1)
    assert fam.distance(fam.nominal) == 0.0


def test_a_point_is_built_by_the_catalog_or_refused(tmp_path: Path) -> None:
    path = write(tmp_path, '"stalled.0.pos_m" = { min = 100.0, max = 600.0 }\n'
                           '"ego.pos_m" = { min = 40.0, max = 300.0 }')
    fam = load_search_catalog(path).families[0]
    sc = build_point(fam, [250.0, 60.0], "fam__t0007")
    assert not isinstance(sc, Refused)
    assert sc.name == "fam__t0007" and sc.family == "fam"
    assert sc.stalled[0].pos_m == 250.0 and sc.ego.pos_m == 60.0
    assert dict(sc.sweep_values) == {"stalled.0.pos_m": 250.0, "ego.pos_m": 60.0}
    # the ego on top of the stalled car: SUMO would refuse it, so the catalog does
    refused = build_point(fam, [200.0, 200.0], "fam__t0008")
    assert isinstance(refused, Refused) and refused.reason
