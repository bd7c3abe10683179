"""What the per-step path computes once per SUMO step and reuses between them gives the
numbers it gave when computed every step: the moved traffic, the extrapolation with
the headings' cos/sin held, the relative lanes and off-route roads kept for SUMO's last
step's roads, the acceleration tracker, the recorder's extras written row by row, the
loop's paused collector, and the ego's subscribed variable codes."""

from __future__ import annotations

import dataclasses
import gc
import math

import numpy as np
import pytest

from controllers.behaviour import perception
from controllers.behaviour.perception import FrenetTraffic, relative_lanes
from controllers.behaviour.tracking import AccelerationTracker
from controllers.behaviour.types import LaneContext, LaneSlot, Traffic
from suite.world.multirate import extrapolate_traffic, headings


def _traffic(n: int, seed: int = 3, road: str = "e0") -> Traffic:
    rng = np.random.default_rng(seed)
    return Traffic(ids=tuple(f"v{k}" for k in range(n)), x_m=rng.uniform(0, 500, n),
                   y_m=rng.uniform(-6, 6, n), heading_rad=rng.normal(0, 0.2, n),
                   speed_mps=rng.uniform(0, 35, n), length_m=rng.uniform(4, 12, n),
                   width_m=rng.uniform(1.6, 2.5, n), lane_index=rng.integers(0, 3, n),
                   road_id=(road,) * n, stalled=rng.random(n) < 0.2,
                   agent=rng.integers(0, 3, n).astype(np.int8))


def _fields_equal(a: Traffic, b: Traffic) -> None:
    for f in dataclasses.fields(Traffic):
        va, vb = getattr(a, f.name), getattr(b, f.name)
        if isinstance(va, np.ndarray):
            assert va.dtype == vb.dtype
            np.testing.assert_array_equal(va, vb)
        else:
            assert va == vb


def test_moved_traffic_equals_the_checked_constructor() -> None:
    tr = _traffic(7)
    x, y = tr.x_m + 1.0, tr.y_m - 2.0
    _fields_equal(tr.moved(x, y), dataclasses.replace(tr, x_m=x, y_m=y))
    with pytest.raises(ValueError, match="shape"):
        tr.moved(x[:3], y)
    with pytest.raises(dataclasses.FrozenInstanceError):
        tr.moved(x, y).x_m = x  # type: ignore[misc]


def test_extrapolation_with_held_headings_is_bit_identical() -> None:
    tr = _traffic(40)
    direction = headings(tr)
    for tau in (0.02, 0.04, 0.06, 0.08):
        a = extrapolate_traffic(tr, tau)
        b = extrapolate_traffic(tr, tau, direction)
        ref_x = tr.x_m + tr.speed_mps * tau * np.cos(tr.heading_rad)
        ref_y = tr.y_m + tr.speed_mps * tau * np.sin(tr.heading_rad)
        _fields_equal(a, b)
        np.testing.assert_array_equal(b.x_m, ref_x)
        np.testing.assert_array_equal(b.y_m, ref_y)
        assert b.road_id is tr.road_id and b.lane_index is tr.lane_index
    assert extrapolate_traffic(tr, 0.0, direction) is tr


def _context(by_road: dict[str, int]) -> LaneContext:
    slots = {i: LaneSlot(i, 3.5, True, False, offset_m=3.5 * (i - 1)) for i in range(3)}
    return LaneContext(slots, 1, by_road)


def _frenet(tr: Traffic) -> FrenetTraffic:
    z = np.zeros(tr.count)
    return FrenetTraffic(tr.x_m, tr.y_m, z, z, tr.length_m, tr.width_m)


def test_relative_lanes_kept_for_the_same_roads_equal_a_fresh_answer() -> None:
    tr = _traffic(30)
    ctx = _context({"e0": 1})
    first = relative_lanes(tr, _frenet(tr), ctx, 3.5)
    moved = extrapolate_traffic(tr, 0.04)  # the same roads and lane indices
    again = relative_lanes(moved, _frenet(moved), ctx, 3.5)
    np.testing.assert_array_equal(again, tr.lane_index - 1)
    np.testing.assert_array_equal(first, again)
    again[0] = 99  # the caller's copy: the kept answer is not changed
    np.testing.assert_array_equal(relative_lanes(moved, _frenet(moved), ctx, 3.5), first)
    # a different reference lane on the road: answered afresh
    np.testing.assert_array_equal(relative_lanes(moved, _frenet(moved), _context({"e0": 0}),
                                                 3.5), tr.lane_index)
    # new lane indices (the next SUMO step): answered afresh
    shifted = dataclasses.replace(tr, lane_index=(tr.lane_index + 1) % 3)
    np.testing.assert_array_equal(relative_lanes(shifted, _frenet(shifted), ctx, 3.5),
                                  (tr.lane_index + 1) % 3 - 1)


def test_relative_lanes_by_geometry_are_never_kept() -> None:
    tr = _traffic(10, road="off")
    ctx = _context({"e0": 1})
    a = relative_lanes(tr, _frenet(tr), ctx, 3.5)
    shifted = tr.moved(tr.x_m, tr.y_m + 3.5)  # same roads, moved a lane left
    b = relative_lanes(shifted, _frenet(shifted), ctx, 3.5)
    assert not np.array_equal(a, b)


