"""suite.rerun.stream.strip_array: line strips built as one arrow array equal Rerun's own
strip-by-strip conversion (the values the .rrd then holds)."""

from __future__ import annotations

import numpy as np
import pytest
import rerun as rr

from suite.rerun.stream import strip_array


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
