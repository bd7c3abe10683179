"""One scalar linear interpolation on Python lists, with numpy.interp's numbers.

``np.interp`` on a single float costs a few microseconds of argument conversion; the lane
context asks for a handful of them every control step. :func:`interp_scalar` does the
same arithmetic on a ``bisect`` of a Python list, in the same order, so that it returns
the same double bit for bit (tests/test_interp_scalar.py checks it against np.interp):

* ``x < xs[0]``: ``left``; ``x > xs[-1]``: ``right``; ``x == xs[-1]``: ``ys[-1]``;
* else j is the last index with ``xs[j] <= x`` (``bisect_right - 1``, the one numpy's
  search finds, ties included); ``xs[j] == x`` gives ``ys[j]``;
* else ``slope (x - xs[j]) + ys[j]`` with ``slope = (ys[j+1] - ys[j]) / (xs[j+1] - xs[j])``,
  and when that is NaN ``slope (x - xs[j+1]) + ys[j+1]``, then ``ys[j]`` if still NaN and
  ``ys[j] == ys[j+1]``.

``xs`` must be ascending (as for np.interp); NaN ``x`` gives NaN.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from collections.abc import Sequence


def interp_scalar(x: float, xs: Sequence[float], ys: Sequence[float], left: float,
                  right: float) -> float:
    """numpy.interp(x, xs, ys, left, right) for one float ``x`` (module docstring)."""
    n = len(xs)
    if n == 0:
        raise ValueError("interp_scalar needs at least one sample")
    if x != x:  # NaN
        return math.nan
    last = xs[n - 1]
    if x > last:
        return right
    if x < xs[0]:
        return left
    if x == last:
        return ys[n - 1]
    j = bisect_right(xs, x) - 1
    if xs[j] == x:
        return ys[j]
    y0 = ys[j]
    y1 = ys[j + 1]
    slope = (y1 - y0) / (xs[j + 1] - xs[j])
    out = slope * (x - xs[j]) + y0
    if out != out:
        out = slope * (x - xs[j + 1]) + y1
        if out != out and y0 == y1:
            out = y0
    return out
