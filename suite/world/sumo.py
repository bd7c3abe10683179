"""The SUMO world: one libsumo simulation per scenario, handed over as numpy arrays.

libsumo hosts one simulation per *process* and is not thread-safe, so a
:class:`SumoWorld` must be the only one alive in its process (the executors run each
scenario in its own process).

Conventions: SUMO reports a vehicle's *front bumper* centre and a heading in navigation
degrees (0 = north, clockwise); everything leaving this module is in the suite's
convention (box *centre* [m], heading in radians counter-clockwise from +X).

The ego is inserted as a normal vehicle of type ``ego`` carrying SUMO's SSM device.
Driven from outside, its speed mode is 32 and its lane-change mode 0 and each step its
pose is pushed with ``moveToXY(..., keepRoute=2)`` (free placement, mapped to the
nearest lane) so that the other agents react to the plant's truth; otherwise SUMO's own
driver model drives it, capped at the target speed.

Multi-rate (:mod:`suite.world.multirate`): SUMO steps every ``scenario.sumo_step_s``
while :meth:`SumoWorld.step` is called every control step ``step_s``; the ego's pose is
pushed before every SUMO step, and between SUMO steps the scene holds SUMO's last state
(its view of the ego, no new collisions) with the other vehicles extrapolated at
constant speed along their headings. When SUMO's driver drives the ego it is the ego's
plant, so SUMO then steps every ``step_s``.

Collisions: SUMO runs with ``--collision.action warn`` and ``--collision.stoptime 0``, so
a collision it registers is only reported (``Scene.collisions``, collisions.xml): no
vehicle is teleported, removed or stopped. Without its sublane model SUMO judges
collisions along the lane (same lane, overlapping lane positions, 1-D), so its report is
recorded beside the 2-D box test the verdict rests on (docs/metrics.md).

Recorded traffic (``scenario.replay``, :mod:`suite.world.replay`): the recorded vehicles
are moved to their recorded poses before every SUMO step, the time of SUMO step k of
the run being k ``sumo_step_s`` (run time 0 = the recording's initial step); in reactive
mode they are tested for their handover after each step. A scenario with recorded
traffic always takes the start's second SUMO step (the one that places the ego when it
is driven from outside), so that the recorded vehicles of run time 0 are in the first
scene.
"""

from __future__ import annotations

import bisect
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from controllers.behaviour.types import Traffic
from controllers.plant.vehicle_model import VehicleParams
from reports.geometry import (
    arc_lengths_m,
    box_centre_from_front,
    box_centres_from_fronts,
    math_rad_to_nav_deg,
    nav_deg_to_math_rad,
    nav_deg_to_math_rad_scalar,
)
from reports.record import ReplaySummary, StalledVehicle, SumoCollision
from suite.catalog import Scenario
from suite.catalog.tracks import read_tracks
from suite.road.network import RoadNetwork
from suite.world.actors import ActorScript
from suite.world.multirate import MultiRate, extrapolate_traffic, headings
from suite.world.protocol import EgoPose, Scene, WorldEgo, WorldSummary
from suite.world.replay import HandoverEgo, ReplayAgents
from suite.world.route_position import route_position_m
from suite.world.routes import EGO_ID, STALLED_PREFIX, RouteFile
from suite.world.ssm import parse_ssm
from suite.world.storyboard import StoryRunner

HAZARD_SIGNAL = 1 << 2  # SUMO VEH_SIGNAL_BLINKER_EMERGENCY
# The ego's subscribed variables (traci.constants' codes: VAR_POSITION, VAR_ANGLE,
# VAR_SPEED, VAR_ACCELERATION, VAR_LANE_INDEX, VAR_ROAD_ID, VAR_LANE_ID,
# VAR_LANEPOSITION), read once per SUMO step by SumoWorld._ego.
_POSITION, _ANGLE, _SPEED, _ACCELERATION = 0x42, 0x43, 0x40, 0x72
_LANE_INDEX, _ROAD_ID, _LANE_ID, _LANE_POSITION = 0x52, 0x50, 0x51, 0x56
_EGO_VARS = (_POSITION, _ANGLE, _SPEED, _ACCELERATION, _LANE_INDEX, _ROAD_ID, _LANE_ID,
             _LANE_POSITION)
