"""A collision verdict rests on 2-D geometry, in real SUMO (issue #20).

Without its sublane model SUMO judges collisions along the lane only: two vehicles on one
lane whose lane positions overlap. A scripted plug-in controller (written to a file and
passed with ``--plugin``, as a user would) drives the ego at 10 m/s past a car stalled in
the right lane of the bundled straight 3-lane net and cuts back in front of it: its front
bumper enters the stalled car's lane while its rear is still alongside, 0.4 m clear of
it. SUMO reports the ego as the victim of the stalled car; the boxes never touch. That
run must show no collision in the verdict, not be stopped by SUMO's report (SUMO, set to
'warn', alters no vehicle), and list the disagreement in run.json and on its report
page. The second run drives straight into a car stalled in the ego's lane: the boxes
overlap, SUMO agrees, and the collision is counted and classified as before.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from geometry_reference import box_corners, box_distance_reference

from reports.metrics import evaluate
from reports.metrics.collisions import judge_collisions
from reports.metrics.context import build_context
from reports.record import RunRecord, load_run
from reports.record.verdict import SUMO_ONLY

pytestmark = pytest.mark.sumo

ROOT = Path(__file__).resolve().parents[1]
STALLED = "stalled0"
COMFORT_OFF = ("min_long_acc_mps2", "max_long_acc_mps2", "max_abs_lat_acc_mps2",
               "max_abs_yaw_rate_radps", "max_abs_yaw_acc_radps2", "max_abs_long_jerk_mps3",
               "max_abs_jerk_mps3")

# The scripted controller: pure pursuit of a lateral offset profile along the reference
# (the ego's start lane), at a constant speed; it ignores every other vehicle.
PLUGIN = '''
"""scripted_offset: pure pursuit of a smooth lateral offset profile, constant speed."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from controllers import registry
from controllers.params import build, param, to_dict
from controllers.protocol import Command, Observation, ScenarioContext, StepDiagnostics


@dataclass(frozen=True)
class OffsetParams:
    speed_mps: float = param(10.0, "m/s", "speed held")
    shift_m: float = param(0.0, "m", "lateral offset reached, left +")
    shift_start_m: float = param(0.0, "m", "progress where the shift starts")
    shift_length_m: float = param(20.0, "m", "distance over which it is reached")
    lookahead_m: float = param(6.0, "m", "pure-pursuit look-ahead")


@dataclass(frozen=True, slots=True)
class OffsetDiagnostics(StepDiagnostics):
    offset_ref_m: float = math.nan


class ScriptedOffset:
    name = "scripted_offset"
    diagnostics_type: ClassVar[type[StepDiagnostics]] = OffsetDiagnostics
    obstacle_policy = None

    def __init__(self, params: OffsetParams) -> None:
        self.params = params
        self._ctx: ScenarioContext | None = None
        self._s = 0.0

    def reset(self, context: ScenarioContext) -> None:
        self._ctx = context
        s, _ = context.reference_path().project(float(context.initial_state[0]),
                                                float(context.initial_state[1]))
        self._s = float(s)

    def offset_at(self, s: float) -> float:
        p = self.params
        u = min(max((s - p.shift_start_m) / p.shift_length_m, 0.0), 1.0)
        return p.shift_m * u ** 3 * (10.0 - 15.0 * u + 6.0 * u * u)

    def step(self, observation: Observation) -> Command:
        if self._ctx is None:
            raise RuntimeError("step before reset")
        p, veh, path = self.params, self._ctx.vehicle, self._ctx.reference_path()
        x, y, psi, u, v = (float(observation.state[i]) for i in range(5))
        self._s = float(path.project_pose(x, y, psi, s_hint=self._s)[0])
        ahead = self._s + p.lookahead_m
        tx, ty = path.to_global(ahead, self.offset_at(ahead))
        dx, dy = float(tx) - x, float(ty) - y
        lx = dx * math.cos(psi) + dy * math.sin(psi)
        ly = -dx * math.sin(psi) + dy * math.cos(psi)
        steer = math.atan(2.0 * veh.wheelbase_m * ly / max(lx * lx + ly * ly, 1e-6))
        steer = min(max(steer, -veh.max_steer_rad), veh.max_steer_rad)
        accel = min(max(p.speed_mps - math.hypot(u, v), -3.0), 1.5)
        diag = OffsetDiagnostics(outer_s=0.0, inner_s=0.0, offset_ref_m=self.offset_at(self._s))
        return Command(steer_rad=steer, torque_nm=veh.mass_kg * veh.wheel_radius_m * accel,
                       diagnostics=diag)

    def parameters(self) -> dict[str, Any]:
        return {"name": self.name, **to_dict(self.params)}


