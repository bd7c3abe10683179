"""``road.json``: the lanes of the route and the controller's reference path.

Coordinates are SUMO network coordinates [m]. ``lanes`` holds every lane of every
route edge and the internal junction lanes between them (``internal``), each with its
centreline polyline and width, so that a reader can rebuild the drivable area without
the network file.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from reports.record.codec import RecordError

XY = npt.NDArray[np.float64]


@dataclass(frozen=True)
class LaneRecord:
    """One lane: id, edge, index (0 = rightmost of its edge), width [m], centreline (M, 2)
    [m], vehicle classes allowed (empty = all), shoulder flag, passenger cars allowed,
    speed limit [m/s], and whether it is an internal junction lane."""

    id: str
    edge_id: str
    index: int
    width_m: float
    shape_xy_m: XY = field(compare=False, repr=False)
    allowed: tuple[str, ...] = ()
    is_shoulder: bool = False
    allows_passenger: bool = True
    speed_mps: float = 0.0
    internal: bool = False

    def drivable(self, allow_shoulder: bool) -> bool:
        """May the ego be here? Passenger cars allowed; a shoulder only if allowed."""
        if self.is_shoulder:
            return allow_shoulder
        return self.allows_passenger

    def as_plain(self) -> dict[str, Any]:
        return {"id": self.id, "edge_id": self.edge_id, "index": self.index,
                "width_m": self.width_m, "shape_xy_m": np.asarray(self.shape_xy_m).tolist(),
                "allowed": list(self.allowed), "is_shoulder": self.is_shoulder,
                "allows_passenger": self.allows_passenger, "speed_mps": self.speed_mps,
                "internal": self.internal}


@dataclass(frozen=True)
class RoadRecord:
    """The route's lanes, the reference path polyline (M, 2) [m] and its length [m]."""

    lanes: tuple[LaneRecord, ...] = ()
    reference_xy_m: XY = field(default_factory=lambda: np.zeros((0, 2)), compare=False)
    reference_length_m: float = float("nan")
    route: tuple[str, ...] = ()

    def as_plain(self) -> dict[str, Any]:
        return {"lanes": [lane.as_plain() for lane in self.lanes],
                "reference_xy_m": np.asarray(self.reference_xy_m).tolist(),
                "reference_length_m": self.reference_length_m, "route": list(self.route)}

    @classmethod
    def from_plain(cls, data: Any, path: str | Path) -> RoadRecord:
        if not isinstance(data, Mapping):
            raise RecordError(path, "", "a table with lanes, reference_xy_m, route", data)
        lanes_raw = data.get("lanes", [])
        if not isinstance(lanes_raw, Sequence) or isinstance(lanes_raw, str):
            raise RecordError(path, "lanes", "a list of lane tables", lanes_raw)
        lanes = tuple(_lane(raw, path, f"lanes.{i}") for i, raw in enumerate(lanes_raw))
        ref = _xy(data.get("reference_xy_m", []), path, "reference_xy_m")
        length = data.get("reference_length_m", float("nan"))
        if isinstance(length, bool) or not isinstance(length, int | float):
            raise RecordError(path, "reference_length_m", "a number", length)
        route = data.get("route", [])
        if not isinstance(route, list) or any(not isinstance(e, str) for e in route):
            raise RecordError(path, "route", "a list of edge ids", route)
        return cls(lanes, ref, float(length), tuple(route))


def _xy(raw: Any, path: str | Path, key: str) -> XY:
    try:
        arr = np.asarray(raw, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise RecordError(path, key, "a list of [x, y] pairs", raw) from exc
    if arr.size == 0:
        return np.zeros((0, 2))
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise RecordError(path, key, "a list of [x, y] pairs", raw)
    return arr


def _lane(raw: Any, path: str | Path, key: str) -> LaneRecord:
    if not isinstance(raw, Mapping):
        raise RecordError(path, key, "a lane table", raw)
    for name, kind in (("id", str), ("edge_id", str)):
        if not isinstance(raw.get(name), kind):
            raise RecordError(path, f"{key}.{name}", "a string", raw.get(name))
    index = raw.get("index")
    if isinstance(index, bool) or not isinstance(index, int):
        raise RecordError(path, f"{key}.index", "an integer", index)
    width = raw.get("width_m")
    if isinstance(width, bool) or not isinstance(width, int | float) or not width > 0:
        raise RecordError(path, f"{key}.width_m", "a number > 0", width)
    allowed = raw.get("allowed", [])
    if not isinstance(allowed, list) or any(not isinstance(a, str) for a in allowed):
        raise RecordError(path, f"{key}.allowed", "a list of vehicle classes", allowed)
    passenger = raw.get("allows_passenger")
    if not isinstance(passenger, bool):
        passenger = (not allowed) or ("passenger" in allowed)
    speed = raw.get("speed_mps", 0.0)
    return LaneRecord(
        id=raw["id"], edge_id=raw["edge_id"], index=index, width_m=float(width),
        shape_xy_m=_xy(raw.get("shape_xy_m", []), path, f"{key}.shape_xy_m"),
        allowed=tuple(allowed), is_shoulder=bool(raw.get("is_shoulder", False)),
        allows_passenger=passenger,
        speed_mps=float(speed) if isinstance(speed, int | float) else 0.0,
        internal=bool(raw.get("internal", False)))
