"""A failure records the manoeuvre phase and the fallback at its step (issue #37): the
metrics take them from the trace when the run is judged, run.json keeps them, an older
run.json without them still loads, and the search names a failure mode from the
verdict alone, never opening trace.parquet again."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import synthetic_runs as sr

from controllers.behaviour.types import Side
from reports.metrics import Criteria
from reports.metrics.values import Measured, measured
from reports.record import TRACE, Failure, RunRecord, Trace, Verdict, load_run
from reports.record.run import read_run_json
from reports.record.verdict import PHASES, phase_name
from suite.search.loop import failure_mode

# a side code per trace row: every phase in turn, and one code PHASES does not list
SIDES = (0, 1, -1, 2, 7)


def _m(name: str, value: float, worst_step: int | None = None,
       increments: np.ndarray | None = None) -> Measured:
    return measured(name, value, "-", "safety", worst_step=worst_step, increments=increments)


def _trace_columns(n: int) -> tuple[np.ndarray, np.ndarray]:
    side = np.array([SIDES[i % len(SIDES)] for i in range(n)], dtype=np.int64)
    fallback = np.arange(n) % 3 == 0
    return side, fallback


def test_check_records_the_phase_and_the_fallback_at_the_failure_step() -> None:
    side, fallback = _trace_columns(20)
    inc = np.zeros(20)
    inc[[6, 9]] = 1.0  # the running total first exceeds 0 at row 6
    failed = Criteria(max_fallbacks=0.0).check(
        [_m("max_abs_lat_acc_mps2", 5.0, worst_step=7), _m("min_ttc_s", 0.2, worst_step=3),
         _m("fallbacks", 2.0, increments=inc), _m("progress_ratio", 0.1)],
        0.1 * np.arange(20), side=side, fallback=fallback)
    by_metric = {f.metric: f for f in failed}
    # row 7: side -1, no fallback; row 3: side 2, a fallback; row 6: side 1, a fallback
    assert (by_metric["max_abs_lat_acc_mps2"].step, by_metric["max_abs_lat_acc_mps2"].phase,
            by_metric["max_abs_lat_acc_mps2"].fell_back) == (7, "right", False)
    assert (by_metric["min_ttc_s"].step, by_metric["min_ttc_s"].phase,
            by_metric["min_ttc_s"].fell_back) == (3, "follow", True)
    assert (by_metric["fallbacks"].step, by_metric["fallbacks"].phase,
            by_metric["fallbacks"].fell_back) == (6, "left", True)
    for f in failed:
        if f.step is None:  # an aggregate: no row, no phase
            assert (f.phase, f.fell_back) == ("", None)
        else:
            assert f.phase == phase_name(int(side[f.step]))
            assert f.fell_back == bool(fallback[f.step])


def test_a_side_code_outside_the_table_and_missing_columns() -> None:
    side, fallback = _trace_columns(10)
    (f,) = Criteria().check([_m("max_abs_lat_acc_mps2", 5.0, worst_step=4)], side=side,
                            fallback=fallback)
    assert f.phase == "side7" and f.fell_back is False
    (g,) = Criteria().check([_m("max_abs_lat_acc_mps2", 5.0, worst_step=4)])
    assert (g.step, g.phase, g.fell_back) == (4, "", None)
    (h,) = Criteria().check([_m("max_abs_lat_acc_mps2", 5.0, worst_step=40)], side=side,
                            fallback=fallback)  # past the trace's end: unknown
    assert (h.phase, h.fell_back) == ("", None)
    assert PHASES == {1: "left", -1: "right", 0: "lane", 2: "follow"}
    # every side code the behaviour writes into the trace has its phase name
    assert set(PHASES) == {int(side) for side in Side}
    with pytest.raises(ValueError, match="without a step"):
        Failure(criterion="c", metric="m", value=1.0, limit=0.0, bound="max", phase="lane")


def _phased_turn() -> tuple[RunRecord, np.ndarray, np.ndarray]:
    """A sharp turn (fails lateral acceleration, yaw rate, ... at known rows) whose
    trace carries every side code in turn and a fallback every third row."""
    tr = sr.turn_trace(radius_m=60.0, speed_mps=20.0)
    side, fallback = _trace_columns(len(tr))
    tr.decision.side[:] = side
    tr.controller.fallback[:] = fallback
    return sr.make_record(tr, name="phased_turn"), side, fallback


def test_evaluate_records_them_and_run_json_keeps_them(tmp_path: Path) -> None:
    record, side, fallback = _phased_turn()
    run_dir = sr.write_judged(record, tmp_path / "phased_turn")
    _, _, verdict = read_run_json(run_dir)
    assert verdict is not None and verdict.status == "fail"
    located = [f for f in verdict.failures if f.step is not None]
    assert located
    for f in located:
        assert f.step is not None
        assert f.phase == phase_name(int(side[f.step]))
        assert f.fell_back == bool(fallback[f.step])
    stored = json.loads((run_dir / "run.json").read_text())["verdict"]["failures"]
    assert {"phase", "fell_back"} <= set(stored[0])


def _old_mode(run_dir: Path, verdict: Verdict) -> str:
    """The failure mode as the search named it before the phase was recorded: the
    trace reloaded, its decision side at the earliest failure's step."""
    criteria = "+".join(sorted({f.criterion for f in verdict.failures}))
    steps = [f.step for f in verdict.failures if f.step is not None]
    if not steps:
        return f"{criteria}@whole_run"
    side = int(load_run(run_dir, neighbours=False, arrays=False,
                        series=False).trace.decision.side[min(steps)])
    return f"{criteria}@{PHASES.get(side, f'side{side}')}"


