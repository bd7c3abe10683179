"""The public ALKS interpretation of UN R157 (catalogs/r157/source, MPL-2.0): every
template imports, and into exactly the files of the bundled catalogs/r157/imported;
every variation file expands to its parameter sets (the count per file below), and every
template runs in SUMO, none of them in error (slow)."""

from __future__ import annotations

import csv
import json
import tempfile
from pathlib import Path

import pytest

from suite.catalog import load_catalog
from suite.cli import main
from suite.importers.openscenario import ImportOptions, import_files
from suite.importers.openscenario.pipeline import import_file

PACK = Path(__file__).resolve().parents[1] / "catalogs" / "r157"
LOGICAL = PACK / "source" / "logical_scenarios"
pytestmark = [pytest.mark.slow]

# parameter sets per variation file, and how many of them violate the template's
# constraints (the files say such sets are to be discarded)
SETS = {
    "4_1_1_free_driving": (12, 0), "4_1_2_swerving_lead_vehicle": (300, 0),
    "4_1_3_side_vehicle": (1200, 0), "4_2_1_fully_blocking_target": (360, 0),
    "4_2_2_partially_blocking_target": (6120, 0), "4_2_3_crossing_pedestrian": (120, 0),
    "4_2_4_multiple_blocking_targets": (1800, 0),
    "4_3_1_follow_lead_vehicle_comfortable": (2400, 300),
    "4_3_2_follow_lead_vehicle_emergency_brake": (1400, 175),
    "4_4_1_cut_in_no_collision": (52500, 22750), "4_5_1_cut_out_fully_blocking": (8640, 600),
    "4_5_2_cut_out_multiple_blocking_targets": (43200, 3000),
    "4_6_1_forward_detection_range": (6, 0), "4_6_2_lateral_detection_range": (2, 0),
}


def _templates() -> list[Path]:
    return sorted((LOGICAL / "concrete_scenarios").glob("*_template.xosc"))


