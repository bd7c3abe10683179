"""Issue #35 items 2 and 8: ``hwyeval import commonroad`` never overwrites what it did
not write, and validates its input as strictly as the catalog loader does.

Every hostile case runs the real CLI (:func:`suite.cli.main`; one case in a subprocess,
for the absence of a traceback) on a copy of a shared CommonRoad file edited with
ElementTree, and checks exit 2, that the message names the file and the element (its
id), and that the output folder is byte for byte what it was (a refusal happens before
anything is written). The shared files are read from ../shared/commonroad (never copied
into the repository); the tests skip without them."""

from __future__ import annotations

import copy
import hashlib
import shutil
import subprocess
import sys
import tomllib
import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path

import pytest

from suite.cli import main

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "commonroad"
BASE = SHARED / "USA_US101-4_1_T-1.xml"  # 2020a: <dynamicObstacle>
SMALL = SHARED / "USA_US101-3_3_T-1.xml"  # 2018b, the fastest to import (~1 s)
STEM = "USA_US101-3_3_T-1"  # the hostile copies take this stem: they would replace it

pytest.importorskip("commonroad.common.reader.file_reader_xml")
pytestmark = pytest.mark.skipif(not SHARED.is_dir(), reason=f"{SHARED} (the shared "
                                "CommonRoad development files) is absent")

Edit = Callable[[ET.Element], str]  # edits the root, returns the element id to be named


def _snapshot(folder: Path) -> dict[str, str]:
    """Every file under ``folder`` (relative name -> sha256): what must not change."""
    if not folder.exists():
        return {}
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            if p.is_file() else "<dir>" for p in sorted(folder.rglob("*"))}


@pytest.fixture(scope="module")
def previous(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder holding one earlier import of SMALL (copied by each test that needs it)."""
    out = tmp_path_factory.mktemp("guards") / "prev"
    assert main(["import", "commonroad", str(SMALL), "--out", str(out)]) == 0
    return out


def _cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str]:
    code = main(["import", "commonroad", *args])
    return code, capsys.readouterr().err


def _hostile(tmp_path: Path, edit: Edit, base: Path = BASE) -> tuple[Path, str]:
    """A copy of ``base`` edited by ``edit``, named like SMALL (``<tmp>/in/<STEM>.xml``),
    and the id the refusal must name."""
    tree = ET.parse(base)
    ident = edit(tree.getroot())
    path = tmp_path / "in" / f"{STEM}.xml"
    path.parent.mkdir(parents=True, exist_ok=True)
    tree.write(path)
    return path, ident


def _obstacles(root: ET.Element) -> list[ET.Element]:
    return [e for e in root if e.tag in ("dynamicObstacle", "obstacle")]


def _first_obstacle(root: ET.Element) -> ET.Element:
    return _obstacles(root)[0]


def _set(el: ET.Element, path: str, value: str) -> None:
    found = el.find(path)
    assert found is not None, path
    found.text = value


# ------------------------------------------------------------------ item 8: hostile input

def duplicate_lanelet(root: ET.Element) -> str:
    """A second lanelet with the first's id, 1 km away (commonroad-io keeps one)."""
    ll = root.findall("lanelet")[0]
    twin = copy.deepcopy(ll)
    for x in twin.iter("x"):
        x.text = str(float(x.text or 0.0) + 1000.0)
    root.insert(list(root).index(ll) + 1, twin)
    return f"lanelet {ll.get('id')}"


def duplicate_obstacle(root: ET.Element) -> str:
    first, second = _obstacles(root)[:2]
    second.set("id", first.get("id", ""))
    return f"obstacle {first.get('id')}"


def nan_position(root: ET.Element) -> str:
    ob = _first_obstacle(root)
    _set(ob, "initialState/position/point/x", "nan")
    return f"obstacle {ob.get('id')}"


def inf_orientation(root: ET.Element) -> str:
    ob = _first_obstacle(root)
    _set(ob, "trajectory/state/orientation/exact", "inf")
    return f"obstacle {ob.get('id')}"


def nan_velocity(root: ET.Element) -> str:
    ob = _first_obstacle(root)
    _set(ob, "trajectory/state/velocity/exact", "nan")
    return f"obstacle {ob.get('id')}"


def inf_size(root: ET.Element) -> str:
    ob = _first_obstacle(root)
    _set(ob, "shape/rectangle/length", "inf")
    return f"obstacle {ob.get('id')}"


def nan_vertex(root: ET.Element) -> str:
    ll = root.findall("lanelet")[0]
    _set(ll, "leftBound/point/y", "nan")
    return f"lanelet {ll.get('id')}"


def nan_ego(root: ET.Element) -> str:
    pp = root.find("planningProblem")
    assert pp is not None
    _set(pp, "initialState/velocity/exact", "nan")
    return f"planningProblem {pp.get('id')}"


def far_obstacle(root: ET.Element) -> str:
    """1e15 m: float64's spacing there is 0.125 m, a collision check's noise."""
    ob = _first_obstacle(root)
    _set(ob, "trajectory/state/position/point/x", "1e15")
    return f"obstacle {ob.get('id')}"


def far_vertex(root: ET.Element) -> str:
    ll = root.findall("lanelet")[-1]
    points = ll.findall("rightBound/point")
    _set(points[-1], "x", "1e15")
    return f"lanelet {ll.get('id')}"


def far_ego(root: ET.Element) -> str:
    pp = root.find("planningProblem")
    assert pp is not None
    _set(pp, "initialState/position/point/y", "-3e7")
    return f"planningProblem {pp.get('id')}"


def late_sample(root: ET.Element) -> str:
    """A sample 1e9 steps (= 3.2 years at 0.1 s) after the start."""
    ob = _first_obstacle(root)
    _set(ob, "trajectory/state[last()]/time/exact", "1000000000")
    return f"obstacle {ob.get('id')}"


def long_recording(root: ET.Element) -> str:
    """A sample 250 000 steps (6.9 h at 0.1 s) after the start: within a day, but a run
    is at most 1e6 control steps of 20 ms (5.6 h): the catalog would not load."""
    ob = _first_obstacle(root)
    _set(ob, "trajectory/state[last()]/time/exact", "250000")
    return f"obstacle {ob.get('id')}"


def missing_goal_lanelet(root: ET.Element) -> str:
    pp = root.find("planningProblem")
    assert pp is not None
    pos = pp.find("goalState/position")
    assert pos is not None
    for child in list(pos):
        pos.remove(child)
    ET.SubElement(pos, "lanelet", ref="9999")
    return "9999"


HOSTILE: dict[str, Edit] = {
    "duplicate_lanelet": duplicate_lanelet, "duplicate_obstacle": duplicate_obstacle,
    "nan_position": nan_position, "inf_orientation": inf_orientation,
    "nan_velocity": nan_velocity, "inf_size": inf_size, "nan_vertex": nan_vertex,
    "nan_ego": nan_ego, "far_obstacle": far_obstacle, "far_vertex": far_vertex,
    "far_ego": far_ego, "late_sample": late_sample, "long_recording": long_recording,
    "missing_goal_lanelet": missing_goal_lanelet,
}


@pytest.mark.parametrize("case", sorted(HOSTILE))
def test_hostile_input_exits_2_naming_the_element_and_writes_nothing(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], previous: Path,
        case: str) -> None:
    src, ident = _hostile(tmp_path, HOSTILE[case])
    out = tmp_path / "out"
    shutil.copytree(previous, out)
    before = _snapshot(out)
    code, err = _cli(capsys, str(src), "--out", str(out))
    assert code == 2, err
    assert str(src) in err and ident in err, err
    assert "Traceback" not in err
    assert _snapshot(out) == before  # the earlier import of the same stem is intact


