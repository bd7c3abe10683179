"""The report of an interrupted night (#26): the scenarios its manifest lists that were
not run are named on the page and are skipped cases in junit.xml, with the provenance
as <properties>; a complete night has neither."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import synthetic_runs as sr

from reports import write_reports
from reports.manifest import Manifest, write_manifest
from reports.provenance import Provenance
from reports.record import iter_run_dirs


def _manifest(out: Path, extra: tuple[str, ...]) -> None:
    names = tuple(d.name for d in iter_run_dirs(out)) + extra
    write_manifest(out, Manifest(catalog="/c/nightly.toml", catalog_name="nightly",
                                 scenarios=names, started="2026-12-02T01:00:00", jobs=1,
                                 executor="local",
                                 provenance=Provenance(git_sha="a" * 40, host="ci-7")))


def test_scenarios_not_run_are_named_and_skipped(tmp_path: Path) -> None:
    out = sr.make_catalog(tmp_path / "night", controllers=("ctrl_a",))
    _manifest(out, ("late_one", "late_two"))
    paths = write_reports(out)
    root = ET.parse(paths.junit_xml).getroot()
    skipped = [c.get("name") for c in root.iter("testcase") if c.find("skipped") is not None]
    assert skipped == ["late_one", "late_two"]
    assert root.get("skipped") == "2"
    assert int(root.get("tests") or 0) == len(list(iter_run_dirs(out))) + 2
    props = {p.get("name"): p.get("value") for p in root.iter("property")}
    assert props["git_revision"] == "a" * 40 and props["host"] == "ci-7"
    assert props["catalog"] == "/c/nightly.toml"
    html = paths.report_html.read_text()
    assert 'id="not-run"' in html and "late_one" in html and "late_two" in html


def test_a_complete_night_has_no_skipped_cases(tmp_path: Path) -> None:
    out = sr.make_catalog(tmp_path / "night", controllers=("ctrl_a",))
    _manifest(out, ())
    paths = write_reports(out)
    root = ET.parse(paths.junit_xml).getroot()
    assert root.get("skipped") == "0"
    assert not [c for c in root.iter("testcase") if c.find("skipped") is not None]
    assert 'id="not-run"' not in paths.report_html.read_text()
