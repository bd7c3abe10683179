"""UN R157's acceptance logic over a pack's runs (reports.r157.outcome) with known
answers, the Annex 5 section an OpenSCENARIO file names, the catalog's ``labels`` and
the importer's ``--param`` (real files of the bundled pack)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from reports.r157.outcome import PackRow, RunOutcome, summarise
from suite.catalog import CatalogError, load_catalog
from suite.importers.openscenario.pipeline import ImportOptions, r157_section
from suite.importers.openscenario.xml_safe import read_xml

TEMPLATES = (Path(__file__).resolve().parents[1] / "catalogs" / "r157" / "source"
             / "logical_scenarios" / "concrete_scenarios")


def _run(status: str = "pass", collisions: int = 0, at_fault: int = 0,
         gap_s: float = 0.0) -> RunOutcome:
    return RunOutcome(status=status, collisions=collisions, at_fault_collisions=at_fault,
                      at_fault_delta_v_mps=math.nan, min_ttc_s=math.nan,
                      gap_shortfall_s=gap_s, failed=(), run="r")


def _row(system: RunOutcome, reference: RunOutcome | None, section: str = "4.4") -> PackRow:
    return PackRow(section, "s", 60.0, "two_loop", system, reference)


def test_a_collision_the_reference_driver_avoids_is_not_accepted() -> None:
    acc = _row(_run("fail", collisions=1), _run()).acceptance
    assert not acc.met and acc.preventable and not acc.unpreventable


def test_a_collision_the_reference_driver_meets_too_is_accepted_if_not_caused() -> None:
    acc = _row(_run("fail", collisions=1), _run("fail", collisions=1, at_fault=1)).acceptance
    assert acc.met and acc.unpreventable and not acc.preventable


def test_a_collision_caused_by_the_system_is_never_accepted() -> None:
    acc = _row(_run("fail", collisions=1, at_fault=1), _run("fail", collisions=1)).acceptance
    assert not acc.met and len(acc.reasons) == 1


def test_the_following_gap_and_an_error_are_not_accepted() -> None:
    assert not _row(_run("fail", gap_s=0.3), None).acceptance.met
    assert not _row(_run("error"), _run()).acceptance.met
    # without a reference run a contact the system did not cause is not judged preventable
    assert _row(_run("fail", collisions=1), None).acceptance.met


def test_comfort_failures_are_no_part_of_the_regulations_verdict() -> None:
    run = RunOutcome("fail", 0, 0, math.nan, math.nan, 0.0, ("max_abs_long_jerk_mps3",), "r")
    assert _row(run, _run()).acceptance.met


def test_the_summary_counts_per_section_and_in_all() -> None:
    rows = [_row(_run("fail", collisions=1), _run(), "4.4"),
            _row(_run(), _run("fail", collisions=1), "4.4"),
            _row(_run(), None, "4.1")]
    by = {(s.section, s.controller): s for s in summarise(rows)}
    s44, s_all = by[("4.4", "two_loop")], by[("all", "two_loop")]
    assert (s44.scenarios, s44.met, s44.collided, s44.preventable) == (2, 1, 1, 1)
    assert (s44.with_reference, s44.reference_passed, s44.reference_collided) == (2, 1, 1)
    assert (s_all.scenarios, s_all.met, s_all.with_reference) == (3, 2, 2)


def test_each_alks_template_names_its_section() -> None:
    for path in sorted(TEMPLATES.glob("*_template.xosc")):
        # alks_scenario_4_<n>_<k>_...: the section is 4.<n>
        assert r157_section(read_xml(path).getroot(), path) == f"4.{path.stem.split('_')[3]}"


def test_a_section_is_read_from_the_description_then_the_name(tmp_path: Path) -> None:
    def section(description: str, stem: str) -> str | None:
        path = tmp_path / f"{stem}.xosc"
        path.write_text(f'<OpenSCENARIO><FileHeader description="{description}"/>'
                        "</OpenSCENARIO>")
        return r157_section(read_xml(path).getroot(), path)

    assert section("R157 test 4.5 cut-out", "x") == "4.5"
    assert section("scenario", "alks_4_3_follow") == "4.3"
    assert section("revision 14.2, 4.7", "case_10_1") is None  # not 4.1-4.6, nor 14.2
    assert section("", "r157_4_6") == "4.6"


def test_labels_are_checked_and_no_part_of_the_test(tmp_path: Path) -> None:
    base = ('[defaults]\ncontroller = "two_loop"\nduration_s = 5.0\nstep_s = 0.02\n'
            '[[scenario]]\nname = "a"\nnet = "straight_2lane"\n'
            'ego = { lane = 0, pos_m = 20.0, speed_mps = 20.0 }\n')
    cat = tmp_path / "c.toml"
    cat.write_text(base + 'labels = { r157_section = "4.4" }\n')
    (labelled,) = load_catalog(cat)
    assert dict(labelled.labels) == {"r157_section": "4.4"}
    cat.write_text(base)
    (plain,) = load_catalog(cat)
    assert "labels" not in plain.as_dict()
    from suite.run.info import scenario_content_sha256

    assert scenario_content_sha256(labelled, "n") == scenario_content_sha256(plain, "n")
    for bad in ('{ "Bad Key" = "x" }', '{ k = 3 }', '{ k = "" }', '"4.4"'):
        cat.write_text(base + f"labels = {bad}\n")
        with pytest.raises(CatalogError) as exc:
            load_catalog(cat)
        assert "labels" in str(exc.value)


@pytest.mark.slow  # netconvert
def test_param_replaces_a_declared_value_and_constraints_still_hold(tmp_path: Path) -> None:
    from suite.importers.openscenario import import_files
    from suite.importers.openscenario.errors import OscImportError

    template = TEMPLATES / "alks_scenario_4_4_1_cut_in_no_collision_template.xosc"
    out = import_files([template], tmp_path / "a", ImportOptions(
        parameters=(("Ego_InitSpeed_Ve0_kph", "50"),)))
    assert not out.failures
    (sc,) = load_catalog(tmp_path / "a" / "catalog.toml")
    assert sc.ego.speed_mps == pytest.approx(50.0 / 3.6, abs=1e-5)
    # beyond the template's 60 km/h cap: refused naming the parameter, unless ignored
    out = import_files([template], tmp_path / "b", ImportOptions(
        parameters=(("Ego_InitSpeed_Ve0_kph", "130"),)))
    assert len(out.failures) == 1 and isinstance(out.failures[0], OscImportError)
    assert "Ego_InitSpeed_Ve0_kph" in str(out.failures[0])
    out = import_files([template], tmp_path / "c", ImportOptions(
        parameters=(("Ego_InitSpeed_Ve0_kph", "130"),), ignore_constraints=True))
    (sc,) = load_catalog(tmp_path / "c" / "catalog.toml")
    assert sc.ego.speed_mps == pytest.approx(130.0 / 3.6, abs=1e-5)
    # a parameter the file does not declare is an error, not silently dropped
    out = import_files([template], tmp_path / "d", ImportOptions(
        parameters=(("NoSuchParameter", "1"),)))
    assert len(out.failures) == 1 and "NoSuchParameter" in str(out.failures[0])