def make(options: Mapping[str, Any]) -> ScriptedOffset:
    opts = dict(options)
    opts.pop("name", None)
    return ScriptedOffset(build(OffsetParams, opts))


registry.register("scripted_offset", make, OffsetParams)
'''

CATALOG = f"""
[defaults]
net = "straight_3lane"
duration_s = 20.0
step_s = 0.05

# Past the car stalled in lane 0, then back into lane 0 just ahead of it: the front
# bumper enters its lane while the rear is alongside, the boxes 0.4 m apart.
[[scenario]]
name = "cut_back_ahead_of_stalled"
ego = {{ lane = 1, pos_m = 100.0, speed_mps = 10.0 }}
stalled = [ {{ lane = 0, pos_m = 250.0 }} ]
criteria = {{ {", ".join(f'{c} = "off"' for c in COMFORT_OFF)} }}
[scenario.controller]
name = "scripted_offset"
speed_mps = 10.0
shift_m = -3.5
# progress on the reference = route position (the reference starts where the lane does)
shift_start_m = 245.2
shift_length_m = 12.0

# Straight into a car stalled in the ego's lane.
[[scenario]]
name = "straight_into_stalled"
ego = {{ lane = 1, pos_m = 100.0, speed_mps = 10.0 }}
stalled = [ {{ lane = 1, pos_m = 250.0 }} ]
controller = {{ name = "scripted_offset", speed_mps = 10.0 }}
"""


@pytest.fixture(scope="module")
def out(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("collision_geometry")
    (root / "scripted_offset.py").write_text(PLUGIN)
    (root / "catalog.toml").write_text(CATALOG)
    out = root / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "suite", "run", str(root / "catalog.toml"), "--out", str(out),
         "--plugin", str(root / "scripted_offset.py"), "--jobs", "1", "--no-log"],
        cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert (out / "results.csv").is_file(), proc.stdout[-3000:] + proc.stderr[-3000:]
    return out


def _run(out: Path, name: str) -> RunRecord:
    rec = load_run(out / name)
    assert rec.outcome.end == "ok", rec.outcome.error
    assert rec.verdict is not None
    return rec


def _results(out: Path) -> pd.DataFrame:
    return pd.read_csv(out / "results.csv").set_index("scenario")


def _front_bumper(rec: RunRecord) -> tuple[np.ndarray, np.ndarray]:
    ego, d = rec.trace.ego, rec.info.ego.cg_to_front_bumper_m
    return ego.x_m + d * np.cos(ego.psi_rad), ego.y_m + d * np.sin(ego.psi_rad)


@pytest.mark.slow
def test_a_collision_only_sumo_reports_is_no_collision(out: Path) -> None:
    rec = _run(out, "cut_back_ahead_of_stalled")
    reports = [c for c in rec.outcome.sumo_collisions if STALLED in (c.collider, c.victim)]
    # the precondition: SUMO's 1-D check did fire (else this test proves nothing)
    assert reports, "precondition: SUMO reported no collision with the stalled car"
    assert all((c.collider, c.victim) == (STALLED, "ego") for c in reports)
    # ... and the 2-D boxes never touched, at a row or between two
    assert not rec.trace.safety.geom_collision.any()
    assert judge_collisions(build_context(rec)).events == ()
    v = rec.verdict
    assert v is not None
    assert v.status == "pass", v.failed_text
    for name in ("collision", "collisions", "at_fault_collisions", "collisions_stopped_track"):
        assert v.value(name) == 0.0, name
    assert v.value("sumo_collisions_as_victim") == 1.0
    assert v.value("sumo_collisions_reported") == len(rec.outcome.sumo_collisions)
    strict = evaluate(rec, {"max_collision": 0.0}).verdict  # any contact fails: none
    assert not [f for f in strict.failures if "collision" in f.criterion]


def test_sumo_s_report_neither_stops_the_run_nor_alters_a_vehicle(out: Path) -> None:
    rec = _run(out, "cut_back_ahead_of_stalled")
    origin = rec.outcome.sumo_t_origin_s
    last_report_t = max(c.t_s for c in rec.outcome.sumo_collisions) - origin
    assert not rec.outcome.stop_reason.startswith("collision"), rec.outcome.stop_reason
    t = rec.trace.t_s
    assert t[-1] >= last_report_t + 2.0  # the 0.5 s grace would have ended it long before
    assert t[-1] == pytest.approx(rec.info.duration_s)
    # SUMO ('warn', stoptime 0) left the stalled car where it was, standing, every step
    nb = rec.neighbours
    mine = nb.id == STALLED
    (stalled,) = rec.outcome.stalled
    assert set(nb.step[mine].tolist()) == set(rec.trace.step.tolist())
    np.testing.assert_allclose(nb.x_m[mine], stalled.x_m, atol=1e-9)
    np.testing.assert_allclose(nb.y_m[mine], stalled.y_m, atol=1e-9)
    assert np.all(nb.speed_mps[mine] == 0.0)
    # ... and kept the ego where the plant put it: SUMO's front bumper is the pushed pose
    # of that row (a SUMO step) or of the row before (held between SUMO steps)
    fx, fy = _front_bumper(rec)
    sx, sy = rec.trace.ego.sumo_front_x_m, rec.trace.ego.sumo_front_y_m
    here = np.hypot(sx[1:] - fx[1:], sy[1:] - fy[1:])
    before = np.hypot(sx[1:] - fx[:-1], sy[1:] - fy[:-1])
    assert np.max(np.minimum(here, before)) < 1e-6


def test_the_disagreement_is_in_run_json_results_and_the_page(out: Path) -> None:
    rec = _run(out, "cut_back_ahead_of_stalled")
    v = rec.verdict
    assert v is not None
    (d,) = v.collision_disagreements  # read back from run.json by load_run
    origin = rec.outcome.sumo_t_origin_s
    times = sorted(c.t_s - origin for c in rec.outcome.sumo_collisions)
    assert (d.kind, d.other_id, d.sumo_role, d.sumo_type) == (SUMO_ONLY, STALLED, "victim",
                                                              "collision")
    assert d.sumo_reports == len(times)
    assert (d.t_s, d.last_t_s) == (pytest.approx(times[0]), pytest.approx(times[-1]))
    # SUMO judged along the lane: both on the stalled car's lane ...
    (stalled,) = rec.outcome.stalled
    assert d.ego_lane_index == d.other_lane_index == stalled.lane_index
    # ... while the boxes stayed apart: their smallest distance over SUMO's reports
    rows = [int(np.argmin(np.abs(rec.trace.t_s - t))) for t in times]
    ego = build_context(rec).corners_m[rows[0]:rows[-1] + 1]
    box = box_corners(stalled.x_m, stalled.y_m, stalled.heading_rad, stalled.length_m,
                      stalled.width_m)
    assert d.min_gap_m == pytest.approx(float(np.min(box_distance_reference(ego, box))))
    assert 0.1 < d.min_gap_m < 1.0
    row = _results(out).loc["cut_back_ahead_of_stalled"]
    assert (row["collision"], row["collision_disagreements"], row["sumo_only_collisions"]) == (
        0, 1, 1)
    page = (out / "report-runs" / "cut_back_ahead_of_stalled.html").read_text()
    assert 'id="collision-disagreements"' in page
    assert f'data-kind="{SUMO_ONLY}"' in page and STALLED in page
    junit = (out / "junit.xml").read_text()
    assert "collision_disagreements=1" in junit


def test_a_collision_the_boxes_show_is_counted_and_classified(out: Path) -> None:
    rec = _run(out, "straight_into_stalled")
    v = rec.verdict
    assert v is not None
    assert rec.trace.safety.geom_collision.any()
    (e,) = judge_collisions(build_context(rec)).events
    assert (e.other_id, e.kind.value, e.at_fault, e.evidence) == (STALLED, "stopped_track", True,
                                                                  "overlap")
    assert e.sumo_role == "collider" and e.sumo_reports >= 1  # SUMO agrees
    assert v.collision_disagreements == ()
    assert v.value("collision") == 1.0 and v.value("at_fault_collisions") == 1.0
    assert v.value("max_at_fault_delta_v_mps") == pytest.approx(0.5 * e.ego_speed_mps)
    first = int(np.flatnonzero(rec.trace.safety.geom_collision)[0])
    (fail,) = [f for f in v.failures if f.criterion == "max_at_fault_collisions"]
    assert fail.step == e.row == first
    assert rec.outcome.stop_reason.startswith("collision")  # the contact stopped it
    assert rec.trace.t_s[-1] == pytest.approx(rec.trace.t_s[first] + 0.5, abs=0.06)
    row = _results(out).loc["straight_into_stalled"]
    assert (row["status"], row["collision"], row["collision_disagreements"]) == ("fail", 1, 0)
    page = (out / "report-runs" / "straight_into_stalled.html").read_text()
    assert 'id="collision-disagreements"' not in page
