"""The lanes' speed limits [m/s], from the CommonRoad ``MAX_SPEED`` signs the lanelets
reference (:mod:`~suite.importers.commonroad.reader`), else a default.

1. A lanelet's own sign (the lowest it references) holds over the whole lanelet (and
   all its pieces).
2. A sign holds downstream until the next one: a lanelet without a sign takes the
   lowest limit of its predecessors that have one; repeated to a fixed point.
3. A lanelet still without a limit takes the lowest limit of its row (the signs of a
   carriageway are often referenced by one lane only); then 2 again.
4. The rest takes the default: :data:`COUNTRY_DEFAULT_MPS` for the scenario's country
   (DEU: the motorway advisory speed 130 km/h = 36.11 m/s, where an Autobahn without a
   sign has no limit; USA: 65 mph = 29.06 m/s, the US-101 / I-80 of NGSIM), otherwise
   the recording's highest speed (vehicles and ego) rounded up to a multiple of
   10 km/h, at least :data:`MIN_DEFAULT_MPS`.

``override_mps`` (``NetParams.speed_limit_mps``) replaces all of this by one value.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from suite.importers.commonroad.lanelets import RoadRows
from suite.importers.commonroad.records import ObstacleRecord, RecordedFile

__all__ = ["COUNTRY_DEFAULT_MPS", "MIN_DEFAULT_MPS", "SpeedPlan", "default_limit_mps",
           "lane_speeds"]

KMH = 1.0 / 3.6
COUNTRY_DEFAULT_MPS = {"DEU": 130.0 * KMH, "USA": 65.0 * 0.44704}
MIN_DEFAULT_MPS = 50.0 * KMH


@dataclass(frozen=True)
class SpeedPlan:
    """Per row, per lane (right to left) speed limits [m/s]; how many lanes took a
    sign's limit (own or inherited) and the default; the default [m/s] and its source."""

    lanes_mps: tuple[tuple[float, ...], ...]
    from_signs: int
    from_default: int
    default_mps: float
    default_source: str

    def __post_init__(self) -> None:
        for row in self.lanes_mps:
            for v in row:
                if not (math.isfinite(v) and v > 0.0):
                    raise ValueError(f"lane speed limit: expected > 0, got {v!r}")
        if not (math.isfinite(self.default_mps) and self.default_mps > 0.0):
            raise ValueError(f"default_mps: expected > 0, got {self.default_mps!r}")

    @property
    def note(self) -> str:
        if self.default_source == "override":
            return f"speed limit {self.default_mps:.2f} m/s on every lane (set)"
        return (f"speed limits: {self.from_signs} lanes from MAX_SPEED signs, "
                f"{self.from_default} at the default {self.default_mps:.2f} m/s "
                f"({self.default_source})")


def _recorded_max_mps(obstacles: Sequence[ObstacleRecord], ego_mps: float) -> float:
    top = ego_mps
    for ob in obstacles:
        v = ob.speed_mps[np.isfinite(ob.speed_mps)]
        if v.size:
            top = max(top, float(v.max()))
    return top


def default_limit_mps(rec: RecordedFile) -> tuple[float, str]:
    """The default limit [m/s] and where it comes from (module docstring, step 4)."""
    if rec.country in COUNTRY_DEFAULT_MPS:
        return COUNTRY_DEFAULT_MPS[rec.country], f"default for {rec.country}"
    top = _recorded_max_mps(rec.obstacles, rec.ego.speed_mps)
    v = max(MIN_DEFAULT_MPS, math.ceil(top / KMH / 10.0 - 1e-9) * 10.0 * KMH)
    return v, f"the recording's top speed {top:.1f} m/s rounded up to 10 km/h"


def _propagate(road: RoadRows, limit: dict[int, float]) -> None:
    """Step 2 in place: predecessors' limits downstream to a fixed point."""
    changed = True
    while changed:
        changed = False
        for row in road.rows:
            for ll in row.lanelets:
                if ll.lanelet_id in limit:
                    continue
                known = [limit[p] for p in ll.predecessors if p in limit]
                if known:
                    limit[ll.lanelet_id] = min(known)
                    changed = True


def lane_speeds(road: RoadRows, rec: RecordedFile, override_mps: float | None) -> SpeedPlan:
    """Every lane's limit (module docstring)."""
    if override_mps is not None:
        return SpeedPlan(tuple((override_mps,) * len(row.lanelets) for row in road.rows),
                         0, sum(len(row.lanelets) for row in road.rows), override_mps,
                         "override")
    limit = {ll.lanelet_id: ll.speed_limit_mps for row in road.rows for ll in row.lanelets
             if ll.speed_limit_mps is not None}
    _propagate(road, limit)
    for row in road.rows:
        known = [limit[ll.lanelet_id] for ll in row.lanelets if ll.lanelet_id in limit]
        for ll in row.lanelets:
            if known and ll.lanelet_id not in limit:
                limit[ll.lanelet_id] = min(known)
    _propagate(road, limit)
    default, source = default_limit_mps(rec)
    lanes = tuple(tuple(limit.get(ll.lanelet_id, default) for ll in row.lanelets)
                  for row in road.rows)
    n = sum(len(row.lanelets) for row in road.rows)
    return SpeedPlan(lanes, len(limit), n - len(limit), default, source)
