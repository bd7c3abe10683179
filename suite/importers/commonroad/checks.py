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

**Glitches of the recording.** A kept vehicle whose box overlaps the ego's at run time
0 (the ego as the run places it: its centre, heading and box) is an error naming the
obstacle (:func:`refuse_overlap_at_start`): the run would start in a collision that is
the recording's. A vehicle that *jumps* between two consecutive samples, its
displacement differing from what its speeds and headings allow by more than
:data:`reports.metrics.collisions.JUMP_EXCESS_MPS` times the interval
(:func:`reports.geometry.motion.jump_excess_mps`), is a warning naming it, the time
and the jump (:func:`find_jumps`); at run time a contact during or just after such a
jump is the recording's (``replayed_into_ego``), by the same test on the replayed
poses.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from reports.geometry import box_corners, boxes_overlap, jump_excess_mps
from reports.metrics.collisions import JUMP_EXCESS_MPS
from suite.catalog.tracks import TRACK_ID_PREFIX, Track
from suite.importers.commonroad.errors import ImportFailure
from suite.importers.commonroad.geometry import angle_diff_rad, project
from suite.importers.commonroad.records import FloatArray, ObstacleRecord

__all__ = ["MAX_JUMP_NOTES", "MIN_PAIRS", "MIN_SPEED_MPS", "PLAUSIBLE_MULTIPLES", "EgoBox",
           "LaneShape", "Placement", "StepCheck", "StepParams", "TrackJump", "check_step",
           "find_jumps", "jump_notes", "place_point", "refuse_overlap_at_start"]

MAX_JUMP_NOTES = 20
"""Jumps listed one by one in the notes; the count covers every one."""

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


# ------------------------------------------------------------------ glitches


@dataclass(frozen=True)
class EgoBox:
    """The ego's box at run time 0: centre ``x_m``/``y_m`` [m, net], ``heading_rad``
    [rad], ``length_m`` x ``width_m`` [m]."""

    x_m: float
    y_m: float
    heading_rad: float
    length_m: float
    width_m: float

    def __post_init__(self) -> None:
        if not all(math.isfinite(v) for v in (self.x_m, self.y_m, self.heading_rad)):
            raise ValueError(f"EgoBox: expected a finite pose, got ({self.x_m}, {self.y_m}, "
                             f"{self.heading_rad})")
        if not (self.length_m > 0.0 and self.width_m > 0.0):
            raise ValueError(f"EgoBox: length_m/width_m: expected > 0, got "
                             f"{self.length_m}/{self.width_m}")


def _obstacle(track_id: str) -> str:
    """``obstacle <id>`` for track ``rec_<id>`` (the element an error names)."""
    return f"obstacle {track_id.removeprefix(TRACK_ID_PREFIX)}"


def refuse_overlap_at_start(path: str, tracks: Sequence[Track], ego: EgoBox) -> None:
    """:class:`ImportFailure` naming the first track whose box at run time 0 overlaps
    the ego's (tracks not present at 0 are not on the road then)."""
    ego_box = box_corners(ego.x_m, ego.y_m, ego.heading_rad, ego.length_m, ego.width_m)
    for track in tracks:
        pose = track.pose_at(0.0)
        if pose is None:
            continue
        box = box_corners(pose.x_m, pose.y_m, pose.heading_rad, track.length_m,
                          track.width_m)
        if bool(boxes_overlap(ego_box, box)):
            raise ImportFailure(path, _obstacle(track.track_id), (
                f"recorded vehicle {track.track_id} overlaps the ego's box at t = 0 (its "
                f"centre {math.hypot(pose.x_m - ego.x_m, pose.y_m - ego.y_m):.2f} m from "
                "the ego's): the run would start in the recording's collision"))


@dataclass(frozen=True)
class TrackJump:
    """A jump of a recorded vehicle between the samples at run times ``t_s`` and
    ``t_s + dt_s`` [s]: ``jump_m`` [m], how far its displacement lies from what its
    speeds and headings allow (``excess_mps`` [m/s] = jump_m / dt_s)."""

    track_id: str
    t_s: float
    dt_s: float
    jump_m: float

    def __post_init__(self) -> None:
        if not self.track_id:
            raise ValueError("TrackJump.track_id must not be empty")
        if not (self.dt_s > 0.0 and self.jump_m >= 0.0 and math.isfinite(self.t_s)):
            raise ValueError(f"TrackJump {self.track_id}: expected dt_s > 0, jump_m >= 0 and "
                             f"a finite t_s, got {self.dt_s}, {self.jump_m}, {self.t_s}")

    @property
    def excess_mps(self) -> float:
        return self.jump_m / self.dt_s


def find_jumps(tracks: Sequence[Track]) -> tuple[TrackJump, ...]:
    """Every jump (module docstring) of every track, in track then time order."""
    out: list[TrackJump] = []
    for track in tracks:
        if track.time_s.shape[0] < 2:
            continue
        excess = jump_excess_mps(track.time_s, track.x_m, track.y_m, track.heading_rad,
                                 track.speed_mps)
        dt = np.diff(track.time_s)
        for i in np.flatnonzero(excess > JUMP_EXCESS_MPS):
            out.append(TrackJump(track.track_id, float(track.time_s[i]), float(dt[i]),
                                 float(excess[i] * dt[i])))
    return tuple(out)


def jump_notes(jumps: Sequence[TrackJump]) -> list[str]:
    """One warning per jump (the first :data:`MAX_JUMP_NOTES`) and the count."""
    if not jumps:
        return []
    ids = sorted({j.track_id for j in jumps})
    lines = [f"WARNING {len(jumps)} jumps in the recording ({len(ids)} vehicles: "
             f"{', '.join(ids[:MAX_JUMP_NOTES])}): a contact during or within 0.5 s after "
             "one is the recording's (replayed_into_ego)"]
    lines.extend(f"WARNING recorded vehicle {j.track_id} jumps {j.jump_m:.2f} m beyond what "
                 f"its speed allows between t = {j.t_s:.2f} s and {j.t_s + j.dt_s:.2f} s"
                 for j in jumps[:MAX_JUMP_NOTES])
    return lines
