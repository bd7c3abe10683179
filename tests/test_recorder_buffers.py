"""The recorder's growable column buffers: neighbours and world-frame ellipses equal what
per-step recording (``Traffic.take`` within the radius, ``ellipses_in_world``) gives,
across buffer growth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.behaviour.ellipses import ellipses_in_world
from controllers.behaviour.types import Decision, Obstacles, Reason, Traffic
from controllers.path.frenet import FrenetPath
from controllers.protocol import Command, StepDiagnostics
from suite.run.ego import EgoState
from suite.run.recorder import StepTiming, TraceRecorder, _append_within, _Columns
from suite.run.safety import SafetySample

PATH = FrenetPath.from_polyline(np.column_stack([np.linspace(0.0, 900.0, 200),
                                   20.0 * np.sin(np.linspace(0.0, 3.0, 200))]))


def _traffic(rng: np.random.Generator, n: int, x0: float) -> Traffic:
    return Traffic(ids=tuple(f"v{k}" for k in rng.permutation(200)[:n]),
                   x_m=x0 + rng.uniform(-250.0, 250.0, n), y_m=rng.uniform(-10.0, 10.0, n),
                   heading_rad=rng.normal(0.0, 0.1, n), speed_mps=rng.uniform(0.0, 30.0, n),
                   length_m=rng.uniform(4.0, 12.0, n), width_m=rng.uniform(1.6, 2.5, n),
                   lane_index=rng.integers(0, 3, n), road_id=("e0",) * n,
                   stalled=rng.random(n) < 0.1)


def _obstacles(rng: np.random.Generator, k: int, s0: float, step: int = 0) -> Obstacles:
    ids = tuple(f"v{step}_{j}" for j in range(k)) if step % 2 else ()  # ids every other step
    return Obstacles(s0 + rng.uniform(5.0, 80.0, k), rng.uniform(-3.0, 3.0, k), np.zeros(k),
                     np.zeros(k), rng.uniform(5.0, 9.0, k), rng.uniform(1.5, 2.5, k), ids)


def test_buffers_equal_per_step_recording() -> None:
    rng = np.random.default_rng(7)
    n_steps = 60
    rec = TraceRecorder(n_steps, StepDiagnostics, PATH, record_radius_m=150.0)
    rec._nb = _Columns({k: v.dtype for k, v in rec._nb.data.items()}, 3)  # force growth
    expected_nb: list[Traffic] = []
    expected_ell: list[np.ndarray] = []
    for step in range(n_steps):
        x = 100.0 + 10.0 * step
        state = np.array([x, 0.0, 0.0, 25.0, 0.0, 0.0])
        ego = EgoState(state, 0.0, 0.0, 0.0, 0.0, x, 0.0, 0.0)
        traffic = _traffic(rng, int(rng.integers(0, 40)), x) if step % 7 else Traffic.empty()
        obstacles = _obstacles(rng, int(rng.integers(0, 4)), x, step)
        decision = Decision(obstacles=obstacles, target_speed_mps=25.0,
                            reason_code=Reason.KEEP, reason="keep lane: free")
        rec.record(step, 0.02 * step, ego, decision,
                   Command(0.0, 0.0, diagnostics=StepDiagnostics()),
                   SafetySample(math.inf, "", False, False), StepTiming(0.0, 0.0, 0.0), traffic)
        if traffic.count:
            keep = np.hypot(traffic.x_m - x, traffic.y_m) <= 150.0
            expected_nb.append(traffic.take(keep))
        else:
            expected_nb.append(Traffic.empty())
        expected_ell.append(ellipses_in_world(PATH, obstacles))
    trace, nb, arrays = rec.finish(detection_radius_m=120.0)
    assert len(trace) == n_steps
    steps = np.concatenate([np.full(t.count, k) for k, t in enumerate(expected_nb)])
    np.testing.assert_array_equal(nb.step, steps)
    np.testing.assert_allclose(nb.t_s, 0.02 * steps)
    assert list(nb.id) == [i for t in expected_nb for i in t.ids]
    for name in ("x_m", "y_m", "heading_rad", "speed_mps", "length_m", "width_m", "lane_index",
                 "stalled"):
        np.testing.assert_array_equal(getattr(nb, name),
                                      np.concatenate([getattr(t, name) for t in expected_nb]))
    width = max(e.shape[0] for e in expected_ell)
    assert arrays.ellipses.shape == (n_steps, width, 6)
    for k, e in enumerate(expected_ell):
        np.testing.assert_allclose(arrays.ellipses[k, : e.shape[0]], e, rtol=1e-12, atol=1e-9)
        assert np.all(np.isnan(arrays.ellipses[k, e.shape[0]:]))
        # each ellipse's vehicle id beside it ('' where not given, and in the padding)
        n_k = e.shape[0]
        want = [f"v{k}_{j}" if k % 2 else "" for j in range(n_k)] + [""] * (width - n_k)
        assert [arrays.ellipse_id(k, j) for j in range(width)] == want
    assert arrays.detection_radius_m == 120.0
    assert set(trace.decision.reason_code) == {"keep"}
    assert set(trace.decision.side_reason) == {"keep lane: free"}


def test_columns_grow_and_keep_their_rows() -> None:
    cols = _Columns({"a": np.int64, "b": np.float64}, 2)
    for k in range(10):
        start = cols.reserve(3)
        cols.data["a"][start:start + 3] = k
        cols.data["b"][start:start + 3] = [k, k + 0.5, k + 0.25]
    assert cols.size == 30
    np.testing.assert_array_equal(cols.head("a"), np.repeat(np.arange(10), 3))
    assert cols.head("b")[-1] == pytest.approx(9.25)
    with pytest.raises(ValueError):
        _Columns({"a": np.int64}, 0)


def test_the_neighbour_kernel_selects_as_numpy_does() -> None:
    """``_append_within`` keeps the vehicles numpy's ``dx*dx + dy*dy <= r²`` keeps, on
    the circle itself too, in traffic order, and writes their rows after ``a``."""
    rng = np.random.default_rng(11)
    for trial in range(200):
        n = int(rng.integers(1, 60))
        r = float(rng.uniform(1.0, 200.0))
        ex, ey = rng.uniform(-500.0, 500.0, 2)
        ang = rng.uniform(-math.pi, math.pi, n)
        rad = rng.uniform(0.0, 2.0 * r, n)
        rad[rng.random(n) < 0.3] = r  # on the circle (up to rounding of the angle)
        x, y = ex + rad * np.cos(ang), ey + rad * np.sin(ang)
        if trial % 5 == 0:
            x[0], y[0] = ex + r, ey  # exactly on it
        f = [rng.normal(size=n) for _ in range(4)]
        lane = rng.integers(-1, 4, n)
        stalled = rng.random(n) < 0.5
        agent = rng.integers(0, 3, n).astype(np.int8)
        a = int(rng.integers(0, 5))
        out_f = [np.full(a + n, np.nan) for _ in range(7)]
        out_i = [np.full(a + n, -9, dtype=np.int64) for _ in range(2)]
        out_b = np.zeros(a + n, dtype=np.bool_)
        out_g = np.zeros(a + n, dtype=np.int8)
        picked = np.empty(n, dtype=np.int64)
        got = _append_within(3, 0.06, ex, ey, r * r, x, y, *f, lane, stalled, agent, a,
                             out_i[0], out_f[0], out_f[1], out_f[2], out_f[3], out_f[4],
                             out_f[5], out_f[6], out_i[1], out_b, out_g, picked)
        dx, dy = x - ex, y - ey
        idx = np.flatnonzero(dx * dx + dy * dy <= r * r)
        assert got == idx.size
        np.testing.assert_array_equal(picked[:got], idx)
        rows = slice(a, a + got)
        assert np.all(out_i[0][rows] == 3) and np.all(out_f[0][rows] == 0.06)
        for column, source in zip(out_f[1:], (x, y, *f), strict=True):
            np.testing.assert_array_equal(column[rows], source[idx])
        np.testing.assert_array_equal(out_i[1][rows], lane[idx])
        np.testing.assert_array_equal(out_b[rows], stalled[idx])
        np.testing.assert_array_equal(out_g[rows], agent[idx])
        assert np.all(np.isnan(out_f[1][:a])) and np.all(np.isnan(out_f[1][a + got:]))


def test_columns_trim_keeps_the_filled_rows() -> None:
    cols = _Columns({"a": np.int64}, 4)
    start = cols.reserve(5)
    cols.data["a"][start:start + 2] = [7, 8]
    cols.trim(start + 2)
    np.testing.assert_array_equal(cols.head("a"), [7, 8])
    with pytest.raises(ValueError):
        cols.trim(3)
