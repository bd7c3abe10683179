"""The OCP's residual against a central finite difference of its objective (tests)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from controllers.two_loop.outer.ocp_layout import stage_fractions


def assert_residual_is_objective_gradient(prob: Any, params: Any, u: np.ndarray,
                                          x0: np.ndarray, obs: Any, target_mps: float,
                                          horizon_s: float, tshift_s: float, m: int,
                                          label: object = "", **extra: Any) -> None:
    """F_k dtau_i = dJ/du_k for every unknown u_k but stage 0's constraint rows (the
    residual is the gradient of the discrete Lagrangian divided by dtau_i)."""
    f, _, _ = prob.residual(u, x0, obs, target_mps, horizon=horizon_s, tshift=tshift_s,
                            **extra)
    dtau = np.diff(stage_fractions(params)) * horizon_s
    for k in range(u.shape[0]):
        i, comp = divmod(k, m)
        if i == 0 and comp >= 2:
            continue
        d = 1e-6 * max(1.0, abs(u[k]))
        up, um = u.copy(), u.copy()
        up[k] += d
        um[k] -= d
        fd = (prob.objective(up, x0, obs, target_mps, horizon_s, tshift_s, True, **extra)
              - prob.objective(um, x0, obs, target_mps, horizon_s, tshift_s, True, **extra)
              ) / (2 * d)
        assert dtau[i] * f[k] == pytest.approx(fd, rel=1e-5, abs=1e-7), (label, i, comp)
