"""The K obstacle slots of the C/GMRES outer loop (docs/two_loop.md §4).

A slot keeps its obstacle between updates, so that the slot's unknowns Z_ij, mu_ij
(stage i, slot j) stay continuous. The slot table is ``obstacle_table(K)`` (K, OBS_COLS)
of :mod:`controllers.two_loop.outer.ocp_layout`: s, y [m] and v_s, v_y [m/s] at the
table's time stamp ``t_s``, A, B [m], active (0/1), barrier weight w in [0, 1], dw/dt [1/s].

Each update (:meth:`ObstacleSlots.update`):

1. every active slot moves to now at constant velocity, its weight ramps by dw/dt;
2. each of the first min(count, K) obstacles is matched to the active slot of its
   vehicle (``Obstacles.vehicle_ids``: a slot keeps the id of the vehicle it holds);
   an obstacle without an id, to the nearest active slot without one within
   max(3 m, A/2) along and 1 m across (the constant-velocity prediction of the slot's
   previous centre);
3. a slot whose obstacle is gone fades out (dw/dt = -1 / obstacle_fade_s) and becomes
   inert (trivial rows Z = 1, mu = 0) once w = 0 and |mu_ij| <= 1e-3 Cz at every stage;
4. a new obstacle takes an inert slot, else the weakest fading one; it fades in from
   w = 0 (at full weight at the very first update) with Z, mu set so that its rows vanish
   on the current plan (``activate_slot``).
"""

from __future__ import annotations

import math

import numpy as np

from controllers.protocol import Obstacles
from controllers.two_loop.outer.ocp_layout import obstacle_table, stage_width
from controllers.two_loop.outer.ocp_start import activate_slot, deactivate_slot
from controllers.two_loop.outer.params import CgmresParams

__all__ = ["ObstacleSlots"]


