"""Transition shapes and the time a dynamics takes: the pure kinematics of the
storyboard's actions (docs/openscenario.md, "Runtime").

A transition from a to b along shape f over progress u in [0, 1] is a + (b - a) f(u):
step f = 1, linear f = u, cubic f = 3u² - 2u³, sinusoidal f = (1 - cos(pi u)) / 2.
"""

from __future__ import annotations

import math

__all__ = ["lane_offset_duration_s", "shape", "transition_duration"]


def shape(name: str, u: float) -> float:
    """f(u) of the named shape, u clipped to [0, 1]."""
    u = min(max(u, 0.0), 1.0)
    if name == "step":
        return 1.0
    if name == "linear":
        return u
    if name == "cubic":
        return u * u * (3.0 - 2.0 * u)
    return 0.5 * (1.0 - math.cos(math.pi * u))


def transition_duration(dimension: str, value: float, change: float) -> float:
    """How long [s] (dimension time), how far [m] (distance), or, for a rate, how long
    [s] a change of ``change`` takes at mean rate ``value`` (|change| / value; a rate of
    0 never gets there: inf, unless there is nothing to change)."""
    if dimension == "rate":
        if change == 0.0:
            return 0.0
        return abs(change) / value if value > 0.0 else math.inf
    return value


def lane_offset_duration_s(shape_name: str, change_m: float, max_acc_mps2: float) -> float:
    """The duration [s] of a lateral offset change of ``change_m`` [m] whose peak
    lateral acceleration is ``max_acc_mps2`` [m/s²]: sinusoidal pi sqrt(d / (2 a)),
    cubic sqrt(6 d / a), linear (taken as accelerate-then-brake) 2 sqrt(d / a), step 0."""
    d = abs(change_m)
    if shape_name == "step" or d == 0.0:
        return 0.0
    if shape_name == "sinusoidal":
        return math.pi * math.sqrt(d / (2.0 * max_acc_mps2))
    if shape_name == "cubic":
        return math.sqrt(6.0 * d / max_acc_mps2)
    return 2.0 * math.sqrt(d / max_acc_mps2)
