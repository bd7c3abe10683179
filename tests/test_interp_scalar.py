"""interp_scalar returns numpy.interp's double bit for bit (suite/road/interp.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from suite.road.interp import interp_scalar


def _same(a: float, b: float) -> bool:
    return (math.isnan(a) and math.isnan(b)) or a == b and math.copysign(1, a) == \
        math.copysign(1, b)


@pytest.mark.parametrize("seed", range(6))
def test_equals_numpy_interp_on_random_profiles(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for _ in range(300):
        n = int(rng.integers(1, 40))
        xs = np.sort(rng.normal(0.0, 100.0, n))
        if n > 3 and rng.random() < 0.3:  # ties, as sorted projections can have
            xs[1] = xs[2]
        ys = rng.normal(0.0, 5.0, n)
        if n > 2 and rng.random() < 0.2:  # inf in the values: numpy's NaN fallbacks
            ys[int(rng.integers(0, n))] = np.inf
        left, right = float(rng.normal()), float(rng.normal())
        probes = np.concatenate([rng.uniform(xs[0] - 20, xs[-1] + 20, 30), xs,
                                 [np.nextafter(xs[0], -np.inf), np.nextafter(xs[-1], np.inf)]])
        xl, yl = xs.tolist(), ys.tolist()
        for x in probes.tolist():
            want = float(np.interp(x, xs, ys, left=left, right=right))
            got = interp_scalar(x, xl, yl, left, right)
            assert _same(got, want), (x, got, want)


def test_edges_and_nan() -> None:
    xs, ys = [0.0, 10.0, 20.0], [1.0, 3.0, -1.0]
    assert interp_scalar(-1.0, xs, ys, -7.0, 9.0) == -7.0
    assert interp_scalar(21.0, xs, ys, -7.0, 9.0) == 9.0
    assert interp_scalar(20.0, xs, ys, -7.0, 9.0) == -1.0
    assert interp_scalar(5.0, xs, ys, 0.0, 0.0) == 2.0
    assert math.isnan(interp_scalar(math.nan, xs, ys, 0.0, 0.0))
    with pytest.raises(ValueError):
        interp_scalar(1.0, [], [], 0.0, 0.0)
