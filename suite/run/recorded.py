"""The recorded driver (controller ``recorded``): the ego drives its own recording.

A scenario whose ``replay.ego_track`` names a track of its tracks file (the recorded
ego: docs/recorded.md) can run the controller ``recorded``: the ego then moves along that
track, its pose pushed into the world each step as the plant's would be (and as the
replayed cars' are), while the loop's controller stage commands nothing
(:class:`RecordedDrivesEgo`). The metrics judge the run like any other: nuPlan's
log-replay expert, the human's verdict beside the controllers'.

The track's samples (n,) at run times t_i [s]: box centre c_i [m], heading psi_i [rad,
unwrapped], speed v_i [m/s]. At control step j, run time t_j = j dt (dt = ``step_s``,
j = 0..J with J = floor(t_end / dt + 1e-6): the last step inside the track), clipped to
[t_0, t_end]:

    c(t_j), psi(t_j), v(t_j)    linear interpolation between the samples around t_j
    a_i = dv/dt (t_i), r_i = dpsi/dt (t_i)
                                finite differences of the samples (np.gradient: central,
                                second order inside, one-sided at the ends)
    a(t_j), r(t_j)              linear interpolation of those
    front bumper  f = c + (L/2) (cos psi, sin psi)        pushed into the world
    CG            g = c - d (cos psi, sin psi)            d = cg_to_box_centre_m

and the ego's state is [g_x, g_y, psi, v, 0, r] with longitudinal acceleration a, lateral
acceleration v r, steer and torque NaN (not known, as for SUMO's driver). Interpolating
the finite differences, rather than differentiating the interpolated speed, keeps the
acceleration continuous between samples (the latter steps at every sample, a jerk of
Delta a / dt that the recording does not have).

**The recorded box.** The ego is the recorded vehicle: its box is the track's length L x
width W (:func:`recorded_vehicle`: hwyeval's car scaled along its length to L, so the
CG keeps its place in the body, 0.2 L / 4.8 behind the box centre), in SUMO as in the
metrics. Its collisions are therefore the recording's own.

**The end.** The track ends the run: after its last sample (t_j > t_end) the ego leaves
the simulation, as a replayed car does after its last sample (the loop's stop reason
``the ego left the simulation``). An imported catalog sets ``duration_s`` to the ego
track's end, so the recorded run and the controller's cover the same time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from controllers.baselines.recorded_driver import RecordedDriverModel
from controllers.plant.vehicle_model import VehicleParams
from controllers.protocol import (
    Command,
)
from reports.geometry import box_front
from suite.catalog import Scenario
from suite.catalog.tracks import EGO_TRACK_START_TOL_S, Track, read_tracks
from suite.run.dynamics import DrivenEgoStage
from suite.run.ego import EgoProjector, EgoState, FloatArray
from suite.world.protocol import EgoPose, Scene, World

__all__ = ["RecordedDrivesEgo", "RecordedDynamics", "RecordedPath", "recorded_track",
           "recorded_vehicle"]

_STEP_TOL = 1e-6  # a control step this close (in steps) to the track's end is inside it


def recorded_track(scenario: Scenario) -> Track:
    """The ego's recorded track of ``scenario`` (``replay.ego_track`` of its tracks
    file); ValueError naming the scenario and the key when it has none."""
    replay = scenario.replay
    if replay is None or replay.ego_track is None or replay.tracks_path is None:
        raise ValueError(f"scenario {scenario.name!r}: controller 'recorded' needs "
                         "replay.ego_track, the ego's recorded track, and it names none")
    track = read_tracks(replay.tracks_path).by_id().get(replay.ego_track)
    if track is None:
        raise ValueError(f"scenario {scenario.name!r}: replay.ego_track "
                         f"{replay.ego_track!r} is no track of {replay.tracks_path}")
    return track


def recorded_vehicle(vehicle: VehicleParams, length_m: float, width_m: float) -> VehicleParams:
    """``vehicle`` with the recorded box ``length_m`` x ``width_m`` [m]: its axles and
    front overhang scaled by length_m / vehicle.length_m, so that the CG keeps its place
    in the body (and the parameters stay consistent for any length > 0)."""
    if not (math.isfinite(length_m) and length_m > 0.0 and math.isfinite(width_m)
            and width_m > 0.0):
        raise ValueError(f"recorded box: expected a length and width > 0 m, got "
                         f"{length_m!r} x {width_m!r}")
    k = length_m / vehicle.length_m
    return replace(vehicle, length_m=length_m, width_m=width_m,
                   cg_to_front_axle_m=vehicle.cg_to_front_axle_m * k,
                   cg_to_rear_axle_m=vehicle.cg_to_rear_axle_m * k,
                   front_overhang_m=vehicle.front_overhang_m * k)


@dataclass(frozen=True, eq=False)
class RecordedPath:
    """A recorded track at the control steps j = 0..J (module docstring), arrays (J+1,):
    run time ``t_s`` [s], box centre ``x_m``/``y_m`` [m], heading ``heading_rad`` [rad],
    speed ``speed_mps`` [m/s], longitudinal acceleration ``accel_mps2`` [m/s²], yaw rate
    ``yaw_rate_radps`` [rad/s]; ``track_id`` the track it comes from."""

    track_id: str
    step_s: float
    t_s: FloatArray
    x_m: FloatArray
    y_m: FloatArray
    heading_rad: FloatArray
    speed_mps: FloatArray
    accel_mps2: FloatArray
    yaw_rate_radps: FloatArray

    _ARRAYS: ClassVar[tuple[str, ...]] = ("t_s", "x_m", "y_m", "heading_rad", "speed_mps",
                                          "accel_mps2", "yaw_rate_radps")

    def __post_init__(self) -> None:
        if not (math.isfinite(self.step_s) and self.step_s > 0.0):
            raise ValueError(f"{self.track_id}: step_s: expected > 0, got {self.step_s!r}")
        n = self.t_s.shape[0]
        if self.t_s.ndim != 1 or n < 1:
            raise ValueError(f"{self.track_id}: t_s: expected shape (n,) with n >= 1, got "
                             f"{self.t_s.shape}")
        for name in self._ARRAYS:
            arr = getattr(self, name)
            if arr.shape != (n,):
                raise ValueError(f"{self.track_id}: {name}: expected shape ({n},), got "
                                 f"{arr.shape}")
            if not bool(np.all(np.isfinite(arr))):
                raise ValueError(f"{self.track_id}: {name}: expected finite values")

    @classmethod
    def from_track(cls, track: Track, step_s: float) -> RecordedPath:
        """``track`` resampled at the control steps of period ``step_s`` [s] from run
        time 0 (the track must start there: ValueError otherwise)."""
        if abs(track.start_s) > EGO_TRACK_START_TOL_S:  # the catalog's check
            raise ValueError(f"{track.track_id}: the recorded ego's track must start at run "
                             f"time 0, it starts at {track.start_s:g} s")
        last = math.floor(track.end_s / step_s + _STEP_TOL)
        t = np.clip(np.arange(last + 1, dtype=np.float64) * step_s, track.start_s, track.end_s)
        if track.time_s.shape[0] > 1:
            accel = np.gradient(track.speed_mps, track.time_s)
            yaw_rate = np.gradient(track.heading_rad, track.time_s)
        else:
            accel = yaw_rate = np.zeros(1)

        def at(values: FloatArray) -> FloatArray:
            return np.asarray(np.interp(t, track.time_s, values), dtype=np.float64)

        return cls(track.track_id, float(step_s), t, at(track.x_m), at(track.y_m),
                   at(track.heading_rad), at(track.speed_mps), at(accel), at(yaw_rate))

    @property
    def last_step(self) -> int:
        """J, the last control step inside the track."""
        return int(self.t_s.shape[0]) - 1


class RecordedDynamics:
    """The ego moves along its recorded track (the EgoDynamics role; module docstring):
    each step's pose is the track's at that step's run time, pushed into ``world``."""

    externally_driven = True

    def __init__(self, path: RecordedPath, world: World, projector: EgoProjector,
                 vehicle: VehicleParams) -> None:
        self.path = path
        self.world = world
        self.projector = projector
        self.vehicle = vehicle
        self._j = 0
        self._scene: Scene | None = None

    def pose(self, j: int) -> EgoPose:
        """The front bumper pose at control step ``j`` (what SUMO gets)."""
        p = self.path
        psi = float(p.heading_rad[j])
        fx, fy = box_front(float(p.x_m[j]), float(p.y_m[j]), psi, self.vehicle.length_m)
        return EgoPose(fx, fy, psi)

    def state(self, j: int) -> FloatArray:
        """(6,) [X_m, Y_m, psi_rad, u_mps, v_mps, r_radps] of the CG at control step ``j``."""
        p, d = self.path, self.vehicle.cg_to_box_centre_m
        psi = float(p.heading_rad[j])
        return np.array([float(p.x_m[j]) - d * math.cos(psi),
                         float(p.y_m[j]) - d * math.sin(psi), psi,
                         float(p.speed_mps[j]), 0.0, float(p.yaw_rate_radps[j])])

    def _ego(self, j: int, scene: Scene) -> EgoState:
        state = self.state(j)
        s, y, e = self.projector.project(state)
        return EgoState(state, float(self.path.accel_mps2[j]), float(state[3] * state[5]),
                        math.nan, math.nan, s, y, e, scene.ego, self.projector.at(s, y, e))

    def start(self) -> tuple[EgoState, Scene]:
        self._j = 0
        self._scene = self.world.start(self.pose(0))
        return self._ego(0, self._scene), self._scene

    def advance(self, command: Command) -> tuple[EgoState | None, Scene]:
        del command  # the recording drives
        if self._scene is None:
            raise RuntimeError("RecordedDynamics.advance before start")
        if self._j >= self.path.last_step:
            return None, self._scene  # the track has ended: the ego leaves
        self._j += 1
        self._scene = self.world.step(self.pose(self._j))
        return self._ego(self._j, self._scene), self._scene


class RecordedDrivesEgo(DrivenEgoStage):
    """The loop's controller stage when the recording drives: commands nothing (NaN);
    its parameters say which track and box it drives."""

    def __init__(self, model: RecordedDriverModel, track: Track) -> None:
        super().__init__(model.name, {
            **model.parameters(), "ego_track": track.track_id,
            "samples": int(track.time_s.shape[0]), "end_s": track.end_s,
            "length_m": track.length_m, "width_m": track.width_m})
        self.model = model
        self.track = track
