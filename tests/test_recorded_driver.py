"""The recorded driver (controller ``recorded``) without SUMO: the registry's marker, the
track resampled at the control steps (poses, finite-difference accelerations), the
recorded box, the dynamics against a fake world, the catalog key ``replay.ego_track``
(validated at load, never replayed) and the importer's recorded ego (chosen with
``--ego-obstacle``, detected at the planning problem's initial state).

With libsumo, on the three shared recordings: tests/test_recorded_driver_sumo.py."""

from __future__ import annotations

import math
import re
import subprocess
import sys
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from replay_fixtures import LANE_Y_M, track

from controllers import registry
from controllers.baselines.recorded_driver import RecordedDriverModel
from controllers.behaviour.types import Traffic
from controllers.path.frenet import FrenetPath
from controllers.plant.vehicle_model import VehicleParams
from controllers.protocol import Command, ConfigError, Controller
from suite.catalog import CatalogError, ReplaySpec, SpecError, load_catalog
from suite.catalog.tracks import (
    Track,
    TrackSet,
    ego_track_problem,
    read_tracks,
    track_spans,
    write_tracks,
)
from suite.run.ego import EgoProjector
from suite.run.recorded import (
    RecordedDrivesEgo,
    RecordedDynamics,
    RecordedPath,
    recorded_vehicle,
)
from suite.world.protocol import EgoPose, Scene, WorldSummary

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "commonroad"
US101_3_3 = SHARED / "USA_US101-3_3_T-1.xml"


# ------------------------------------------------------------------ the marker
def test_recorded_is_a_registered_driver_model_without_options() -> None:
    model = registry.make("recorded", {})
    assert isinstance(model, RecordedDriverModel) and not isinstance(model, Controller)
    assert model.name == "recorded" and model.parameters()
    assert registry.options("recorded") == []
    with pytest.raises(ConfigError) as info:
        registry.make("recorded", {"speed_factor": 1.1})
    assert info.value.key == "controller.speed_factor"
    with pytest.raises(ConfigError):
        registry.make("recorded", {"name": "sumo"})


# ------------------------------------------------------------------ the resampled track
def _track(dt: float = 0.1, end: float = 2.0, t0: float = 0.0) -> Track:
    """A car accelerating at 1 m/s^2 from 20 m/s on a gentle left curve (yaw rate 0.05
    rad/s), samples every ``dt`` from ``t0``."""
    t = np.arange(t0, end + 1e-9, dt)
    v = 20.0 + 1.0 * t
    psi = 0.05 * t
    x = 100.0 + np.cumsum(np.r_[0.0, 0.5 * (v[1:] + v[:-1]) * np.diff(t) * np.cos(psi[:-1])])
    y = np.cumsum(np.r_[0.0, 0.5 * (v[1:] + v[:-1]) * np.diff(t) * np.sin(psi[:-1])])
    return Track("rec_7", "car", 4.4, 1.8, t, x, y, psi, v)


def test_the_path_hits_every_sample_and_interpolates_between() -> None:
    tr = _track()
    path = RecordedPath.from_track(tr, 0.02)
    assert path.last_step == 100 and path.t_s[-1] == pytest.approx(2.0)
    for k in range(tr.time_s.shape[0]):
        j = 5 * k  # sample k at control step 5k
        assert (path.x_m[j], path.y_m[j]) == pytest.approx((tr.x_m[k], tr.y_m[k]), abs=1e-12)
        assert path.heading_rad[j] == pytest.approx(tr.heading_rad[k], abs=1e-15)
        assert path.speed_mps[j] == pytest.approx(tr.speed_mps[k], abs=1e-12)
    # t = 0.34 s: 40 % of the way from sample 3 (0.3 s) to sample 4 (0.4 s)
    for name in ("x_m", "y_m", "heading_rad", "speed_mps"):
        a, b = getattr(tr, name)[3:5]
        assert getattr(path, name)[17] == pytest.approx(a + 0.4 * (b - a), abs=1e-9)


