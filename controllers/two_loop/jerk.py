"""Longitudinal jerk limiter: the last stage between the inner loop and the wheels.

The outer OCP's point-mass model has the speed V as an *input*, so nothing in the plan
bounds how fast the planned acceleration may change; when C/GMRES catches up with a
changed problem (an obstacle entering the horizon, a slot filled) the planned speeds
move abruptly and the conversion (14) turns that into a torque step, i.e. a jerk far
beyond comfort although the acceleration itself stays small (docs/two_loop.md, "The
longitudinal jerk limiter"). The limiter bounds the rate of the drive/brake torque:

    T_k = min(T_{k-1} + clip(T_req - T_{k-1}, -m R j_down dt, m R j_up dt), m R a_max)

with m R the torque per unit acceleration [N m/(m/s²)] and dt the control period, so
the commanded longitudinal acceleration T/(m R) changes by at most j dt per period and
never exceeds a_max (``max_accel_mps2``: pulling out from behind a stopped car at low
speed, the plan's speed-up and the tangential correction together asked for 2.9 m/s²,
beyond comfort; drag and rolling resistance only lower what the car then does).

An urgent braking need raises the bounds the way it raises the minimal-risk
manoeuvre's (:func:`controllers.two_loop.fallback.onset_jerk_mps3`): when the plan's
speed half a second ahead is below the car's by more than comfortable braking gives,
the onset is not slowed below what that deceleration calls for (the controller checks
this only when the bound would hold a braking request back). While the minimal-risk
manoeuvre drives, the bounds are raised to its own current jerk bound
(``at_least_mps3``: its emergency braking must not be slowed down, its comfortable
braking and release keep the limiter's bound); during the standstill launch the
limiter is bypassed (the state follows the command).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from controllers.params import check_leaves, check_range, param


@dataclass(frozen=True)
class JerkLimitParams:
    """Rate limits of the commanded longitudinal acceleration T/(m R)."""

    enabled: bool = param(True, "-", "limit the torque's rate (off: the paper's command)")
    jerk_up_mps3: float = param(3.0, "m/s³", "bound of the rise of the commanded acceleration")
    jerk_down_mps3: float = param(3.0, "m/s³", "bound of its fall (braking onset)")
    max_accel_mps2: float = param(2.0, "m/s²", "bound of the commanded acceleration")

    def __post_init__(self) -> None:
        check_leaves(self)
        for name in ("jerk_up_mps3", "jerk_down_mps3", "max_accel_mps2"):
            check_range(self, name, gt=0.0)


class JerkLimiter:
    """State: the last torque handed out [N m] (None before the first command)."""

    def __init__(self, params: JerkLimitParams) -> None:
        self.params = params
        self._last: float | None = None
        self.limited = False

    def reset(self) -> None:
        self._last = None
        self.limited = False

    @property
    def last_torque_nm(self) -> float:
        """The last torque handed out [N m] (0 before the first command of a run)."""
        return 0.0 if self._last is None else self._last

    def limit(self, torque_nm: float, dt_s: float, torque_per_accel_nm: float,
              at_least_mps3: float = 0.0) -> float:
        """The requested ``torque_nm`` rate-limited (module docstring), both bounds raised
        to ``at_least_mps3``; the first command of a run and a non-finite request pass
        unchanged. ``limited`` says whether the bound acted."""
        last = self._last
        self.limited = False
        if (not self.params.enabled or last is None or not math.isfinite(torque_nm)
                or not math.isfinite(last) or dt_s <= 0.0):
            return self.follow(torque_nm)
        p = self.params
        up = max(p.jerk_up_mps3, at_least_mps3) * torque_per_accel_nm * dt_s
        down = max(p.jerk_down_mps3, at_least_mps3) * torque_per_accel_nm * dt_s
        out = min(max(torque_nm, last - down), last + up,
                  p.max_accel_mps2 * torque_per_accel_nm)
        self.limited = out != torque_nm
        self._last = out
        return out

    def brakes_harder_than_bound(self, torque_nm: float, dt_s: float,
                                 torque_per_accel_nm: float) -> bool:
        """Whether ``limit`` would hold back this request's braking onset at the
        configured bound (the caller may then raise it for an urgent need)."""
        last = self._last
        if not self.params.enabled or last is None or not math.isfinite(torque_nm):
            return False
        return torque_nm < last - self.params.jerk_down_mps3 * torque_per_accel_nm * dt_s

    def follow(self, torque_nm: float) -> float:
        """Bypass: remember ``torque_nm`` as handed out (bumpless when limiting resumes)."""
        self._last = float(torque_nm)
        return float(torque_nm)
