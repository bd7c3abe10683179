"""The output folder rules both importers share (suite/importers/common; docs/recorded.md,
"The output folder"; docs/openscenario.md): brought to ``hwyeval import openscenario``,
and checked here for both importers with the same tests. Every case runs the real CLI
and checks exit 2 and that the output folder is byte for byte what it was (a refusal
happens before anything is written).

OpenSCENARIO cases use the hand-written files of tests/data/openscenario; CommonRoad
cases the shared development file ../shared/commonroad (skipped without it or without
commonroad-io; tests/test_import_guards.py has the CommonRoad-only cases)."""

from __future__ import annotations

import hashlib
import importlib.util
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

from suite.cli import main

DATA = Path(__file__).resolve().parent / "data" / "openscenario"
XOSC = DATA / "bend_cut_in.xosc"
SHARED_CR = Path(__file__).resolve().parents[1].parent / "shared" / "commonroad"
CR_STEM = "USA_US101-3_3_T-1"


def _snapshot(folder: Path) -> dict[str, str]:
    """Every file under ``folder`` (relative name -> sha256): what must not change."""
    if not folder.exists():
        return {}
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            if p.is_file() else "<dir>" for p in sorted(folder.rglob("*"))}


def _osc_copies(folder: Path, names: list[str]) -> list[Path]:
    """Copies of XOSC named ``names`` in ``folder``, beside a copy of its road and
    catalogs (so they share that road)."""
    shutil.copyfile(DATA / "bend_road.xodr", folder / "bend_road.xodr")
    shutil.copytree(DATA / "catalogs", folder / "catalogs", dirs_exist_ok=True)
    for name in names:
        shutil.copyfile(XOSC, folder / name)
    return [folder / name for name in names]


def _cr_copies(folder: Path, names: list[str]) -> list[Path]:
    for name in names:
        shutil.copyfile(SHARED_CR / f"{CR_STEM}.xml", folder / name)
    return [folder / name for name in names]


@dataclass(frozen=True)
class Importer:
    """One importer as these tests drive it: its CLI format, an input, the files one
    import of it writes (its net first), how to copy it, and why it cannot run here."""

    command: str
    source: Path
    outputs: tuple[str, ...]
    copies: Callable[[Path, list[str]], list[Path]]
    missing: str | None

    def copy(self, folder: Path, *names: str) -> list[Path]:
        """Copies of ``source`` named ``names`` in ``folder`` (created)."""
        folder.mkdir(parents=True, exist_ok=True)
        return self.copies(folder, list(names))


IMPORTERS = {
    "openscenario": Importer(
        "openscenario", XOSC, ("bend_road.net.xml", "bend_cut_in.scenario.json",
                               "bend_cut_in.story.json", "bend_road.lanes.json",
                               "catalog.toml"), _osc_copies, None),
    "commonroad": Importer(
        "commonroad", SHARED_CR / f"{CR_STEM}.xml",
        (f"{CR_STEM}.net.xml", f"{CR_STEM}.scenario.json", f"{CR_STEM}.tracks.parquet",
         "catalog.toml"), _cr_copies,
        f"{SHARED_CR} (the shared CommonRoad development files) is absent"
        if not SHARED_CR.is_dir() else "commonroad-io is not installed"
        if importlib.util.find_spec("commonroad") is None else None),
}


@pytest.fixture(scope="module", params=sorted(IMPORTERS))
def importer(request: pytest.FixtureRequest) -> Importer:
    imp = IMPORTERS[str(request.param)]
    if imp.missing:
        pytest.skip(imp.missing)
    return imp


@pytest.fixture(scope="module")
def previous(importer: Importer, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder holding one earlier import of the importer's input (copied by each test
    that needs it)."""
    out = tmp_path_factory.mktemp(f"guards_{importer.command}") / "prev"
    assert main(["import", importer.command, str(importer.source), "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(importer.outputs)
    return out


def _cli(capsys: pytest.CaptureFixture[str], importer: Importer, *args: str
         ) -> tuple[int, str]:
    code = main(["import", importer.command, *args])
    return code, capsys.readouterr().err


def _refused(capsys: pytest.CaptureFixture[str], importer: Importer, out: Path,
             *args: str) -> str:
    """Import the importer's input into ``out``: exit 2 and ``out`` unchanged; the
    message."""
    before = _snapshot(out)
    code, err = _cli(capsys, importer, str(importer.source), "--out", str(out), *args)
    assert code == 2, err
    assert _snapshot(out) == before
    return err


def test_a_hand_written_catalog_is_never_replaced_silently(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], importer: Importer) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "catalog.toml").write_text('[defaults]\ncontroller = "two_loop"\n')
    err = _refused(capsys, importer, out)
    assert "catalog.toml" in err and f"hwyeval import {importer.command}" in err, err


@pytest.mark.slow  # two imports
def test_an_edited_generated_catalog_is_refused_and_overwrite_replaces_it(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], importer: Importer,
        previous: Path) -> None:
    out = tmp_path / "out"
    shutil.copytree(previous, out)
    catalog = out / "catalog.toml"
    text = catalog.read_text()
    assert text.startswith(f"# generated by hwyeval import {importer.command}; sha256 ")
    # what a killed import leaves is the import's own: removed by the next import
    (out / ".hwyeval-import-killed").mkdir()
    (out / f"{importer.outputs[0]}.partial").write_text("half")
    code, err = _cli(capsys, importer, str(importer.source), "--out", str(out))
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == sorted(importer.outputs)
    assert catalog.read_text() == text
    catalog.write_text(text.replace("seed = 0", "seed = 7"))
    err = _refused(capsys, importer, out)
    assert "catalog.toml" in err and "edited" in err, err
    code, err = _cli(capsys, importer, str(importer.source), "--out", str(out),
                     "--overwrite")
    assert code == 0, err
    assert catalog.read_text() == text


@pytest.mark.parametrize("entry", ["notes.txt", "sub/", "link.net.xml@", "input"])
def test_a_folder_with_foreign_files_needs_overwrite(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], importer: Importer,
        previous: Path, entry: str) -> None:
    """A file, a folder, a symbolic link (even one named like an output), the input
    itself: none is an import's output."""
    out = tmp_path / "out"
    shutil.copytree(previous, out)
    name = importer.source.name if entry == "input" else entry.rstrip("/@")
    if entry.endswith("/"):
        (out / name).mkdir()
    elif entry.endswith("@"):
        (out / name).symlink_to(out / importer.outputs[0])
    else:
        (out / name).write_text("mine\n")
    err = _refused(capsys, importer, out)
    assert str(out) in err and name in err, err


