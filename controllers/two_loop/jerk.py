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

The torque is also kept within the actuators' range [-T_brake, T_drive] (``reset``):
the plant saturates there anyway, and a request beyond it remembered as handed out winds
the limiter up (a -9000 N m request against the 4500 N m brake took 3.3 s at the jerk
bound to come back to -4500 N m: the car braked at 10 m/s² to a standstill). A run
starts from the torque that holds the initial speed (``reset(initial_torque_nm)``), so
its first command is rate-limited too (before, it passed unchanged: a plan 6 m/s below
the car's speed braked at 10 m/s² in the first period).

Emergency braking raises the bounds the way it raises the minimal-risk manoeuvre's
(:func:`controllers.two_loop.fallback.onset_jerk_mps3`), and only for an obstacle
(:func:`controllers.two_loop.fallback.planner_emergency`): when the plan's speed half a
second ahead is below the car's by more than comfortable braking gives *and* an
obstacle ahead needs braking beyond comfort, the onset is not slowed below what that
deceleration calls for. A set-point below the car's speed never raises it. While the
minimal-risk manoeuvre drives, the bounds are raised to its own current jerk bound
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
        self._lo = -math.inf
        self._hi = math.inf
        self.limited = False

    def reset(self, initial_torque_nm: float | None = None,
              torque_range_nm: tuple[float, float] = (-math.inf, math.inf)) -> None:
        """Start of a run: the first command is limited from ``initial_torque_nm`` [N m]
        (None: it passes unchanged); every command handed out (and remembered) is kept
        within ``torque_range_nm`` = (lowest, highest) [N m], the actuators' range."""
        lo, hi = (float(v) for v in torque_range_nm)
        if not lo <= hi:
            raise ValueError(f"torque_range_nm must be (low, high) with low <= high, "
                             f"got {torque_range_nm!r}")
        self._lo, self._hi = lo, hi
        self._last = None if initial_torque_nm is None else self._clip(float(initial_torque_nm))
        self.limited = False

    def _clip(self, torque_nm: float) -> float:
        """``torque_nm`` within the actuators' range (a non-finite value unchanged)."""
        return min(max(torque_nm, self._lo), self._hi) if math.isfinite(torque_nm) \
            else torque_nm

    @property
    def last_torque_nm(self) -> float:
        """The last torque handed out [N m] (0 before the first command of a run)."""
        return 0.0 if self._last is None else self._last

    def limit(self, torque_nm: float, dt_s: float, torque_per_accel_nm: float,
              at_least_mps3: float = 0.0) -> float:
        """The requested ``torque_nm`` rate-limited (module docstring), both bounds raised
        to ``at_least_mps3``, within the actuators' range; a non-finite request, and the
        first command of a run reset without an initial torque, pass unchanged (but for
        the range). ``limited`` says whether a bound acted."""
        last = self._last
        self.limited = False
        if (not self.params.enabled or last is None or not math.isfinite(torque_nm)
                or not math.isfinite(last) or dt_s <= 0.0):
            return self.follow(torque_nm)
        p = self.params
        up = max(p.jerk_up_mps3, at_least_mps3) * torque_per_accel_nm * dt_s
        down = max(p.jerk_down_mps3, at_least_mps3) * torque_per_accel_nm * dt_s
        out = self._clip(min(max(torque_nm, last - down), last + up,
                             p.max_accel_mps2 * torque_per_accel_nm))
        self.limited = out != torque_nm
        self._last = out
        return out

    def follow(self, torque_nm: float) -> float:
        """Bypass: hand out ``torque_nm`` within the actuators' range and remember it
        (bumpless when limiting resumes)."""
        self._last = self._clip(float(torque_nm))
        return self._last
