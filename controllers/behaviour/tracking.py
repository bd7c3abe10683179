"""Per-vehicle acceleration estimates from successive speeds (what a radar track gives).

The world reports speeds only; car following needs the lead's acceleration to see a
braking lead before the gap shrinks (a lead faster than the ego that brakes hard leaves
a growing gap for seconds while its stopping distance collapses). For every vehicle seen
at times t_k with speed v_k the estimate is a first-order low-pass of the difference
quotient,

    a_raw = (v_k - v_{k-1}) / (t_k - t_{k-1}),   a_k = a_{k-1} + (a_raw - a_{k-1}) dt / (tau + dt),

so a speed that SUMO updates only every few control steps (the same speed twice, then a
jump) averages to its true slope within about tau. A vehicle seen for the first time
starts at a = 0; one not seen for ``forget_s`` is dropped.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from controllers.behaviour.types import FloatArray, Traffic, require_numbers


@dataclass(frozen=True)
class TrackingParams:
    """tau_s [s]: the low-pass time constant; forget_s [s]: a vehicle unseen this long is
    dropped (and starts again at a = 0)."""

    tau_s: float = 0.4
    forget_s: float = 1.0

    def __post_init__(self) -> None:
        require_numbers(self, ("tau_s", "forget_s"), strict=True)


@dataclass
class AccelerationTracker:
    """Filtered acceleration [m/s²] along the heading of every vehicle by id."""

    params: TrackingParams = field(default_factory=TrackingParams)
    _state: dict[str, tuple[float, float, float]] = field(default_factory=dict, init=False)

    def reset(self) -> None:
        self._state.clear()

    def update(self, t_s: float, traffic: Traffic) -> FloatArray:
        """Feed the speeds at time ``t_s`` [s]; returns the estimates, shape (n,) [m/s²]."""
        tau, forget = self.params.tau_s, self.params.forget_s
        out: list[float] = []
        state = self._state
        # Python floats from one tolist(): indexing the array per vehicle costs more
        speeds = np.asarray(traffic.speed_mps, dtype=np.float64).tolist()
        for vid, v in zip(traffic.ids, speeds, strict=True):
            prev = state.get(vid)
            a = 0.0
            if prev is not None and 0.0 < t_s - prev[0] <= forget:
                dt = t_s - prev[0]
                a = prev[2] + ((v - prev[1]) / dt - prev[2]) * dt / (tau + dt)
            elif prev is not None and t_s == prev[0]:
                a = prev[2]
            state[vid] = (t_s, v, a)
            out.append(a)
        if len(state) > 2 * traffic.count + 16:
            for vid in [i for i, s in state.items() if t_s - s[0] > forget]:
                del state[vid]
        return np.array(out, dtype=np.float64)


__all__ = ["AccelerationTracker", "TrackingParams"]