def test_accelerations_are_the_samples_finite_differences_interpolated() -> None:
    path = RecordedPath.from_track(_track(), 0.02)
    np.testing.assert_allclose(path.accel_mps2, 1.0, atol=1e-9)  # dv/dt of v = 20 + t
    np.testing.assert_allclose(path.yaw_rate_radps, 0.05, atol=1e-9)
    tr = _track()
    bumpy = Track(tr.track_id, tr.kind, tr.length_m, tr.width_m, tr.time_s, tr.x_m, tr.y_m,
                  tr.heading_rad, tr.speed_mps + 0.3 * (np.arange(tr.time_s.size) % 2))
    p = RecordedPath.from_track(bumpy, 0.02)
    a = np.gradient(bumpy.speed_mps, bumpy.time_s)
    assert p.accel_mps2[10] == pytest.approx(a[2]) and p.accel_mps2[12] == pytest.approx(
        0.6 * a[2] + 0.4 * a[3])
    # continuous between samples: each control step changes it by at most a sample's step
    assert np.max(np.abs(np.diff(p.accel_mps2))) <= np.max(np.abs(np.diff(a))) / 5 + 1e-9


def test_the_path_ends_with_the_track_and_must_start_at_zero() -> None:
    path = RecordedPath.from_track(_track(end=3.1), 0.02)
    assert path.last_step == 155  # 3.1 / 0.02, a float a hair off a whole step
    assert path.t_s[-1] == pytest.approx(3.1)
    with pytest.raises(ValueError, match="must start at run time 0"):
        RecordedPath.from_track(_track(t0=0.1), 0.02)
    one = Track("rec_1", "car", 4.0, 1.8, np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1),
                np.full(1, 5.0))
    assert RecordedPath.from_track(one, 0.02).last_step == 0


def test_the_path_validates_its_arrays() -> None:
    z = np.zeros(3)
    with pytest.raises(ValueError, match="speed_mps"):
        RecordedPath("rec_1", 0.02, z, z, z, z, np.zeros(2), z, z)
    with pytest.raises(ValueError, match="finite"):
        RecordedPath("rec_1", 0.02, z, z, z, z, np.full(3, np.nan), z, z)
    with pytest.raises(ValueError, match="step_s"):
        RecordedPath("rec_1", 0.0, z, z, z, z, z, z, z)


# ------------------------------------------------------------------ the recorded box
@pytest.mark.parametrize("length", [2.2, 4.4, 4.8, 12.0])
def test_the_recorded_box_scales_the_car_along_its_length(length: float) -> None:
    base = VehicleParams()
    v = recorded_vehicle(base, length, 1.7)
    assert (v.length_m, v.width_m) == (length, 1.7)
    k = length / base.length_m
    assert v.cg_to_front_bumper_m == pytest.approx(base.cg_to_front_bumper_m * k)
    assert v.cg_to_box_centre_m == pytest.approx(base.cg_to_box_centre_m * k)
    assert v.mass_kg == base.mass_kg and v.friction_coeff == base.friction_coeff
    with pytest.raises(ValueError, match="recorded box"):
        recorded_vehicle(base, 0.0, 1.7)


# ------------------------------------------------------------------ the dynamics
@dataclass
class _World:
    """A world that records the ego poses it was given."""

    poses: list[EgoPose] = field(default_factory=list)
    dt: float = 0.02

    def _scene(self) -> Scene:
        return Scene(t_s=(len(self.poses) - 1) * self.dt, traffic=Traffic.empty(), ego=None)

    def start(self, ego_pose: EgoPose | None) -> Scene:
        assert ego_pose is not None
        self.poses.append(ego_pose)
        return self._scene()

    def step(self, ego_pose: EgoPose | None) -> Scene:
        assert ego_pose is not None
        self.poses.append(ego_pose)
        return self._scene()

    def close(self) -> WorldSummary:
        return WorldSummary()


