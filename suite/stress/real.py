"""The real motorways for the stress generator: ``../shared/nets_real`` beside the
repository (three OpenStreetMap cuts: A 2, A 391, A 36; see its README.md) with its
``catalog.toml``, whose scenarios give each net's route.

:func:`real_nets` lists what is there (nothing when the folder is absent);
:func:`on_ramps` finds the on-ramps of a route: edges off the route whose lane
connections lead onto it (:func:`suite.catalog.traffic_checks.ramp_route`), joining it
after its first edge, with at most two lanes and a speed limit of at most 30 m/s (a slip
road, not a motorway continuing from upstream).
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path

from suite.catalog.traffic_checks import ramp_route
from suite.road.network import RoadNetwork

__all__ = ["OnRamp", "RealNet", "default_real_dir", "on_ramps", "real_nets"]

MAX_RAMP_LANES = 2
MAX_RAMP_SPEED_MPS = 30.0


def default_real_dir() -> Path:
    """``<repository>/../shared/nets_real``."""
    return Path(__file__).resolve().parents[2].parent / "shared" / "nets_real"


@dataclass(frozen=True)
class RealNet:
    """A real net file and the route its catalog drives."""

    path: Path
    route: tuple[str, ...]

    @property
    def name(self) -> str:
        return self.path.name


def real_nets(directory: Path | None) -> tuple[RealNet, ...]:
    """The nets of ``directory``'s catalog.toml with a route (first scenario per net),
    sorted by file name; () if the folder or its catalog is missing."""
    if directory is None:
        return ()
    catalog = Path(directory) / "catalog.toml"
    if not catalog.is_file():
        return ()
    doc = tomllib.loads(catalog.read_text(encoding="utf-8"))
    routes: dict[str, tuple[str, ...]] = {}
    for sc in doc.get("scenario", []):
        net, route = sc.get("net"), sc.get("route")
        if isinstance(net, str) and isinstance(route, list) and net not in routes:
            if (Path(directory) / net).is_file():
                routes[net] = tuple(str(e) for e in route)
    return tuple(RealNet(Path(directory) / net, routes[net]) for net in sorted(routes))


@dataclass(frozen=True)
class OnRamp:
    """An on-ramp edge and the route position [m] where the route edge it joins starts."""

    edge: str
    joins_at_m: float


def on_ramps(network: RoadNetwork, route: tuple[str, ...]) -> tuple[OnRamp, ...]:
    """The route's on-ramps (module doc), ordered by where they join."""
    starts = network.route_edge_starts_m(route)
    out = []
    for edge in network.edge_ids():
        if edge in route or network.lane_count(edge) > MAX_RAMP_LANES:
            continue
        if max(li.speed_mps for li in network.lane_info((edge,))) > MAX_RAMP_SPEED_MPS:
            continue
        path = ramp_route(network, edge, route)
        if path is None:
            continue
        joins = next(e for e in path if e in starts)
        if starts[joins] > 0.0:
            out.append(OnRamp(edge, starts[joins]))
    return tuple(sorted(out, key=lambda r: (r.joins_at_m, r.edge)))
