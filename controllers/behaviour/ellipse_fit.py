"""Fitting an obstacle ellipse around the ego: the semi-axes that leave the ego outside.

The planner's barrier on an ellipse, -log(value) with value = (ds / A)² + (dy / B)² - 1,
is undefined with the ego's CG inside (value <= 0), and the planner fails there. So an
ellipse that would contain the ego (a car alongside in the next lane, a lead followed
at standstill distance) is narrowed: :func:`leave_ego_outside`, applied to a set of
ellipses by :meth:`controllers.behaviour.types.Obstacles.around_ego`. The behaviour does
it when it decides (:mod:`controllers.behaviour.obstacle_choice`) and again at each
control step between two decisions, on the ellipses moved by their own prediction
(:meth:`controllers.behaviour.types.Decision.ahead`), since the ego moves meanwhile.
Pure arithmetic on floats: no import of the behaviour's types.
"""

from __future__ import annotations

import math

__all__ = ["OUTSIDE_VALUE", "leave_ego_outside"]

OUTSIDE_VALUE = 1.05  # (ds/A)² + (dy/B)² the ego is kept at, at least: the value 0.05


def leave_ego_outside(ds_m: float, dy_m: float, semi_a_m: float, semi_b_m: float,
                      min_a_m: float) -> tuple[float, float]:
    """Semi-axes (A, B) [m] such that the ego's CG at (ds, dy) [m] from the centre is
    outside (ellipse value >= 0.05): the axis along which the ego is deeper shrinks (A:
    following a car at standstill distance; B: a car alongside in the next lane), A not
    below ``min_a_m`` (the box-sum half length), B not below 0.5 m. Unchanged when the
    ego is outside already."""
    along, across = (ds_m / semi_a_m) ** 2, (dy_m / semi_b_m) ** 2
    if along + across >= OUTSIDE_VALUE:
        return semi_a_m, semi_b_m
    if along >= across and across < 1.0:
        a = abs(ds_m) / math.sqrt(max(OUTSIDE_VALUE - across, 1e-3))
        return max(a, min_a_m), semi_b_m
    b = abs(dy_m) / math.sqrt(max(OUTSIDE_VALUE - along, 1e-3))
    return semi_a_m, max(b, 0.5)