def test_the_dynamics_push_the_recorded_front_bumper_and_fill_the_state() -> None:
    tr = _track(end=0.4)
    vehicle = recorded_vehicle(VehicleParams(), tr.length_m, tr.width_m)
    line = np.column_stack([np.linspace(0.0, 400.0, 81), np.zeros(81)])
    world = _World()
    dyn = RecordedDynamics(RecordedPath.from_track(tr, 0.02), world,
                           EgoProjector(FrenetPath.from_polyline(line)), vehicle)
    assert dyn.externally_driven
    ego, _ = dyn.start()
    nan = Command(math.nan, math.nan)
    states = [ego]
    while (after := dyn.advance(nan)[0]) is not None:
        states.append(after)
    assert len(states) == 21 and len(world.poses) == 21  # t = 0, 0.02, ..., 0.4
    assert dyn.advance(nan)[0] is None  # still over, nothing pushed
    assert len(world.poses) == 21
    for j, (ego, pose) in enumerate(zip(states, world.poses, strict=True)):
        psi = float(ego.state[2])
        centre = ego.state[:2] + vehicle.cg_to_box_centre_m * np.array([math.cos(psi),
                                                                       math.sin(psi)])
        front = centre + 0.5 * tr.length_m * np.array([math.cos(psi), math.sin(psi)])
        assert (pose.front_x_m, pose.front_y_m) == pytest.approx(tuple(front), abs=1e-12)
        assert pose.heading_rad == psi
        if j % 5 == 0:  # a sample
            k = j // 5
            assert tuple(centre) == pytest.approx((tr.x_m[k], tr.y_m[k]), abs=1e-12)
            assert ego.state[3] == pytest.approx(tr.speed_mps[k])
        assert ego.state[4] == 0.0 and ego.state[5] == pytest.approx(0.05)
        assert ego.long_acc_mps2 == pytest.approx(1.0)
        assert ego.lat_acc_mps2 == pytest.approx(ego.state[3] * 0.05)
        assert math.isnan(ego.steer_rad) and math.isnan(ego.torque_nm)
        assert ego.on_path is not None and ego.s_m > 0.0


def test_the_stand_in_commands_nothing_and_names_its_track() -> None:
    tr = _track()
    stage = RecordedDrivesEgo(RecordedDriverModel(), tr)
    assert isinstance(stage, Controller) and stage.name == "recorded"
    assert stage.obstacle_policy is None
    command = stage.step(None)  # type: ignore[arg-type]
    assert math.isnan(command.steer_rad) and math.isnan(command.torque_nm)
    params = stage.parameters()
    assert params["ego_track"] == "rec_7" and params["samples"] == 21
    assert params["length_m"] == 4.4


# ------------------------------------------------------------------ the catalog key
CATALOG = """
[defaults]
duration_s = 8.0
step_s = 0.02
net = "straight_3lane"
route = ["e0", "e1", "e2", "e3", "e4"]

[[scenario]]
name = "human"
ego = {{ lane = 1, pos_m = 102.4, speed_mps = 20.0 }}
replay = {{ tracks = "t.tracks.parquet"{extra} }}
controller = "{controller}"
"""


def _tracks() -> TrackSet:
    t = np.arange(0.0, 10.01, 0.1)
    late = np.arange(1.0, 10.01, 0.1)
    return TrackSet((track("rec_1", t, 100.0 + 20.0 * t, np.full_like(t, LANE_Y_M[1])),
                     track("rec_2", t, 160.0 + 20.0 * t, np.full_like(t, LANE_Y_M[1])),
                     track("rec_3", late, 60.0 + 20.0 * late, np.full_like(late, LANE_Y_M[0])),
                     Track("rec_4", "car", 4.5, 1.8, np.zeros(1), np.full(1, 300.0),
                           np.zeros(1), np.zeros(1), np.full(1, 20.0))), 0.1)


def _catalog(tmp_path: Path, extra: str = "", controller: str = "recorded") -> Path:
    write_tracks(tmp_path / "t.tracks.parquet", _tracks())
    path = tmp_path / "c.toml"
    path.write_text(CATALOG.format(extra=extra, controller=controller))
    return path


def test_ego_track_builds_into_the_spec_and_the_scenario_dict(tmp_path: Path) -> None:
    (sc,) = load_catalog(_catalog(tmp_path, ', ego_track = "rec_1"'))
    assert sc.replay is not None and sc.replay.ego_track == "rec_1"
    assert sc.as_dict()["replay"]["ego_track"] == "rec_1"
    (plain,) = load_catalog(_catalog(tmp_path, "", controller="lane_keep"))
    assert plain.replay is not None and plain.replay.ego_track is None
    assert "ego_track" not in plain.as_dict()["replay"]  # older scenarios keep their identity


@pytest.mark.parametrize(("extra", "needle"), [
    (', ego_track = "rec_9"', "the id of a track of the file (rec_1, rec_2, rec_3, rec_4)"),
    (', ego_track = "rec_3"', "first sample is at run time 0"),
    (', ego_track = "rec_4"', "at least two samples"),
    (', ego_track = "car_1"', "rec_<id in the recording>"),
    (", ego_track = 1", "rec_<id in the recording>"),
])
def test_a_bad_ego_track_is_an_issue_at_its_key(tmp_path: Path, extra: str, needle: str) -> None:
    with pytest.raises(CatalogError) as exc:
        load_catalog(_catalog(tmp_path, extra, controller="lane_keep"))
    [issue] = exc.value.issues
    assert issue.key == "scenario[0].replay.ego_track"
    assert needle in issue.expected
    if "rec_" in extra and "car" not in extra:
        assert str(tmp_path / "t.tracks.parquet") in issue.expected


