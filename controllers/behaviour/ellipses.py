"""Obstacle ellipses for the outer loop (docs/method.md §4), pure functions of the behaviour layer.

An obstacle vehicle (box length L_o, width W_o, centre (s, y) in the reference-path
Frenet frame) becomes an ellipse around the Minkowski sum of the two boxes (the
SPMM is a point at the ego CG), a rectangle of half sizes

    a = L_o/2 + L_ego/2,    b = W_o/2 + W_ego/2.

An ellipse with semi-axes a and b is *inscribed* in that rectangle: its corners
stick out ((a/a)^2 + (b/b)^2 = 2 > 1), so c >= 0 would not exclude contact. We
therefore take the across-axis first and stretch the along-axis until the
rectangle's corners lie on the ellipse, then add the margins:

    B0 = b + margin_lat_m,   A0 = a / sqrt(1 - (b/B0)^2)      (corner (a, b) on it)
    A  = A0 + margin_long_m, B  = B0 + offset_m               [m]

A long, narrow ellipse suits highway passing better than the minimum-area
(sqrt(2)-scaled) one, which would be 2.7 m wide for two cars. The centre is
shifted by ``offset_m`` *away* from the pass side (pass_side = +1: pass on the
left, so the centre moves right: y - offset), which breaks the tie of an obstacle
sitting on the reference path (paper Fig. 7); B includes ``offset_m`` so that the
shift never eats into the margin on the pass side. With pass_side = 0 (no free
side / follow mode) there is no shift.

Which vehicles become ellipses is the lane behaviour's choice
(:mod:`controllers.behaviour.obstacle_choice`).
"""

from __future__ import annotations

import numpy as np

from controllers.behaviour.types import ObstaclePolicy, Obstacles
from controllers.path.frenet import FrenetPath


def lateral_margin_m(policy: ObstaclePolicy) -> float:
    """b0 - b [m]: the policy's lateral margin, at least 0.05 m (a strictly positive
    margin keeps A0 = a / sqrt(1 - (b/b0)²) finite)."""
    return max(policy.margin_lat_m, 0.05)


def ellipse_semi_axes(obstacle_length_m: float, obstacle_width_m: float, ego_length_m: float,
                      ego_width_m: float, policy: ObstaclePolicy) -> tuple[float, float]:
    """(A, B) [m] as in the module docstring: the ellipse contains the box-sum rectangle."""
    a = 0.5 * obstacle_length_m + 0.5 * ego_length_m
    b = 0.5 * obstacle_width_m + 0.5 * ego_width_m
    b0 = b + lateral_margin_m(policy)
    a0 = a / np.sqrt(1.0 - (b / b0) ** 2)
    return float(a0 + policy.margin_long_m), float(b0 + policy.offset_m)


def box_half_length_m(semi_a_m: np.ndarray, semi_b_m: np.ndarray,
                      policy: ObstaclePolicy) -> np.ndarray:
    """The box-sum half length a [m] (half the obstacle's plus half the ego's length)
    inside ellipses of semi-axes (A, B) built by :func:`ellipse_semi_axes` with
    ``policy``: the inverse of its A = a / sqrt(1 - (b/b0)²) + margin_long, with
    b0 = B - offset and b = b0 - :func:`lateral_margin_m`. Shapes as the inputs."""
    b0 = np.asarray(semi_b_m, dtype=np.float64) - policy.offset_m
    b = b0 - lateral_margin_m(policy)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.clip(np.where(b0 > 0.0, b / b0, 0.0), 0.0, 1.0)
    return (np.asarray(semi_a_m, dtype=np.float64) - policy.margin_long_m) * np.sqrt(
        1.0 - ratio ** 2)


def offset_centre_y(y_m: float, pass_side: int, policy: ObstaclePolicy) -> float:
    """Centre y shifted by offset_m away from the pass side (no shift if pass_side = 0)."""
    return float(y_m) - float(np.sign(pass_side)) * policy.offset_m


def ellipse_value(s_m: np.ndarray | float, y_m: np.ndarray | float, centre_s_m: float,
                  centre_y_m: float, semi_a_m: float, semi_b_m: float) -> np.ndarray:
    """c = (s - s_c)²/A² + (y - y_c)²/B² - 1 (< 0 inside)."""
    s = np.asarray(s_m, dtype=np.float64)
    y = np.asarray(y_m, dtype=np.float64)
    return (s - centre_s_m) ** 2 / semi_a_m**2 + (y - centre_y_m) ** 2 / semi_b_m**2 - 1.0


def ellipses_in_world(path: FrenetPath, obstacles: Obstacles) -> np.ndarray:
    """(K, 6) [cx_m, cy_m, heading_rad, semi_a_m, semi_b_m, active] of the ellipses in
    the world frame, axes along the path tangent at their centre (for logs)."""
    k = obstacles.count
    out = np.zeros((k, 6))
    if k == 0:
        return out
    x, y = path.to_global(obstacles.s_m, obstacles.y_m)
    out[:, 0] = x
    out[:, 1] = y
    out[:, 2] = path.gamma(obstacles.s_m)
    out[:, 3] = obstacles.semi_a_m
    out[:, 4] = obstacles.semi_b_m
    out[:, 5] = 1.0
    return out