def test_failure_mode_is_named_without_the_trace(tmp_path: Path) -> None:
    record, _, _ = _phased_turn()
    run_dir = sr.write_judged(record, tmp_path / "phased_turn")
    loaded = load_run(run_dir, neighbours=False, arrays=False, series=False)
    assert loaded.verdict is not None
    mode = failure_mode(loaded)
    assert mode == _old_mode(run_dir, loaded.verdict)  # the same name as before
    assert "@" in mode and not mode.endswith(("@unknown", "@whole_run"))
    (run_dir / TRACE).unlink()
    assert failure_mode(loaded) == mode  # the trace is never opened again
    info, outcome, verdict = read_run_json(run_dir)  # run.json alone names it too
    alone = RunRecord(info=info, outcome=outcome, road=loaded.road,
                         trace=Trace.empty(), neighbours=loaded.neighbours,
                         arrays=loaded.arrays, verdict=verdict, run_dir=run_dir)
    assert failure_mode(alone) == mode


def _strip_phases(run_dir: Path) -> None:
    path = run_dir / "run.json"
    doc = json.loads(path.read_text())
    for f in doc["verdict"]["failures"]:
        del f["phase"], f["fell_back"]
    path.write_text(json.dumps(doc))


def test_an_older_run_json_without_them_still_loads(tmp_path: Path) -> None:
    record, _, _ = _phased_turn()
    run_dir = sr.write_judged(record, tmp_path / "phased_turn")
    _strip_phases(run_dir)
    loaded = load_run(run_dir)  # run.json is not among the files it lists: still valid
    assert loaded.verdict is not None and loaded.verdict.failures
    assert all((f.phase, f.fell_back) == ("", None) for f in loaded.verdict.failures)
    mode = failure_mode(loaded)
    assert mode.endswith("@unknown")  # it was located, but its phase was not recorded
    whole = Verdict(status="fail", failures=(Failure(
        criterion="min_progress_fraction", metric="progress_ratio", value=0.1, limit=0.5,
        bound="min"),))
    assert failure_mode(RunRecord(
        info=loaded.info, outcome=loaded.outcome, road=loaded.road, trace=loaded.trace,
        neighbours=loaded.neighbours, arrays=loaded.arrays,
        verdict=whole)) == "min_progress_fraction@whole_run"


CATALOG = """
[defaults]
controller = "lane_keep"
duration_s = 6.0
step_s = 0.02
[[scenario]]
name = "stall_ahead"
net = "straight_3lane"
ego = { lane = 1, pos_m = 50.0, speed_mps = 25.0 }
stalled = [ { lane = 1, pos_m = 200.0 } ]
criteria = { min_ttc_s = 100.0 }
"""


@pytest.mark.sumo
@pytest.mark.slow
def test_a_real_run_names_its_mode_from_run_json_alone(tmp_path: Path) -> None:
    catalog = tmp_path / "stall.toml"
    catalog.write_text(CATALOG)
    out = tmp_path / "out"
    done = subprocess.run([str(Path(sys.executable).parent / "hwyeval"), "run", str(catalog),
                           "--out", str(out), "--no-log", "--jobs", "1"],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 1, done.stdout + done.stderr  # min_ttc_s fails
    (run_dir,) = [d for d in out.iterdir() if (d / "run.json").is_file()]
    loaded = load_run(run_dir, neighbours=False, arrays=False, series=False)
    assert loaded.verdict is not None and loaded.status == "fail"
    ttc = next(f for f in loaded.verdict.failures if f.metric == "min_ttc_s")
    assert ttc.step is not None
    assert ttc.phase == phase_name(int(loaded.trace.decision.side[ttc.step]))
    assert ttc.fell_back == bool(loaded.trace.controller.fallback[ttc.step])
    mode = failure_mode(loaded)
    assert mode == _old_mode(run_dir, loaded.verdict)
    (run_dir / TRACE).unlink()
    assert failure_mode(loaded) == mode
