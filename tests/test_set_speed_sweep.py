"""A set speed away from the start speed, in real SUMO: start speed x set speed over
18-36 m/s on the empty three-lane straight, with and without traffic in the other lanes,
with and without a stalled car far ahead in the ego's lane (issue #20, item 4).

Before, a set speed below the start speed was an emergency brake: the OCP's target
ramp started at the set speed, the closed-form start put the plan's V there, the first
command (not rate-limited) braked at 10 m/s² and the jerk limiter, wound up beyond the
brake's range, held it for 3 s (33 -> 27 m/s stopped the car on the motorway). Now every
run must pass (its verdict), keep every comfort metric within its limit, never stop,
and reach the set speed (|v - set| <= 0.5 m/s) within the ramp's time and a margin,
unless the behaviour lowered the set-point below the car's speed (something ahead
forced slower) before that.

The road's limit is 33.33 m/s; a 36 m/s set speed is accepted (neither the catalog nor
the controller clamps it to the lane's limit: docs/two_loop.md, "Speed reference") and
is the speed to reach.
"""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from controllers.two_loop.outer.params import OcpParams
from reports.record import load_run

pytestmark = [pytest.mark.sumo, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[1]
SPEEDS_MPS = (18.0, 24.0, 30.0, 36.0)
EGO_POS_M = 60.0
STALL_AHEAD_M = 350.0  # far ahead: beyond the detection distance at the start
DURATION_S = 25.0
REACH_TOL_MPS = 0.5
MARGIN_S = 2.0  # tracking lag and the car's drag, beyond the ramp's own time
COMFORT = ("min_long_acc_mps2", "max_long_acc_mps2", "max_abs_long_jerk_mps3",
           "max_abs_jerk_mps3", "max_abs_lat_acc_mps2", "max_abs_yaw_rate_radps",
           "max_abs_yaw_acc_radps2")
# Traffic in the other lanes only, each kept in its lane (lane_speeds_mps).
TRAFFIC = ("{ vehicles_per_hour = 1500, seed = 7, lanes = [0, 2], "
           "lane_speeds_mps = { 0 = 30.0, 2 = 33.0 } }")
Sweep = tuple[Path, pd.DataFrame, str]  # runs directory, results.csv, the command's output
CASES = {"free": (False, False), "traffic": (True, False), "stall": (False, True),
         "traffic_stall": (True, True)}


def ramp_time_s(dv_mps: float, accel_mps2: float, jerk_mps3: float) -> float:
    """Time-optimal jerk-limited change of speed by |dv| from rest to rest [s]."""
    dv = abs(dv_mps)
    if dv >= accel_mps2**2 / jerk_mps3:
        return dv / accel_mps2 + accel_mps2 / jerk_mps3
    return 2.0 * math.sqrt(dv / jerk_mps3)


def _catalog() -> str:
    speeds = ", ".join(f"{v:.1f}" for v in SPEEDS_MPS)
    lines = ["[defaults]", 'controller = "two_loop"', f"duration_s = {DURATION_S}",
             "step_s = 0.02", "seed = 0", ""]
    for name, (traffic, stall) in CASES.items():
        lines += ["[[scenario]]", f'name = "{name}"', 'net = "straight_3lane"',
                  f"ego = {{ lane = 1, pos_m = {EGO_POS_M}, speed_mps = 30.0 }}"]
        if traffic:
            lines.append(f"traffic = {TRAFFIC}")
        if stall:
            lines.append(f"stalled = [ {{ lane = 1, pos_m = {EGO_POS_M + STALL_AHEAD_M} }} ]")
        lines += ["[scenario.sweep]", f'"ego.speed_mps" = [{speeds}]',
                  f'"ego.target_speed_mps" = [{speeds}]', ""]
    return "\n".join(lines)


@pytest.fixture(scope="module")
def sweep(tmp_path_factory: pytest.TempPathFactory) -> Sweep:
    work = tmp_path_factory.mktemp("set_speed_sweep")
    cat = work / "set_speed_sweep.toml"
    cat.write_text(_catalog())
    out = work / "runs"
    proc = subprocess.run([sys.executable, "-m", "suite", "run", str(cat), "--out", str(out),
                           "--jobs", "2", "--no-log"], cwd=ROOT, capture_output=True,
                          text=True, timeout=900)
    results = pd.read_csv(out / "results.csv").set_index("scenario")
    return out, results, proc.stdout + proc.stderr


def _runs(out: Path, results: pd.DataFrame) -> list[tuple[str, float, float, pd.DataFrame]]:
    """(name, start speed, set speed, trace) of every run."""
    rows = []
    for name in results.index:
        info = load_run(out / name, trace=False, neighbours=False, arrays=False,
                        series=False).info
        ego = info.scenario_spec["ego"]
        rows.append((name, float(ego["speed_mps"]), float(ego["target_speed_mps"]),
                     pd.read_parquet(out / name / "trace.parquet")))
    return rows


def test_the_sweep_covers_every_start_and_set_speed(sweep: Sweep) -> None:
    out, results, output = sweep
    assert len(results) == len(CASES) * len(SPEEDS_MPS) ** 2, output[-3000:]
    pairs = {(v0, vs) for _, v0, vs, _ in _runs(out, results)}
    assert pairs == {(a, b) for a in SPEEDS_MPS for b in SPEEDS_MPS}


def test_every_run_passes_within_the_comfort_limits(sweep: Sweep) -> None:
    out, results, output = sweep
    failed = results[results["status"] != "pass"]
    assert failed.empty, failed[["status", "failed_criteria"]].to_string() + output[-3000:]
    for name in results.index:
        verdict = load_run(out / name, trace=False, neighbours=False, arrays=False,
                           series=False).verdict
        assert verdict is not None
        for metric in COMFORT:
            limit = verdict.criteria[metric]
            assert limit is not None, metric
            value = verdict.value(metric)
            ok = value >= limit if metric.startswith("min_") else value <= limit
            assert ok, (name, metric, value, limit)


def test_no_standstill_and_no_emergency_on_the_way(sweep: Sweep) -> None:
    """Nothing in the sweep needs braking beyond comfort (the stalled car is far and the
    lane beside it free at some point): no emergency flag, no fallback, never stopped."""
    out, results, _ = sweep
    for name, v0, vs, tr in _runs(out, results):
        assert tr["speed_mps"].min() > 0.5 * min(v0, vs), name
        assert not tr["emergency"].any(), name
        assert not tr["fallback"].any(), name


def test_the_set_speed_is_reached_within_the_ramp_time(sweep: Sweep) -> None:
    """Known answer: the OCP's target ramp takes ramp_time_s(|dv|, a, j) with a the
    acceleration limit up, the set speed's deceleration limit down; the car follows it
    within a few tenths of a m/s. A run where the behaviour lowered the set-point below
    the set speed before then (the stalled car ahead, traffic in the lane it passes in)
    is exempt; every run without the stalled car is checked."""
    out, results, _ = sweep
    o = OcpParams()
    checked: set[str] = set()
    for name, v0, vs, tr in _runs(out, results):
        a_lim = o.target_accel_mps2 if vs > v0 else o.set_speed_decel_mps2
        deadline = ramp_time_s(vs - v0, a_lim, o.target_jerk_mps3) + MARGIN_S
        t = tr["t_s"].to_numpy()
        v = tr["speed_mps"].to_numpy()
        assert tr["ocp_target_speed_mps"].iloc[0] == pytest.approx(v0, abs=0.1), name
        lowered = tr["target_speed_mps"].to_numpy() < vs - REACH_TOL_MPS
        if lowered[t <= deadline].any():
            continue  # something ahead asked for less than the set speed meanwhile
        near = abs(v - vs) <= REACH_TOL_MPS
        assert near.any(), (name, v[-1])
        t_reach = float(t[near][0])
        # Not sooner than the comfortable acceleration allows: a ramp, not a step.
        assert (abs(vs - v0) - REACH_TOL_MPS) / (a_lim + 0.25) <= t_reach <= deadline, \
            (name, t_reach, deadline)
        checked.add(name)
    unchecked = {n for n in results.index if not n.startswith(("stall", "traffic_stall"))}
    assert unchecked <= checked, unchecked - checked