def test_recorded_without_an_ego_track_is_an_issue_naming_scenario_and_key(
        tmp_path: Path) -> None:
    with pytest.raises(CatalogError) as exc:
        load_catalog(_catalog(tmp_path))
    [issue] = exc.value.issues
    assert issue.key == "scenario[0].controller" and issue.got == "recorded"
    assert "replay.ego_track" in issue.expected
    line = str(exc.value)
    assert "'human'" in line and "controller" in line and "--ego-obstacle" in line


def test_recorded_without_replay_at_all_is_an_issue(tmp_path: Path) -> None:
    path = tmp_path / "c.toml"
    path.write_text(CATALOG.format(extra="", controller="recorded").replace(
        'replay = { tracks = "t.tracks.parquet" }\n', ""))
    with pytest.raises(CatalogError) as exc:
        load_catalog(path)
    assert [i.key for i in exc.value.issues] == ["scenario[0].controller"]


def test_a_controller_sweep_gives_the_human_beside_the_controller(tmp_path: Path) -> None:
    path = _catalog(tmp_path, ', ego_track = "rec_1"', controller="lane_keep")
    path.write_text(path.read_text() + '[scenario.sweep]\ncontroller = ["lane_keep", '
                    '"recorded"]\n')
    names = [s.name for s in load_catalog(path)]
    assert names == ["human__lane_keep", "human__recorded"]


def test_the_spec_rule_and_the_track_rule() -> None:
    with pytest.raises(SpecError):
        ReplaySpec("t.parquet", ego_track="ego")
    assert ReplaySpec("t.parquet", ego_track="rec_5").as_dict()["ego_track"] == "rec_5"
    spans = track_spans(_tracks())
    assert ego_track_problem(spans, "rec_1") is None
    assert spans["rec_3"].start_s == pytest.approx(1.0) and spans["rec_4"].samples == 1


def test_the_ego_track_is_never_replayed() -> None:
    ts = _tracks()
    rest = ts.without("rec_1")
    assert [t.track_id for t in rest.tracks] == ["rec_2", "rec_3", "rec_4"]
    assert rest.dt_s == ts.dt_s and ts.without(None) is ts


# ------------------------------------------------------------------ the importer
def _needs_commonroad() -> None:
    if not US101_3_3.is_file():
        pytest.skip(f"no shared CommonRoad files in {SHARED}")
    pytest.importorskip("commonroad.common.reader.file_reader_xml")


def _hwyeval(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "suite", *args], cwd=ROOT, text=True,
                          capture_output=True, timeout=600)


def _xml_state(text: str, obstacle: int) -> tuple[float, float, float, float]:
    """Obstacle ``obstacle``'s initial (x, y, orientation, velocity), read from the XML
    text directly (2018b: ``<obstacle id=..>``; exact values)."""
    block = re.search(rf'<obstacle id="{obstacle}">(.*?)</obstacle>', text, re.S)
    assert block is not None
    init = re.search(r"<initialState>(.*?)</initialState>", block.group(1), re.S)
    assert init is not None
    body = init.group(1)

    def num(tag: str) -> float:
        m = re.search(rf"<{tag}>.*?<exact>([-0-9.eE]+)</exact>", body, re.S) if tag in (
            "orientation", "velocity") else re.search(rf"<{tag}>([-0-9.eE]+)</{tag}>", body)
        assert m is not None, tag
        return float(m.group(1))

    return num("x"), num("y"), num("orientation"), num("velocity")