SENSING_RADIUS_M = 300.0  # vehicles this close to the ego are reported every step
# The heading conversions live in reports.geometry.poses; re-exported here for callers.
__all__ = ["HAZARD_SIGNAL", "SENSING_RADIUS_M", "SumoWorld", "math_rad_to_nav_deg",
           "nav_deg_to_math_rad", "nav_deg_to_math_rad_scalar", "sumo_binary"]


def sumo_binary() -> str:
    import sumo_nets

    return os.path.join(sumo_nets.sumo_home(), "bin", "sumo")


class SumoWorld:
    """A running libsumo simulation for one scenario (the :class:`World` role).

    ``work_dir`` receives the generated route file and SUMO's own outputs (SSM,
    collisions). Sensing reaches further than what is logged: the side choice needs to
    see the target lane over the whole manoeuvre (planning range + gap window).
    """

    def __init__(self, scenario: Scenario, network: RoadNetwork, vehicle: VehicleParams,
                 work_dir: Path, *, externally_driven: bool) -> None:
        self.scenario = scenario
        self.network = network
        self.vehicle = vehicle
        self.work_dir = Path(work_dir)
        self.externally_driven = externally_driven
        self._routes = RouteFile(scenario, network, vehicle, self.ssm_file, externally_driven)
        triggered = any(ev.when is not None for a in scenario.actors for ev in a.events)
        self._actors = ActorScript(scenario.actors, self._route_pos if triggered else None,
                                   EGO_ID)
        self._edge_starts_m = network.route_edge_starts_m(tuple(scenario.route))
        self._radius_m = max(float(scenario.record_radius_m), SENSING_RADIUS_M)
        self._ls: Any = None
        self._tc: Any = None
        self._t_origin = 0.0
        self._collisions: list[SumoCollision] = []
        self._stalled: tuple[StalledVehicle, ...] = ()
        # lane id -> (cumulative shape length scaled to the lane's length, segment headings)
        self._lane_geometry: dict[str, tuple[list[float], list[float]]] = {}
        self.rate = MultiRate(scenario.steps_per_world_step if externally_driven else 1,
                              float(scenario.step_s))
        self._k = 0  # control steps since the start
        self._held: Scene | None = None  # the scene of SUMO's last step
        # cos, sin of its vehicles' headings (held until the next SUMO step)
        self._held_dir: tuple[np.ndarray, np.ndarray] | None = None
        self._replay: ReplayAgents | None = None
        self._replay_origin_s = 0.0  # SUMO time of the run's t = 0, known before it
        # the OpenSCENARIO storyboard (suite.world.storyboard), if the scenario has one
        self._story = (StoryRunner(scenario.story, network, tuple(scenario.route),
                                   float(scenario.ego.pos_m))
                       if scenario.story is not None else None)
        self._story_origin_s = 0.0  # SUMO time of the run's t = 0, known before it

    @property
    def ssm_file(self) -> Path:
        """SUMO writes the SSM log when the simulation closes."""
        return self.work_dir / "ssm.xml"

    # ------------------------------------------------------------------ World
    def start(self, ego_pose: EgoPose | None) -> Scene:
        import libsumo
        import traci.constants as tc

        self.work_dir.mkdir(parents=True, exist_ok=True)
        routes = self.work_dir / "routes.rou.xml"
        routes.write_text(self._routes.xml())
        try:
            libsumo.start(self._sumo_args(routes))
        except Exception as exc:  # libsumo's TraCIException says only "Process Error"
            said = self._sumo_errors()
            raise RuntimeError(f"SUMO did not start: {exc}"
                               + (f"; SUMO's error log: {said}" if said else "")) from exc
        self._ls, self._tc = libsumo, tc
        libsumo.simulationStep()  # inserts the vehicles departing at t = 0
        sc = self.scenario
        if EGO_ID not in libsumo.vehicle.getIDList():
            raise RuntimeError(
                f"SUMO could not insert the ego at lane {sc.ego.lane}, pos {sc.ego.pos_m} m "
                f"(occupied or invalid); see {routes}")
        for vid in self._routes.stalled_ids:
            if vid in libsumo.vehicle.getIDList():
                libsumo.vehicle.setSignals(vid, HAZARD_SIGNAL)
        self._actors.start(libsumo)
        if self._story is not None:
            self._story.start(libsumo)
            self._story_origin_s = self._time() + self.rate.world_step_s
        self._start_replay(libsumo, ego_pose is not None)
        if self.externally_driven:
            libsumo.vehicle.setSpeedMode(EGO_ID, 32)
            libsumo.vehicle.setLaneChangeMode(EGO_ID, 0)
        else:
            libsumo.vehicle.setMaxSpeed(EGO_ID, float(sc.ego.target_speed_mps))
        libsumo.vehicle.subscribe(EGO_ID, list(_EGO_VARS))
        libsumo.vehicle.subscribeContext(
            EGO_ID, tc.CMD_GET_VEHICLE_VARIABLE, self._radius_m,
            [tc.VAR_POSITION, tc.VAR_ANGLE, tc.VAR_SPEED, tc.VAR_LENGTH, tc.VAR_WIDTH,
             tc.VAR_LANE_INDEX, tc.VAR_ROAD_ID])
        hits: tuple[SumoCollision, ...] = ()
        if ego_pose is not None or self._replay is not None or self._story is not None:
            if ego_pose is not None:
                self._move_ego(ego_pose)
            hits = self._advance()
        self._t_origin = self._time()
        self._stalled = self._stalled_vehicles()
        self._k = 0
        self._held = self._scene(hits)
        self._held_dir = None
        return self._held

    def step(self, ego_pose: EgoPose | None) -> Scene:
        """One control step: a SUMO step (pose pushed first) every
        ``rate.steps_per_world_step`` calls, else SUMO's last scene extrapolated."""
        self._k += 1
        held = self._held
        if held is None or self.rate.is_world_step(self._k):
            if ego_pose is not None:
                self._move_ego(ego_pose)
            self._held = self._scene(self._advance())
            self._held_dir = None
            return self._held
        tau = self.rate.since_world_step_s(self._k)
        if self._held_dir is None:
            self._held_dir = headings(held.traffic)
        return Scene(t_s=held.t_s + tau,
                     traffic=extrapolate_traffic(held.traffic, tau, self._held_dir), ego=held.ego,
                     fresh=False)

    def _route_pos(self, ls: Any, vid: str) -> float:
        """A vehicle's front bumper route position [m]: its edge's start on the route plus
        its lane position; NaN on an edge off the route or inside a junction."""
        return route_position_m(ls.vehicle, vid, self._edge_starts_m)

    def close(self) -> WorldSummary:
        if self._story is not None:
            try:
                self._story.write_log(self.work_dir / "storyboard.json")
            except OSError:  # pragma: no cover - the run's own files are written later
                pass
        if self._ls is not None:
            try:
                self._ls.close()
            finally:
                self._ls = None
        try:
            times, ttcs, summary = parse_ssm(self.ssm_file)
        except Exception as exc:  # noqa: BLE001 - a malformed SSM log must not lose the run
            from reports.record import SsmSummary

            times, ttcs = np.zeros(0), np.zeros(0)
            summary = SsmSummary(error=f"{type(exc).__name__}: {exc}")
        return WorldSummary(stalled=self._stalled, collisions=tuple(self._collisions),
                            ssm=summary, ssm_times_s=times, ssm_ttc_s=ttcs,
                            t_origin_s=self._t_origin, replay=self._replay_summary())

    def storyboard_stopped_at_s(self) -> float | None:
        """The run time [s] the storyboard's stop trigger fired at (None: not yet, or
        no storyboard)."""
        return None if self._story is None else self._story.engine.stopped_at_s

    def _start_replay(self, ls: Any, ego_pose_given: bool) -> None:
        """Read the scenario's tracks (once) and prepare the recorded vehicles; the run's
        t = 0 is the end of the start's next SUMO step."""
        spec = self.scenario.replay
        if spec is None or spec.tracks_path is None:
            return
        dt = self.rate.world_step_s
        steps = int(math.ceil(float(self.scenario.duration_s) / dt)) + 2
        # the recorded ego's own track (replay.ego_track) is the ego, never traffic
        self._replay = ReplayAgents(spec, read_tracks(spec.tracks_path).without(spec.ego_track),
                                    dt, steps, tuple(self.scenario.route))
        self._replay.prepare(ls)
        self._replay_origin_s = self._time() + dt

    def _replay_summary(self) -> ReplaySummary | None:
        r = self._replay
        spec = self.scenario.replay
        if r is None or spec is None:
            return None
        return ReplaySummary(tracks=spec.tracks, mode=spec.mode, vehicles=len(r.seen),
                             handovers=tuple(r.handovers))

    # ------------------------------------------------------------------ internals
    def _sumo_args(self, routes: Path) -> list[str]:
        sc = self.scenario
        seed = int(sc.traffic.seed) if sc.traffic is not None else int(sc.seed)
        return [
            sumo_binary(), "-n", str(sc.net_path), "-r", str(routes),
            "--step-length", repr(self.rate.world_step_s), "--seed", str(seed),
            "--time-to-teleport", "-1", "--collision.mingap-factor", "0",
            # SUMO's collision check is recorded beside ours, never acted on: 'warn' reports
            # it and alters no vehicle (no teleport, no removal), stoptime 0 stops none.
            "--collision.action", "warn", "--collision.stoptime", "0",
            "--collision.check-junctions", "true",
            "--collision-output", str(self.work_dir / "collisions.xml"),
            "--no-step-log", "true", "--no-warnings", "true", "--duration-log.disable", "true",
            "--default.action-step-length", repr(self.rate.world_step_s),
            "--lanechange.duration", "3",
            "--error-log", str(self.error_log),
        ]

    @property
    def error_log(self) -> Path:
        """SUMO's own error messages (its reason when it refuses to start)."""
        return self.work_dir / "sumo_errors.txt"

    def _sumo_errors(self, max_chars: int = 600) -> str:
        """The last of SUMO's error messages, on one line."""
        try:
            text = self.error_log.read_text(errors="replace").strip()
        except OSError:
            return ""
        return " ".join(text.split())[-max_chars:]

    def _time(self) -> float:
        return float(self._ls.simulation.getTime())

    def _move_ego(self, pose: EgoPose) -> None:
        self._ls.vehicle.moveToXY(EGO_ID, "", -1, float(pose.front_x_m), float(pose.front_y_m),
                                  math_rad_to_nav_deg(pose.heading_rad), keepRoute=2)

    def _advance(self) -> tuple[SumoCollision, ...]:
        """One SUMO step (the actors' commands first); the collisions involving the ego."""
        self._actors.apply(self._ls, self._time() - self._t_origin)
        if self._story is not None:
            self._story.apply(self._ls, self._time() - self._story_origin_s,
                              self.rate.world_step_s)
        if self._replay is not None:
            dt = self.rate.world_step_s
            self._replay.apply(self._ls, int(round(
                (self._time() + dt - self._replay_origin_s) / dt)))
        self._ls.simulationStep()
        t = self._time()
        hits = tuple(SumoCollision(t_s=t, collider=str(c.collider), victim=str(c.victim),
                                   type=str(c.type))
                     for c in self._ls.simulation.getCollisions()
                     if EGO_ID in (c.collider, c.victim))
        self._collisions.extend(hits)
        return hits

    def _scene(self, hits: tuple[SumoCollision, ...]) -> Scene:
        ego = self._ego() if EGO_ID in self._ls.vehicle.getIDList() else None
        traffic = self._traffic() if ego is not None else Traffic.empty()
        t_s = self._time() - self._t_origin
        if self._replay is not None and ego is not None:
            self._replay.observe(self._ls, self._handover_ego(ego), traffic, t_s)
        return Scene(t_s=t_s, traffic=traffic, ego=ego, collisions=hits)

    def _handover_ego(self, ego: WorldEgo) -> HandoverEgo:
        """The ego's SUMO box for the handover rule (centre from the front bumper)."""
        cx, cy = box_centre_from_front(ego.front_x_m, ego.front_y_m, ego.heading_rad,
                                       float(self.vehicle.length_m))
        return HandoverEgo(cx, cy, ego.heading_rad, ego.speed_mps, float(self.vehicle.length_m),
                           float(self.vehicle.width_m), ego.road_id, ego.lane_index)

    def _ego(self) -> WorldEgo:
        """The ego from its variable subscription (:data:`_EGO_VARS`, the values of the
        eight getters, read in one call)."""
        r = self._ls.vehicle.getSubscriptionResults(EGO_ID)
        x, y = r[_POSITION]
        return WorldEgo(front_x_m=float(x), front_y_m=float(y),
                        heading_rad=nav_deg_to_math_rad_scalar(float(r[_ANGLE])),
                        speed_mps=float(r[_SPEED]), accel_mps2=float(r[_ACCELERATION]),
                        lane_index=int(r[_LANE_INDEX]), road_id=str(r[_ROAD_ID]),
                        lane_heading_rad=self._lane_heading(str(r[_LANE_ID]),
                                                            float(r[_LANE_POSITION])))

    def _lane_heading(self, lane_id: str, pos_m: float) -> float:
        """Heading [rad] of the segment of lane ``lane_id``'s polyline at position ``pos_m``
        (SUMO's lane positions run along the lane's length, its shape scaled to it)."""
        if not lane_id:
            return math.nan
        geom = self._lane_geometry.get(lane_id)
        if geom is None:
            shape = np.asarray(self._ls.lane.getShape(lane_id), dtype=np.float64).reshape(-1, 2)
            if len(shape) < 2:
                return math.nan
            seg = np.diff(shape, axis=0)
            arc = arc_lengths_m(shape)
            length = float(self._ls.lane.getLength(lane_id))
            scale = length / arc[-1] if arc[-1] > 0 else 1.0
            # lists and bisect: numpy's dispatch costs more than the search on a scalar
            geom = ((arc * scale).tolist(), np.arctan2(seg[:, 1], seg[:, 0]).tolist())
            self._lane_geometry[lane_id] = geom
        cum, heading = geom
        k = min(max(bisect.bisect_right(cum, pos_m) - 1, 0), len(heading) - 1)
        return heading[k]

    def _traffic(self) -> Traffic:
        """Vehicles within the sensing radius of the ego (the ego excluded)."""
        tc = self._tc
        res = self._ls.vehicle.getContextSubscriptionResults(EGO_ID)
        ids = tuple(vid for vid in res if vid != EGO_ID)
        if not ids:
            return Traffic.empty()
        rows = [res[vid] for vid in ids]
        pos, ang, spd, lng, wid, lane = (tc.VAR_POSITION, tc.VAR_ANGLE, tc.VAR_SPEED,
                                         tc.VAR_LENGTH, tc.VAR_WIDTH, tc.VAR_LANE_INDEX)
        # One pass over the rows into a (n, 7) table (lane indices are small integers,
        # exact as floats): the same numbers as a comprehension per column.
        table = np.array([(r[pos][0], r[pos][1], r[ang], r[spd], r[lng], r[wid], r[lane])
                          for r in rows], dtype=np.float64)
        fx, fy, length = table[:, 0], table[:, 1], table[:, 4]
        heading = nav_deg_to_math_rad(table[:, 2])
        cx, cy = box_centres_from_fronts(fx, fy, heading, length)
        return Traffic(
            ids=ids, x_m=cx, y_m=cy, heading_rad=heading,
            speed_mps=table[:, 3].copy(), length_m=length.copy(), width_m=table[:, 5].copy(),
            lane_index=table[:, 6].astype(np.int64),
            road_id=tuple(str(r[tc.VAR_ROAD_ID]) for r in rows),
            stalled=np.array([vid.startswith(STALLED_PREFIX) for vid in ids], dtype=bool),
            agent=self._replay.agents(ids) if self._replay is not None
            else np.zeros(len(ids), dtype=np.int8))

    def _stalled_vehicles(self) -> tuple[StalledVehicle, ...]:
        """Every stalled vehicle's box (centre, heading) and lane, wherever the ego is."""
        v = self._ls.vehicle
        present = set(v.getIDList())
        out = []
        for vid in self._routes.stalled_ids:
            if vid not in present:
                continue
            fx, fy = v.getPosition(vid)
            heading = float(nav_deg_to_math_rad(v.getAngle(vid)))
            length = float(v.getLength(vid))
            cx, cy = box_centre_from_front(fx, fy, heading, length)
            out.append(StalledVehicle(
                id=vid, x_m=cx, y_m=cy, heading_rad=heading,
                length_m=length, width_m=float(v.getWidth(vid)),
                lane_index=int(v.getLaneIndex(vid))))
        return tuple(out)
