"""Multi-rate stepping: SUMO steps every ``sumo_step_s``, the ego's loop every ``step_s``.

With m = sumo_step_s / step_s control steps per SUMO step (a whole number >= 1), control
step k (k = 1, 2, ... after the start) is a *world step* when k is a multiple of m: the
ego's pose is pushed and SUMO advances by sumo_step_s. At the other steps the world holds
SUMO's last state and the other vehicles are extrapolated from it
(:func:`extrapolate_traffic`), tau = (k mod m) step_s after SUMO's last step (0 < tau <
sumo_step_s).

Extrapolation: constant speed along the vehicle's heading, heading and size held,

    x(t + tau) = x(t) + v(t) tau cos(h(t)),   y(t + tau) = y(t) + v(t) tau sin(h(t)),

which is SUMO's own motion model over a step (a vehicle moves at one speed along its
heading, lane changes included through the heading) up to the speed change within the
step; docs/performance.md measures the error against SUMO run at the control rate.
Lane index and road are those of SUMO's last step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from controllers.behaviour.types import FloatArray, Traffic


@dataclass(frozen=True)
class MultiRate:
    """``steps_per_world_step`` control steps of ``step_s`` [s] per SUMO step."""

    steps_per_world_step: int
    step_s: float

    def __post_init__(self) -> None:
        m = self.steps_per_world_step
        if isinstance(m, bool) or not isinstance(m, int) or m < 1:
            raise ValueError(f"steps_per_world_step must be an int >= 1, got {m!r}")
        if not (isinstance(self.step_s, int | float) and math.isfinite(self.step_s)
                and self.step_s > 0.0):
            raise ValueError(f"step_s must be a finite number > 0 [s], got {self.step_s!r}")

    @property
    def world_step_s(self) -> float:
        """SUMO's step [s]."""
        return round(self.steps_per_world_step * float(self.step_s), 9)

    def is_world_step(self, k: int) -> bool:
        """Whether control step ``k`` (1, 2, ... after the start) steps SUMO."""
        return k % self.steps_per_world_step == 0

    def since_world_step_s(self, k: int) -> float:
        """tau [s]: time of control step ``k`` after SUMO's last step (0 at a world step)."""
        return (k % self.steps_per_world_step) * float(self.step_s)


def headings(traffic: Traffic) -> tuple[FloatArray, FloatArray]:
    """(cos, sin) of every vehicle's heading, (n,): held between SUMO steps, so the
    world computes them once per SUMO step for :func:`extrapolate_traffic`."""
    return np.cos(traffic.heading_rad), np.sin(traffic.heading_rad)


def extrapolate_traffic(traffic: Traffic, tau_s: float,
                        direction: tuple[FloatArray, FloatArray] | None = None) -> Traffic:
    """The vehicles ``tau_s`` [s] later at constant speed along their headings (module
    docstring); arrays (n,) as in ``traffic``, which is not changed. ``direction``:
    :func:`headings` of ``traffic`` when already known (the same numbers)."""
    if traffic.count == 0 or tau_s == 0.0:
        return traffic
    cos_h, sin_h = headings(traffic) if direction is None else direction
    step = traffic.speed_mps * float(tau_s)
    return traffic.moved(traffic.x_m + step * cos_h, traffic.y_m + step * sin_h)
