"""The compiled box geometry (reports.geometry) against its numpy references and
known answers: distance, overlap, swept TTC, one box against many, the nearest box."""

from __future__ import annotations

import math

import geometry_reference as gref
import numpy as np
import pytest

from reports import geometry as g


def _random_boxes(rng: np.random.Generator, n: int, spread_m: float = 8.0) -> np.ndarray:
    return g.box_corners(rng.uniform(-spread_m, spread_m, n), rng.uniform(-4.0, 4.0, n),
                         rng.uniform(-math.pi, math.pi, n), rng.uniform(0.5, 12.0, n),
                         rng.uniform(0.5, 3.0, n))


def test_distance_and_overlap_equal_the_numpy_reference_on_random_boxes() -> None:
    rng = np.random.default_rng(1)
    a, b = _random_boxes(rng, 4000), _random_boxes(rng, 4000)
    a[:4, 1, 0] = np.nan  # numpy's NaN semantics kept: such a box counts as overlapping
    b[4:6, 3, 1] = np.nan
    dist, ref = g.box_distance(a, b), gref.box_distance_reference(a, b)
    np.testing.assert_allclose(dist, ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(g.boxes_overlap(a, b), gref.boxes_overlap_reference(a, b))
    overlapping = g.boxes_overlap(a, b)
    assert 0.1 < overlapping.mean() < 0.9  # both cases are exercised
    assert np.all(dist[overlapping] == 0.0) and np.all(dist[~overlapping] > 0.0)


def test_broadcasting_matches_the_reference() -> None:
    rng = np.random.default_rng(2)
    one, many = _random_boxes(rng, 1)[0], _random_boxes(rng, 50).reshape(5, 10, 4, 2)
    assert g.box_distance(one, many).shape == (5, 10)
    np.testing.assert_allclose(g.box_distance(one, many), gref.box_distance_reference(one, many),
                               rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(g.boxes_overlap(many, one),
                                  gref.boxes_overlap_reference(many, one))
    assert g.box_distance(one, one).shape == ()
    with pytest.raises(ValueError, match="4, 2"):
        g.box_distance(np.zeros((3, 2)), np.zeros((3, 2)))


def test_known_distances() -> None:
    unit = g.box_corners(0.0, 0.0, 0.0, 2.0, 2.0)
    # side by side 1 m apart, corner to corner sqrt(2) m apart, overlapping, touching
    assert float(g.box_distance(unit, g.box_corners(3.0, 0.0, 0.0, 2.0, 2.0))) == \
        pytest.approx(1.0)
    assert float(g.box_distance(unit, g.box_corners(3.0, 3.0, 0.0, 2.0, 2.0))) == \
        pytest.approx(math.sqrt(2.0))
    assert bool(g.boxes_overlap(unit, g.box_corners(1.5, 0.5, 0.3, 2.0, 2.0)))
    assert bool(g.boxes_overlap(unit, g.box_corners(2.0, 0.0, 0.0, 2.0, 2.0)))
    # a diamond whose corner points at the square's side 0.5 m away
    diamond = g.box_corners(1.5 + math.sqrt(2.0), 0.0, math.pi / 4, 2.0, 2.0)
    assert float(g.box_distance(unit, diamond)) == pytest.approx(0.5)


def test_swept_ttc_equals_the_reference_and_known_answers() -> None:
    rng = np.random.default_rng(3)
    a, b = _random_boxes(rng, 3000, 30.0), _random_boxes(rng, 3000, 30.0)
    va, vb = rng.normal(0.0, 10.0, (3000, 2)), rng.normal(0.0, 10.0, (3000, 2))
    va[:3] = 0.0
    vb[:3] = 0.0  # relative motion zero: 'still' on every axis
    va[3] = np.nan
    ttc = g.swept_box_ttc(a, va, b, vb, 10.0)
    ref = gref.swept_box_ttc_reference(a, va, b, vb, 10.0)
    np.testing.assert_allclose(ttc, ref, rtol=1e-12, atol=1e-12)
    assert 0.1 < np.isfinite(ttc).mean() < 0.9
    # 10 m nose to tail, closing at 5 m/s: touch after 2 s; receding: never
    ego = g.box_corners(0.0, 0.0, 0.0, 4.0, 2.0)
    lead = g.box_corners(14.0, 0.0, 0.0, 4.0, 2.0)
    assert float(g.swept_box_ttc(ego, np.array([25.0, 0.0]), lead, np.array([20.0, 0.0]),
                                 10.0)) == pytest.approx(2.0)
    assert math.isinf(float(g.swept_box_ttc(ego, np.array([20.0, 0.0]), lead,
                                            np.array([25.0, 0.0]), 10.0)))
    assert math.isinf(float(g.swept_box_ttc(ego, np.array([1.0, 0.0]), lead, np.zeros(2),
                                            5.0)))  # 10 s away, beyond the horizon


def _scene(rng: np.random.Generator, n: int) -> tuple[np.ndarray, ...]:
    return (rng.uniform(-40.0, 40.0, n), rng.uniform(-7.0, 7.0, n), rng.normal(0.0, 0.3, n),
            rng.uniform(1.0, 12.0, n), rng.uniform(1.0, 3.0, n))


def test_one_box_against_many_and_the_nearest_box() -> None:
    rng = np.random.default_rng(4)
    ego = (1.0, 0.5, 0.05, 4.8, 1.9)
    hits = 0
    for _ in range(1500):
        xs, ys, hs, ls, ws = _scene(rng, int(rng.integers(1, 70)))
        gap, overlap = g.box_gaps(*ego, xs, ys, hs, ls, ws)
        ref = gref.box_distance_reference(g.box_corners(*ego)[None],
                                       g.box_corners(xs, ys, hs, ls, ws))
        np.testing.assert_allclose(gap, ref, rtol=1e-12, atol=1e-12)
        np.testing.assert_array_equal(overlap, gap == 0.0)
        i, d, any_overlap = g.nearest_box(*ego, xs, ys, hs, ls, ws)
        assert i == int(np.argmin(gap)) and d == gap[i] and any_overlap == bool(overlap.any())
        hits += any_overlap
    assert hits > 50  # overlaps occur among the random scenes
    empty = np.zeros(0)
    assert g.nearest_box(*ego, empty, empty, empty, empty, empty) == (-1, math.inf, False)


def test_nearest_box_takes_the_first_of_equal_distances() -> None:
    xs = np.array([10.0, -10.0, 10.0])
    zeros = np.zeros(3)
    i, d, ov = g.nearest_box(0.0, 0.0, 0.0, 4.0, 2.0, xs, zeros, zeros, np.full(3, 4.0),
                             np.full(3, 2.0))
    assert i == 0 and d == pytest.approx(6.0) and not ov
