"""``r157_reference``: UN R157's careful and competent human driver, as a baseline.

UN Regulation No. 157 (ALKS) gives, in its guidance on traffic disturbance critical
scenarios, a performance model of a careful and competent human driver: the
collisions such a driver avoids are the ones an ALKS must avoid. This controller drives
that model in hwyeval's worlds (docs/baselines.md gives every value with the place in
the regulation it comes from, and what the regulation leaves open):

* **Lateral**: it keeps its lane, the reference lane, with the ``lane_keep`` baseline's
  pure pursuit (:class:`controllers.baselines.lane_keep.LaneKeepController`, composed:
  only its steering is used). It never changes lanes, whatever the behaviour proposes.
* **Normal driving** (not in the model, which defines the critical reaction only): the
  scenario's set speed V_t (the context's; the behaviour's lowered speed target is not
  used: the driver reacts to other vehicles through its own laws only), a = K_c (V_t -
  V), and a time-gap law behind the lead in its lane, a = K_g (gap - d_0 - T V) + K_v
  (V_lead - V); the smaller of the two, within [-comfort deceleration, maximum
  acceleration].
* **The critical reaction** (the model): a risk is perceived at t_r when the lead in its
  lane decelerates beyond a threshold, or when a vehicle beside its lane, ahead and
  close (its bumper gap under the following gap T V, or a time to collision under
  ``critical_ttc_s``), moves towards its lane with its centre more than 0.375 m from its
  own lane's centre (the lateral wandering distance). Then (``phase``)
  1 perceiving for the risk perception time (0.4 s), 2 reacting for the reaction time
  (0.75 s) — the pedal held where it was, never accelerating — and 3 braking from
  t_b = t_r + 0.4 + 0.75 s, the deceleration ramped at the jerk J = 0.774 g / 0.6 s to
  0.774 g and held until the threat is gone: the ego no faster than that vehicle while
  it no longer brakes beyond the threshold, the ego stopped, or the vehicle out of
  sight. Over a control step [t_k, t_k + dt] the command is the ramp's value at the
  step's end, min(J (t_k + dt - t_b), 0.774 g).

The acceleration a becomes the drive torque T = R (m a + F_road(V)) as ``lane_keep``'s
does (the road load fed forward). It takes the behaviour's obstacles (its
:class:`ObstaclePolicy` with no centre offset, so each obstacle's centre is its
vehicle's): see :mod:`controllers.baselines.r157_scene` for what it reads of them.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import dataclass
from enum import IntEnum
from typing import Any, ClassVar

from controllers.baselines.lane_keep import LaneKeepController, LaneKeepParams
from controllers.baselines.r157_scene import (
    DecelerationTracker,
    Other,
    deviation_towards_ego_m,
    lead,
    obstacle_keys,
    read_others,
    time_to_collision_s,
)
from controllers.behaviour.types import ObstaclePolicy
from controllers.params import build, check_leaves, check_range, param, section, to_dict
from controllers.path.frenet import FrenetPath
from controllers.plant.vehicle_model import road_load_n
from controllers.protocol import (
    Command,
    ConfigError,
    Observation,
    ScenarioContext,
    StepDiagnostics,
)

NAME = "r157_reference"
G_MPS2 = 9.80665  # standard gravity: 0.774 g = 7.59 m/s²


class Phase(IntEnum):
    """The model's phase (the trace's ``phase``)."""

    NORMAL = 0
    PERCEIVING = 1
    REACTING = 2
    BRAKING = 3


class Trigger(IntEnum):
    """What started the critical reaction (the trace's ``trigger``)."""

    NONE = 0
    LEAD_BRAKING = 1
    CUT_IN = 2


@dataclass(frozen=True)
class R157ModelParams:
    """The performance model (docs/baselines.md: the values and their sources)."""

    risk_perception_s: float = param(0.4, "s", "risk perception (evaluation) time")
    reaction_s: float = param(0.75, "s", "from the end of perception to the start of braking")
    brake_decel_g: float = param(0.774, "g", "full braking deceleration (road friction 1.0)")
    brake_ramp_s: float = param(0.6, "s", "time from the start of braking to full braking")
    wandering_m: float = param(0.375, "m", "lateral wandering: a cut-in is perceived once a "
                               "vehicle's centre is this far from its lane's centre")
    lead_decel_threshold_mps2: float = param(5.0, "m/s²", "a lead decelerating beyond this "
                                             "is a risk (our choice, not the regulation's)")
    critical_ttc_s: float = param(2.0, "s", "a cut-in closer than this in time to collision "
                                  "(or than the following gap) is a risk (our choice)")
    stop_speed_mps: float = param(0.1, "m/s", "the ego counts as stopped below this")

    def __post_init__(self) -> None:
        check_leaves(self)
        for name in ("risk_perception_s", "reaction_s", "wandering_m", "critical_ttc_s",
                     "stop_speed_mps"):
            check_range(self, name, ge=0.0)
        for name in ("brake_decel_g", "brake_ramp_s", "lead_decel_threshold_mps2"):
            check_range(self, name, gt=0.0)

    @property
    def brake_decel_mps2(self) -> float:
        """Full braking [m/s²]: 0.774 g = 7.59 m/s²."""
        return self.brake_decel_g * G_MPS2

    @property
    def jerk_mps3(self) -> float:
        """The braking ramp's jerk [m/s³]: 0.774 g / 0.6 s = 12.65 m/s³."""
        return self.brake_decel_mps2 / self.brake_ramp_s


@dataclass(frozen=True)
class FollowParams:
    """Normal driving: set speed and time gap (not part of the regulation's model)."""

    time_gap_s: float = param(2.0, "s", "T: time gap kept behind the lead")
    standstill_gap_m: float = param(3.0, "m", "d_0: bumper gap kept at standstill")
    gap_gain_per_s2: float = param(0.2, "1/s²", "K_g: gap error -> acceleration")
    speed_gain_per_s: float = param(0.6, "1/s", "K_v: speed difference to the lead -> "
                                    "acceleration")
    cruise_gain_per_s: float = param(0.8, "1/s", "K_c: set-speed error -> acceleration")
    max_accel_mps2: float = param(1.5, "m/s²", "largest acceleration in normal driving")
    comfort_decel_mps2: float = param(3.0, "m/s²", "largest deceleration in normal driving")

    def __post_init__(self) -> None:
        check_leaves(self)
        for name in ("time_gap_s", "standstill_gap_m", "gap_gain_per_s2", "speed_gain_per_s",
                     "cruise_gain_per_s", "max_accel_mps2", "comfort_decel_mps2"):
            check_range(self, name, ge=0.0)


@dataclass(frozen=True)
class R157ReferenceParams:
    """The reference driver's options (module docstring)."""

    model: R157ModelParams = section(R157ModelParams, "the regulation's performance model")
    follow: FollowParams = section(FollowParams, "normal driving: set speed and time gap")
    steering: LaneKeepParams = section(LaneKeepParams, "lane keeping: lane_keep's pure "
                                       "pursuit (its speed options are not used)")
    detection_distance_m: float = param(150.0, "m", "vehicles closer than this are seen")

    def __post_init__(self) -> None:
        check_leaves(self)
        check_range(self, "detection_distance_m", gt=0.0)


@dataclass(frozen=True, slots=True)
class R157Diagnostics(StepDiagnostics):
    """Per step, beyond the common fields: ``phase`` (:class:`Phase`: 0 normal,
    1 perceiving, 2 reacting, 3 braking), ``trigger`` (:class:`Trigger`: 0 none, 1 lead
    braking, 2 cut-in), ``risk_t_s`` the time the risk was perceived [s] and
    ``brake_start_t_s`` the time braking starts, t_r + perception + reaction [s] (NaN in
    normal driving), ``decel_cmd_mps2`` the deceleration commanded [m/s², > 0 braking;
    normal driving's too]."""

    phase: int = 0
    trigger: int = 0
    risk_t_s: float = math.nan
    brake_start_t_s: float = math.nan
    decel_cmd_mps2: float = 0.0


@dataclass
class Timeline:
    """The critical reaction's clock: which vehicle, what triggered it and when."""

    model: R157ModelParams
    trigger: Trigger = Trigger.NONE
    key: str = ""
    risk_t_s: float = math.nan

    @property
    def brake_start_t_s(self) -> float:
        return self.risk_t_s + self.model.risk_perception_s + self.model.reaction_s

    def start(self, trigger: Trigger, key: str, t_s: float) -> None:
        self.trigger, self.key, self.risk_t_s = trigger, key, t_s

    def end(self) -> None:
        self.trigger, self.key, self.risk_t_s = Trigger.NONE, "", math.nan

    def phase(self, t_s: float) -> Phase:
        """The phase at ``t_s`` (a small tolerance absorbs the steps' float sums)."""
        if self.trigger is Trigger.NONE:
            return Phase.NORMAL
        eps = 1e-9
        if t_s + eps < self.risk_t_s + self.model.risk_perception_s:
            return Phase.PERCEIVING
        if t_s + eps < self.brake_start_t_s:
            return Phase.REACTING
        return Phase.BRAKING

    def brake_decel_mps2(self, t_end_s: float) -> float:
        """The ramp's deceleration at ``t_end_s`` [m/s²]."""
        ramp = self.model.jerk_mps3 * max(t_end_s - self.brake_start_t_s, 0.0)
        return min(ramp, self.model.brake_decel_mps2)


def _normal_accel(p: FollowParams, target_mps: float, speed_mps: float,
                  ahead: Other | None) -> float:
    """Normal driving's acceleration [m/s²] (module docstring)."""
    acc = p.cruise_gain_per_s * (target_mps - speed_mps)
    if ahead is not None:
        wanted = p.standstill_gap_m + p.time_gap_s * speed_mps
        acc = min(acc, p.gap_gain_per_s2 * (ahead.gap_m - wanted)
                  + p.speed_gain_per_s * (ahead.speed_mps - speed_mps))
    return min(max(acc, -p.comfort_decel_mps2), p.max_accel_mps2)


class R157ReferenceController:
    """The careful and competent human driver of UN R157 (module docstring)."""

    name = NAME
    diagnostics_type: ClassVar[type[StepDiagnostics]] = R157Diagnostics

    def __init__(self, params: R157ReferenceParams | None = None) -> None:
        self.params = params if params is not None else R157ReferenceParams()
        self.obstacle_policy: ObstaclePolicy | None = ObstaclePolicy(
            detection_distance_m=self.params.detection_distance_m, offset_m=0.0,
            max_obstacles=8)
        self._steering = LaneKeepController(self.params.steering)
        self._ctx: ScenarioContext | None = None
        self._path: FrenetPath | None = None
        self._tracker = DecelerationTracker()
        self._timeline = Timeline(self.params.model)
        self._held_accel = 0.0
        self._s_hint = 0.0

    def reset(self, context: ScenarioContext) -> None:
        self._ctx = context
        self._path = context.reference_path()
        self._steering.reset(context)
        self._tracker.reset(context.control_period_s)
        self._timeline = Timeline(self.params.model)
        self._held_accel = 0.0
        x, y = float(context.initial_state[0]), float(context.initial_state[1])
        self._s_hint = float(self._path.project(x, y)[0])

    def step(self, observation: Observation) -> Command:
        if self._ctx is None:
            raise RuntimeError("R157ReferenceController.step called before reset")
        t0 = time.perf_counter()
        ctx = self._ctx
        speed = math.hypot(float(observation.state[3]), float(observation.state[4]))
        others = self._others(observation)
        ahead = lead(others, ctx.lane_width_m)
        t = observation.t_s
        if self._timeline.trigger is Trigger.NONE:
            self._detect(others, ahead, speed, t)
        phase = self._timeline.phase(t)
        if phase is Phase.BRAKING and self._threat_gone(others, speed):
            self._timeline.end()
            phase = Phase.NORMAL
        acc = self._accel(phase, observation, speed, ahead)
        steer = self._steering.step(observation).steer_rad
        veh = ctx.vehicle
        torque = veh.wheel_radius_m * (veh.mass_kg * acc + road_load_n(veh, speed))
        diag = R157Diagnostics(outer_s=time.perf_counter() - t0, inner_s=0.0,
                               phase=int(phase), trigger=int(self._timeline.trigger),
                               risk_t_s=self._timeline.risk_t_s,
                               brake_start_t_s=self._timeline.brake_start_t_s,
                               decel_cmd_mps2=-acc)
        return Command(steer_rad=steer, torque_nm=torque, diagnostics=diag)

    def parameters(self) -> dict[str, Any]:
        """``{"name": "r157_reference", **parameters}``: accepted back by the factory."""
        return {"name": self.name, **to_dict(self.params)}

    # ------------------------------------------------------------------ the steps
    def _ego_s(self, observation: Observation) -> float:
        if observation.ego is not None:
            return observation.ego.s_m
        assert self._path is not None
        s, _ = self._path.project(float(observation.state[0]), float(observation.state[1]),
                                  s_hint=self._s_hint)
        self._s_hint = float(s)
        return self._s_hint

    def _others(self, observation: Observation) -> list[Other]:
        assert self._ctx is not None
        obs = observation.obstacles
        keys = obstacle_keys(obs)
        speeds = {key: float(obs.speed_s_mps[k]) for k, key in enumerate(keys)}
        decel = self._tracker.update(observation.t_s, speeds)
        return read_others(obs, self._ego_s(observation), self._ctx.vehicle.length_m, decel)

    def _detect(self, others: list[Other], ahead: Other | None, speed: float,
                t_s: float) -> None:
        """Start the timeline at a perceived risk (module docstring)."""
        m = self.params.model
        if ahead is not None and ahead.decel_mps2 >= m.lead_decel_threshold_mps2:
            self._timeline.start(Trigger.LEAD_BRAKING, ahead.key, t_s)
            return
        assert self._ctx is not None
        w = self._ctx.lane_width_m
        for other in others:
            if deviation_towards_ego_m(other, w) >= m.wandering_m \
                    and self._close(other, speed):
                self._timeline.start(Trigger.CUT_IN, other.key, t_s)
                return

    def _close(self, other: Other, speed: float) -> bool:
        """A vehicle ahead within the following gap or the critical time to collision."""
        if other.gap_m < 0.0:
            return False
        following = self.params.follow.time_gap_s * speed
        ttc = time_to_collision_s(other.gap_m, speed, other.speed_mps)
        return other.gap_m < following or ttc < self.params.model.critical_ttc_s

    def _threat_gone(self, others: list[Other], speed: float) -> bool:
        m = self.params.model
        if speed <= m.stop_speed_mps:
            return True
        threat = next((o for o in others if o.key == self._timeline.key), None)
        if threat is None:
            return True
        return speed <= threat.speed_mps and threat.decel_mps2 < m.lead_decel_threshold_mps2

    def _accel(self, phase: Phase, observation: Observation, speed: float,
               ahead: Other | None) -> float:
        if phase is Phase.BRAKING:
            assert self._ctx is not None
            return -self._timeline.brake_decel_mps2(observation.t_s
                                                    + self._ctx.control_period_s)
        if phase is not Phase.NORMAL:  # perceiving, reacting: the pedal held, no throttle
            return min(self._held_accel, 0.0)
        assert self._ctx is not None
        self._held_accel = _normal_accel(self.params.follow, self._ctx.target_speed_mps,
                                         speed, ahead)
        return self._held_accel


def make_r157_reference(options: Mapping[str, Any]) -> R157ReferenceController:
    """``r157_reference`` from catalog options; raises ConfigError naming the bad key."""
    opts = dict(options)
    given = opts.pop("name", NAME)
    if given != NAME:
        raise ConfigError("controller.name", f"{NAME!r}", given)
    return R157ReferenceController(build(R157ReferenceParams, opts))


__all__ = ["NAME", "FollowParams", "Phase", "R157Diagnostics", "R157ModelParams",
           "R157ReferenceController", "R157ReferenceParams", "Timeline", "Trigger",
           "make_r157_reference"]
