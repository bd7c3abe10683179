"""The recorded driver on the three shared recordings, with libsumo, in replay mode: each
file imported with ``--ego-obstacle`` (a vehicle present throughout the recording), its
``__recorded`` variant run with ``hwyeval run``. Checked against the XML's own numbers,
read here with ElementTree (not through the importer or the run's interpolation):

* the start: the ego's state at t = 0 and SUMO's ego there (built by the runner and
  started, no step taken) within 0.05 m of the obstacle's initial state;
* the trajectory: the trace's box centre at every sample time of the file within 0.05 m
  of that sample (and its heading and speed the sample's);
* collisions: the run collides exactly when the recording has the ego obstacle's box
  overlapping another's at a common sample (none of the three does);
* the ego's own track is never among the replayed cars.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import tomllib
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from reports.geometry import box_corners, boxes_overlap
from reports.record import load_run

pytestmark = [pytest.mark.sumo, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "commonroad"
POS_TOL_M = 0.05
# (file stem, scenario name, the obstacle made the ego: a car present at every step)
CASES = (("USA_US101-3_3_T-1", "usa_us101_3_3_t_1", 388),
         ("USA_US101-4_1_T-1", "usa_us101_4_1_t_1", 451),
         ("DEU_A9-3_1_T-1", "deu_a9_3_1_t_1", 3602))

START_SCRIPT = """
import json, math, sys, time
from pathlib import Path
from controllers.plant.vehicle_model import VehicleParams
from suite.catalog import load_catalog
from suite.run.options import RunOptions
from suite.run.runner import _build
catalog = load_catalog(Path(sys.argv[1]))
out = {}
for name in sys.argv[3:]:
    sc = catalog.get(name)
    run = _build(sc, Path(sys.argv[2]) / name, VehicleParams(friction_coeff=sc.friction),
                 RunOptions(), time.perf_counter())
    try:
        ego, scene = run.stages.dynamics.start()
    finally:
        run.world.close()
    box, w = run.info.ego, scene.ego
    x, y, psi = (float(v) for v in ego.state[:3])
    d, half = box.cg_to_box_centre_m, 0.5 * box.length_m
    out[name] = {"t_s": scene.t_s, "centre": [x + d * math.cos(psi), y + d * math.sin(psi)],
                 "heading": psi, "speed": float(ego.state[3]),
                 "sumo_centre": [w.front_x_m - half * math.cos(w.heading_rad),
                                 w.front_y_m - half * math.sin(w.heading_rad)],
                 "sumo_heading": w.heading_rad}
