"""controllers.behaviour.perception._nearest_in_lane, the compiled lead/follower search,
equals the numpy form it replaced (relative lane | intruding | merging, then the nearest
ahead or behind, the first of equals), on random scenes with ties, NaNs and unknown
lanes; and known answers."""

from __future__ import annotations

import numpy as np
import pytest

from controllers.behaviour.perception import CUT_IN_MAX_LATERAL_MPS, INTRUSION_M, _nearest_in_lane

MAX_VY = CUT_IN_MAX_LATERAL_MPS


def _numpy_form(rel_lane: np.ndarray, y: np.ndarray, v_y: np.ndarray, width: np.ndarray,
                ds: np.ndarray, merging: np.ndarray, rel: int, known: bool, centre: float,
                lane_width: float, horizon: float, ahead: bool) -> int:
    if known:
        reach = 0.5 * (lane_width + width) - INTRUSION_M
        y_now = y - centre
        y_then = y_now + np.clip(v_y, -MAX_VY, MAX_VY) * horizon
        lo, hi = np.minimum(y_now, y_then), np.maximum(y_now, y_then)
        intruding = (hi > -reach) & (lo < reach)
    else:
        intruding = np.zeros(rel_lane.size, dtype=bool)
    in_lane = (rel_lane == rel) | intruding | merging
    mask = in_lane & (ds > 0.0) if ahead else in_lane & (ds <= 0.0)
    if not np.any(mask):
        return -1
    idx = np.flatnonzero(mask)
    return int(idx[np.argmin(ds[idx])] if ahead else idx[np.argmax(ds[idx])])


@pytest.mark.parametrize("seed", range(40))
def test_equals_the_numpy_form(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(0, 30))
    rel_lane = rng.integers(-2, 3, n)
    y = rel_lane * 3.5 + rng.normal(0.0, 1.0, n)
    v_y = rng.normal(0.0, 2.5, n)  # some beyond the clip
    width = rng.uniform(1.6, 2.6, n)
    ds = np.round(rng.uniform(-80.0, 80.0, n), 0)  # rounded: ties happen
    if n:
        y[rng.integers(0, n)] = np.nan
        ds[rng.integers(0, n)] = np.nan
    merging = rng.random(n) < 0.1
    for rel in (-1, 0, 1):
        for known in (True, False):
            for ahead in (True, False):
                horizon = 1.0 if ahead else 0.0
                args = (rel_lane, y, v_y, width, ds, merging if ahead else np.zeros(n, bool),
                        rel, known, rel * 3.5, 3.5, horizon)
                assert _nearest_in_lane(*args, INTRUSION_M, ahead, MAX_VY) == \
                    _numpy_form(*args, ahead)


def test_known_answers() -> None:
    rel_lane = np.array([0, 0, 1, 1])
    y = np.array([0.0, 0.1, 3.5, 2.2])  # the last straddles the line into lane 0
    ds = np.array([40.0, -20.0, 10.0, 25.0])
    zeros, none = np.zeros(4), np.zeros(4, dtype=bool)
    width = np.full(4, 1.9)
    common = (rel_lane, y, zeros, width, ds, none, 0, True, 0.0, 3.5)
    assert _nearest_in_lane(*common, 0.0, INTRUSION_M, True, MAX_VY) == 3  # the straddler
    assert _nearest_in_lane(*common, 0.0, INTRUSION_M, False, MAX_VY) == 1
    unknown = (rel_lane, y, zeros, width, ds, none, 0, False, 0.0, 3.5)
    assert _nearest_in_lane(*unknown, 0.0, INTRUSION_M, True, MAX_VY) == 0  # lane index only
    assert _nearest_in_lane(rel_lane, y, zeros, width, ds, none, 5, True, 17.5, 3.5, 0.0,
                            INTRUSION_M, True, MAX_VY) == -1


def test_a_steep_heading_two_lanes_away_is_no_cut_in() -> None:
    """A car two lanes right (y = -7 m) heading 25 deg at 21 m/s (v_y = 8.9 m/s: an
    on-ramp's junction lane) would reach the ego's lane within the 1 s horizon at its
    own lateral speed, not at the fastest lane change's (3 m/s)."""
    one = np.ones(1)
    args = (np.array([-2]), np.array([-7.0]), np.array([8.9]), 1.9 * one, np.array([20.0]),
            np.zeros(1, dtype=bool), 0, True, 0.0, 3.5, 1.0, INTRUSION_M, True)
    assert _nearest_in_lane(*args, 100.0) == 0
    assert _nearest_in_lane(*args, MAX_VY) == -1
    # one lane away, the clipped motion still reaches the lane: a cut-in
    near = (np.array([-1]), np.array([-3.5]), np.array([8.9]), *args[3:])
    assert _nearest_in_lane(*near, MAX_VY) == 0
