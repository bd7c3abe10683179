"""The target-speed ramp V_t(t) every outer solver feeds its OCP (jerk-limited, class doc)."""

from __future__ import annotations

import math

__all__ = ["CruiseSetPoint", "TargetSpeedRamp"]


class TargetSpeedRamp:
    """Jerk-limited target speed V_t(t) for the OCP, shared by every outer solver.

    Time-optimal under -d <= a <= accel and |da/dt| <= j: with e = set point - V_t
    and e_stop = e - 1.5 a dt - a |a| / (2 j) (what is left once the ramp's
    acceleration a has been brought back to zero at the jerk limit, discretely), a is
    driven at most j dt per update towards +accel if e_stop > 0, else -d; V_t <- V_t +
    a dt. Once the set point is within one step and |a| <= j dt, V_t lands on it with
    a = 0. A change of the set point by dv therefore takes about |dv| / a_lim + a_lim / j
    seconds (a_lim = accel or d) when |dv| >= a_lim² / j, and 2 sqrt(|dv| / j) below
    (a triangle in a, peak sqrt(|dv| j)).

    Two deceleration limits d: ``set_speed_decel_mps2`` (a comfortable one) while the
    set point is at or above ``cruise_speed_mps`` (the run's cruise set-point: a slower
    set speed, or a start faster than it, with nothing ahead to follow), and
    ``decel_mps2`` when the set point is below the cruise speed (the behaviour lowered it
    to follow a lead or to stop: the firmer limit its following law counts on).
    ``set_speed_decel_mps2`` None, or ``cruise_speed_mps`` inf (the default), gives
    ``decel_mps2`` everywhere.

    V_t, a and hence the OCP's cost change continuously, so neither the continuation
    nor the car sees a step in speed or acceleration (a bare rate limit switches the
    acceleration on at once: a jerk spike at every start and braking onset). The ramp
    starts where the car is (``reset`` with the measured speed): started at the set point
    instead, the plan's speed input V would step to it at once.
    """

    def __init__(self, accel_mps2: float, decel_mps2: float, jerk_mps3: float,
                 set_speed_decel_mps2: float | None = None) -> None:
        self.accel_mps2 = float(accel_mps2)
        self.decel_mps2 = float(decel_mps2)
        self.jerk_mps3 = float(jerk_mps3)
        self.set_speed_decel_mps2 = (None if set_speed_decel_mps2 is None
                                     else float(set_speed_decel_mps2))
        self.cruise_speed_mps = math.inf
        self.speed_mps = 0.0
        self.ramp_accel_mps2 = 0.0

    def reset(self, speed_mps: float) -> None:
        self.speed_mps = float(speed_mps)
        self.ramp_accel_mps2 = 0.0

    def decel_for_mps2(self, set_speed_mps: float) -> float:
        """The deceleration limit d [m/s², > 0] toward ``set_speed_mps`` (class docstring)."""
        if self.set_speed_decel_mps2 is not None and set_speed_mps >= self.cruise_speed_mps:
            return self.set_speed_decel_mps2
        return self.decel_mps2

    def update(self, set_speed_mps: float, dt_s: float) -> float:
        """Advance by ``dt_s`` towards ``set_speed_mps``; returns V_t [m/s]."""
        if dt_s <= 0.0:
            return self.speed_mps
        target = float(set_speed_mps)
        a = self.ramp_accel_mps2
        step = self.jerk_mps3 * dt_s
        err = target - self.speed_mps
        if abs(err) <= step * dt_s and abs(a) <= step:
            self.speed_mps, self.ramp_accel_mps2 = target, 0.0
            return self.speed_mps
        # Left over after this step (a dt) and after ramping a to zero from the next one
        # (a|a|/2j, plus half a step for the discrete ramp).
        e_stop = err - 1.5 * a * dt_s - a * abs(a) / (2.0 * self.jerk_mps3)
        a_goal = self.accel_mps2 if e_stop > 0.0 else -self.decel_for_mps2(target)
        a += min(max(a_goal - a, -step), step)
        self.ramp_accel_mps2 = a
        self.speed_mps = max(self.speed_mps + a * dt_s, 0.0)
        return self.speed_mps


class CruiseSetPoint:
    """What an outer planner owning a :class:`TargetSpeedRamp` (``_ramp``) shares: the
    run's cruise set-point."""

    _ramp: TargetSpeedRamp

    def set_cruise_speed(self, cruise_speed_mps: float) -> None:
        """The run's cruise set-point [m/s]: the target ramp decelerates toward a
        set-point at or above it at ``set_speed_decel_mps2``, toward a lower one (the
        behaviour lowered it to follow) at ``target_decel_mps2`` (:class:`TargetSpeedRamp`).
        Until it is given (after ``reset``), ``target_decel_mps2`` everywhere."""
        self._ramp.cruise_speed_mps = float(cruise_speed_mps)
