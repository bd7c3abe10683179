"""The checks a recording needs: its time step, and which obstacles are on the ego's road.

**Time step.** For each pair of consecutive samples of one obstacle, k time steps apart,
with displacement d [m] and mean speed v = (v_a + v_b) / 2 >= :data:`MIN_SPEED_MPS`, the
step the samples imply is dt_i = d / (v k). The estimate is the median over every pair of
every obstacle (robust to a few bad samples); it is compared with the header's dt. If it
differs by more than ``tolerance`` (20 %), the step is corrected to the header dt times
the plausible multiple (:data:`PLAUSIBLE_MULTIPLES`) nearest to the ratio (in log scale),
when that multiple explains the estimate within ``tolerance``; otherwise the header is
kept and the disagreement noted. Fewer than :data:`MIN_PAIRS` pairs: not checked.

**On the road.** A vehicle's first sample is on the ego's road when it is within half a
lane width of the centre line of some lane of the net (lanelet centre lines and the
extension lanes) and heads within 90 deg of that lane; heading against the nearest lane
is "opposite carriageway", being beyond every lane is "off the ego's road".
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from suite.importers.commonroad.geometry import angle_diff_rad, project
from suite.importers.commonroad.records import FloatArray, ObstacleRecord

__all__ = ["MIN_PAIRS", "MIN_SPEED_MPS", "PLAUSIBLE_MULTIPLES", "LaneShape", "Placement",
           "StepCheck", "StepParams", "check_step", "place_point"]

MIN_SPEED_MPS = 1.0
"""Sample pairs slower than this [m/s] say nothing about the step (noise dominates)."""

MIN_PAIRS = 5
PLAUSIBLE_MULTIPLES = (0.1, 0.2, 0.25, 0.5, 2.0, 2.5, 4.0, 5.0, 10.0)
"""Multiples of the header dt a mislabelled file may really have (0.1 s vs 0.2, 0.04 s
vs 0.1, ...)."""


@dataclass(frozen=True)
class StepParams:
    """``tolerance``: relative disagreement of the estimated and header step above which
    the step is corrected (0.2 = 20 %)."""

    tolerance: float = 0.2

    def __post_init__(self) -> None:
        if not (math.isfinite(self.tolerance) and 0.0 < self.tolerance < 1.0):
            raise ValueError(f"tolerance: expected in (0, 1), got {self.tolerance!r}")


@dataclass(frozen=True)
class StepCheck:
    """Header step, estimated step (NaN: not checked), step used [s], the number of
    sample pairs, whether it was corrected and the note to record."""

    header_dt_s: float
    estimated_dt_s: float
    dt_s: float
    pairs: int
    corrected: bool
    note: str


def check_step(obstacles: Sequence[ObstacleRecord], header_dt_s: float,
               params: StepParams) -> StepCheck:
    """The time-step check of the module docstring."""
    ratios: list[float] = []
    for ob in obstacles:
        if ob.static or ob.steps.shape[0] < 2:
            continue
        k = np.diff(ob.steps).astype(np.float64)
        d = np.hypot(np.diff(ob.x_m), np.diff(ob.y_m))
        v = 0.5 * (ob.speed_mps[1:] + ob.speed_mps[:-1])
        ok = np.isfinite(v) & (v >= MIN_SPEED_MPS) & (k > 0)
        ratios.extend((d[ok] / (v[ok] * k[ok])).tolist())
    if len(ratios) < MIN_PAIRS:
        return StepCheck(header_dt_s, math.nan, header_dt_s, len(ratios), False,
                         f"time step not checked: only {len(ratios)} moving sample pairs; "
                         f"header dt = {header_dt_s:g} s kept")
    est = float(np.median(ratios))
    ratio = est / header_dt_s
    if abs(ratio - 1.0) <= params.tolerance:
        return StepCheck(header_dt_s, est, header_dt_s, len(ratios), False,
                         f"time step checked: header dt = {header_dt_s:g} s, displacement/"
                         f"speed gives {est:.4f} s over {len(ratios)} sample pairs")
    best = min(PLAUSIBLE_MULTIPLES, key=lambda m: abs(math.log(ratio / m)))
    if abs(ratio / best - 1.0) <= params.tolerance:
        dt = header_dt_s * best
        return StepCheck(header_dt_s, est, dt, len(ratios), True,
                         f"WARNING time step corrected: header dt = {header_dt_s:g} s but "
                         f"displacement/speed gives {est:.4f} s (median of {len(ratios)} "
                         f"sample pairs): dt = {dt:g} s used")
    return StepCheck(header_dt_s, est, header_dt_s, len(ratios), False,
                     f"WARNING time step doubtful: header dt = {header_dt_s:g} s, displacement/"
                     f"speed gives {est:.4f} s, no plausible multiple: header kept")


@dataclass(frozen=True, eq=False)
class LaneShape:
    """A lane's centre line (n, 2) [m] and width [m], on edge ``edge_id`` lane ``index``."""

    edge_id: str
    index: int
    xy_m: FloatArray
    width_m: float


@dataclass(frozen=True)
class Placement:
    """Where a point is: ``status`` ``"on_road"``, ``"opposite"`` or ``"off_road"``, the
    nearest same-direction lane (``None`` if none) and the arc length on it [m]."""

    status: str
    lane: LaneShape | None
    s_m: float
    lateral_m: float


def place_point(lanes: Sequence[LaneShape], x_m: float, y_m: float,
                heading_rad: float) -> Placement:
    """Classify a point with a heading against the lanes (module docstring)."""
    best: tuple[float, LaneShape, float, float] | None = None
    nearest_any: tuple[float, float] | None = None  # (distance, heading difference)
    for lane in lanes:
        pr = project(lane.xy_m, x_m, y_m)
        diff = angle_diff_rad(pr.heading_rad, heading_rad)
        if nearest_any is None or pr.distance_m < nearest_any[0]:
            nearest_any = (pr.distance_m, diff)
        if diff > 0.5 * math.pi:
            continue
        excess = pr.distance_m - 0.5 * lane.width_m
        if best is None or excess < best[0]:
            best = (excess, lane, pr.s_m, pr.lateral_m)
    if best is not None and best[0] <= 0.0:
        return Placement("on_road", best[1], best[2], best[3])
    if nearest_any is not None and nearest_any[1] > 0.5 * math.pi:
        return Placement("opposite", None, math.nan, math.nan)
    return Placement("off_road", None, math.nan, math.nan)
