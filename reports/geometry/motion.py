"""Whether a recorded track's motion agrees with its own speeds and headings (a replayed
vehicle that jumped: ``reports.metrics.collisions``, the recordings' import checks)."""

from __future__ import annotations

import numpy as np


def jump_excess_mps(t_s: np.ndarray, x_m: np.ndarray, y_m: np.ndarray,
                    heading_rad: np.ndarray, speed_mps: np.ndarray) -> np.ndarray:
    """Per pair of consecutive samples (n - 1,): |d - dt (v_a u_a + v_b u_b) / 2| / dt
    [m/s], with d the displacement [m] and u the heading's unit vector: how much faster
    than its recorded speeds and headings allow the vehicle moved (about 0 for a smooth
    track; NaN where dt <= 0 or a value is not finite)."""
    dt = np.diff(t_s)
    ok = dt > 0.0
    safe = np.where(ok, dt, 1.0)
    vx, vy = speed_mps * np.cos(heading_rad), speed_mps * np.sin(heading_rad)
    ex = np.diff(x_m) - 0.5 * dt * (vx[1:] + vx[:-1])
    ey = np.diff(y_m) - 0.5 * dt * (vy[1:] + vy[:-1])
    out = np.hypot(ex, ey) / safe
    return np.where(ok & np.isfinite(out), out, np.nan)
