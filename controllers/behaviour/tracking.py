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

**Lateral motion** (:meth:`AccelerationTracker.lateral`): a cut-in is recognised from a
car's lateral speed toward a lane, and a recording's jitter (a heading that wobbles by a
few hundredths of a radian at 20 m/s is +-0.6 m/s across the lane) must not count as
one. Each vehicle's lateral speed across the path is low-passed the same way,

    w_k = w_{k-1} + (v_y - w_{k-1}) dt / (tau_y + dt),

and the lateral speed v_y itself is handed out only while the filtered one says it is a
deliberate motion, with hysteresis: from the step where |w| reaches
``lateral_enter_mps`` until |w| falls below ``lateral_exit_mps`` (0 otherwise). The
gate, not the filter, is what the cut-in prediction waits for: a SUMO lane change at
1.2 m/s is recognised about 0.1 s after it starts (tau_y = 0.3 s) and predicted at its
own speed from then on (predicting with w itself lagged the recognition of a cut-in
8 m ahead by a quarter of a second and brought its collision back); a wobble at the
recording's sample rate is attenuated to a fraction of its amplitude and never opens
the gate.

The state lives in arrays indexed by a slot per vehicle id; the filter runs in one
compiled pass (:func:`_filter`, the expression above in the same order: the numbers of
the per-vehicle definition bit for bit, tests/test_step_path_reuse.py). The id -> slot
lookup is redone only when the world hands out a new id tuple (at its own steps; the
extrapolated scenes in between share it).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba
import numpy as np
import numpy.typing as npt

from controllers.behaviour.types import FloatArray, Traffic, require_numbers

IntArray = npt.NDArray[np.int64]


@dataclass(frozen=True)
class TrackingParams:
    """tau_s [s]: the low-pass time constant; forget_s [s]: a vehicle unseen this long is
    dropped (and starts again at a = 0); lateral_tau_s [s], lateral_enter_mps,
    lateral_exit_mps [m/s]: the lateral-motion filter and its hysteresis (module
    docstring)."""

    tau_s: float = 0.4
    forget_s: float = 1.0
    lateral_tau_s: float = 0.3
    lateral_enter_mps: float = 0.35
    lateral_exit_mps: float = 0.15

    def __post_init__(self) -> None:
        require_numbers(self, ("tau_s", "forget_s", "lateral_tau_s", "lateral_enter_mps",
                               "lateral_exit_mps"), strict=True)
        if self.lateral_exit_mps > self.lateral_enter_mps:
            raise ValueError("TrackingParams.lateral_exit_mps must be <= lateral_enter_mps, "
                             f"got {self.lateral_exit_mps} > {self.lateral_enter_mps}")


@numba.njit(cache=True)
def _filter(t_s: float, speeds: FloatArray, slots: IntArray, t_prev: FloatArray,
            v_prev: FloatArray, a_prev: FloatArray, tau_s: float, forget_s: float,
            out: FloatArray) -> None:
    """The module docstring's filter for every vehicle j in order (slot ``slots[j]``;
    ``t_prev`` NaN: never seen), updating the slots' state in place."""
    for j in range(slots.shape[0]):
        k = slots[j]
        v = speeds[j]
        a = 0.0
        tp = t_prev[k]
        if tp == tp:  # seen before
            if 0.0 < t_s - tp <= forget_s:
                dt = t_s - tp
                a = a_prev[k] + ((v - v_prev[k]) / dt - a_prev[k]) * dt / (tau_s + dt)
            elif t_s == tp:
                a = a_prev[k]
        t_prev[k] = t_s
        v_prev[k] = v
        a_prev[k] = a
        out[j] = a


@numba.njit(cache=True)
def _lateral(t_s: float, v_y: FloatArray, slots: IntArray, t_prev: FloatArray,
             w_prev: FloatArray, on_prev: FloatArray, tau_s: float, enter: float,
             leave: float, forget_s: float, out: FloatArray) -> None:
    """The lateral filter and its gate (module docstring) for every vehicle j
    (``t_prev`` NaN: never seen; ``on_prev`` 1.0 while counted), in place; ``out`` the
    speeds v_y where the gate is open, else 0."""
    for j in range(slots.shape[0]):
        k = slots[j]
        w = v_y[j]
        tp = t_prev[k]
        if tp == tp and 0.0 < t_s - tp <= forget_s:
            dt = t_s - tp
            w = w_prev[k] + (v_y[j] - w_prev[k]) * dt / (tau_s + dt)
        elif tp == tp and t_s == tp:
            w = w_prev[k]
        else:
            w = 0.0  # first seen: no motion known yet
        on = abs(w) >= enter or (on_prev[k] > 0.0 and abs(w) >= leave)
        t_prev[k] = t_s
        w_prev[k] = w
        on_prev[k] = 1.0 if on else 0.0
        out[j] = v_y[j] if on else 0.0


