"""Logical scenarios: a variation file imports as a family whose `[scenario.search]`
spans its distributions (`openscenario.parameters.<Name>`, `openscenario.value_sets.<i>`),
and `hwyeval search` makes each point by importing the template with the point's values
(suite/search/logical.py). Known answers from the ALKS variation files
(catalogs/r157/source, read only) and tests/data/openscenario (bend_cut_in_variation:
deterministic; bend_cut_in_logical: stochastic, a quarter of its Gap range violating the
template's Gap >= 10)."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

import pytest

from suite.catalog import CatalogError, load_catalog
from suite.catalog import storyboard as sb
from suite.cli import main
from suite.importers.openscenario.logical import logical_tables
from suite.importers.openscenario.pipeline import ImportOptions, import_file
from suite.importers.openscenario.variation import distribution_space, template_of
from suite.importers.openscenario.xml_safe import read_xml
from suite.search.space import load_search_catalog

DATA = Path(__file__).resolve().parent / "data" / "openscenario"
LOGICAL = Path(__file__).resolve().parents[1] / "catalogs" / "r157" / "source" / \
    "logical_scenarios"
CUT_IN = LOGICAL / "alks_scenario_4_4_1_cut_in_no_collision_variation.xosc"
P = "openscenario.parameters."


def _tables(path: Path, catalog_dir: Path, **kw: Any) -> dict[str, Any]:
    root = read_xml(path).getroot()
    template = template_of(root, path)
    tables, notes = logical_tables(template, read_xml(template).getroot(),
                                   distribution_space(root), catalog_dir, **kw)
    assert notes == []
    return tables


def _steps(lo: float, hi: float, step: float) -> list[float]:
    return [lo + k * step for k in range(round((hi - lo) / step) + 1)]


# ---------------------------------------------------------------- the importer's tables

def test_a_deterministic_file_searches_its_values(tmp_path: Path) -> None:
    t = _tables(DATA / "bend_cut_in_variation.xosc", DATA)
    osc = t["openscenario"]
    assert osc["template"] == "bend_cut_in.xosc"  # relative to the catalog's folder
    # the varied parameters at the template's declared values; the value set apart
    assert osc["parameters"] == {"Gap": 30.0}
    assert osc["value_sets"] == [{"HeroSpeed": 25.0, "LaneRate": 1.2}]
    assert t["search"] == {
        P + "Gap": {"choices": [5.0, 17.5, 30.0]},  # DistributionRange 5..30 by 12.5
        "openscenario.value_sets.0": {"choices": [{"HeroSpeed": 20.0, "LaneRate": 1.0},
                                                  {"HeroSpeed": 30.0, "LaneRate": 2.0}]}}
    # --search-ranges: a DistributionRange between its ends
    ranged = _tables(DATA / "bend_cut_in_variation.xosc", tmp_path, search_ranges=True)
    assert ranged["search"][P + "Gap"] == {"min": 5.0, "max": 30.0}
    assert ranged["openscenario"]["template"].endswith("tests/data/openscenario/bend_cut_in.xosc")
    assert (tmp_path / ranged["openscenario"]["template"]).resolve() == DATA / "bend_cut_in.xosc"


def test_a_stochastic_file_searches_its_ranges() -> None:
    t = _tables(DATA / "bend_cut_in_logical.xosc", DATA)
    assert t["openscenario"]["parameters"] == {"Gap": 30.0, "HeroSpeed": 25.0, "LaneRate": 1.2}
    assert t["search"] == {P + "Gap": {"min": 0.0, "max": 40.0},  # uniform
                           P + "HeroSpeed": {"min": 18.0, "max": 32.0},  # normal, clipped
                           P + "LaneRate": {"choices": [1.0, 2.0]}}  # probability set
    t = _tables(DATA / "bend_cut_in_stochastic.xosc", DATA)
    assert t["search"] == {P + "Gap": {"min": 12.0, "max": 40.0},
                           P + "HeroSpeed": {"min": 15.0, "max": 35.0}}


def test_stochastic_distributions_without_a_range(tmp_path: Path) -> None:
    (tmp_path / "bend_cut_in.xosc").symlink_to(DATA / "bend_cut_in.xosc")
    path = tmp_path / "v.xosc"
    path.write_text("""<?xml version="1.0"?>
