"""OpenDRIVE lane bands: where each lane lies across a road at s, from the lane widths
(``a + b ds + c ds² + d ds³``) and the road's ``laneOffset``, to turn a road position
(s, t) into a lane and an offset from its centre. t [m] is left of the reference line."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from suite.importers.openscenario.errors import fail_at

__all__ = ["RoadBands", "read_bands"]

Poly = tuple[float, float, float, float, float]  # start s (or sOffset), a, b, c, d


def _poly(records: list[Poly], ds: float) -> float:
    rec = [r for r in records if r[0] <= ds + 1e-9] or records[:1]
    if not rec:
        return 0.0
    s0, a, b, c, d = rec[-1]
    u = ds - s0
    return a + b * u + c * u * u + d * u * u * u


@dataclass(frozen=True)
class RoadBands:
    """A road's lane offset polynomials and, per lane section start [m], each lane's
    width polynomials (lane id -> records)."""

    offsets: tuple[Poly, ...]
    sections: tuple[tuple[float, dict[int, list[Poly]]], ...]

    def bands(self, s_m: float) -> dict[int, tuple[float, float]]:
        """Lane id -> (inner t, outer t) [m] at ``s_m`` (t of the border nearer to and
        farther from the reference line)."""
        sec = [x for x in self.sections if x[0] <= s_m + 1e-9] or list(self.sections[:1])
        s0, lanes = sec[-1]
        base = _poly(list(self.offsets), s_m)
        out: dict[int, tuple[float, float]] = {}
        for sign in (-1, 1):
            t = base
            for lane_id in sorted((k for k in lanes if k * sign > 0), key=abs):
                w = _poly(lanes[lane_id], s_m - s0)
                out[lane_id] = (t, t + sign * w)
                t += sign * w
        return out

    def lane_at(self, s_m: float, t_m: float) -> tuple[int, float] | None:
        """(lane id, offset from its centre [m, towards +t]) of the point (s, t)."""
        for lane_id, (inner, outer) in self.bands(s_m).items():
            lo, hi = min(inner, outer), max(inner, outer)
            if lo - 1e-9 <= t_m <= hi + 1e-9 and hi > lo:
                return lane_id, t_m - 0.5 * (inner + outer)
        return None

    def centre_t(self, s_m: float, lane_id: int) -> float:
        inner, outer = self.bands(s_m)[lane_id]
        return 0.5 * (inner + outer)


def _rec(el: Any, start_key: str) -> Poly:
    return (float(el.get(start_key, "0")), float(el.get("a", "0")), float(el.get("b", "0")),
            float(el.get("c", "0")), float(el.get("d", "0")))


def read_bands(road: Any) -> RoadBands:
    """The lane bands of an OpenDRIVE ``road`` element."""
    try:
        offsets = tuple(_rec(o, "s") for o in road.iterfind("lanes/laneOffset"))
        sections = []
        for sec in road.iterfind("lanes/laneSection"):
            lanes: dict[int, list[Poly]] = {}
            for lane in sec.iterfind("*/lane"):
                lanes[int(lane.get("id"))] = [_rec(w, "sOffset")
                                              for w in lane.iterfind("width")]
            sections.append((float(sec.get("s", "0")), lanes))
    except (TypeError, ValueError):
        raise fail_at(road, "lane widths and offsets must be numbers") from None
    return RoadBands(offsets, tuple(sorted(sections, key=lambda x: x[0])))