@dataclass
class AccelerationTracker:
    """Filtered acceleration [m/s²] along the heading of every vehicle by id."""

    params: TrackingParams = field(default_factory=TrackingParams)
    _slot: dict[str, int] = field(default_factory=dict, init=False)
    _t: FloatArray = field(default_factory=lambda: np.full(64, np.nan), init=False)
    _v: FloatArray = field(default_factory=lambda: np.zeros(64), init=False)
    _a: FloatArray = field(default_factory=lambda: np.zeros(64), init=False)
    _ty: FloatArray = field(default_factory=lambda: np.full(64, np.nan), init=False)
    _w: FloatArray = field(default_factory=lambda: np.zeros(64), init=False)
    _on: FloatArray = field(default_factory=lambda: np.zeros(64), init=False)
    _ids: tuple[str, ...] | None = field(default=None, init=False)
    _slots: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64), init=False)

    def reset(self) -> None:
        self._slot.clear()
        self._t[:] = np.nan
        self._ty[:] = np.nan
        self._ids = None

    def _slots_of(self, ids: tuple[str, ...]) -> IntArray:
        """Each id's state slot (new ids get a fresh one, the arrays grow as needed)."""
        if ids is self._ids:
            return self._slots
        slot = self._slot
        out = np.empty(len(ids), dtype=np.int64)
        for j, vid in enumerate(ids):
            k = slot.get(vid)
            if k is None:
                k = len(slot)
                if k >= self._t.shape[0]:
                    grow = self._t.shape[0]
                    self._t = np.concatenate([self._t, np.full(grow, np.nan)])
                    self._v = np.concatenate([self._v, np.zeros(grow)])
                    self._a = np.concatenate([self._a, np.zeros(grow)])
                    self._ty = np.concatenate([self._ty, np.full(grow, np.nan)])
                    self._w = np.concatenate([self._w, np.zeros(grow)])
                    self._on = np.concatenate([self._on, np.zeros(grow)])
                slot[vid] = k
            out[j] = k
        self._ids, self._slots = ids, out
        return out

    def update(self, t_s: float, traffic: Traffic) -> FloatArray:
        """Feed the speeds at time ``t_s`` [s]; returns the estimates, shape (n,) [m/s²]."""
        slots = self._slots_of(traffic.ids)
        out = np.empty(slots.shape[0], dtype=np.float64)
        _filter(float(t_s), np.ascontiguousarray(traffic.speed_mps, dtype=np.float64), slots,
                self._t, self._v, self._a, self.params.tau_s, self.params.forget_s, out)
        if len(self._slot) > 2 * traffic.count + 16:
            self._forget(float(t_s))
        return out

    def lateral(self, t_s: float, ids: tuple[str, ...], v_y_mps: FloatArray) -> FloatArray:
        """Feed the lateral speeds across the path [m/s] of the vehicles ``ids`` at time
        ``t_s`` [s] (after :meth:`update` of the same step); returns each speed where the
        filtered one counts as a deliberate lateral motion, else 0, shape (n,) [m/s]."""
        slots = self._slots_of(ids)
        out = np.empty(slots.shape[0], dtype=np.float64)
        p = self.params
        _lateral(float(t_s), np.ascontiguousarray(v_y_mps, dtype=np.float64), slots,
                 self._ty, self._w, self._on, p.lateral_tau_s, p.lateral_enter_mps,
                 p.lateral_exit_mps, p.forget_s, out)
        return out

    def _forget(self, t_s: float) -> None:
        """Drop the vehicles unseen for longer than ``forget_s`` (compacting the slots)."""
        keep = [(vid, k) for vid, k in self._slot.items()
                if not t_s - float(self._t[k]) > self.params.forget_s]
        old = np.array([k for _, k in keep], dtype=np.int64)
        size = max(64, self._t.shape[0])
        t, v, a = np.full(size, np.nan), np.zeros(size), np.zeros(size)
        t[: old.size], v[: old.size], a[: old.size] = self._t[old], self._v[old], self._a[old]
        self._t, self._v, self._a = t, v, a
        ty, w, on = np.full(size, np.nan), np.zeros(size), np.zeros(size)
        ty[: old.size], w[: old.size], on[: old.size] = (self._ty[old], self._w[old],
                                                         self._on[old])
        self._ty, self._w, self._on = ty, w, on
        self._slot = {vid: n for n, (vid, _) in enumerate(keep)}
        self._ids = None


__all__ = ["AccelerationTracker", "TrackingParams"]