@pytest.fixture(scope="module")
def alks(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("alks")
    outcome = import_files(_templates(), out, ImportOptions(r157=True))
    assert not outcome.failures, [str(f) for f in outcome.failures]
    assert len(outcome.results) == 15
    return out


def _same_files(made_dir: Path, bundled: Path) -> None:
    made = sorted(p.relative_to(made_dir) for p in made_dir.rglob("*") if p.is_file())
    kept = sorted(p.relative_to(bundled) for p in bundled.rglob("*") if p.is_file())
    assert made == kept
    changed = [str(rel) for rel in made
               if (made_dir / rel).read_bytes() != (bundled / rel).read_bytes()]
    assert changed == []


def test_the_bundled_pack_is_what_the_import_makes(alks: Path) -> None:
    """catalogs/r157/imported is the import of catalogs/r157/source's templates, byte for
    byte: an importer change that alters it fails here until the folder is regenerated
    (catalogs/r157/README.md has the command)."""
    _same_files(alks, PACK / "imported")
    # the MPL-2.0 files keep their licence: the text beside them, a header in each
    assert "Mozilla Public License Version 2.0" in (PACK / "source" / "LICENSE").read_text()
    assert all("MPL-2.0" in f.read_text() for f in _templates())


def test_every_template_imports(alks: Path) -> None:
    catalog = load_catalog(alks / "catalog.toml")
    assert len(catalog) == 15
    assert all(s.story is not None for s in catalog)
    cut_in = catalog.get("alks_scenario_4_4_1_cut_in_no_collision_template")
    assert cut_in.ego.speed_mps == pytest.approx(60.0 / 3.6, abs=1e-5)
    assert cut_in.story is not None
    (init,) = cut_in.story.inits
    # ds = 30 + (-10 x (-20 / 3.6)) m ahead of the ego's reference point, both fronts 3.9
    assert init.position.pos_m - cut_in.ego.pos_m == pytest.approx(30.0 + 200.0 / 3.6,
                                                                   abs=1e-3)
    assert init.speed_mps == pytest.approx(40.0 / 3.6)


def test_the_bundled_variations_are_what_the_import_makes() -> None:
    """catalogs/r157/variations is the import of the variation files with three sets
    each (--variants 3 --r157), byte for byte; each scenario is labelled with the section
    its template names. (Imported into a folder beside it: a logical scenario names its
    template relative to its catalog.)"""
    files = sorted(LOGICAL.glob("*_variation*.xosc"))
    with tempfile.TemporaryDirectory(dir=PACK, prefix=".test-") as made:
        outcome = import_files(files, Path(made), ImportOptions(r157=True, variants=3))
        assert not outcome.failures, [str(f) for f in outcome.failures]
        _same_files(Path(made), PACK / "variations")
    catalog = load_catalog(PACK / "variations" / "catalog.toml")
    sections = {s.name: s.labels["r157_section"] for s in catalog}
    # every file's own scenario and its sets but the crossing pedestrian's three (their
    # ego lane drives against the road's reference line: refused, with a warning)
    assert len(sections) == 15 + 3 * 15 - 1 - 3
    assert all(v == f"4.{k.split('_')[3]}" for k, v in sections.items())


@pytest.mark.parametrize("stem", sorted(SETS))
def test_every_variation_file_expands(stem: str, tmp_path: Path) -> None:
    path = LOGICAL / f"alks_scenario_{stem}_variation.xosc"
    r = import_file(path, tmp_path, ImportOptions())
    assert (r.sets, r.invalid_sets) == SETS[stem]


@pytest.fixture(scope="module")
def pack_runs(alks: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The 15 templates run with two_loop, and three (4.2_2, 4.2_3 crossing pedestrian,
    4.4_2 unavoidable cut-in) with r157_reference: the two output folders."""
    out = tmp_path_factory.mktemp("runs")
    rc = main(["run", str(alks / "catalog.toml"), "--out", str(out / "two_loop"), "--jobs",
               "1", "--no-log", "--no-fail"])
    assert rc == 0
    text = (alks / "catalog.toml").read_text()
    ref = alks / "reference.toml"
    ref.write_text(text.replace('controller = "two_loop"', 'controller = "r157_reference"'))
    rc = main(["run", str(ref), "--out", str(out / "reference"), "--jobs", "1", "--no-log",
               "--no-fail", "--filter", "*4_[24]_[23]_*"])
    assert rc == 0
    return out / "two_loop", out / "reference"


def test_every_template_runs_none_in_error(pack_runs: tuple[Path, Path]) -> None:
    out = pack_runs[0]
    with (out / "results.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 15
    statuses = {r["scenario"]: r["status"] for r in rows}
    assert not [n for n, s in statuses.items() if s in ("error", "timeout")], statuses
    # 4.4_1 ends 10 s after the cut-in completes: its storyboard's stop trigger ends the run
    run = json.loads((out / "alks_scenario_4_4_1_cut_in_no_collision_template" / "run.json")
                     .read_text())
    assert run["outcome"]["stop_reason"].startswith("storyboard stop trigger at t = ")
    log = json.loads((out / "alks_scenario_4_4_1_cut_in_no_collision_template" / "sumo"
                      / "storyboard.json").read_text())
    end = next(t for t, _, n, w in log["transitions"]
               if n == "CutInAction" and w == "endTransition")
    assert log["stopped_at_s"] == pytest.approx(end + 10.0, abs=0.2)


def test_the_pack_report_groups_by_section_with_the_reference_beside(
        pack_runs: tuple[Path, Path]) -> None:
    """hwyeval r157: a row per template under its section, the reference driver's
    outcome beside the three it ran, the exit code 0 exactly when every row's acceptance
    is met."""
    system, reference = pack_runs
    rc = main(["r157", str(system), "--reference", str(reference)])
    with (system / "r157.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 15
    per_section: dict[str, int] = {}
    for r in rows:
        per_section[r["section"]] = per_section.get(r["section"], 0) + 1
    assert per_section == {"4.1": 3, "4.2": 4, "4.3": 2, "4.4": 2, "4.5": 2, "4.6": 2}
    with (reference / "results.csv").open() as f:
        ref_runs = {r["scenario"]: r for r in csv.DictReader(f)}
    assert len(ref_runs) >= 2
    for r in rows:
        mine = ref_runs.get(r["scenario"])
        assert r["reference_status"] == ("" if mine is None else mine["status"])
        if mine is not None:
            assert int(r["reference_collisions"]) == int(float(mine["collisions"]))
    assert rc == (0 if all(r["acceptance"] == "met" for r in rows) else 1)
    page = (system / "r157.html").read_text()
    assert page.count("<h3 ") == 6  # one table per section
