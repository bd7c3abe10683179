"""The ego's state after a step, as every later stage sees it."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from controllers.behaviour.types import EgoFrenet
from controllers.path.frenet import FrenetPath, path_gamma
from controllers.protocol import EgoOnPath
from suite.world.protocol import WorldEgo

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class EgoState:
    """state: (6,) [X_m, Y_m, psi_rad, u_mps, v_mps, r_radps] of the CG; body
    accelerations over the last step [m/s²]; applied steer [rad] / torque [N m] (NaN
    when SUMO drives); the CG on the reference path: s_m, lat_m [m], heading error
    [rad]; the ego as the world has it (None if unknown); ``on_path``: that projection
    with the path's tangent angle and curvature there, as the controller gets it (None:
    not computed, the controller projects itself)."""

    state: FloatArray
    long_acc_mps2: float
    lat_acc_mps2: float
    steer_rad: float
    torque_nm: float
    s_m: float
    lat_m: float
    heading_err_rad: float
    world: WorldEgo | None = None
    on_path: EgoOnPath | None = None

    @property
    def speed_mps(self) -> float:
        return math.hypot(float(self.state[3]), float(self.state[4]))

    def frenet(self, t_s: float) -> EgoFrenet:
        """The ego as the behaviour sees it at run time ``t_s``."""
        return EgoFrenet(float(self.state[0]), float(self.state[1]), self.s_m, self.lat_m,
                         self.speed_mps, t_s)


class EgoProjector:
    """Projects the CG pose onto the reference path, each projection seeding the next."""

    def __init__(self, path: FrenetPath) -> None:
        self.path = path
        self._s_hint: float | None = None

    def project(self, state: FloatArray) -> tuple[float, float, float]:
        """(s_m, lat_m, heading_err_rad) of the CG pose in ``state``."""
        s, y, e = self.path.project_pose(state[0], state[1], state[2], s_hint=self._s_hint)
        self._s_hint = float(s)
        return float(s), float(y), float(e)

    def at(self, s_m: float, lat_m: float, heading_err_rad: float) -> EgoOnPath:
        """The projection (s_m, lat_m, heading_err_rad) with the path's tangent angle and
        curvature at ``s_m`` (the compiled scalar kernel: the values the controller's
        own projection computes, bit for bit)."""
        meta, coef, _ = self.path.tables()
        gamma, kappa, _ = path_gamma(meta, coef, s_m)
        return EgoOnPath(s_m, lat_m, heading_err_rad, float(gamma), float(kappa))
