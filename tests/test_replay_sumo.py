"""Recorded traffic replayed in real SUMO runs (suite.world.replay), read back from the
run directories: poses, presence, ids, agent kinds, the reactive handover, the
collision class of a replayed car driving into the ego, the run page and the .rrd."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from replay_fixtures import (
    cut_in_tracks,
    fidelity_tracks,
    rear_end_tracks,
    write_replay_catalog,
)
from rerun_fixtures import read_chunks

from controllers.behaviour.types import Traffic
from reports.metrics.collisions import CollisionClass, classify_collisions
from reports.metrics.context import build_context
from reports.record import AGENT_REACTIVE, AGENT_REPLAYED, AGENT_SUMO, RunRecord, load_run
from suite.catalog.tracks import TrackSet
from suite.world.replay import HandoverEgo, handover_due

pytestmark = [pytest.mark.sumo, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[1]
SUMO_STEP_S = 0.1  # the catalog's default SUMO step for step_s = 0.02
POS_TOL_M = 0.05
HEADING_TOL_RAD = math.radians(1.0)
SPEED_TOL_MPS = 0.1


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    base = tmp_path_factory.mktemp("replay")
    catalog = write_replay_catalog(base)
    out = base / "out"
    proc = subprocess.run([sys.executable, "-m", "suite", "run", str(catalog), "--out",
                           str(out), "--jobs", "1"], cwd=ROOT, capture_output=True,
                          text=True, timeout=900)
    assert proc.returncode in (0, 1), proc.stdout + proc.stderr
    return out


def _sumo_rows(t_s: np.ndarray) -> np.ndarray:
    """Rows at SUMO step times (between them the scene is extrapolated: multi-rate)."""
    return np.abs(t_s / SUMO_STEP_S - np.round(t_s / SUMO_STEP_S)) < 1e-6


def _pose_errors(rec: RunRecord, tracks: TrackSet) -> tuple[float, float, float]:
    """Max centre [m], heading [rad] and speed [m/s] error of the replayed rows at SUMO
    steps against the tracks interpolated to those times."""
    nb = rec.neighbours
    by_id = tracks.by_id()
    pos = head = speed = 0.0
    checked = 0
    for k in np.flatnonzero(_sumo_rows(nb.t_s) & (nb.agent == AGENT_REPLAYED)):
        pose = by_id[str(nb.id[k])].pose_at(float(nb.t_s[k]))
        assert pose is not None, (nb.id[k], nb.t_s[k])
        pos = max(pos, math.hypot(nb.x_m[k] - pose.x_m, nb.y_m[k] - pose.y_m))
        dh = (nb.heading_rad[k] - pose.heading_rad + math.pi) % (2 * math.pi) - math.pi
        head = max(head, abs(dh))
        speed = max(speed, abs(nb.speed_mps[k] - pose.speed_mps))
        checked += 1
    assert checked > 20
    return pos, head, speed


def test_replayed_vehicles_are_at_their_recorded_poses(runs: Path) -> None:
    """Centre within 0.05 m, heading within 1 deg, speed within 0.1 m/s at every SUMO
    step, the steps between rec_1's 0.25 s samples (interpolated) included."""
    rec = load_run(runs / "rp_fidelity")
    pos, head, speed = _pose_errors(rec, fidelity_tracks())
    assert pos <= POS_TOL_M and head <= HEADING_TOL_RAD and speed <= SPEED_TOL_MPS
    nb = rec.neighbours
    between = (nb.id == "rec_1") & _sumo_rows(nb.t_s) & (
        np.abs(nb.t_s / 0.25 - np.round(nb.t_s / 0.25)) > 1e-6)
    assert between.sum() > 20  # interpolated poses were checked


def test_replayed_vehicles_appear_and_leave_when_recorded(runs: Path) -> None:
    rec = load_run(runs / "rp_fidelity")
    nb = rec.neighbours
    sumo = _sumo_rows(nb.t_s)
    for track in fidelity_tracks().tracks:
        mine = (nb.id == track.track_id) & sumo
        times = np.round(nb.t_s[mine] / SUMO_STEP_S).astype(int)
        first = max(math.ceil(track.start_s / SUMO_STEP_S - 1e-6), 1)  # rows start at 1
        last = min(math.floor(track.end_s / SUMO_STEP_S + 1e-6), 80)
        assert times.min() == first and times.max() == last, track.track_id
        assert np.array_equal(times, np.arange(first, last + 1)), track.track_id
    assert rec.outcome.replay is not None and rec.outcome.replay.vehicles == 3


def test_ids_sizes_and_agent_kinds(runs: Path) -> None:
    """rec_* ids with their recorded box sizes and agent 1; the stalled car and the
    scripted actor beside them have agent 0."""
    rec = load_run(runs / "rp_fidelity")
    nb = rec.neighbours
    ids = set(nb.id.tolist())
    assert {"rec_1", "rec_2", "rec_3", "actor_a1"} <= ids
    for track in fidelity_tracks().tracks:
        mine = nb.id == track.track_id
        assert np.all(nb.agent[mine] == AGENT_REPLAYED)
        assert np.allclose(nb.length_m[mine], track.length_m)
        assert np.allclose(nb.width_m[mine], track.width_m)
    others = ~np.char.startswith(nb.id.astype(str), "rec_")
    assert others.any() and np.all(nb.agent[others] == AGENT_SUMO)
    assert nb.agent.dtype == np.int8
    assert [s.lane_index for s in rec.outcome.stalled] == [0]