class ObstacleSlots:
    """The slot table of :class:`controllers.two_loop.outer.cgmres.CgmresOuter`.

    params: the solver's settings (n_stages, c_z, obstacle_fade_s); n_slots: K;
    w: the stage fractions (N+1,) of the horizon. ``table`` (K, OBS_COLS) is what the
    kernels read; ``t_s`` its time stamp [s]; ``vehicle_ids`` (K,) the vehicle each slot
    holds ('' none, or an obstacle without an id). The unknowns U (N (2 + 2K),) are the
    planner's: the methods that touch Z, mu take them as an argument (in place).
    """

    def __init__(self, params: CgmresParams, n_slots: int, w: np.ndarray) -> None:
        if not (isinstance(n_slots, int) and n_slots >= 0):
            raise ValueError(f"n_slots must be an int >= 0, got {n_slots!r}")
        self.params = params
        self.n_slots = n_slots
        self.w = w
        self.table = obstacle_table(n_slots)
        self.t_s = 0.0
        self.vehicle_ids: list[str] = [""] * n_slots

    def clear(self) -> None:
        """Every slot inert (a new table; the time stamp is kept)."""
        self.table = obstacle_table(self.n_slots)
        self.vehicle_ids = [""] * self.n_slots

    def update(self, t_s: float, obstacles: Obstacles, u: np.ndarray, xs: np.ndarray,
               horizon_s: float, prm: np.ndarray, initialised: bool) -> None:
        """Keep each obstacle in its slot; fade slots in and out (module docstring).

        u: the unknowns (in place); xs (N+1, 3): the current plan's states; horizon_s:
        the horizon of that plan [s]; prm: the packed parameters of this update;
        initialised: False at the very first update (new obstacles at full weight).
        """
        if self.n_slots == 0:
            return
        self._advance(max(t_s - self.t_s, 0.0))
        used, assign = self._assign_known(obstacles)
        fade_rate = 1.0 / self.params.obstacle_fade_s
        # Slots whose obstacle is gone fade out, then become inert.
        tab = self.table
        for j in range(self.n_slots):
            if tab[j, 6] > 0.5 and not used[j]:
                tab[j, 8] = -fade_rate
                if tab[j, 7] <= 0.0 and self._multipliers_gone(u, j):
                    self._free(u, j)
        for q in range(assign.shape[0]):
            new = assign[q] < 0
            if new:
                j_new = self._take(u, used)
                if j_new < 0:
                    continue
                assign[q] = j_new
                used[j_new] = True
            self._fill(int(assign[q]), obstacles, q, new, fade_rate, initialised)
            if new and initialised:
                activate_slot(u, xs, horizon_s, 0.0, self.w, prm, self.table, int(assign[q]))
        self.t_s = t_s

    def _advance(self, dt: float) -> None:
        """Every active slot to dt later: constant velocity, weight ramp."""
        tab = self.table
        for j in range(self.n_slots):
            if tab[j, 6] > 0.5:
                tab[j, 0] += tab[j, 2] * dt
                tab[j, 1] += tab[j, 3] * dt
                tab[j, 7] = min(max(tab[j, 7] + tab[j, 8] * dt, 0.0), 1.0)

    def _assign_known(self, obstacles: Obstacles) -> tuple[np.ndarray, np.ndarray]:
        """(used (K,) bool, assign (n,) slot or -1): each of the first n = min(count, K)
        obstacles matched to the active slot of its vehicle id, or (an obstacle without
        an id) to the nearest active slot without one within 3 m / half its A along and
        1 m across."""
        tab = self.table
        k = self.n_slots
        n_in = min(obstacles.count, k)
        used = np.zeros(k, dtype=bool)
        assign = np.full(n_in, -1, dtype=np.int64)
        ids = obstacles.vehicle_ids
        for q in range(n_in):
            vid = ids[q] if ids else ""
            if vid:
                j = self._slot_of(vid)
                if j >= 0 and not used[j]:
                    used[j] = True
                    assign[q] = j
                continue
            best, best_d = -1, math.inf
            for j in range(k):
                if used[j] or tab[j, 6] < 0.5 or self.vehicle_ids[j]:
                    continue
                ds = abs(float(obstacles.s_m[q]) - tab[j, 0])
                dy = abs(float(obstacles.y_m[q]) - tab[j, 1])
                if ds < max(3.0, 0.5 * tab[j, 4]) and dy < 1.0 and ds + dy < best_d:
                    best, best_d = j, ds + dy
            if best >= 0:
                used[best] = True
                assign[q] = best
        return used, assign

    def _slot_of(self, vehicle_id: str) -> int:
        """The active slot holding ``vehicle_id`` (-1 none)."""
        for j in range(self.n_slots):
            if self.vehicle_ids[j] == vehicle_id and self.table[j, 6] > 0.5:
                return j
        return -1

    def _multipliers_gone(self, u: np.ndarray, j: int) -> bool:
        """Slot j's multipliers mu_ij have decayed (|mu| <= 1e-3 Cz at every stage): only
        then do its rows become the trivial ones. Freed while mu still lags behind the
        faded weight, the mu dc/dx terms vanish from every costate at once and E jumps
        (to ~4 one step after the fade-out, before this check)."""
        p = self.params
        m = stage_width(self.n_slots)
        mu = u.reshape(p.n_stages, m)[:, 2 + self.n_slots + j]
        return bool(np.max(np.abs(mu)) <= 1e-3 * p.c_z)

    def _free(self, u: np.ndarray, j: int) -> None:
        self.table[j] = obstacle_table(1)[0]
        self.vehicle_ids[j] = ""
        deactivate_slot(u, self.params.n_stages, self.n_slots, j)

    def _take(self, u: np.ndarray, used: np.ndarray) -> int:
        """A free slot for a new obstacle: an inert one, else the weakest fading one
        (its multipliers are the smallest), freed; -1 if every slot is in use."""
        tab = self.table
        free = [j for j in range(self.n_slots) if not used[j] and tab[j, 6] < 0.5]
        if free:
            return free[0]
        fading = [j for j in range(self.n_slots) if not used[j]]
        if not fading:
            return -1
        jf = min(fading, key=lambda jj: tab[jj, 7])
        self._free(u, jf)
        return jf

    def _fill(self, j: int, obstacles: Obstacles, q: int, new: bool, fade_rate: float,
              initialised: bool) -> None:
        """Write obstacle q into slot j; a new one fades in (at full weight at the very
        first update); the slot takes the obstacle's vehicle id ('' none)."""
        tab = self.table
        self.vehicle_ids[j] = obstacles.vehicle_ids[q] if obstacles.vehicle_ids else ""
        tab[j, 0] = float(obstacles.s_m[q])
        tab[j, 1] = float(obstacles.y_m[q])
        tab[j, 2] = float(obstacles.speed_s_mps[q])
        tab[j, 3] = float(obstacles.speed_y_mps[q])
        tab[j, 4] = max(float(obstacles.semi_a_m[q]), 1e-3)
        tab[j, 5] = max(float(obstacles.semi_b_m[q]), 1e-3)
        if new:
            tab[j, 6] = 1.0
            tab[j, 7] = 0.0 if initialised else 1.0
        tab[j, 8] = fade_rate if tab[j, 7] < 1.0 else 0.0
