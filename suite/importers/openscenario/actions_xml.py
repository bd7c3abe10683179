"""Private actions of the XML storyboard -> the typed model
(:mod:`suite.catalog.storyboard`). Any other action is an error naming it."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from suite.catalog import storyboard as sb
from suite.importers.openscenario.conditions_xml import _flag, _only_child
from suite.importers.openscenario.errors import fail_at
from suite.importers.openscenario.position_xml import num, read_position
from suite.importers.openscenario.positions import Placer

__all__ = ["ActionReader"]


def _dyn(parent: Any, tag: str) -> tuple[str, str, float]:
    """(shape, dimension, |value|) of ``parent``'s dynamics element ``tag``."""
    el = parent.find(tag)
    if el is None:
        raise fail_at(parent, f"{tag} is required")
    shape, dim = el.get("dynamicsShape", ""), el.get("dynamicsDimension", "time")
    if shape not in sb.SHAPES or dim not in sb.DIMENSIONS:
        raise fail_at(el, f"dynamicsShape {shape!r} / dynamicsDimension {dim!r} unsupported "
                      f"(shapes {list(sb.SHAPES)}, dimensions {list(sb.DIMENSIONS)})")
    return shape, dim, abs(num(el, "value", 0.0))


def _need(parent: Any, tag: str) -> Any:
    el = parent.find(tag)
    if el is None:
        raise fail_at(parent, f"{tag} is required")
    return el


@dataclass
class ActionReader:
    """Reads PrivateActions with the scenario's placer and entity names."""

    placer: Placer
    entities: set[str]
    ego: str

    def entity(self, el: Any, key: str = "entityRef") -> str:
        name = el.get(key, "")
        if name not in self.entities:
            raise fail_at(el, f"unknown entity {name!r}")
        return str(name)

    def private(self, el: Any) -> Any:
        """The model action of a ``PrivateAction`` element."""
        kid = _only_child(el)
        tag = str(kid.tag)
        if tag == "LongitudinalAction":
            return self.longitudinal(_only_child(kid))
        if tag == "LateralAction":
            return self.lateral(_only_child(kid))
        if tag == "TeleportAction":
            return self.teleport(kid)
        if tag in ("ControllerAction", "ActivateControllerAction"):
            act = kid if tag == "ActivateControllerAction" else _only_child(kid)
            if act.tag != "ActivateControllerAction":
                raise fail_at(act, f"controller action {act.tag} is not supported")
            return sb.ActivateControllerAction(_flag(act, "lateral", True),
                                               _flag(act, "longitudinal", True))
        if tag == "RoutingAction":
            return self.routing(_only_child(kid))
        raise fail_at(kid, f"action {tag} is not supported")

    def longitudinal(self, el: Any) -> Any:
        if el.tag == "SpeedAction":
            shape, dim, value = _dyn(el, "SpeedActionDynamics")
            target = _only_child(_need(el, "SpeedActionTarget"))
            if target.tag == "AbsoluteTargetSpeed":
                return sb.SpeedAction(num(target, "value"), shape, dim, value)
            kind = target.get("speedTargetValueType", "delta")
            return sb.SpeedAction(num(target, "value"), shape, dim, value,
                                  self.entity(target), kind, _flag(target, "continuous"))
        if el.tag == "LongitudinalDistanceAction":
            dist = el.get("distance")
            return sb.LongitudinalDistanceAction(
                self.entity(el), _flag(el, "freespace"),
                el.get("displacement", "leadingReferencedEntity") != "trailingReferencedEntity",
                _flag(el, "continuous"),
                distance_m=None if dist is None else num(el, "distance"),
                time_gap_s=None if dist is not None else num(el, "timeGap"))
        raise fail_at(el, f"longitudinal action {el.tag} is not supported")

    def _sumo_dlane(self, el: Any, value: int) -> int:
        """An OpenDRIVE lane-id step as SUMO lanes to the left (mirrored on lanes that
        drive against the reference line)."""
        del el
        ego = self.placer.places.get(self.ego)
        if ego is None:
            return value
        odr = self.placer.to_lane(ego)
        return value if odr.lane < 0 else -value

    def lateral(self, el: Any) -> Any:
        if el.tag == "LaneChangeAction":
            shape, dim, value = _dyn(el, "LaneChangeActionDynamics")
            target = _only_child(_need(el, "LaneChangeTarget"))
            offset = num(el, "targetLaneOffset", 0.0)
            if target.tag == "RelativeTargetLane":
                rel = sb.RelativeLaneTarget(self.entity(target),
                                            self._sumo_dlane(target, int(num(target, "value"))))
                return sb.LaneChangeAction(shape, dim, value, relative=rel,
                                           target_offset_m=offset)
            lane_id = int(num(target, "value"))
            road = next(iter(self.placer.lane_map.roads))
            pairs = self.placer.lane_map.lanes.get((road, lane_id))
            if not pairs:
                raise fail_at(target, f"lane {lane_id} has no SUMO lane")
            return sb.LaneChangeAction(shape, dim, value, lane=pairs[0][1],
                                       target_offset_m=offset)
        if el.tag == "LaneOffsetAction":
            d = el.find("LaneOffsetActionDynamics")
            if d is None:
                raise fail_at(el, "LaneOffsetActionDynamics is required")
            shape = d.get("dynamicsShape", "")
            if shape not in sb.SHAPES:
                raise fail_at(d, f"dynamicsShape {shape!r} unsupported")
            acc = num(d, "maxLateralAcc", 1e6)
            target = _only_child(_need(el, "LaneOffsetTarget"))
            ref = (self.entity(target) if target.tag == "RelativeTargetLaneOffset" else None)
            return sb.LaneOffsetAction(num(target, "value"), shape, acc, ref,
                                       _flag(el, "continuous"))
        raise fail_at(el, f"lateral action {el.tag} is not supported")

    def teleport(self, el: Any) -> Any:
        pos = el.find("Position")
        if pos is None:
            raise fail_at(el, "a Position is required")
        kid = _only_child(pos)
        if kid.tag == "RelativeLanePosition" and kid.get("entityRef") in self.entities:
            return sb.TeleportAction(relative_to=self.entity(kid), ds_m=num(kid, "ds"),
                                     dlane=self._sumo_dlane(kid, int(num(kid, "dLane"))),
                                     lateral_m=num(kid, "offset", 0.0))
        return sb.TeleportAction(position=read_position(pos, self.placer))

    def routing(self, el: Any) -> Any:
        if el.tag != "FollowTrajectoryAction":
            raise fail_at(el, f"routing action {el.tag} is not supported")
        traj = el.find("TrajectoryRef/Trajectory")
        traj = el.find("Trajectory") if traj is None else traj
        poly = None if traj is None else traj.find("Shape/Polyline")
        if poly is None:
            raise fail_at(el, "only a Trajectory with a Polyline shape is supported")
        timing = el.find("TimeReference/Timing")
        if timing is None:
            raise fail_at(el, "a TimeReference with Timing is required (the polyline's times)")
        if timing.get("domainAbsoluteRelative", "relative") != "relative":
            raise fail_at(timing, "only relative timing is supported")
        verts = []
        for v in poly.iterfind("Vertex"):
            pos = v.find("Position")
            if pos is None or v.get("time") is None:
                raise fail_at(v, "a Vertex needs a time and a Position")
            verts.append(sb.TrajectoryVertex(num(v, "time"), read_position(pos, self.placer)))
        return sb.FollowTrajectoryAction(tuple(verts), num(timing, "scale", 1.0),
                                         num(timing, "offset", 0.0))
