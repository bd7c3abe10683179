"""FrenetPath: curvature, continuity, projection round trips, kinks, extrapolation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from controllers.path.frenet import FrenetPath, path_gamma, path_point


def _arc(radius: float, angle: float, n: int) -> np.ndarray:
    th = np.linspace(0.0, angle, n)
    return np.column_stack([radius * np.sin(th), radius * (1.0 - np.cos(th))])


@pytest.fixture(scope="module")
def circle() -> FrenetPath:
    # Vertices every ~2.4 m, like a SUMO lane shape.
    return FrenetPath.from_polyline(_arc(400.0, 1.2, 200))


def test_circle_curvature_and_length(circle: FrenetPath) -> None:
    s = np.linspace(20.0, circle.length_m - 20.0, 200)
    assert circle.length_m == pytest.approx(480.0, abs=0.05)
    assert np.max(np.abs(circle.kappa(s) - 1.0 / 400.0)) < 1e-4
    assert np.max(np.abs(circle.dkappa(s))) < 1e-5
    # gamma grows like s / R and is continuous (unwrapped).
    g = circle.gamma(s)
    assert np.allclose(np.diff(g) / np.diff(s), 1.0 / 400.0, atol=1e-4)
    assert circle.max_deviation_m < 0.05


def test_derivatives_are_exact_derivatives_of_gamma(circle: FrenetPath) -> None:
    # kappa = d gamma/ds and kappa' = d kappa/ds everywhere, including across knots.
    s = np.linspace(-30.0, circle.length_m + 30.0, 997) + 0.123
    h = 1e-4
    fd_k = (circle.gamma(s + h) - circle.gamma(s - h)) / (2 * h)
    fd_dk = (circle.kappa(s + h) - circle.kappa(s - h)) / (2 * h)
    assert np.max(np.abs(fd_k - circle.kappa(s))) < 1e-8
    assert np.max(np.abs(fd_dk - circle.dkappa(s))) < 1e-7
    # C²: no jumps of gamma, kappa, kappa' at the knots (sampled either side).
    meta, coef, _ = circle.tables()
    knots = meta[0] + meta[1] * np.arange(5, int(meta[2]) - 5)
    for f in (circle.gamma, circle.kappa, circle.dkappa):
        assert np.max(np.abs(f(knots + 1e-9) - f(knots - 1e-9))) < 1e-8


def test_positions_consistent_with_heading(circle: FrenetPath) -> None:
    s = np.linspace(0.0, circle.length_m, 301)
    p = circle.point(s)
    h = 1e-3
    tangent = (circle.point(s + h) - circle.point(s - h)) / (2 * h)
    g = circle.gamma(s)
    assert np.allclose(tangent[:, 0], np.cos(g), atol=1e-6)
    assert np.allclose(tangent[:, 1], np.sin(g), atol=1e-6)
    # The points lie on the circle of radius 400 centred at (0, 400).
    r = np.hypot(p[:, 0], p[:, 1] - 400.0)
    assert np.max(np.abs(r[10:-10] - 400.0)) < 0.05


def test_numba_tables_match_python(circle: FrenetPath) -> None:
    meta, coef, knots = circle.tables()
    for s in (-100.0, -3.3, 0.0, 17.25, 250.0, circle.length_m + 5.0, 5000.0):
        g, k, dk = path_gamma(meta, coef, s)
        assert g == pytest.approx(float(circle.gamma(s)), abs=1e-12)
        assert k == pytest.approx(float(circle.kappa(s)), abs=1e-12)
        assert dk == pytest.approx(float(circle.dkappa(s)), abs=1e-12)
        x, y = path_point(meta, coef, knots, s)
        assert np.allclose([x, y], circle.point(s), atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(s=st.floats(0.0, 480.0), y=st.floats(-6.0, 6.0), hint_off=st.floats(-15.0, 15.0))
def test_project_round_trip(s: float, y: float, hint_off: float) -> None:
    path = FrenetPath.cached(_arc(400.0, 1.2, 200))
    gx, gy = path.to_global(s, y)
    s1, y1 = path.project(gx, gy, s + hint_off)
    assert float(s1) == pytest.approx(s, abs=1e-6)
    assert float(y1) == pytest.approx(y, abs=1e-6)
    s2, y2 = path.project(gx, gy)  # global search
    assert float(s2) == pytest.approx(s, abs=1e-6)
    assert float(y2) == pytest.approx(y, abs=1e-6)


def test_project_pose_heading_error(circle: FrenetPath) -> None:
    gx, gy = circle.to_global(100.0, -1.0)
    heading = float(circle.gamma(100.0)) + 0.05 + 2 * np.pi  # wrapped
    s, y, e = circle.project_pose(gx, gy, heading, 90.0)
    assert float(s) == pytest.approx(100.0, abs=1e-6)
    assert float(y) == pytest.approx(-1.0, abs=1e-6)
    assert float(e) == pytest.approx(0.05, abs=1e-9)


@settings(max_examples=200, deadline=None)
@given(s=st.floats(0.0, 480.0), y=st.floats(-6.0, 6.0), hint_off=st.floats(-80.0, 80.0),
       heading=st.floats(-7.0, 7.0))
def test_project_pose_of_one_pose_equals_the_general_path_bit_for_bit(
        s: float, y: float, hint_off: float, heading: float) -> None:
    """The scalar fast path (one pose with a hint: the run loop's ego) gives exactly the
    vectorised result, including hints Newton does not converge from (far ones)."""
    path = FrenetPath.cached(_arc(400.0, 1.2, 200))
    gx, gy = (float(v) for v in path.to_global(s, y))
    got = path.project_pose(gx, gy, heading, s + hint_off)
    s_ref, d_ref = path.project(np.array([gx]), np.array([gy]), np.array([s + hint_off]))
    e_ref = (heading - path.gamma(s_ref) + np.pi) % (2 * np.pi) - np.pi
    assert (float(got[0]), float(got[1]), float(got[2])) == \
        (float(s_ref[0]), float(d_ref[0]), float(e_ref[0]))


@settings(max_examples=100, deadline=None)
@given(frac=st.floats(0.0, 1.0), seed=st.integers(0, 2**31 - 1),
       shape=st.sampled_from([(400.0, 1.2), (60.0, 4.5)]))
def test_project_along_equals_hinted_projection_and_gamma_bit_for_bit(
        frac: float, seed: int, shape: tuple[float, float]) -> None:
    """The fused kernel (hints, projections, angles) gives exactly what projecting with
    the tangent hints and then evaluating gamma gives, points that need the global
    search included (on the 60 m hairpin ~15 % of them: the tangent hint is far off)."""
    radius, angle = shape
    path = FrenetPath.cached(_arc(radius, angle, 300))
    length = radius * angle
    s_ref = frac * length
    rng = np.random.default_rng(seed)
    s = s_ref + rng.uniform(-0.6 * length, 0.6 * length, 25)
    x, y = path.to_global(s, rng.uniform(-12.0, 12.0, 25))
    x_ref, y_ref = (float(v) for v in path.to_global(s_ref, 0.4))
    got_s, got_d, got_g = path.project_along(x, y, x_ref, y_ref, s_ref)
    g0 = float(path.gamma(s_ref))
    hints = s_ref + (x - x_ref) * np.cos(g0) + (y - y_ref) * np.sin(g0)
    want_s, want_d = path.project(x, y, s_hint=hints)
    assert np.array_equal(got_s, want_s) and np.array_equal(got_d, want_d)
    assert np.array_equal(got_g, path.gamma(want_s))


def test_kinked_polyline_bounded_and_close() -> None:
    # A 3 degree kink at s = 200 m (SUMO junction-like); y positive left.
    ang = np.radians(3.0)
    xy = np.array([[0.0, 0.0], [200.0, 0.0], [200.0 + 300 * np.cos(ang), 300 * np.sin(ang)]])
    path = FrenetPath.from_polyline(xy)
    s = np.linspace(-60.0, path.length_m + 300.0, 8000)
    k = path.kappa(s)
    # Peak curvature alpha / (sqrt(2 pi) sigma) with sigma = 4 m.
    assert np.max(np.abs(k)) < 1.2 * ang / (np.sqrt(2 * np.pi) * 4.0)
    assert np.all(np.isfinite(k))
    # Stated tolerance: about 0.4 alpha sigma; the whole input polyline is within it.
    assert path.max_deviation_m < 0.5 * ang * 4.0 + 0.01
    sq = np.linspace(0.0, path.length_m, 2000)
    ref = np.column_stack([np.interp(sq, [0, 200, 500], xy[:, 0]),
                           np.interp(sq, [0, 200, 500], xy[:, 1])])
    _, d = path.project(ref[:, 0], ref[:, 1])
    assert np.max(np.abs(d)) < 0.5 * ang * 4.0 + 0.01


def test_straight_extrapolation_beyond_ends() -> None:
    path = FrenetPath.from_polyline(_arc(300.0, 0.5, 60))
    end = path.length_m
    far = np.array([end + 400.0, end + 1000.0])
    assert np.allclose(path.kappa(far), 0.0)
    assert np.allclose(path.gamma(far), path.gamma(end + 400.0))
    p = path.point(far)
    step = p[1] - p[0]
    g = float(path.gamma(end + 400.0))
    assert np.allclose(step / 600.0, [np.cos(g), np.sin(g)], atol=1e-9)
    behind = path.point(np.array([-500.0, -200.0]))
    g0 = float(path.gamma(-500.0))
    assert np.allclose((behind[1] - behind[0]) / 300.0, [np.cos(g0), np.sin(g0)], atol=1e-9)
    # s = 0 is the first input vertex.
    assert np.allclose(path.point(0.0), [0.0, 0.0], atol=1e-9)


def test_cached_reuses_and_rejects_bad_input() -> None:
    xy = _arc(500.0, 0.3, 50)
    a = FrenetPath.cached(xy)
    b = FrenetPath.cached(xy.copy())
    assert a is b
    assert FrenetPath.cached(xy + 1.0) is not a
    with pytest.raises(ValueError):
        FrenetPath.from_polyline(np.zeros((1, 2)))
    with pytest.raises(ValueError):
        FrenetPath.from_polyline(np.array([[0.0, 0.0], [np.nan, 1.0]]))


def test_compiled_kappa_equals_the_array_form_bit_for_bit() -> None:
    """FrenetPath.kappa (one compiled pass) returns what the numpy form _gk does, beyond
    the tables, at knots, NaN and inf included."""
    rng = np.random.default_rng(11)
    t = np.linspace(0.0, 3.0, 400)
    pts = np.column_stack([300.0 * np.sin(t), 300.0 * (1.0 - np.cos(t)) + 5.0 * np.sin(7 * t)])
    path = FrenetPath.from_polyline(pts)
    meta = path.tables()[0]
    knots = meta[0] + meta[1] * np.arange(int(meta[2]) + 1)
    s = np.concatenate([rng.uniform(-50.0, path.length_m + 50.0, 20000), knots,
                        [np.nan, np.inf, -np.inf, 1e300, -1e300]])
    with np.errstate(invalid="ignore"):  # NaN and inf through numpy's casts
        want = path._gk(s)[1]
    got = path.kappa(s)
    assert got.shape == s.shape
    np.testing.assert_array_equal(got, want)
    assert float(path.kappa(100.0)) == float(path._gk(100.0)[1])