@pytest.mark.slow  # an import
def test_overwrite_writes_beside_foreign_files_and_keeps_them(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], importer: Importer) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine\n")
    (out / "sub").mkdir()
    (out / "catalog.toml").write_text("# mine\n")
    code, err = _cli(capsys, importer, str(importer.source), "--out", str(out),
                     "--overwrite")
    assert code == 0, err
    assert (out / "notes.txt").read_text() == "mine\n" and (out / "sub").is_dir()
    assert sorted(p.name for p in out.iterdir()) == sorted([*importer.outputs, "notes.txt",
                                                            "sub"])
    assert (out / "catalog.toml").read_text().startswith("# generated by hwyeval import")


@pytest.mark.parametrize("second", ["b/same", "a/upper"], ids=["other_folder", "other_case"])
def test_two_inputs_with_one_stem_are_refused_before_writing(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], importer: Importer,
        second: str) -> None:
    name = importer.source.name
    (a,) = importer.copy(tmp_path / "a", name)
    folder, how = second.split("/")
    (b,) = importer.copy(tmp_path / folder, name if how == "same" else name.upper())
    out = tmp_path / "out"
    code, err = _cli(capsys, importer, str(a), str(b), "--out", str(out))
    assert code == 2 and str(a) in err and str(b) in err, err
    assert _snapshot(out) == {}


def test_an_out_that_is_a_file_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], importer: Importer) -> None:
    out = tmp_path / "out"
    out.write_text("a file\n")
    err = _refused(capsys, importer, out)
    assert str(out) in err, err


@pytest.mark.slow  # two imports
def test_the_same_input_gives_byte_identical_outputs(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], importer: Importer,
        previous: Path) -> None:
    """Into a fresh folder and again in place: every byte the same (docs/recorded.md,
    "Deterministic outputs")."""
    out = tmp_path / "again"
    for _ in range(2):
        code, err = _cli(capsys, importer, str(importer.source), "--out", str(out))
        assert code == 0, err
        assert _snapshot(out) == _snapshot(previous)
    net = (out / importer.outputs[0]).read_text()
    assert "generated on" not in net and str(tmp_path) not in net


# ------------------------------------------------------------ OpenSCENARIO's own

def test_a_shared_road_is_one_output_two_roads_of_one_name_are_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Several files on one road write its net once for all of them; two road files
    whose nets would have one name would replace each other's: refused."""
    osc = IMPORTERS["openscenario"]
    first, second = osc.copy(tmp_path / "a", "first.xosc", "second.xosc")
    out = tmp_path / "out"
    code, err = _cli(capsys, osc, str(first), str(second), str(first), "--out", str(out))
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == [
        "bend_road.lanes.json", "bend_road.net.xml", "catalog.toml", "first.scenario.json",
        "first.story.json", "second.scenario.json", "second.story.json"]
    (other,) = osc.copy(tmp_path / "b", "other.xosc")  # its own copy of bend_road.xodr
    before = _snapshot(out)
    code, err = _cli(capsys, osc, str(first), str(other), "--out", str(out))
    assert code == 2 and "bend_road.net.xml" in err, err
    assert str(tmp_path / "a" / "bend_road.xodr") in err
    assert str(tmp_path / "b" / "bend_road.xodr") in err
    assert _snapshot(out) == before


@pytest.mark.slow  # two imports
def test_a_file_failing_late_leaves_the_earlier_import_of_its_stem_intact(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A file of an earlier import's stem whose storyboard differs (another gap) is
    built, then its last stage fails: every byte of the earlier import stays (a file's
    outputs are staged, moved in once all are)."""
    from suite.importers.openscenario import OscImportError, catalog_out

    def fail(*args: object, **kw: object) -> Path:
        raise OscImportError(str(XOSC), "Storyboard", "made to fail by the test")

    osc = IMPORTERS["openscenario"]
    out = tmp_path / "out"
    code, err = _cli(capsys, osc, str(XOSC), "--out", str(out))
    assert code == 0, err
    (changed,) = osc.copy(tmp_path / "in", XOSC.name)
    gap = 'name="Gap" parameterType="double" value='
    assert f'{gap}"30.0"' in changed.read_text()
    changed.write_text(changed.read_text().replace(f'{gap}"30.0"', f'{gap}"20.0"'))
    monkeypatch.setattr(catalog_out, "write_fragment", fail)
    before = _snapshot(out)
    code, err = _cli(capsys, osc, str(changed), "--out", str(out))
    assert code == 2 and "made to fail" in err, err
    assert _snapshot(out) == before
    monkeypatch.undo()  # the same file imports, and its storyboard is another
    code, err = _cli(capsys, osc, str(changed), "--out", str(out))
    assert code == 0, err
    after = _snapshot(out)
    assert after["bend_cut_in.story.json"] != before["bend_cut_in.story.json"]
    assert after["bend_road.net.xml"] == before["bend_road.net.xml"]
