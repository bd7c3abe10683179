"""`hwyeval import openscenario` on hand-written files (tests/data/openscenario: a bend
road of two lane sections, a cut-in with a catalog reference, a world position and
expressions, its variation files) and hostile or unsupported ones: where things land,
what is refused and how it is named."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import pytest

from suite.catalog import load_catalog
from suite.catalog import storyboard as sb
from suite.cli import main
from suite.importers.openscenario import ImportOptions, OscImportError, import_files
from suite.importers.openscenario.pipeline import import_file
from suite.road.network import RoadNetwork

DATA = Path(__file__).resolve().parent / "data" / "openscenario"


@pytest.fixture(scope="module")
def imported(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("osc")
    outcome = import_files([DATA / "bend_cut_in.xosc"], out)
    assert not outcome.failures, outcome.failures
    return out


def _story(out: Path, stem: str = "bend_cut_in") -> sb.Storyboard:
    return sb.story_from_json((out / f"{stem}.story.json").read_text())


def _scenario(out: Path, stem: str = "bend_cut_in") -> dict[str, Any]:
    data: dict[str, Any] = json.loads((out / f"{stem}.scenario.json").read_text())
    return dict(data["scenario"])


def test_the_ego_starts_where_its_lane_position_says(imported: Path) -> None:
    sc = _scenario(imported)
    net = RoadNetwork.load(imported / sc["net"])
    # s = 50 m of the 450 m section, scaled to the SUMO edge, plus the front bumper (1.3
    # + 4.6 / 2 ahead of the reference point); OpenDRIVE lane -1 is SUMO lane 1 there
    span = net.route_length_m(sc["route"])  # the road's 900 m as netconvert built it
    expected = 50.0 / 900.0 * span + 1.3 + 2.3
    assert sc["ego"]["pos_m"] == pytest.approx(expected, abs=1e-3)
    assert sc["ego"]["lane"] == 1 and sc["ego"]["speed_mps"] == 25.0
    assert sc["duration_s"] == 20.0 and sc["route"] == ["-7#0", "-7#1"]


def test_a_relative_teleport_lands_where_the_expression_says(imported: Path) -> None:
    story = _story(imported)
    sc = _scenario(imported)
    net = RoadNetwork.load(imported / sc["net"])
    lead = next(i for i in story.inits if i.entity == "Lead")
    scale = net.route_length_m(sc["route"]) / 900.0
    # ds = ${$Gap * 2 + 5} = 65 m from the Hero's s = 50; the Lead's catalog length is
    # assigned ($LeadLength = 4.2), its front 1.2 + 2.1 ahead of its reference point
    assert lead.position.pos_m == pytest.approx((50.0 + 65.0) * scale + 1.2 + 2.1, abs=1e-6)
    assert lead.position.lane == 0  # dLane -1: OpenDRIVE lane -2, SUMO's rightmost
    assert lead.speed_mps == pytest.approx(20.0)  # 25 - 5 (relative to the Hero)
    assert story.entity("Lead").length_m == pytest.approx(4.2)


def test_a_world_position_lands_on_its_lane(imported: Path) -> None:
    van = next(i for i in _story(imported).inits if i.entity == "Van")
    assert van.position.lane == 1 and abs(van.position.lateral_m) < 0.1
    assert van.speed_mps == 0.0
    # projected from x, y: 200 m along the straight start, the front 1.5 + 2.6 ahead
    assert van.position.pos_m == pytest.approx(200.0 + 1.5 + 2.6, abs=0.3)


def test_the_storyboard_is_typed(imported: Path) -> None:
    story = _story(imported)
    event = story.stories[0].acts[0].groups[0].maneuvers[0].events[0]
    (name, action), = event.actions
    assert name == "CutInAction" and isinstance(action, sb.LaneChangeAction)
    assert action.relative == sb.RelativeLaneTarget("Hero", 0)
    assert action.value == 1.2 and action.dimension == "rate"
    cond = event.start.groups[0].conditions[0]
    assert isinstance(cond.check, sb.TimeHeadwayCondition) and cond.edge == "rising"
    assert cond.triggering == ("Hero",)


def test_the_lane_map_is_recorded(imported: Path) -> None:
    lanes = json.loads((imported / "bend_road.lanes.json").read_text())
    by = {(r["road"], r["lane"]): r["sumo"] for r in lanes["lanes"]}
    assert by[("7", -1)] == [["-7#0", 1], ["-7#1", 2]]
    assert by[("7", -3)] == [["-7#1", 0]]
    assert lanes["roads"]["7"]["sections_m"] == [0.0, 450.0]


@pytest.mark.slow  # several imports, each through netconvert
def test_the_catalog_loads_and_the_net_is_deterministic(imported: Path, tmp_path: Path) -> None:
    cat = load_catalog(imported / "catalog.toml")
    (scenario,) = cat.scenarios
    assert scenario.story is not None and scenario.storyboard == "bend_cut_in.story.json"
    assert "storyboard" in scenario.as_dict()
    import_files([DATA / "bend_cut_in.xosc"], tmp_path)
    assert (tmp_path / "bend_road.net.xml").read_bytes() == \
        (imported / "bend_road.net.xml").read_bytes()
    assert b"generated on" not in (tmp_path / "bend_road.net.xml").read_bytes()


@pytest.mark.slow  # several imports, each through netconvert
def test_variation_files_expand_with_their_counts(tmp_path: Path) -> None:
    r = import_file(DATA / "bend_cut_in_variation.xosc", tmp_path, ImportOptions(variants=2))
    assert (r.sets, r.invalid_sets) == (6, 2)  # Gap 5 / 17.5 / 30 x two value sets
    sets = json.loads((tmp_path / "bend_cut_in_variation.sets.json").read_text())
    assert sets["valid"] == 4  # of the six, Gap 17.5 and 30 twice each
    # two of them, spread evenly: the valid sets 0 and 2, Gap 17.5 and 30
    assert [(s["set"], s["values"]["Gap"]) for s in sets["imported"]] == \
        [(0, "17.5"), (2, "30.0")]
    assert len(r.names) == 3
    r = import_file(DATA / "bend_cut_in_stochastic.xosc", tmp_path, ImportOptions())
    assert (r.sets, r.invalid_sets) == (25, 0)
    again = import_file(DATA / "bend_cut_in_stochastic.xosc", tmp_path, ImportOptions())
    assert again.sets == 25  # the seed makes the draws the same


# ---------------------------------------------------------------- refusals

def _copy_with(tmp_path: Path, old: str, new: str, name: str = "case.xosc") -> Path:
    for f in ("bend_road.xodr",):
        shutil.copy(DATA / f, tmp_path / f)
    shutil.copytree(DATA / "catalogs", tmp_path / "catalogs", dirs_exist_ok=True)
    text = (DATA / "bend_cut_in.xosc").read_text()
    assert old in text
    path = tmp_path / name
    path.write_text(text.replace(old, new, 1))
    return path


def test_a_violated_constraint_names_the_parameter(tmp_path: Path) -> None:
    path = _copy_with(tmp_path, 'name="Gap" parameterType="double" value="30.0"',
                      'name="Gap" parameterType="double" value="5.0"')
    with pytest.raises(OscImportError, match=r"parameter Gap: value 5 violates"):
        import_file(path, tmp_path / "out", ImportOptions())
    r = import_file(path, tmp_path / "out", ImportOptions(ignore_constraints=True))
    assert r.names == ("case",)


def test_an_unsupported_element_names_file_element_and_line(tmp_path: Path) -> None:
    path = _copy_with(tmp_path, "<LaneChangeAction>",
                      "<LaneChangeAction>\n<UnknownThing/>")
    text = path.read_text().splitlines()
    with pytest.raises(OscImportError) as info:
        import_file(path, tmp_path / "out", ImportOptions())
    err = info.value
    assert err.path.endswith("case.xosc") and err.line > 0
    assert "LaneChangeAction" in text[err.line - 1] or "UnknownThing" in str(err)
    path = _copy_with(tmp_path, "<TeleportAction><Position><WorldPosition",
                      "<TeleportAction><Position><GeoPosition latitude='1' longitude='2'/>"
                      "</Position></TeleportAction></PrivateAction><PrivateAction>"
                      "<TeleportAction><Position><WorldPosition", name="geo.xosc")
    with pytest.raises(OscImportError) as info:
        import_file(path, tmp_path / "out", ImportOptions())
    assert info.value.element == "GeoPosition" and info.value.line > 0
    assert "GeoPosition" in path.read_text().splitlines()[info.value.line - 1]
    assert str(info.value).startswith(f"{path}:{info.value.line}: <GeoPosition>")


def test_a_global_action_in_a_story_is_refused(tmp_path: Path) -> None:
    path = _copy_with(tmp_path, '<Action name="CutInAction">\n                <PrivateAction>',
                      '<Action name="CutInAction">\n<GlobalAction><EnvironmentAction/>'
                      '</GlobalAction>\n                <PrivateAction>')
    with pytest.raises(OscImportError, match="only private actions|exactly one child"):
        import_file(path, tmp_path / "out", ImportOptions())


HOSTILE = {
    "external": ('<?xml version="1.0"?>\n<!DOCTYPE OpenSCENARIO [\n'
                 '  <!ENTITY secret SYSTEM "file:///etc/passwd">\n]>\n'
                 '<OpenSCENARIO><FileHeader description="&secret;"/></OpenSCENARIO>\n'),
    "bomb": ('<?xml version="1.0"?>\n<!DOCTYPE lolz [\n  <!ENTITY lol "lol">\n'
             '  <!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">\n'
             '  <!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">\n]>\n'
             '<OpenSCENARIO><FileHeader description="&lol3;"/></OpenSCENARIO>\n'),
}


@pytest.mark.parametrize("kind", sorted(HOSTILE))
def test_hostile_xml_is_refused(tmp_path: Path, kind: str) -> None:
    path = tmp_path / f"{kind}.xosc"
    path.write_text(HOSTILE[kind])
    with pytest.raises(OscImportError, match="entit") as info:
        import_file(path, tmp_path / "out", ImportOptions())
    assert info.value.path == str(path)
    assert main(["import", "openscenario", str(path), "--out", str(tmp_path / "cli")]) == 2


def test_a_direct_junction_is_refused_with_its_reason(tmp_path: Path) -> None:
    path = _copy_with(tmp_path, "bend_road.xodr", "direct.xodr")
    road = (DATA / "bend_road.xodr").read_text().replace(
        "</OpenDRIVE>", '  <junction id="9" type="direct"><connection id="0" '
        'incomingRoad="7" linkedRoad="8" contactPoint="start"/></junction>\n</OpenDRIVE>')
    (tmp_path / "direct.xodr").write_text(road)
    with pytest.raises(OscImportError, match="direct junction") as info:
        import_file(path, tmp_path / "out", ImportOptions())
    assert info.value.path.endswith("direct.xodr") and info.value.element == "connection"


def test_the_cli_imports_and_exits_2_on_a_bad_file(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.xosc"
    bad.write_text("<OpenSCENARIO><Storyboard>")
    rc = main(["import", "openscenario", str(DATA / "bend_cut_in.xosc"), str(bad),
               "--out", str(tmp_path / "out")])
    captured = capsys.readouterr()
    assert rc == 2 and "bad.xosc" in captured.err and "not well-formed" in captured.err
    assert "bend_cut_in.xosc -> bend_cut_in" in captured.out
    assert "bend_cut_in" in (tmp_path / "out" / "catalog.toml").read_text()


@pytest.mark.slow  # several imports, each through netconvert
def test_the_ego_must_be_named_or_found(tmp_path: Path) -> None:
    with pytest.raises(OscImportError, match="--ego"):
        import_file(DATA / "bend_cut_in.xosc", tmp_path, ImportOptions(ego="Nobody"))
    path = _copy_with(tmp_path, 'ScenarioObject name="Hero"', 'ScenarioObject name="Main"')
    text = path.read_text().replace('"Hero"', '"Main"')
    path.write_text(text)
    with pytest.raises(OscImportError, match="cannot tell the ego"):
        import_file(path, tmp_path / "o", ImportOptions())
    assert import_file(path, tmp_path / "o", ImportOptions(ego="Main")).names == ("case",)


def _imports(package: Path) -> set[str]:
    import ast

    out: set[str] = set()
    for f in package.rglob("*.py"):
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module:
                out.add(node.module)
            elif isinstance(node, ast.Import):
                out.update(a.name for a in node.names)
    return out


def test_the_importer_and_the_runtime_stay_apart() -> None:
    suite = Path(__file__).resolve().parents[1] / "suite"
    importer = _imports(suite / "importers" / "openscenario")
    assert not [m for m in importer if m.startswith(("suite.run", "suite.world",
                                                     "suite.exec"))]
    runtime = _imports(suite / "world" / "storyboard")
    assert not [m for m in runtime if m.startswith("suite.importers")]
    assert "suite.catalog.storyboard" in importer and "suite.catalog.storyboard" in runtime


def test_nested_parameter_declarations_are_refused(tmp_path: Path) -> None:
    path = _copy_with(tmp_path, '<Maneuver name="CutInManeuver">',
                      '<Maneuver name="CutInManeuver"><ParameterDeclarations>'
                      '<ParameterDeclaration name="Gap" parameterType="double" value="3"/>'
                      '</ParameterDeclarations>')
    with pytest.raises(OscImportError, match="declare them at the top") as info:
        import_file(path, tmp_path / "out", ImportOptions())
    assert info.value.element == "ParameterDeclarations" and info.value.line > 0


def test_an_ego_at_the_end_of_its_road_and_a_left_hand_road_are_refused(tmp_path: Path) -> None:
    path = _copy_with(tmp_path, 'laneId="-1" s="50"', 'laneId="-1" s="880"')
    with pytest.raises(OscImportError, match="before its route ends") as info:
        import_file(path, tmp_path / "out", ImportOptions())
    assert info.value.element == "Init"
    path = _copy_with(tmp_path, "bend_road.xodr", "lht.xodr", name="lht.xosc")
    (tmp_path / "lht.xodr").write_text((DATA / "bend_road.xodr").read_text().replace(
        'rule="RHT"', 'rule="LHT"'))
    with pytest.raises(OscImportError, match="left-hand traffic"):
        import_file(path, tmp_path / "out", ImportOptions())
