"""A scripted entity's motion under its actions: one longitudinal and one lateral
action at a time (a new one in the same domain replaces the running one), integrated
every step dt: pos += v dt along the route, the lateral place y from its transition.

* SpeedAction: v(t) = v0 + (v1 - v0) f(u), u = elapsed time / T with T = value
  (time), |v1 - v0| / rate (rate) or, over a distance D, the time a uniform change
  covers D in: T = 2 D / (v0 + v1); done at u = 1 (a continuous relative target keeps
  following its entity afterwards).
* LaneChangeAction: y from its place to the target lane's centre + target offset over
  T = value (time), D = value / v0 (distance) or |dy| / rate (rate: the mean lateral
  speed, so a change across a lane of width w at rate v_y ends at w / v_y).
* LaneOffsetAction: y to the lane's centre + offset with the shape's peak lateral
  acceleration (:func:`~suite.world.storyboard.profiles.lane_offset_duration_s`).
* TeleportAction: at once. LongitudinalDistanceAction: the gap taken at once (and held
  every step when continuous), the reference's speed. FollowTrajectoryAction: the
  polyline's place at the elapsed time (linear between vertices), its speed the rate
  of change of that place.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from reports.geometry import box_front
from suite.catalog import storyboard as sb
from suite.world.storyboard.profiles import lane_offset_duration_s, shape, transition_duration
from suite.world.storyboard.road import LaneRoad, lane_centre_y, lane_of
from suite.world.storyboard.state import EntityView

__all__ = ["Motion", "Running"]


@dataclass
class Running:
    """A started action: the action, start time [s], start values (pos [m], v [m/s],
    y [m]), its target (speed [m/s] or y [m]) and length T (s or m), done or not."""

    action: Any
    t0_s: float
    pos0_m: float
    v0_mps: float
    y0_m: float
    target: float = 0.0
    length: float = 0.0
    done: bool = False
    lane: int | None = None  # a lane change's target lane


@dataclass
class Motion:
    """One scripted entity's state (front bumper route position [m], lateral place y
    [m], speed [m/s], travelled [m], heading from its lane [rad]) and running actions."""

    entity: sb.Entity
    pos_m: float
    y_m: float
    speed_mps: float
    travelled_m: float = 0.0
    heading_rad: float = 0.0
    longitudinal: Running | None = None
    lateral: Running | None = None

    # ------------------------------------------------------------------ start
    def start(self, action: Any, t_s: float, road: LaneRoad,
              views: Mapping[str, EntityView]) -> Running:
        """Start ``action`` at ``t_s`` (module docstring); returns its running record."""
        run = Running(action, t_s, self.pos_m, self.speed_mps, self.y_m)
        if isinstance(action, sb.SpeedAction):
            run.target = self._speed_target(action, views)
            run.length = (transition_duration(action.dimension, action.value,
                                              run.target - self.speed_mps)
                          if action.dimension != "distance" else
                          2.0 * action.value / max(self.speed_mps + run.target, 1e-9))
            self._replace("longitudinal", run)
        elif isinstance(action, sb.LaneChangeAction):
            self._start_lane_change(run, action, road, views)
        elif isinstance(action, sb.LaneOffsetAction):
            lane, _ = lane_of(road, self.pos_m, self.y_m)
            ref = views.get(action.relative_to or "")
            base = ref.y_m - lane_centre_y(road, self.pos_m, lane) if ref is not None else 0.0
            run.target = lane_centre_y(road, self.pos_m, lane) + base + action.offset_m
            run.length = lane_offset_duration_s(action.shape, run.target - self.y_m,
                                                action.max_lateral_acc_mps2)
            self._replace("lateral", run)
        elif isinstance(action, sb.TeleportAction):
            self._teleport(action, road, views)
            run.done = True
        elif isinstance(action, sb.LongitudinalDistanceAction):
            self._keep_distance(action, views)
            run.done = not action.continuous
            if action.continuous:
                self._replace("longitudinal", run)
        elif isinstance(action, sb.FollowTrajectoryAction):
            self._replace("longitudinal", run)
            self._replace("lateral", run)
        else:  # ActivateControllerAction: nothing moves
            run.done = True
        return run

    def _replace(self, slot: str, run: Running) -> None:
        old: Running | None = getattr(self, slot)
        if old is not None and old is not run:
            old.done = True  # overridden
        setattr(self, slot, run)

    def _speed_target(self, a: sb.SpeedAction, views: Mapping[str, EntityView]) -> float:
        if a.relative_to is None:
            return max(a.target, 0.0)
        ref = views[a.relative_to].speed_mps if a.relative_to in views else self.speed_mps
        return max(ref + a.target if a.relative_kind == "delta" else ref * a.target, 0.0)

    def _start_lane_change(self, run: Running, a: sb.LaneChangeAction, road: LaneRoad,
                           views: Mapping[str, EntityView]) -> None:
        if a.relative is not None:
            ref = views.get(a.relative.entity)
            base = lane_of(road, self.pos_m, ref.y_m if ref else self.y_m)[0]
            lane = base + a.relative.value
        else:
            lane = int(a.lane or 0)
        lane = min(max(lane, 0), len(road.widths(self.pos_m)) - 1)
        run.lane = lane
        run.target = lane_centre_y(road, self.pos_m, lane) + a.target_offset_m
        change = run.target - self.y_m
        run.length = (a.value if a.dimension == "time" else
                      a.value if a.dimension == "distance" else
                      transition_duration("rate", a.value, change))
        self._replace("lateral", run)

    def _teleport(self, a: sb.TeleportAction, road: LaneRoad,
                  views: Mapping[str, EntityView]) -> None:
        if a.position is not None:
            self.pos_m = a.position.pos_m
            self.y_m = lane_centre_y(road, a.position.pos_m, a.position.lane) \
                + a.position.lateral_m
            return
        ref = views[str(a.relative_to)]
        lane, _ = lane_of(road, ref.pos_m, ref.y_m)
        self.pos_m = ref.ref_pos_m + a.ds_m + self.entity.front_m
        self.y_m = lane_centre_y(road, self.pos_m, lane + a.dlane) + a.lateral_m

    def _keep_distance(self, a: sb.LongitudinalDistanceAction,
                       views: Mapping[str, EntityView]) -> None:
        ref = views.get(a.entity_ref)
        if ref is None:
            return
        gap = a.distance_m if a.distance_m is not None else \
            float(a.time_gap_s or 0.0) * ref.speed_mps
        if a.ahead:
            self.pos_m = ref.pos_m + gap + (self.entity.length_m if a.freespace else 0.0)
        else:
            self.pos_m = ref.pos_m - gap - (ref.entity.length_m if a.freespace else 0.0)
        self.speed_mps = ref.speed_mps

    # ------------------------------------------------------------------ advance
    def advance(self, t_s: float, dt_s: float, road: LaneRoad,
                views: Mapping[str, EntityView]) -> None:
        """Move from ``t_s`` to ``t_s + dt_s`` [s] under the running actions."""
        t1 = t_s + dt_s
        lon, lat = self.longitudinal, self.lateral
        if lon is not None and isinstance(lon.action, sb.FollowTrajectoryAction) \
                and not lon.done:
            self._trajectory(lon, t1, dt_s, road)
            return
        v_old, y_old = self.speed_mps, self.y_m
        if lon is not None and not lon.done or (lon is not None and _continuous(lon)):
            self._advance_speed(lon, t1, views)
        self.pos_m += 0.5 * (v_old + self.speed_mps) * dt_s
        self.travelled_m += 0.5 * (v_old + self.speed_mps) * dt_s
        if lat is not None and not lat.done:
            self._advance_lateral(lat, t1)
        moved = 0.5 * (v_old + self.speed_mps) * dt_s
        if moved > 1e-9 or abs(self.y_m - y_old) > 1e-9:  # a still entity keeps its heading
            self.heading_rad = math.atan2(self.y_m - y_old, max(moved, 1e-9))

    def _advance_speed(self, run: Running, t1: float, views: Mapping[str, EntityView]) -> None:
        a = run.action
        if isinstance(a, sb.LongitudinalDistanceAction):
            self._keep_distance(a, views)
            return
        if run.done:  # a continuous relative target after its transition
            self.speed_mps = self._speed_target(a, views)
            return
        u = _progress("time", run, t1, self.pos_m)
        self.speed_mps = max(run.v0_mps + (run.target - run.v0_mps) * shape(a.shape, u), 0.0)
        if u >= 1.0:
            run.done = True

    def _advance_lateral(self, run: Running, t1: float) -> None:
        a = run.action
        dim = a.dimension if isinstance(a, sb.LaneChangeAction) else "time"
        u = _progress(dim, run, t1, self.pos_m)
        self.y_m = run.y0_m + (run.target - run.y0_m) * shape(a.shape, u)
        if u >= 1.0:
            run.done = True

    def _trajectory(self, run: Running, t1: float, dt_s: float, road: LaneRoad) -> None:
        a: sb.FollowTrajectoryAction = run.action
        tau = (t1 - run.t0_s - a.offset_s) / a.scale
        vs = a.vertices
        tau = min(max(tau, vs[0].t_s), vs[-1].t_s)
        k = max(i for i in range(len(vs) - 1) if vs[i].t_s <= tau) if tau > vs[0].t_s else 0
        v0, v1 = vs[k], vs[k + 1]
        span = v1.t_s - v0.t_s
        w = (tau - v0.t_s) / span if span > 0 else 1.0
        y0 = lane_centre_y(road, v0.position.pos_m, v0.position.lane) + v0.position.lateral_m
        y1 = lane_centre_y(road, v1.position.pos_m, v1.position.lane) + v1.position.lateral_m
        pos = v0.position.pos_m + w * (v1.position.pos_m - v0.position.pos_m) \
            + self.entity.front_m
        y = y0 + w * (y1 - y0)
        step = math.hypot(pos - self.pos_m, y - self.y_m)
        self.speed_mps = step / dt_s if dt_s > 0 else 0.0
        self.travelled_m += step
        self.pos_m, self.y_m = pos, y
        self.heading_rad = v0.position.heading_rad
        if tau >= vs[-1].t_s:
            run.done = True
            self.speed_mps = 0.0

    def view(self, road: LaneRoad) -> EntityView:
        """The entity now. Its box is placed at its centre (half its length behind the
        front bumper along the route, on the lane frame there) and heads along the lane
        there: a long vehicle on a curve then sits on its lane as a real one does (its
        front's tangent would swing its rear into the inner lane by L² / 2R)."""
        half = 0.5 * self.entity.length_m
        lane, lateral = lane_of(road, self.pos_m - half, self.y_m)
        cx, cy, h = road.pose(self.pos_m - half, lane, lateral, self.heading_rad)
        x, y = box_front(cx, cy, h, self.entity.length_m)
        return EntityView(self.entity, self.pos_m, self.y_m, x, y, h, self.speed_mps,
                          self.travelled_m)


def _continuous(run: Running) -> bool:
    return bool(getattr(run.action, "continuous", False)) and not isinstance(
        run.action, sb.LaneOffsetAction)


def _progress(dimension: str, run: Running, t1: float, pos_m: float) -> float:
    """u in [0, 1] of a transition at time ``t1`` [s] and route position ``pos_m`` [m]
    (module docstring); a zero length is done at once."""
    if run.length <= 0.0:
        return 1.0
    if dimension == "distance":
        return (pos_m - run.pos0_m) / run.length
    return (t1 - run.t0_s) / run.length