@pytest.mark.slow  # an import in a subprocess, ~2 s
def test_ego_obstacle_makes_a_recorded_vehicle_the_ego(tmp_path: Path) -> None:
    _needs_commonroad()
    proc = _hwyeval("import", "commonroad", str(US101_3_3), "--out", str(tmp_path),
                    "--ego-obstacle", "388")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "recorded ego rec_388" in proc.stdout
    doc = tomllib.loads((tmp_path / "catalog.toml").read_text())
    (sc,) = doc["scenario"]
    assert sc["replay"]["ego_track"] == "rec_388"
    assert sc["sweep"] == {"controller": ["two_loop", "recorded"]}
    x, y, psi, v = _xml_state(US101_3_3.read_text(), 388)
    assert sc["ego"]["speed_mps"] == pytest.approx(v)
    ts = read_tracks(tmp_path / sc["replay"]["tracks"])
    ego = ts.by_id()["rec_388"]
    assert (ego.x_m[0], ego.y_m[0], ego.heading_rad[0]) == (x, y, psi)
    assert ego.start_s == 0.0 and ego.end_s == pytest.approx(sc["duration_s"])
    assert "11 recorded vehicles kept" in ts.notes  # the ego is not traffic
    cat = load_catalog(tmp_path / "catalog.toml")
    assert [s.name for s in cat] == ["usa_us101_3_3_t_1__two_loop",
                                     "usa_us101_3_3_t_1__recorded"]


@pytest.mark.parametrize(("args", "needle"), [
    (["--ego-obstacle", "12345"], "obstacle 12345 (--ego-obstacle): no obstacle of that id"),
    (["--ego-obstacle", "x"], "expected an obstacle id"),
])
def test_a_bad_ego_obstacle_exits_2_naming_it(tmp_path: Path, args: list[str],
                                               needle: str) -> None:
    _needs_commonroad()
    proc = _hwyeval("import", "commonroad", str(US101_3_3), "--out", str(tmp_path), *args)
    assert proc.returncode == 2 and needle in proc.stderr, proc.stderr


def test_ego_obstacle_takes_one_file(tmp_path: Path) -> None:
    _needs_commonroad()
    proc = _hwyeval("import", "commonroad", str(US101_3_3), str(US101_3_3), "--out",
                    str(tmp_path), "--ego-obstacle", "388")
    assert proc.returncode == 2 and "expected one FILE" in proc.stderr


@pytest.mark.slow  # an import in a subprocess, ~2 s
def test_the_recorded_ego_at_the_planning_problem_is_detected(tmp_path: Path) -> None:
    """A copy of US-101-3_3 whose planning problem starts where obstacle 388 does (as
    highD / exiD conversions that keep the ego): 388 is the recorded ego, by itself."""
    _needs_commonroad()
    text = US101_3_3.read_text()
    x, y, psi, v = _xml_state(text, 388)
    head, problem = text.split("<planningProblem", 1)
    problem = (problem.replace("<x>-0.0000</x>", f"<x>{x + 0.3}</x>", 1)
               .replace("<y>0.0000</y>", f"<y>{y}</y>", 1)
               .replace("<exact>-0.7200</exact>", f"<exact>{psi}</exact>", 1)
               .replace("<exact>9.6500</exact>", f"<exact>{v}</exact>", 1))
    src = tmp_path / "USA_US101-3_3_T-1.xml"
    src.write_text(head + "<planningProblem" + problem)
    proc = _hwyeval("import", "commonroad", str(src), "--out", str(tmp_path / "out"))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    (sc,) = tomllib.loads((tmp_path / "out" / "catalog.toml").read_text())["scenario"]
    assert sc["replay"]["ego_track"] == "rec_388"
    frag = (tmp_path / "out" / "USA_US101-3_3_T-1.scenario.json").read_text()
    assert "obstacle 388 (detected: 0.30 m from the planning problem" in frag


def test_a_chosen_egos_start_problems_name_the_obstacle() -> None:
    from suite.importers.commonroad.errors import ImportFailure
    from suite.importers.commonroad.recorded_ego import RecordedEgo, blamed

    with pytest.raises(ImportFailure) as info, blamed(RecordedEgo(388, "chosen")):
        raise ImportFailure("f.xml", "planningProblem 396 initialState", "off the road")
    assert info.value.element == "obstacle 388 (--ego-obstacle) initialState"
    assert info.value.reason == "off the road"
    with pytest.raises(ImportFailure) as info, blamed(RecordedEgo(388, "detected", 0.1)):
        raise ImportFailure("f.xml", "planningProblem 396 initialState", "off the road")
    assert info.value.element == "planningProblem 396 initialState"  # the problem's own
    with pytest.raises(ValueError, match="how"):
        RecordedEgo(1, "guessed")


def test_the_shared_files_have_no_recorded_ego_of_their_own() -> None:
    _needs_commonroad()
    from suite.importers.commonroad.reader import read_file
    from suite.importers.commonroad.recorded_ego import detect

    for path in sorted(SHARED.glob("*.xml")):
        assert detect(read_file(path)) is None, path.name
