"""Perception: other vehicles projected onto the reference path (Frenet frame)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from controllers.behaviour.types import EgoFrenet, Traffic
from controllers.path.frenet import FrenetPath

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class FrenetTraffic:
    """Vehicles in the reference-path frame, arrays (n,): box centre (s_m, y_m) [m],
    velocity along / across the path (v_s_mps, v_y_mps) [m/s], box size [m]."""

    s_m: FloatArray
    y_m: FloatArray
    v_s_mps: FloatArray
    v_y_mps: FloatArray
    length_m: FloatArray
    width_m: FloatArray

    @staticmethod
    def empty() -> FrenetTraffic:
        z = np.zeros(0)
        return FrenetTraffic(z, z, z, z, z, z)


def project_traffic(path: FrenetPath, traffic: Traffic, ego: EgoFrenet) -> FrenetTraffic:
    """Box centres and velocities of ``traffic`` in the frame of ``path``.

    The ego's own projection (s at its CG) seeds every vehicle's Newton projection
    (:meth:`FrenetPath.project_along`); the velocity (speed along the heading) is split
    along the path tangent gamma(s_j) and its normal.
    """
    if traffic.count == 0:
        return FrenetTraffic.empty()
    s, y, gamma = path.project_along(traffic.x_m, traffic.y_m, ego.x_m, ego.y_m, ego.s_m)
    rel = traffic.heading_rad - gamma
    return FrenetTraffic(s, y, traffic.speed_mps * np.cos(rel), traffic.speed_mps * np.sin(rel),
                         traffic.length_m, traffic.width_m)
