"""suite.rerun.stream.strip_array: line strips built as one arrow array equal Rerun's own
strip-by-strip conversion (the values the .rrd then holds); the vectorised per-step
polylines and preview errors of suite.rerun.world equal the step-by-step loops they
replaced."""

from __future__ import annotations

import numpy as np
import pytest
import rerun as rr

from suite.rerun.stream import FlatStrips, strip_array
from suite.rerun.world import _polyline_per_step, _recorded_preview_error


def _rerun_own(strips: list[np.ndarray]) -> list[object]:
    return rr.components.LineStrip2DBatch(strips).as_arrow_array().to_pylist()


@pytest.mark.parametrize("sizes", [[], [2], [3, 2, 7], [5] * 40])
def test_equal_to_reruns_conversion(sizes: list[int]) -> None:
    rng = np.random.default_rng(len(sizes))
    strips = [rng.normal(size=(n, 2)) * 100.0 for n in sizes]
    ours = strip_array(strips)
    assert ours.type == rr.components.LineStrip2DBatch._ARROW_DATATYPE
    assert ours.to_pylist() == _rerun_own(strips)
    # and Rerun takes it as it is
    assert rr.components.LineStrip2DBatch(ours).as_arrow_array().to_pylist() == ours.to_pylist()


def test_anything_else_is_passed_through() -> None:
    odd = [np.zeros((3, 3))]
    assert strip_array(odd) is odd
    arr = np.zeros((4, 2, 2))
    assert strip_array(arr) is arr


def test_flat_strips_give_the_same_array_as_the_list() -> None:
    rng = np.random.default_rng(3)
    strips = [rng.normal(size=(n, 2)) for n in (2, 5, 3)]
    flat = FlatStrips(np.concatenate(strips), np.array([2, 5, 3]))
    assert strip_array(flat).to_pylist() == strip_array(strips).to_pylist()
    assert strip_array(FlatStrips(np.zeros((0, 2)), np.zeros(0, np.int64))).to_pylist() == []


class _Log:
    """What the per-step helpers read of a RunLog: the number of trace rows."""

    def __init__(self, n: int) -> None:
        self.n = n


def _ragged(rng: np.random.Generator, steps: int, points: int) -> np.ndarray:
    """(steps, points, 2) with NaN points anywhere (rows with 0, 1 or many valid)."""
    arr = rng.normal(size=(steps, points, 2)) * 50.0
    arr[rng.random((steps, points)) < 0.4] = np.nan
    arr[0] = np.nan
    arr[1, 1:] = np.nan
    return arr


def test_per_step_polylines_equal_the_step_by_step_loop() -> None:
    arr = _ragged(np.random.default_rng(5), 60, 7)
    strips, lengths, last = _polyline_per_step(_Log(60), arr)  # type: ignore[arg-type]
    want_strips, want_last = [], np.full((60, 2), np.nan)
    for i in range(60):
        pts = arr[i][np.all(np.isfinite(arr[i]), axis=1)]
        if len(pts) >= 2:
            want_strips.append(pts)
        if len(pts):
            want_last[i] = pts[-1]
    assert lengths.tolist() == [int(np.isfinite(arr[i, :, 0]).sum() >= 2) for i in range(60)]
    assert strip_array(strips).to_pylist() == strip_array(want_strips).to_pylist()
    np.testing.assert_array_equal(last, want_last)


def test_preview_error_vectors_equal_the_step_by_step_loop() -> None:
    rng = np.random.default_rng(6)
    prev = _ragged(rng, 60, 7)
    along, normal = rng.normal(size=60), rng.normal(size=60)
    got = _recorded_preview_error(_Log(60), prev, along, normal)  # type: ignore[arg-type]
    want = np.full((60, 2), np.nan)
    for i in range(60):
        pts = prev[i][np.all(np.isfinite(prev[i]), axis=1)]
        if len(pts) < 2:
            continue
        d = pts[-1] - pts[-2]
        d = d / max(float(np.hypot(*d)), 1e-9)
        want[i] = along[i] * d + normal[i] * np.array([-d[1], d[0]])
    np.testing.assert_array_equal(got, want)  # bit for bit
