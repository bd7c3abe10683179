"""Threat braking: a floor under the braking while an obstacle ahead needs more than
comfort, held until the need is gone.

The planner brakes for an obstacle through its plan, and the plan can ease off while the
gap still closes (a C/GMRES solution that catches up with a cut-in, a fallback whose
ramp settles, a wall ellipse reshaped as the ego closes in). The required deceleration
is measured directly instead, every period, from the gap now:

    b_k = (v - v_j)² / (2 d_j)      (:func:`~controllers.two_loop.fallback.most_urgent_obstacle`)

with v the ego's speed, v_j the obstacle's speed along the path and d_j its distance
less the standstill margin (the bumper gap less ``standstill_m`` where the boxes are
close); for a lead that brakes, its own braking counted
(:func:`~controllers.two_loop.fallback.braking_need_mps2`). Braking at b_k from now on
ends the closing exactly ``standstill_m`` short of the obstacle; braking at ``margin``
b_k (> b_k) ends it with room to spare, and b_k then falls.

The floor F_k [m/s²] is the least deceleration handed out:

* **engage** on an emergency (:func:`controllers.two_loop.fallback.planner_emergency`:
  the plan brakes beyond comfort *and* ``NEED_MARGIN`` b_k is beyond comfort; or the
  minimal-risk manoeuvre braces beyond comfort): the plan's own braking is required
  too, so that an obstacle the plan steers round (an evasion) engages nothing;
* **while active**, F_k = min(max(F_{k-1}, margin b_k), ``max_decel_mps2``) when b_k
  rises (b_k >= b_{k-1}): it never decreases while the threat grows; when b_k falls,
  F_k = min(margin b_k, ``max_decel_mps2``) (braking that matched the threat may
  relax as the threat recedes);
* **release** only when ``margin`` b_k has fallen below ``release_decel_mps2`` (below
  comfort): hysteresis, so that the floor does not flicker at the comfort bound.

The controller caps its torque at -m R F_k (the deceleration F_k; drag and rolling
resistance add to it) and lets the jerk limiter raise its bounds to
``onset_jerk_mps3`` of F_k while the floor acts. A floor only ever adds braking: it
never steers and never lowers what the plan asks. ``reason`` records which stage set
each period's braking (:class:`BrakeSource`), so the trace says why.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

from controllers.params import check_leaves, check_range, param


class BrakeSource(IntEnum):
    """Which stage set a period's longitudinal command (the trace's ``brake_source``)."""

    PLAN = 0  # the outer plan through the inner loop
    THREAT_FLOOR = 1  # the threat floor: the plan asked less than the threat needs
    FALLBACK = 2  # the minimal-risk manoeuvre drives (the planner failed)
    LAUNCH = 3  # the standstill launch law drives or blends out
    SAFE_STOP = 4  # a non-finite command replaced by lane-keeping braking


@dataclass(frozen=True)
class ThreatBrakeParams:
    """The threat floor (module docstring)."""

    enabled: bool = param(True, "-", "hold braking at the threat's need (off: the plan's)")
    margin: float = param(1.2, "-", "braking is held at this multiple of the need b")
    release_decel_mps2: float = param(2.0, "m/s²", "margin b below which it releases")
    max_decel_mps2: float = param(9.0, "m/s²", "highest floor (about the tyres' limit on "
                                  "a dry road)")

    def __post_init__(self) -> None:
        check_leaves(self)
        check_range(self, "margin", ge=1.0)
        for name in ("release_decel_mps2", "max_decel_mps2"):
            check_range(self, name, gt=0.0)
        check_range(self, "max_decel_mps2", ge=self.release_decel_mps2)


class ThreatFloor:
    """State: whether the floor is active, its value F [m/s²] and the last need b."""

    def __init__(self, params: ThreatBrakeParams) -> None:
        self.params = params
        self.active = False
        self.floor_mps2 = 0.0
        self._need_prev = 0.0

    def reset(self) -> None:
        self.active = False
        self.floor_mps2 = 0.0
        self._need_prev = 0.0

    def update(self, need_mps2: float, emergency: bool) -> float:
        """This period's floor F [m/s²] (0 when inactive) from the need b [m/s²] and
        whether this period is an emergency (module docstring; a non-finite b, the CG
        already inside the margin and closing, is the highest floor)."""
        p = self.params
        if not p.enabled:
            return 0.0
        need = need_mps2 if math.isfinite(need_mps2) else math.inf
        want = min(p.margin * need, p.max_decel_mps2)
        if not self.active:
            if emergency:
                self.active, self.floor_mps2 = True, want
        elif p.margin * need < p.release_decel_mps2:
            self.active, self.floor_mps2 = False, 0.0
        elif need >= self._need_prev:
            self.floor_mps2 = min(max(self.floor_mps2, want), p.max_decel_mps2)
        else:
            self.floor_mps2 = want
        self._need_prev = need
        return self.floor_mps2 if self.active else 0.0
