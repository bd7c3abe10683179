"""What a stress catalog covers, measured on the catalog as loaded (its validated
``Scenario``s and their networks), not on what the generator meant to write.

Per scenario (:class:`ScenarioFeatures`): the through lanes where the ego starts, a hard
shoulder on the route, the smallest radius and the net turn of the ego's lane ahead (its
physical lane over the route, :func:`suite.stress.lanes.lane_curvature`), the stalled
cars and whether one is close ahead in the ego's lane, the ego's speed, the traffic
flow, slower traffic in the passing lane, on-ramp traffic, the friction, and whether the
net is a real motorway. :meth:`ScenarioFeatures.features` names the :data:`FEATURES` it
has; :class:`Coverage` counts them over a catalog and ranges the numbers.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

from suite.catalog import Catalog, Scenario
from suite.road.network import RoadNetwork
from suite.stress.config import FEATURES, StressConfig
from suite.stress.lanes import RouteLanes, lane_curvature

__all__ = ["Coverage", "ScenarioFeatures", "measure", "measure_catalog"]

REAL_DIR = "real"  # generated catalogs keep the real nets in nets/real/
RADIUS_TOL_M = 15.0  # the ego's lane is up to 1.5 lanes off the carriageway's centre
ANGLE_TOL_DEG = 1.0


@dataclass(frozen=True)
class ScenarioFeatures:
    """Measured properties of one scenario (module doc). Units in the names."""

    name: str
    real: bool
    through_lanes: int
    shoulder: bool
    min_radius_m: float
    turn_deg: float
    stalled: int
    close_stall: bool
    ego_speed_mps: float
    traffic_vph: float
    slow_passing_lane: bool
    merge: bool
    friction: float

    def features(self, cfg: StressConfig) -> frozenset[str]:
        """The :data:`FEATURES` this scenario has (ranges from ``cfg``)."""
        out = set()
        if not self.real:
            out.add(f"lanes_{self.through_lanes}")
            out.add("shoulder" if self.shoulder else "no_shoulder")
            lo_r, hi_r = cfg.curve_radius_m
            lo_a, hi_a = cfg.curve_angle_deg
            if (lo_r - RADIUS_TOL_M <= self.min_radius_m <= hi_r + RADIUS_TOL_M
                    and lo_a - ANGLE_TOL_DEG <= self.turn_deg <= hi_a + ANGLE_TOL_DEG):
                out.add("curve")
        else:
            out.add("real_net")
        far = self.stalled - int(self.close_stall)
        if far >= 4:
            out.add("several_stalled")
        elif far >= 1:
            out.add(f"stalled_{far}")
        for name, on in (("close_stall", self.close_stall), ("free_road", self.traffic_vph == 0),
                         ("traffic", self.traffic_vph > 0),
                         ("slow_passing_lane", self.slow_passing_lane), ("merge", self.merge)):
            if on:
                out.add(name)
        return frozenset(out)


def _close_stall(lanes: RouteLanes, sc: Scenario, cfg: StressConfig) -> bool:
    lo, hi = cfg.close_stall_ahead_m
    for st in sc.stalled:
        gap = st.pos_m - st.length_m - sc.ego.pos_m
        if lo - 1.0 <= gap <= hi + 1.0 and lanes.same_lane(sc.ego.pos_m, sc.ego.lane, st.pos_m,
                                                           st.lane):
            return True
    return False


def _slow_passing(network: RoadNetwork, sc: Scenario) -> bool:
    tr = sc.traffic
    if tr is None or tr.lane_speeds_mps is None or tr.vehicles_per_hour <= 0:
        return False
    passing = max(li.index for li in network.lane_info(sc.route[:1])
                  if li.allows_passenger and not li.is_shoulder)
    speed = tr.lane_speed_mps(passing)
    return speed is not None and speed < sc.ego.speed_mps


def measure(sc: Scenario, cfg: StressConfig) -> ScenarioFeatures:
    """The measured features of one loaded scenario."""
    network = RoadNetwork.load(sc.net_path)
    lanes = RouteLanes(network, sc.route)
    k = lanes.edge_index(sc.ego.pos_m)
    radius, turn = lane_curvature(lanes.centreline(sc.ego.pos_m, sc.ego.lane))
    close = _close_stall(lanes, sc, cfg)
    return ScenarioFeatures(
        name=sc.name, real=sc.net_path.parent.name == REAL_DIR,
        through_lanes=len(lanes.through(k)),
        shoulder=any(li.is_shoulder for li in network.lane_info(sc.route)),
        min_radius_m=radius, turn_deg=turn, stalled=len(sc.stalled), close_stall=close,
        ego_speed_mps=sc.ego.speed_mps,
        traffic_vph=sc.traffic.vehicles_per_hour if sc.traffic is not None else 0.0,
        slow_passing_lane=_slow_passing(network, sc),
        merge=any(r.vehicles_per_hour > 0 for r in sc.ramp_traffic), friction=sc.friction)


def measure_catalog(catalog: Catalog, cfg: StressConfig) -> list[ScenarioFeatures]:
    """:func:`measure` of every scenario family once (controller sweep variants share it)."""
    seen: dict[str, ScenarioFeatures] = {}
    for sc in catalog:
        if sc.family not in seen:
            seen[sc.family] = measure(sc, cfg)
    return list(seen.values())


@dataclass(frozen=True)
class Coverage:
    """Counts of every feature and the ranges of the drawn numbers over a catalog."""

    scenarios: int
    counts: dict[str, int]
    ego_speed_mps: tuple[float, float]
    traffic_vph: tuple[float, float]
    curve_radius_m: tuple[float, float]
    curve_turn_deg: tuple[float, float]
    stalled: tuple[int, int]

    @classmethod
    def of(cls, features: Iterable[ScenarioFeatures], cfg: StressConfig) -> Coverage:
        items = list(features)
        counts = {name: 0 for name in FEATURES}
        for f in items:
            for name in f.features(cfg):
                counts[name] = counts.get(name, 0) + 1
        curved = [f for f in items if not f.real and math.isfinite(f.min_radius_m)]

        def span(values: list[float]) -> tuple[float, float]:
            return (min(values), max(values)) if values else (math.nan, math.nan)

        stalled = [f.stalled for f in items]
        return cls(
            scenarios=len(items), counts=counts,
            ego_speed_mps=span([f.ego_speed_mps for f in items]),
            traffic_vph=span([f.traffic_vph for f in items]),
            curve_radius_m=span([f.min_radius_m for f in curved]),
            curve_turn_deg=span([f.turn_deg for f in curved]),
            stalled=(min(stalled), max(stalled)) if stalled else (0, 0))

    def missing(self, expect_real: bool) -> list[str]:
        """Features no scenario has (``real_net`` only if real nets were expected)."""
        return [name for name in FEATURES if self.counts.get(name, 0) == 0
                and (name != "real_net" or expect_real)]

    def lines(self) -> list[str]:
        """A readable summary, one line per feature, then the ranges."""
        out = [f"{name:<18} {self.counts.get(name, 0):>5}" for name in FEATURES]
        out += [f"ego speed          {self.ego_speed_mps[0]:.1f}..{self.ego_speed_mps[1]:.1f} m/s",
                f"traffic            {self.traffic_vph[0]:.0f}..{self.traffic_vph[1]:.0f} veh/h",
                f"curve radius       {self.curve_radius_m[0]:.0f}..{self.curve_radius_m[1]:.0f} m"
                " (the ego's lane)",
                f"curve turn         {self.curve_turn_deg[0]:.1f}.."
                f"{self.curve_turn_deg[1]:.1f} deg",
                f"stalled cars       {self.stalled[0]}..{self.stalled[1]}"]
        return out
