"""A scenario against its road network: the net resolved and loaded, the route checked
(edges exist and connect; default: the longest edge path), and the ego, stalled vehicles
and traffic lanes placed on lanes that exist (and admit passenger cars) there."""

from __future__ import annotations

import difflib
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from suite.catalog import rules
from suite.catalog.errors import MISSING
from suite.catalog.nets import bundled_net_path
from suite.catalog.report import Report
from suite.catalog.specs import TrafficSpec
from suite.road.network import RoadNetwork, RoadNetworkError

__all__ = ["check_placements", "resolve_net", "resolve_route"]


def resolve_net(raw: Any, catalog_path: Path, bundled: Sequence[str], report: Report
                ) -> tuple[Path | None, RoadNetwork | None]:
    """(net file, loaded network) of a scenario's ``net``; Nones where unusable (reported).
    ``bundled`` names the bundled nets; another value is a path relative to the catalog."""
    if raw is MISSING:
        return None, None
    if not isinstance(raw, str) or not raw:
        report.add("net", "a bundled net name or a .net.xml path", raw)
        return None, None
    path: Path | None = None
    if raw in bundled:
        path = bundled_net_path(raw)
    if path is None:
        candidate = Path(raw).expanduser()
        if not candidate.is_absolute():
            candidate = catalog_path.parent / candidate
        if candidate.is_file():
            path = candidate.resolve()
    if path is None:
        close = difflib.get_close_matches(raw, list(bundled), n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        report.add("net", f"a bundled net (one of {list(bundled)}) or an existing .net.xml "
                   f"file (relative to {catalog_path.parent}){hint}", raw)
        return None, None
    try:
        return path, RoadNetwork.load(path)
    except RoadNetworkError as exc:
        report.add("net", f"a readable SUMO network ({exc})", raw)
        return path, None


def resolve_route(raw: Any, network: RoadNetwork | None, report: Report
                  ) -> tuple[str, ...] | None:
    """A scenario's checked ``route`` (default: the network's); None if unusable."""
    if raw is MISSING:
        return network.default_route() if network is not None else None
    if (not isinstance(raw, list) or not raw
            or any(not isinstance(e, str) for e in raw)):
        report.add("route", "a non-empty list of edge ids (strings)", raw)
        return None
    if network is None:
        return None
    ok = True
    for i, eid in enumerate(raw):
        if not network.has_edge(eid):
            edges = network.edge_ids()
            shown = edges if len(edges) <= 20 else [*edges[:20], "..."]
            report.add(f"route.{i}", f"an edge of {network.path.name} (one of {shown})", eid)
            ok = False
    if not ok:
        return None
    try:
        network.validate_route(raw)
    except ValueError as exc:
        m = re.match(r"route\[(\d+)\]: (.*)", str(exc))
        sub = f"route.{m.group(1)}" if m else "route"
        report.add(sub, "an edge connected from the previous route edge "
                   f"({m.group(2) if m else exc})", raw[int(m.group(1))] if m else raw)
        return None
    return tuple(raw)


def check_placements(network: RoadNetwork, route: tuple[str, ...], ego_raw: Any,
                     stalled_raw: Any, traffic: TrafficSpec | None, allow_shoulder: bool,
                     report: Report, actors_raw: Any = ()) -> None:
    """Report the ego, stalled vehicles, actors and traffic lanes that do not fit the
    network. ``ego_raw``, ``stalled_raw`` and ``actors_raw`` are the raw values (checked
    where individually valid)."""
    length = network.route_length_m(route)
    ego_ok = _check_ego(network, route, length, ego_raw, allow_shoulder, report)
    placed: list[tuple[str, int, float, float]] = []  # key, lane, position, length
    for i, item in enumerate(stalled_raw if isinstance(stalled_raw, list) else []):
        st_lp = _lane_pos(item)
        if st_lp is not None and _place(network, route, length, st_lp[1], st_lp[0],
                                        f"stalled.{i}", report) is not None:
            placed.append((f"stalled.{i}", st_lp[0], st_lp[1], _length(item)))
    for i, item in enumerate(actors_raw if isinstance(actors_raw, list) else []):
        a_lp = _lane_pos(item)
        if a_lp is not None and _place(network, route, length, a_lp[1], a_lp[0],
                                       f"actors.{i}", report) is not None:
            _check_actor_lane(network, route, a_lp, f"actors.{i}", report)
            placed.append((f"actors.{i}", a_lp[0], a_lp[1], _length(item, ACTOR_LENGTH_M)))
    if ego_ok:
        lane, pos = _lane_pos(ego_raw) or (0, 0.0)
        placed.insert(0, ("ego", lane, pos, EGO_LENGTH_M))
    _check_overlaps(network, route, placed, report)
    if traffic is not None and traffic.lanes is not None:
        _check_traffic_lanes(network, route[0], traffic.lanes, report)


EGO_LENGTH_M = 4.8  # controllers.plant.vehicle_model.VehicleParams().length_m
STALLED_LENGTH_M = 4.8  # StalledSpec's default
ACTOR_LENGTH_M = 4.5  # ActorSpec's default
MIN_BUMPER_GAP_M = 1.0  # SUMO inserts nothing closer than this to another car


def _length(raw: Any, default: float = STALLED_LENGTH_M) -> float:
    value = raw.get("length_m", default) if isinstance(raw, dict) else default
    return float(value) if rules.is_number(value) and value > 0 else default


def _check_actor_lane(network: RoadNetwork, route: tuple[str, ...], lane_pos: tuple[int, float],
                      key: str, report: Report) -> None:
    lane, pos = lane_pos
    shoulder, passenger = _lane_props(network, route, pos, lane)
    if not passenger and not shoulder:
        report.add(f"{key}.lane", "a lane open to passenger cars", lane)


def _check_overlaps(network: RoadNetwork, route: tuple[str, ...],
                    placed: list[tuple[str, int, float, float]], report: Report) -> None:
    """Vehicles placed on one lane of one edge must not overlap: SUMO would refuse to
    insert the later one (positions are front bumpers, boxes reach back by a length)."""
    where = [(key, network.locate(route, pos)[0], lane, pos, length)
             for key, lane, pos, length in placed]
    for j, (key, edge, lane, pos, length) in enumerate(where):
        for other, o_edge, o_lane, o_pos, o_length in where[:j]:
            if (edge, lane) != (o_edge, o_lane):
                continue
            ahead, behind = (pos, o_pos) if pos >= o_pos else (o_pos, pos)
            ahead_len = length if pos >= o_pos else o_length
            if ahead - ahead_len - behind < MIN_BUMPER_GAP_M:
                report.add(f"{key}.pos_m", f"a position clear of {other} (both on lane {lane} "
                           f"of {edge!r}: their boxes overlap or leave less than "
                           f"{MIN_BUMPER_GAP_M:g} m between them)", pos)


def _check_ego(network: RoadNetwork, route: tuple[str, ...], length: float, ego_raw: Any,
               allow_shoulder: bool, report: Report) -> bool:
    """Report an ego that does not fit; True when it is placed on an existing lane."""
    ego_lp = _lane_pos(ego_raw)
    if ego_lp is None:
        return False
    lane, pos = ego_lp
    lanes = _place(network, route, length, pos, lane, "ego", report)
    if lanes is None:
        return False
    shoulder, passenger = _lane_props(network, route, pos, lane)
    if shoulder and not allow_shoulder:
        report.add("ego.lane", "a lane open to passenger cars (this lane is a hard "
                   "shoulder; set allow_shoulder = true to start on it)", lane)
    elif not shoulder and not passenger:
        report.add("ego.lane", "a lane open to passenger cars", lane)
    return True


def _check_traffic_lanes(network: RoadNetwork, first: str, lanes: tuple[int, ...],
                         report: Report) -> None:
    count = network.lane_count(first)
    for j, lane in enumerate(lanes):
        if lane >= count:
            report.add(f"traffic.lanes.{j}", f"a lane index in 0..{count - 1} (lanes of "
                       f"the first route edge {first!r})", lane)
        elif not _lane_allows_passenger(network, first, lane):
            report.add(f"traffic.lanes.{j}", "a lane open to passenger cars (lane "
                       f"{lane} of {first!r} is not)", lane)


def _place(network: RoadNetwork, route: tuple[str, ...], length: float, pos: float,
           lane: int, key: str, report: Report) -> int | None:
    """The lane count at ``pos`` if ``pos`` is on the route and ``lane`` exists there."""
    if not 0.0 <= pos < length:
        report.add(f"{key}.pos_m", f"a route position in [0, {length:.1f}) m", pos)
        return None
    lanes = network.lanes_at(route, pos)
    if lane >= lanes:
        edge, _ = network.locate(route, pos)
        report.add(f"{key}.lane", f"a lane index in 0..{lanes - 1} (edge {edge!r} at "
                   f"{pos:g} m on the route has {lanes} lanes)", lane)
        return None
    return lanes


def _lane_props(network: RoadNetwork, route: tuple[str, ...], pos: float, lane: int
                ) -> tuple[bool, bool]:
    """(is a hard shoulder, admits passenger cars) of ``lane`` at route position ``pos``."""
    edge, _ = network.locate(route, pos)
    for info in network.lane_info((edge,)):
        if info.index == lane:
            return info.is_shoulder, info.allows_passenger
    return False, True  # pragma: no cover


def _lane_allows_passenger(network: RoadNetwork, edge: str, lane: int) -> bool:
    return any(i.allows_passenger for i in network.lane_info((edge,)) if i.index == lane)


def _lane_pos(raw: Any) -> tuple[int, float] | None:
    """(lane, pos_m) of a raw ego/stalled table if both are individually valid."""
    if not isinstance(raw, dict) or "lane" not in raw or "pos_m" not in raw:
        return None
    if rules.integer(0)(raw["lane"]) or rules.num(0.0)(raw["pos_m"]):
        return None
    return int(raw["lane"]), float(raw["pos_m"])
