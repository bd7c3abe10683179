"""Issue #35, "recordings judged fairly": a recorded car on top of the ego at t = 0 is
refused by the importer (exit 2, naming the obstacle); one that jumps between samples
is warned of and counted; at run time a contact during or just after such a jump is the
recording's (``replayed_into_ego``), not the ego's fault.

The CommonRoad files are written with commonroad-io's classes
(test_import_commonroad_synthetic.write_file); the run-time case is a hand-made record
(test_collisions.scene) whose replayed neighbour teleports onto the ego's lane."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("commonroad.common.writer.file_writer_xml")

from test_collisions import Other, only, scene  # noqa: E402
from test_import_commonroad_synthetic import Car, Lane, Ref, W, straight, write_file  # noqa: E402

from reports.metrics.collisions import JUMP_EXCESS_MPS, CollisionClass  # noqa: E402
from reports.record import AGENT_REPLAYED, AGENT_SUMO, RunRecord  # noqa: E402
from suite.catalog.tracks import read_tracks  # noqa: E402
from suite.importers.commonroad import ImportParams, import_files  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
JUMP_FROM_M, JUMP_TO_M = 150.0, 160.0  # [m] along the road: where the glitch car is a lane left


def two_lanes(ref: Ref) -> list[Lane]:
    return [Lane(1, ref, 0.0, 400.0, 0.0, left=2), Lane(2, ref, 0.0, 400.0, W, right=1)]


def teleporting(ref: Ref) -> Ref:
    """``ref`` moved one lane left between JUMP_FROM_M and JUMP_TO_M: a car driving
    along it jumps 3.75 m sideways there and back, heading and speed unchanged."""
    def moved(s: float) -> tuple[float, float, float]:
        x, y, h = ref(s)
        return (x, y + W, h) if JUMP_FROM_M <= s < JUMP_TO_M else (x, y, h)
    return moved


EGO = Car(9000, straight(), 60.0, 0.0, 25.0, k1=100)


def test_a_recorded_car_on_the_ego_at_t0_is_refused(tmp_path: Path) -> None:
    ref = straight()
    cars = [Car(1001, ref, 61.0, 0.0, 25.0), Car(1002, ref, 120.0, W, 25.0)]
    src = write_file(tmp_path / "ZAM_OnEgo-1_1_T-1.xml", two_lanes(ref), cars, EGO, 0.1,
                     country="ZAM")
    out = tmp_path / "out"
    outcome = import_files([src], out, ImportParams())
    assert not outcome.results
    (failure,) = outcome.failures
    assert failure.element == "obstacle 1001"
    assert not list(out.glob("ZAM_OnEgo*"))  # nothing of the file written
    proc = subprocess.run([sys.executable, "-m", "suite", "import", "commonroad", str(src),
                           "--out", str(tmp_path / "cli")], cwd=ROOT, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert "1001" in proc.stderr


def test_a_car_that_jumps_between_samples_is_warned_of_and_counted(tmp_path: Path) -> None:
    ref = straight()
    cars = [Car(1001, teleporting(ref), 100.0, 0.0, 25.0),  # steps 20-23 a lane left
            Car(1002, ref, 140.0, W, 25.0)]
    src = write_file(tmp_path / "ZAM_Jump-1_1_T-1.xml", two_lanes(ref), cars, EGO, 0.1,
                     country="ZAM")
    outcome = import_files([src], tmp_path / "out", ImportParams())
    assert not outcome.failures, outcome.failures
    (r,) = outcome.results
    assert r.jumps == 2  # onto the left lane and back
    named = [n for n in r.notes if "rec_1001" in n]
    assert named and not [n for n in r.notes if "rec_1002" in n]
    assert any("rec_1001" in n for n in read_tracks(r.tracks_path).notes)


def test_a_smooth_recording_has_no_jumps(tmp_path: Path) -> None:
    ref = straight()
    cars = [Car(1001, ref, 100.0, 0.0, 25.0), Car(1002, ref, 140.0, W, 25.0)]
    src = write_file(tmp_path / "ZAM_Smooth-1_1_T-1.xml", two_lanes(ref), cars, EGO, 0.1,
                     country="ZAM")
    outcome = import_files([src], tmp_path / "out", ImportParams())
    assert not outcome.failures, outcome.failures
    assert outcome.results[0].jumps == 0


# ------------------------------------------------------------------ at run time

JUMP_T_S = 1.0  # [s] the neighbour moves one lane right between 1.0 and 1.1 s


def cut_in(agent: int, lateral_s: float) -> RunRecord:
    """The ego at 20 m/s on y = 0; a car 4 m ahead (box centres) at 20 m/s on y = 3.75
    moves onto y = 0 between JUMP_T_S and JUMP_T_S + ``lateral_s``, heading along the
    road throughout: the ego's front edge is in its box (nuPlan: active_front)."""
    record = scene(0.0, 0.0, 20.0, [Other("rec_7", 4.0, W, 20.0)], dt_s=0.05)
    nb = record.neighbours
    t = nb.t_s
    u = np.clip((t - JUMP_T_S) / lateral_s, 0.0, 1.0)
    nb.y_m[:] = W * (1.0 - u)
    nb.agent[:] = agent
    return record


def test_a_contact_during_a_jump_of_a_replayed_car_is_the_recordings() -> None:
    event = only(cut_in(AGENT_REPLAYED, 0.1))  # 3.75 m in 0.1 s: 37.5 m/s sideways
    assert 37.5 > JUMP_EXCESS_MPS
    assert event.kind == CollisionClass.REPLAYED_INTO_EGO and not event.at_fault


def test_without_a_jump_or_from_sumo_the_same_contact_stays_at_fault() -> None:
    smooth = only(cut_in(AGENT_REPLAYED, 2.0))  # 1.9 m/s sideways: a cut-in, no jump
    assert smooth.kind == CollisionClass.ACTIVE_FRONT and smooth.at_fault
    sumo = only(cut_in(AGENT_SUMO, 0.1))  # not a recording: judged as before
    assert sumo.kind == CollisionClass.ACTIVE_FRONT and sumo.at_fault