<OpenSCENARIO>
<FileHeader revMajor="1" revMinor="2" date="2026-01-01T00:00:00" description="x" author="x"/>
<ParameterValueDistribution><ScenarioFile filepath="bend_cut_in.xosc"/>
<Stochastic numberOfTestRuns="3" randomSeed="1">
 <StochasticDistribution parameterName="Gap">
   <NormalDistribution expectedValue="20" variance="4"/></StochasticDistribution>
 <StochasticDistribution parameterName="HeroSpeed"><Histogram>
   <Bin weight="1"><Range lowerLimit="10" upperLimit="20"/></Bin>
   <Bin weight="2"><Range lowerLimit="20" upperLimit="30"/></Bin>
 </Histogram></StochasticDistribution>
 <StochasticDistribution parameterName="LaneRate">
   <PoissonDistribution expectedValue="4"/></StochasticDistribution>
</Stochastic></ParameterValueDistribution></OpenSCENARIO>
""")
    t = _tables(path, tmp_path)
    assert t["search"] == {P + "Gap": {"min": 14.0, "max": 26.0},  # mean +- 3 sd
                           P + "HeroSpeed": {"min": 10.0, "max": 30.0},  # the bins' span
                           # a count, mean +- 3 sqrt(mean), whole numbers
                           P + "LaneRate": {"min": 0, "max": 10, "int": True}}


def test_the_alks_cut_in_is_searched_over_its_file_s_sets(tmp_path: Path) -> None:
    t = _tables(CUT_IN, tmp_path)
    assert t["search"] == {
        P + "Ego_InitSpeed_Ve0_kph": {"choices": _steps(20.0, 60.0, 10.0)},
        P + "CutInVehicle_Model": {"choices": ["car", "truck", "van", "bus", "motorbike"]},
        P + "CutInVehicle_InitPosition_RelativeLaneId": {"choices": [1, -1]},  # an int
        P + "CutInVehicle_RelativeInitSpeed_Ve0_Vo0_kph": {"choices": _steps(-50.0, -10.0, 10.0)},
        P + "CutInVehicle_HeadwayDistanceTrigger_dx0_m": {"choices": _steps(0.0, 60.0, 10.0)},
        P + "CutInVehicle_LaneChange_MaxLateralVelocity_Vy_mps": {"choices":
                                                                 _steps(0.5, 3.0, 0.5)},
        P + "CutInVehicle_Acceleration_Rate_mps2": {"choices": _steps(-3.0, 3.0, 1.5)}}
    # 5 x 5 x 2 x 5 x 7 x 6 x 5 = 52500 points, the file's sets
    assert math.prod(len(v["choices"]) for v in t["search"].values()) == 52500
    assert t["openscenario"]["parameters"]["Ego_InitSpeed_Ve0_kph"] == 60.0  # the template's
    ranged = _tables(CUT_IN, tmp_path, search_ranges=True)["search"]
    assert ranged[P + "Ego_InitSpeed_Ve0_kph"] == {"min": 20.0, "max": 60.0}
    assert ranged[P + "CutInVehicle_InitPosition_RelativeLaneId"] == {"choices": [1, -1]}
    # a --param value is fixed, not searched
    fixed = _tables(CUT_IN, tmp_path, fixed=(("Ego_InitSpeed_Ve0_kph", "40"),))
    assert P + "Ego_InitSpeed_Ve0_kph" not in fixed["search"]
    assert fixed["openscenario"]["parameters"]["Ego_InitSpeed_Ve0_kph"] == 40.0


def test_alks_value_sets_are_one_key(tmp_path: Path) -> None:
    t = _tables(LOGICAL / "alks_scenario_4_2_1_fully_blocking_target_variation.xosc", tmp_path)
    assert list(t["search"]) == [P + "Road", P + "Ego_InitSpeed_Ve0_kph",
                                 "openscenario.value_sets.0"]
    assert len(t["search"][P + "Road"]["choices"]) == 5
    assert t["search"][P + "Ego_InitSpeed_Ve0_kph"]["choices"] == _steps(5.0, 60.0, 5.0)
    models = t["search"]["openscenario.value_sets.0"]["choices"]
    assert [m["TargetBlocking_Model"] for m in models] == \
        ["pedestrian", "car", "truck", "van", "bus", "motorbike"]
    assert models[0]["TargetBlocking_Catalog"] == "pedestrian_catalog"


# ---------------------------------------------------------------- the catalog

@pytest.fixture(scope="module")
def logical_catalog(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("logical")
    r = import_file(DATA / "bend_cut_in_logical.xosc", out, ImportOptions(variants=1))
    assert len(r.names) == 2
    from suite.importers.common.catalog import write_catalog
    from suite.importers.openscenario.catalog_out import OUTPUTS
    return write_catalog(out, OUTPUTS)


def test_the_import_writes_a_logical_scenario(logical_catalog: Path) -> None:
    cat = load_catalog(logical_catalog)  # run reads it, the openscenario table as data
    assert [s.name for s in cat] == ["bend_cut_in_logical", "bend_cut_in_logical__set0"]
    (fam,) = load_search_catalog(logical_catalog).families
    assert fam.logical is not None and fam.logical.template == DATA / "bend_cut_in.xosc"
    assert fam.paths == (P + "Gap", P + "HeroSpeed", P + "LaneRate")
    assert fam.nominal == (30.0, 25.0, 1.2)
    # the set imported as a scenario names its values, and is no family
    frag = json.loads((logical_catalog.parent / "bend_cut_in_logical__set0.scenario.json")
                      .read_text())["scenario"]
    assert "search" not in frag
    assert set(frag["openscenario"]["parameters"]) == {"Gap", "HeroSpeed", "LaneRate"}


def _variant(catalog: Path, tmp_path: Path, old: str, new: str) -> Path:
    text = catalog.read_text().split("\n", 1)[1]  # without the generated-by line
    assert old in text
    path = catalog.parent / f"{tmp_path.name}.toml"
    path.write_text(text.replace(old, new, 1))
    return path


@pytest.mark.parametrize(("old", "new", "key"), [
    ('template = "', 'template = 3 # "', "openscenario.template"),
    ("parameters = { Gap = 30.0,", "colour = 1\nparameters = { Gap = 30.0,",
     "openscenario.colour"),
    ("parameters = { Gap = 30.0,", "parameters = { Gap = [30.0],", "openscenario.parameters"),
])
def test_the_loader_checks_the_openscenario_table(logical_catalog: Path, tmp_path: Path,
                                                  old: str, new: str, key: str) -> None:
    path = _variant(logical_catalog, tmp_path, old, new)
    with pytest.raises(CatalogError, match=key.replace(".", r"\.")):
        load_catalog(path)


@pytest.mark.parametrize(("old", "new", "expected"), [
    ('"openscenario.parameters.Gap"', '"openscenario.parameters.Nope"', "'Nope' is not one"),
    ('"openscenario.parameters.Gap"', '"ego.speed_mps"', "does not write"),
    ('template = "', 'template = "missing/', "a readable OpenSCENARIO scenario file"),
    ('"openscenario.parameters.Gap"', '"openscenario.template"', "openscenario.parameters"),
])
def test_the_search_checks_a_logical_family(logical_catalog: Path, tmp_path: Path, old: str,
                                            new: str, expected: str) -> None:
    path = _variant(logical_catalog, tmp_path, old, new)
    with pytest.raises(CatalogError, match=expected):
        load_search_catalog(path)


# ---------------------------------------------------------------- searching (SUMO)

def _rows(out: Path) -> list[dict[str, str]]:
    with (out / "search.csv").open() as fh:
        return list(csv.DictReader(fh))


def _point(out: Path, run: str) -> dict[str, Any]:
    return dict(json.loads((out / "openscenario" / run / "point.json").read_text()))


def _ego_speed(out: Path, run: str) -> float:
    info = json.loads((out / run / "run.json").read_text())["info"]
    return float(info["scenario_spec"]["ego"]["speed_mps"])


@pytest.mark.slow
def test_search_imports_each_point_and_refuses_what_the_template_does(
        logical_catalog: Path, tmp_path: Path) -> None:
    out = tmp_path / "search"
    rc = main(["search", str(logical_catalog), "--out", str(out), "--sampler", "random",
               "--budget", "4", "--no-log", "--jobs", "1", "--seed", "1", "--no-shrink"])
    assert rc in (0, 1)
    rows = _rows(out)
    ran = [r for r in rows if r["status"] != "refused"]
    refused = [r for r in rows if r["status"] == "refused"]
    assert len(ran) == 4 and refused  # refused points do not count against the budget
    assert sorted(d.name for d in out.iterdir() if (d / "run.json").is_file()) == \
        sorted(r["run"] for r in ran)
    gaps: list[tuple[float, float]] = []
    for r in ran:
        gap, speed, rate = (json.loads(r[P + k]) for k in ("Gap", "HeroSpeed", "LaneRate"))
        point = _point(out, r["run"])
        # the point's own values reached the import (exactly) and the run
        assert point["parameters"] == {"Gap": repr(gap), "HeroSpeed": repr(speed),
                                       "LaneRate": repr(rate)}
        assert _ego_speed(out, r["run"]) == pytest.approx(speed, abs=1e-6)
        story = sb.story_from_json((out / "openscenario" / r["run"] / "point.story.json")
                                   .read_text())
        lead = next(i for i in story.inits if i.entity == "Lead")
        # the lead starts ds = Gap x 2 + 5 m ahead of the hero (along the bend's inner
        # lane: the road's s scaled to the lane, docs/openscenario.md, within 0.5 m here)
        gaps.append((gap, lead.position.pos_m - point["scenario"]["ego"]["pos_m"]))
    assert all(abs(d - (2.0 * g + 5.0)) < 0.5 for g, d in gaps), gaps
    for r in refused:
        assert json.loads(r[P + "Gap"]) < 10.0
        assert "parameter Gap" in r["reason"] and "greaterOrEqual 10" in r["reason"]
        assert not (out / "openscenario" / f"bend_cut_in_logical__t{int(r['trial']):04d}").exists()
    if rc == 1:  # found.toml replays the failing point's own import
        found = load_catalog(out / "found.toml")
        for sc in found:
            assert sc.story is not None and "openscenario" in str(sc.net_path)


@pytest.mark.slow
def test_search_on_the_alks_cut_in(tmp_path: Path) -> None:
    cat_dir = tmp_path / "cat"
    r = import_file(CUT_IN, cat_dir, ImportOptions(r157=True))
    assert r.sets == 52500
    from suite.importers.common.catalog import write_catalog
    from suite.importers.openscenario.catalog_out import OUTPUTS
    catalog = write_catalog(cat_dir, OUTPUTS)
    out = tmp_path / "search"
    rc = main(["search", str(catalog), "--out", str(out), "--sampler", "random", "--budget",
               "4", "--no-log", "--jobs", "1", "--seed", "0", "--no-shrink"])
    assert rc in (0, 1)
    rows = _rows(out)
    ran = [r for r in rows if r["status"] != "refused"]
    assert len(ran) == 4
    for row in ran:
        point = _point(out, row["run"])
        for key, text in point["parameters"].items():
            value = json.loads(row[P + key])
            assert text == (repr(value) if isinstance(value, float) else str(value))
        kph = json.loads(row[P + "Ego_InitSpeed_Ve0_kph"])
        assert _ego_speed(out, row["run"]) == pytest.approx(kph / 3.6, abs=1e-5)
    refused = [r for r in rows if r["status"] == "refused"]
    assert refused and all("violates its constraints" in r["reason"] for r in refused)
