"""The recorded vehicles as a :class:`suite.catalog.tracks.TrackSet`, in run time.

Run time t = (k - k0) dt for time step k, k0 the planning problem's initial time step and
dt the step after :func:`~suite.importers.commonroad.checks.check_step`. Headings are
unwrapped per track; a missing speed is |d(position)/dt| (central differences). A
dynamic obstacle is kept when it is a road vehicle (not a pedestrian, bicycle, ...) and
its first sample is on the ego's road (:func:`~suite.importers.commonroad.checks.place_point`);
the others are dropped and counted by reason. Ids: ``rec_<obstacle id>``.

**Before the initial time step.** A replay needs nothing before t = 0 (the planning
problem's initial step): samples with t < 0 are dropped, except the last one before 0
when the track has no sample at t = 0 itself and goes on after it, so that the pose at
t = 0 interpolates between it and the next sample. A vehicle with no sample at t >= 0 is
dropped (reason ``before_start``); the on-road check uses its first kept sample.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from suite.catalog.tracks import TRACK_ID_PREFIX, Track, TrackSet
from suite.importers.commonroad.checks import LaneShape, place_point
from suite.importers.commonroad.records import FloatArray, ObstacleRecord

__all__ = ["NOT_VEHICLES", "TrackSelection", "first_kept", "select_tracks", "to_track"]

NOT_VEHICLES = frozenset({"pedestrian", "bicycle", "train", "building", "pillar",
                          "median_strip", "constructionZone", "roadBoundary"})
"""CommonRoad obstacle types that are not road vehicles (dropped from the tracks)."""


@dataclass(frozen=True)
class TrackSelection:
    """The kept tracks and the dropped obstacle ids by reason (``opposite``,
    ``off_road``, ``not_vehicle``, ``before_start``), and how many samples before the
    initial time step were dropped."""

    tracks: tuple[Track, ...]
    dropped: dict[str, tuple[int, ...]] = field(default_factory=dict)
    early_samples_dropped: int = 0

    def __post_init__(self) -> None:
        if self.early_samples_dropped < 0:
            raise ValueError(f"early_samples_dropped: expected >= 0, got "
                             f"{self.early_samples_dropped}")

    @property
    def dropped_count(self) -> int:
        return sum(len(v) for v in self.dropped.values())


def _speed(ob: ObstacleRecord, time_s: FloatArray) -> FloatArray:
    speed = np.asarray(ob.speed_mps, dtype=np.float64).copy()
    missing = ~np.isfinite(speed)
    if missing.any():
        if time_s.shape[0] > 1:
            vx = np.gradient(ob.x_m, time_s)
            vy = np.gradient(ob.y_m, time_s)
            speed[missing] = np.hypot(vx, vy)[missing]
        else:
            speed[missing] = 0.0
    return speed


def first_kept(ob: ObstacleRecord, k0: int) -> int | None:
    """Index of the first sample kept (module docstring), ``None`` if none is."""
    later = np.flatnonzero(ob.steps >= k0)
    if later.size == 0:
        return None
    i = int(later[0])
    return i - 1 if i > 0 and int(ob.steps[i]) > k0 else i


def to_track(ob: ObstacleRecord, k0: int, dt_s: float) -> Track:
    """One obstacle as a track, from its first kept sample (module docstring); the
    speeds are computed before the earlier samples are cut."""
    time_s = (ob.steps - k0).astype(np.float64) * dt_s
    speed = _speed(ob, time_s)
    heading = np.unwrap(ob.heading_rad)
    i = first_kept(ob, k0)
    if i is None:
        raise ValueError(f"obstacle {ob.obstacle_id} has no sample at or after step {k0}")
    return Track(track_id=f"{TRACK_ID_PREFIX}{ob.obstacle_id}", kind=ob.kind,
                 length_m=ob.length_m, width_m=ob.width_m, time_s=time_s[i:].copy(),
                 x_m=ob.x_m[i:].copy(), y_m=ob.y_m[i:].copy(),
                 heading_rad=heading[i:].copy(), speed_mps=speed[i:].copy())


def select_tracks(obstacles: Sequence[ObstacleRecord], lanes: Sequence[LaneShape], k0: int,
                  dt_s: float) -> TrackSelection:
    """Keep the dynamic road vehicles whose first sample is on the ego's road."""
    kept: list[Track] = []
    dropped: dict[str, list[int]] = {}
    early = 0
    for ob in obstacles:
        if ob.static:
            continue
        if ob.kind in NOT_VEHICLES:
            dropped.setdefault("not_vehicle", []).append(ob.obstacle_id)
            continue
        i = first_kept(ob, k0)
        if i is None:
            dropped.setdefault("before_start", []).append(ob.obstacle_id)
            continue
        where = place_point(lanes, float(ob.x_m[i]), float(ob.y_m[i]), float(ob.heading_rad[i]))
        if where.status != "on_road":
            dropped.setdefault(where.status, []).append(ob.obstacle_id)
            continue
        early += i
        kept.append(to_track(ob, k0, dt_s))
    return TrackSelection(tuple(kept), {k: tuple(v) for k, v in dropped.items()}, early)


def track_set(selection: TrackSelection, dt_s: float, notes: Sequence[str]) -> TrackSet:
    return TrackSet(selection.tracks, dt_s, tuple(notes))
