"""controllers.behaviour.obstacle_choice._select_obstacles, the compiled choice of the vehicles
that get an ellipse, equals the numpy/Python form it replaced (relevance masks, then
leads first and by distance, stable), on random scenes with ties and NaNs."""

from __future__ import annotations

import numpy as np
import pytest

from controllers.behaviour.obstacle_choice import _select_obstacles


def _old_form(ds: np.ndarray, y: np.ndarray, lat: float, rel_lane: np.ndarray,
              lanes: set[int], leads: set[int], home: int, stalled: np.ndarray,
              moving: bool, detection: float, rear: float, max_obstacles: int) -> list[int]:
    dist = np.hypot(ds, y - lat)
    in_lanes = np.zeros(ds.size, dtype=bool)
    for r in lanes:
        in_lanes |= rel_lane == r
    in_lanes[list(leads)] = True
    relevant = (dist <= detection) & (ds >= -rear) & in_lanes
    relevant &= ~((rel_lane == home) & (ds < 0.0))
    if not moving:
        relevant &= stalled
    idx = np.flatnonzero(relevant)
    key = [(0 if i in leads else 1, float(dist[i])) for i in idx]
    order = [int(idx[k]) for k in sorted(range(len(idx)), key=key.__getitem__)]
    return order[:max_obstacles]


@pytest.mark.parametrize("seed", range(60))
def test_equals_the_old_form(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(0, 40))
    rel_lane = rng.integers(-2, 3, n)
    ds = np.round(rng.uniform(-120.0, 160.0, n), 0)  # rounded: equal distances happen
    y = rel_lane * 3.5 + np.round(rng.normal(0.0, 0.5, n), 1)
    if n > 2:
        ds[rng.integers(0, n)] = np.nan
        y[rng.integers(0, n)] = np.nan
    stalled = rng.random(n) < 0.3
    lanes = {int(v) for v in rng.integers(-1, 2, 2)}
    leads = {int(v) for v in rng.integers(0, n, 3)} if n else set()
    for moving in (True, False):
        for max_obstacles in (0, 3, 40):
            args = (ds, y, 0.2, rel_lane)
            rest = (int(rng.integers(-1, 2)), stalled, moving, 100.0, 30.0, max_obstacles)
            got = _select_obstacles(*args, np.array(sorted(lanes), dtype=np.int64),
                                    np.array(sorted(leads), dtype=np.int64), *rest)
            assert got.dtype == np.intp
            assert got.tolist() == _old_form(*args, lanes, leads, *rest)