def _rule_on_record(rec: RunRecord, row: int, vid: str, gap_s: float) -> bool:
    """The handover rule on the logged poses of the ego and ``vid`` at trace row ``row``
    (one road: road ids left equal)."""
    nb, e, box = rec.neighbours, rec.trace.ego, rec.info.ego
    k = np.flatnonzero((nb.step == rec.trace.step[row]) & (nb.id == vid))
    if k.size == 0:
        return False
    psi = float(e.sumo_heading_rad[row])
    ego = HandoverEgo(float(e.sumo_front_x_m[row]) - 0.5 * box.length_m * math.cos(psi),
                      float(e.sumo_front_y_m[row]) - 0.5 * box.length_m * math.sin(psi), psi,
                      float(e.speed_mps[row]), box.length_m, box.width_m, "",
                      int(e.lane_index[row]))
    one = Traffic((vid,), nb.x_m[k], nb.y_m[k], nb.heading_rad[k], nb.speed_mps[k],
                  nb.length_m[k], nb.width_m[k], nb.lane_index[k], ("",), np.zeros(1, bool))
    return bool(handover_due(ego, one, gap_s)[0])


def test_reactive_handover_happens_when_the_rule_says_and_not_before(runs: Path) -> None:
    """rec_5 closes in from the next lane and cuts in: replayed until the first SUMO
    step at which the time-gap rule holds, reactive from the next one on."""
    rec = load_run(runs / "rp_cut_in")
    nb, tr = rec.neighbours, rec.trace
    sumo_rows = np.flatnonzero(_sumo_rows(tr.t_s))
    due = [r for r in sumo_rows if _rule_on_record(rec, int(r), "rec_5", 1.0)]
    assert due, "the rule never held"
    t_due = float(tr.t_s[due[0]])
    assert 4.0 < t_due < 5.0  # the cut-in starts at 4 s; its gap is then ~1 s
    assert rec.outcome.replay is not None
    [hand] = rec.outcome.replay.handovers
    assert hand.track_id == "rec_5" and hand.t_s == pytest.approx(t_due, abs=1e-6)
    mine = nb.id == "rec_5"
    before = mine & (nb.t_s <= t_due + 1e-6)
    after = mine & (nb.t_s >= t_due + SUMO_STEP_S - 1e-6)
    assert before.any() and np.all(nb.agent[before] == AGENT_REPLAYED)
    assert after.any() and np.all(nb.agent[after] == AGENT_REACTIVE)
    pos, _, _ = _pose_errors(rec, cut_in_tracks())  # replayed exactly until then
    assert pos <= POS_TOL_M


def test_a_replayed_car_driving_into_the_ego_is_not_at_fault(runs: Path) -> None:
    rec = load_run(runs / "rp_rear_end__modereplay")
    events = classify_collisions(build_context(rec))
    assert events, "the replayed car did not reach the ego"
    first = events[0]
    assert first.other_id == "rec_9"
    assert first.kind == CollisionClass.REPLAYED_INTO_EGO and not first.at_fault
    assert rec.verdict is not None
    assert rec.verdict.value("collisions_replayed_into_ego") >= 1.0
    assert rec.verdict.value("at_fault_collisions") == 0.0
    # a blind recorded car's approach is not the ego's time to collision either
    assert "min_ttc_s" not in {f.criterion for f in rec.verdict.failures}
    page = (runs / "report-runs" / "rp_rear_end__modereplay.html").read_text()
    assert 'id="replay"' in page


def test_in_reactive_mode_the_same_car_hands_over_and_does_not_hit(runs: Path) -> None:
    rec = load_run(runs / "rp_rear_end__modereactive")
    assert classify_collisions(build_context(rec)) == ()
    assert rec.outcome.replay is not None
    [hand] = rec.outcome.replay.handovers
    assert hand.track_id == "rec_9" and hand.t_s == pytest.approx(0.0)  # behind, in lane
    nb = rec.neighbours
    assert np.all(nb.agent[(nb.id == "rec_9") & (nb.t_s > SUMO_STEP_S - 1e-6)]
                  == AGENT_REACTIVE)
    assert len(rear_end_tracks().tracks) == 1


def test_rerun_log_shows_replayed_and_reactive_cars_apart(runs: Path) -> None:
    chunks = read_chunks(runs / "rp_cut_in" / "run.rrd")
    labels: dict[str, set[str]] = {}
    colours: dict[str, set[int]] = {}
    for c in chunks:
        if c.entity_path not in ("/world/replayed", "/world/reactive", "/world/vehicles"):
            continue
        rb = c.to_record_batch()
        for name in rb.schema.names:
            if name.endswith(":labels"):
                for row in rb.column(name).to_pylist():
                    labels.setdefault(c.entity_path, set()).update(row or [])
            if name.endswith(":colors"):
                for row in rb.column(name).to_pylist():
                    colours.setdefault(c.entity_path, set()).update(row or [])
    assert labels["/world/replayed"] == {"rec_5 (replayed)"}
    assert labels["/world/reactive"] == {"rec_5 (reactive)"}
    assert colours["/world/replayed"] and colours["/world/reactive"]
    assert not colours["/world/replayed"] & colours["/world/reactive"]
    page = (runs / "report-runs" / "rp_cut_in.html").read_text()
    assert 'id="replay"' in page and "#9333ea" in page and "#0d9488" in page