@pytest.mark.slow  # an import in a subprocess, ~1.5 s
def test_hostile_input_in_a_subprocess_has_no_traceback(tmp_path: Path) -> None:
    src, ident = _hostile(tmp_path, missing_goal_lanelet)
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "suite", "import", "commonroad", str(src),
                           "--out", str(out)], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and ident in proc.stderr
    assert _snapshot(out) == {}


@pytest.mark.parametrize("option", ["--extension-m", "--approach-m"])
@pytest.mark.parametrize("value", ["1e12", "inf", "nan", "0"])
def test_options_that_size_the_net_are_bounded(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], option: str,
        value: str) -> None:
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as info:
        main(["import", "commonroad", str(SMALL), "--out", str(out), option, value])
    assert info.value.code == 2
    assert option in capsys.readouterr().err
    assert not out.exists()


def test_net_params_refuse_an_absurd_extension() -> None:
    from suite.importers.commonroad.net_build import MAX_EXTENSION_M, NetParams

    NetParams(downstream_extension_m=MAX_EXTENSION_M)
    with pytest.raises(ValueError):
        NetParams(downstream_extension_m=MAX_EXTENSION_M * 1.01)
    with pytest.raises(ValueError):
        NetParams(upstream_extension_m=1e12)


# ------------------------------------------------------------------ item 2: the output folder
# (the rules both importers share are tested for both in tests/test_import_folder.py)

def test_the_same_file_given_twice_is_imported_once(tmp_path: Path) -> None:
    from suite.importers.common.out_guard import check_inputs
    from suite.importers.commonroad.catalog_out import OUTPUTS

    alias = tmp_path / "alias"
    alias.symlink_to(SHARED)
    assert check_inputs([SMALL, SMALL, alias / SMALL.name, BASE], OUTPUTS) == (SMALL, BASE)


def test_a_file_failing_late_leaves_the_earlier_import_of_its_stem_intact(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], previous: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A file that fails after its net and tracks are built (here its last stage, made
    to fail) keeps every byte of the earlier import of the same stem: a file's outputs
    are staged and moved into the folder only once the whole file has imported."""
    from suite.importers.commonroad import ImportFailure, catalog_out

    def fail(*args: object, **kw: object) -> Path:
        raise ImportFailure(str(SMALL), "scenario", "made to fail by the test")

    monkeypatch.setattr(catalog_out, "write_fragment", fail)
    out = tmp_path / "out"
    shutil.copytree(previous, out)
    before = _snapshot(out)
    # another extension: a net that differs from the earlier one
    code, err = _cli(capsys, str(SMALL), "--out", str(out), "--extension-m", "500")
    assert code == 2 and "made to fail" in err, err
    assert _snapshot(out) == before


def test_the_generated_catalog_loads(previous: Path) -> None:
    from suite.catalog import load_catalog
    from suite.importers.common.catalog_mark import is_unedited

    data = (previous / "catalog.toml").read_bytes()
    assert is_unedited(data) and not is_unedited(data + b"# mine\n")
    doc = tomllib.loads(data.decode())
    assert [s["net"] for s in doc["scenario"]] == [f"{STEM}.net.xml"]
    cat = load_catalog(previous / "catalog.toml", known_controllers=["two_loop"])
    assert [s.name for s in cat.scenarios] == ["usa_us101_3_3_t_1"]
    # docs/recorded.md: edits live in a catalog of one's own beside the folder
    own = previous.parent / "recorded.toml"
    body = data.decode().split("\n", 1)[1]
    own.write_text(body.replace(f'"{STEM}.', f'"{previous.name}/{STEM}.')
                   .replace("seed = 0", "seed = 7"))
    (mine,) = load_catalog(own, known_controllers=["two_loop"]).scenarios
    assert mine.replay is not None and mine.seed == 7