print(json.dumps(out))
"""


# ------------------------------------------------------------------ the XML, read here
@dataclass(frozen=True)
class XmlTrack:
    """One dynamic obstacle as the file gives it: time steps (n,), centre x/y [m],
    orientation [rad] and velocity [m/s] (interval centres where the file gives
    intervals), box length/width [m]."""

    steps: np.ndarray
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    speed: np.ndarray
    length: float
    width: float


def _value(el: ET.Element | None) -> float:
    """``<exact>`` or the centre of ``<intervalStart>``/``<intervalEnd>``."""
    assert el is not None
    exact = el.find("exact")
    if exact is not None and exact.text is not None:
        return float(exact.text)
    lo, hi = el.findtext("intervalStart"), el.findtext("intervalEnd")
    assert lo is not None and hi is not None
    return 0.5 * (float(lo) + float(hi))


def _position(el: ET.Element | None) -> tuple[float, float]:
    assert el is not None
    point = el.find("point")
    if point is None:
        point = el.find("./rectangle/center")
    assert point is not None, ET.tostring(el)[:200]
    return float(point.findtext("x") or "nan"), float(point.findtext("y") or "nan")


def _step(el: ET.Element | None) -> int:
    assert el is not None
    exact = el.findtext("exact")
    return int(exact if exact is not None else el.findtext("intervalStart") or "-1")


def xml_tracks(path: Path) -> tuple[float, dict[int, XmlTrack]]:
    """The header's time step [s] and every dynamic obstacle (2018b ``<obstacle>`` with
    role dynamic, 2020a ``<dynamicObstacle>``)."""
    root = ET.parse(path).getroot()
    dt = float(root.attrib["timeStepSize"])
    obstacles = [o for o in root.findall("obstacle") if o.findtext("role") == "dynamic"]
    obstacles += root.findall("dynamicObstacle")
    out: dict[int, XmlTrack] = {}
    for ob in obstacles:
        states = [ob.find("initialState"), *ob.findall("./trajectory/state")]
        rows = []
        for st in states:
            assert st is not None
            x, y = _position(st.find("position"))
            rows.append((_step(st.find("time")), x, y, _value(st.find("orientation")),
                         _value(st.find("velocity"))))
        arr = np.array(sorted(rows))
        rect = ob.find("./shape/rectangle")
        assert rect is not None
        out[int(ob.attrib["id"])] = XmlTrack(
            arr[:, 0].astype(int), arr[:, 1], arr[:, 2], arr[:, 3], arr[:, 4],
            float(rect.findtext("length") or "nan"), float(rect.findtext("width") or "nan"))
    return dt, out


def recording_collides(tracks: dict[int, XmlTrack], ego_id: int) -> bool:
    """Whether the ego obstacle's box overlaps another's at a common sample."""
    ego = tracks[ego_id]
    for oid, other in tracks.items():
        if oid == ego_id:
            continue
        common, i, j = np.intersect1d(ego.steps, other.steps, return_indices=True)
        if common.size == 0:
            continue
        a = box_corners(ego.x[i], ego.y[i], ego.heading[i], ego.length, ego.width)
        b = box_corners(other.x[j], other.y[j], other.heading[j], other.length, other.width)
        if bool(np.any(boxes_overlap(a, b))):
            return True
    return False


# ------------------------------------------------------------------ the runs
def _hwyeval(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "suite", *args], cwd=ROOT, text=True,
                          capture_output=True, timeout=900)


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if not all((SHARED / f"{stem}.xml").is_file() for stem, _, _ in CASES):
        pytest.skip(f"no shared CommonRoad files in {SHARED}")
    pytest.importorskip("commonroad.common.reader.file_reader_xml")
    base = tmp_path_factory.mktemp("recorded")
    for stem, _, obstacle in CASES:
        proc = _hwyeval("import", "commonroad", str(SHARED / f"{stem}.xml"), "--out",
                        str(base / "imp"), "--ego-obstacle", str(obstacle))
        assert proc.returncode == 0, proc.stdout + proc.stderr
    proc = _hwyeval("run", str(base / "imp" / "catalog.toml"), "--out", str(base / "out"),
                    "--filter", "*__recorded", "--no-log", "--jobs", "1", "--no-fail")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    names = [f"{name}__recorded" for _, name, _ in CASES]
    proc = subprocess.run([sys.executable, "-c", START_SCRIPT,
                           str(base / "imp" / "catalog.toml"), str(base / "start"), *names],
                          cwd=ROOT, text=True, capture_output=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    (base / "start.json").write_text(proc.stdout.strip().splitlines()[-1])
    return base


@pytest.mark.parametrize(("stem", "name", "obstacle"), CASES)
def test_it_starts_exactly_where_the_file_says(runs: Path, stem: str, name: str,
                                               obstacle: int) -> None:
    start = json.loads((runs / "start.json").read_text())[f"{name}__recorded"]
    _, tracks = xml_tracks(SHARED / f"{stem}.xml")
    ob = tracks[obstacle]
    assert start["t_s"] == 0.0
    for centre, heading in ((start["centre"], start["heading"]),
                            (start["sumo_centre"], start["sumo_heading"])):
        assert math.hypot(centre[0] - ob.x[0], centre[1] - ob.y[0]) <= POS_TOL_M
        assert abs(math.remainder(heading - ob.heading[0], 2 * math.pi)) <= 1e-6
    assert start["speed"] == pytest.approx(ob.speed[0], abs=1e-9)


@pytest.mark.parametrize(("stem", "name", "obstacle"), CASES)
def test_its_trajectory_is_the_files_samples(runs: Path, stem: str, name: str,
                                             obstacle: int) -> None:
    rec = load_run(runs / "out" / f"{name}__recorded")
    dt, tracks = xml_tracks(SHARED / f"{stem}.xml")
    ob = tracks[obstacle]
    e, box = rec.trace.ego, rec.info.ego
    assert (box.length_m, box.width_m) == (ob.length, ob.width)  # the recorded box
    cx = e.x_m + box.cg_to_box_centre_m * np.cos(e.psi_rad)
    cy = e.y_m + box.cg_to_box_centre_m * np.sin(e.psi_rad)
    checked = 0
    for k, step in enumerate(ob.steps):
        rows = np.flatnonzero(np.abs(rec.trace.t_s - (step - ob.steps[0]) * dt) < 1e-6)
        if rows.size == 0:  # t = 0: before the first trace row
            assert step == ob.steps[0]
            continue
        j = int(rows[0])
        assert math.hypot(cx[j] - ob.x[k], cy[j] - ob.y[k]) <= POS_TOL_M, (name, step)
        assert abs(math.remainder(e.psi_rad[j] - ob.heading[k], 2 * math.pi)) <= 1e-6
        assert e.speed_mps[j] == pytest.approx(ob.speed[k], abs=1e-9)
        checked += 1
    assert checked == ob.steps.size - 1  # every sample after the start
    assert rec.outcome.end == "ok" and rec.outcome.stop_reason == "duration"


@pytest.mark.parametrize(("stem", "name", "obstacle"), CASES)
def test_it_collides_only_where_the_recording_does(runs: Path, stem: str, name: str,
                                                   obstacle: int) -> None:
    rec = load_run(runs / "out" / f"{name}__recorded")
    _, tracks = xml_tracks(SHARED / f"{stem}.xml")
    assert rec.verdict is not None
    collided = rec.verdict.value("collision") > 0.0
    assert collided == recording_collides(tracks, obstacle)
    assert not collided  # the three chosen vehicles touch nobody in their recordings


@pytest.mark.parametrize(("stem", "name", "obstacle"), CASES)
def test_its_own_track_is_not_replayed_and_the_others_are(runs: Path, stem: str, name: str,
                                                          obstacle: int) -> None:
    rec = load_run(runs / "out" / f"{name}__recorded")
    doc = tomllib.loads((runs / "imp" / "catalog.toml").read_text())
    sc = next(s for s in doc["scenario"] if s["name"] == name)
    assert sc["replay"]["ego_track"] == f"rec_{obstacle}"
    ids = set(rec.neighbours.id.tolist())
    assert f"rec_{obstacle}" not in ids
    assert ids and all(i.startswith("rec_") for i in ids)
    assert rec.outcome.replay is not None
    _, tracks = xml_tracks(SHARED / f"{stem}.xml")
    assert rec.outcome.replay.vehicles == len(tracks) - 1
    assert rec.info.controller == "recorded"
    assert np.all(np.isnan(rec.trace.ego.steer_rad))  # not known, as for SUMO's driver


def test_the_recording_check_sees_an_overlap() -> None:
    """The collision reference itself: two 4.5 m boxes 3 m apart along x at step 1
    overlap, 4.6 m apart they do not."""
    def car(x0: float, x1: float) -> XmlTrack:  # at x0 at step 0, at x1 at step 1
        return XmlTrack(np.array([0, 1]), np.array([x0, x1]), np.zeros(2), np.zeros(2),
                        np.full(2, 10.0), 4.5, 1.8)

    assert recording_collides({1: car(0.0, 0.0), 2: car(100.0, 3.0)}, 1)
    assert not recording_collides({1: car(0.0, 0.0), 2: car(100.0, 4.6)}, 1)