def test_off_route_roads_follow_the_roads_and_the_route() -> None:
    memo = perception._OffRouteRoads()
    roads = ("e0", "ramp", "", ":j0_1", "e1", "ramp")
    assert memo.indices(roads, {"e0": 1, "e1": 1}) == [1, 5]
    assert memo.indices(roads, {"e0": 1, "e1": 1}) == [1, 5]
    assert memo.indices(roads, {"e0": 1, "e1": 1, "ramp": 0}) == []
    assert memo.indices(("ramp", "e0"), {"e0": 1}) == [0]


def test_tracker_equals_its_per_vehicle_definition() -> None:
    tracker = AccelerationTracker()
    rng = np.random.default_rng(5)
    state: dict[str, tuple[float, float, float]] = {}
    tau, forget = tracker.params.tau_s, tracker.params.forget_s
    for k in range(60):
        t = 0.02 * k
        n = int(rng.integers(0, 12))
        ids = tuple(f"v{j}" for j in rng.permutation(15)[:n])
        speeds = rng.uniform(0.0, 30.0, n) if k % 5 == 0 or not state else \
            np.array([state[i][1] if i in state else 20.0 for i in ids])
        tr = Traffic(ids, np.zeros(n), np.zeros(n), np.zeros(n), speeds, np.full(n, 4.5),
                     np.full(n, 1.8), np.zeros(n, dtype=np.int64), ("e0",) * n,
                     np.zeros(n, dtype=bool))
        want = []
        for vid, v in zip(ids, speeds, strict=True):
            prev, a = state.get(vid), 0.0
            if prev is not None and 0.0 < t - prev[0] <= forget:
                dt = t - prev[0]
                a = prev[2] + ((float(v) - prev[1]) / dt - prev[2]) * dt / (tau + dt)
            state[vid] = (t, float(v), a)
            want.append(a)
        got = tracker.update(t, tr)
        assert got.dtype == np.float64 and got.shape == (n,)
        np.testing.assert_array_equal(got, np.array(want, dtype=np.float64))


def test_the_loop_pauses_the_collector_and_restores_it() -> None:
    from suite.run import loop

    seen: list[bool] = []

    def steps(stages: object, n_steps: int) -> str:
        seen.append(gc.isenabled())
        if n_steps < 0:
            raise RuntimeError("boom")
        return loop.DURATION

    original = loop._steps
    loop._steps = steps  # type: ignore[assignment]
    try:
        was = gc.isenabled()
        assert loop.run_loop(None, 1) == loop.DURATION  # type: ignore[arg-type]
        assert gc.isenabled() == was
        with pytest.raises(RuntimeError):
            loop.run_loop(None, -1)  # type: ignore[arg-type]
        assert gc.isenabled() == was
        gc.disable()
        loop.run_loop(None, 1)  # type: ignore[arg-type]
        assert not gc.isenabled()  # left as it was found
    finally:
        loop._steps = original  # type: ignore[assignment]
        gc.enable()
    assert seen == [False, False, False]


def test_the_egos_subscribed_variables_are_tracis_codes() -> None:
    tc = pytest.importorskip("traci.constants")
    from suite.world import sumo

    assert sumo._EGO_VARS == (tc.VAR_POSITION, tc.VAR_ANGLE, tc.VAR_SPEED, tc.VAR_ACCELERATION,
                              tc.VAR_LANE_INDEX, tc.VAR_ROAD_ID, tc.VAR_LANE_ID,
                              tc.VAR_LANEPOSITION)
    assert math.isfinite(sumo.nav_deg_to_math_rad_scalar(90.0))


def test_recorder_extras_reach_the_trace_row_by_row() -> None:
    from controllers.behaviour.types import Decision, Obstacles, Reason
    from controllers.path.frenet import FrenetPath
    from controllers.protocol import Command, StepDiagnostics
    from suite.run.ego import EgoState
    from suite.run.recorder import StepTiming, TraceRecorder
    from suite.run.safety import SafetySample

    @dataclasses.dataclass(frozen=True)
    class Diag(StepDiagnostics):
        gain: float = 0.0
        active: bool = False
        count: int = 0

    path = FrenetPath.from_polyline(np.column_stack([np.linspace(0.0, 500.0, 50),
                                                     np.zeros(50)]))
    rec = TraceRecorder(10, Diag, path, 150.0)
    empty = Obstacles(np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0),
                      np.zeros(0))
    for k in range(6):
        ego = EgoState(np.array([10.0 * k, 0.0, 0.0, 20.0, 0.0, 0.0]), 0.0, 0.0, 0.0, 0.0,
                       10.0 * k, 0.0, 0.0)
        diag = Diag(gain=0.1 * k if k != 3 else math.nan, active=k % 2 == 1, count=k)
        rec.record(k, 0.02 * k, ego, Decision(obstacles=empty, target_speed_mps=20.0,
                                              reason_code=Reason.KEEP, reason="keep"),
                   Command(0.0, 0.0, diagnostics=diag), SafetySample(math.inf, "", False, False),
                   StepTiming(0.0, 0.0, 0.0), Traffic.empty())
    trace, _, _ = rec.finish(100.0)
    assert list(trace.extra) == ["gain", "active", "count"]
    np.testing.assert_array_equal(trace.extra["gain"],
                                  [0.0, 0.1, 0.2, math.nan, 0.1 * 4, 0.1 * 5])
    np.testing.assert_array_equal(trace.extra["active"], [0, 1, 0, 1, 0, 1])
    np.testing.assert_array_equal(trace.extra["count"], np.arange(6.0))
    assert all(v.dtype == np.float64 for v in trace.extra.values())
