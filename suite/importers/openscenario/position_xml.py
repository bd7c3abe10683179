"""A ``Position`` element -> a route position of the entity's reference point
(:class:`~suite.importers.openscenario.positions.Placer`); kinds the runtime cannot
place are an error naming the element and its line."""

from __future__ import annotations

import math
from typing import Any

from suite.catalog.storyboard import RoutePosition
from suite.importers.openscenario.errors import fail_at
from suite.importers.openscenario.positions import Placer

__all__ = ["SUPPORTED", "num", "read_position"]

SUPPORTED = ("WorldPosition", "LanePosition", "RoadPosition", "RelativeLanePosition",
             "RelativeRoadPosition", "RelativeObjectPosition", "RelativeWorldPosition")


def num(el: Any, key: str, default: float | None = None) -> float:
    """Attribute ``key`` of ``el`` as a finite number (``default`` when absent)."""
    raw = el.get(key)
    if raw is None:
        if default is None:
            raise fail_at(el, f"attribute {key} is required")
        return default
    try:
        v = float(raw)
    except ValueError:
        raise fail_at(el, f"attribute {key}={raw!r} is not a number") from None
    if not math.isfinite(v):
        raise fail_at(el, f"attribute {key}={raw!r} is not finite")
    return v


def _heading(el: Any) -> tuple[float, bool]:
    """(h [rad], relative?) of the position's Orientation (0, relative when none)."""
    o = el.find("Orientation")
    if o is None:
        return 0.0, True
    return num(o, "h", 0.0), o.get("type", "relative") == "relative"


def read_position(pos: Any, placer: Placer) -> RoutePosition:
    """The route position of ``pos`` (a ``Position`` element)."""
    kids = [k for k in pos if isinstance(k.tag, str)]
    if len(kids) != 1:
        raise fail_at(pos, "a Position needs exactly one kind of position")
    el = kids[0]
    tag = str(el.tag)
    if tag not in SUPPORTED:
        raise fail_at(el, f"position kind {tag} is not supported (supported: {list(SUPPORTED)})")
    h, relative = _heading(el)
    if tag == "WorldPosition":
        return placer.from_xy(el, num(el, "x"), num(el, "y"), num(el, "h", 0.0))
    if tag == "LanePosition":
        p = placer.from_lane(el, el.get("roadId", ""), int(num(el, "laneId")), num(el, "s"),
                             num(el, "offset", 0.0))
    elif tag == "RoadPosition":
        p = placer.from_road(el, el.get("roadId", ""), num(el, "s"), num(el, "t"))
    elif tag == "RelativeLanePosition":
        if el.get("dsLane") is not None:
            raise fail_at(el, "dsLane (a distance along the lane) is not supported: use ds")
        p = placer.relative_lane(el, el.get("entityRef", ""), int(num(el, "dLane")),
                                 num(el, "ds"), num(el, "offset", 0.0))
    elif tag == "RelativeRoadPosition":
        p = placer.relative_road(el, el.get("entityRef", ""), num(el, "ds"), num(el, "dt"))
    else:
        p = placer.relative_xy(el, el.get("entityRef", ""), num(el, "dx"), num(el, "dy"),
                               tag == "RelativeObjectPosition")
    if not relative:
        _, _, lane_h = placer.xy(RoutePosition(p.pos_m, p.lane, p.lateral_m))
        h = math.remainder(h - lane_h, 2.0 * math.pi)
    return RoutePosition(p.pos_m, p.lane, p.lateral_m, h)
