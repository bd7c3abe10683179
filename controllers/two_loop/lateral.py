"""Lateral-reference shaper: the behaviour's stepped reference -> the OCP's smooth yr, Cy.

The behaviour layer hands over r_raw(t) [m, left +], a step to the neighbour lane's
centre while passing and back to 0 afterwards. C/GMRES tracks a moving optimum, so a
step in a parameter is a step in its residual; every control period the shaper moves

1. a rate limiter r toward r_raw by at most rate h per sub-step, with
   rate = min(``rate_mps``, V ``heading_rad``, a_move T_f e) times the planner's
   relative horizon length (V the measured speed: a slow car cannot follow the rate with
   a sensible heading; a growing C/GMRES horizon is short at first). a_move =
   max(``max_lat_acc_mps2`` - |V² kappa|, ``min_move_lat_acc_mps2``) is what the road's
   curve (kappa at the car, V² kappa its centripetal acceleration) leaves of the lateral
   acceleration for the move: the filter below turns a ramp of slope R into yr'' of at
   most R / (T_f e) (the critically damped response to a ramp, R t e^(-t/T_f) / T_f²,
   peaks at t = T_f), so the move's own lateral acceleration stays within a_move and the
   sum with the curve's within ``max_lat_acc_mps2`` (a change on a tight curve is
   stretched, not sharpened; on a straight road the bound, 2.2 m/s at the defaults, is
   above ``rate_mps`` and changes nothing); while the behaviour marks the
   move evasive (a stopped car ahead the ego cannot stop for comfortably) the
   ``evasive_*`` limits apply instead, not scaled by the horizon: an evasion cannot wait
   for the horizon to grow (a car starting 40-90 m behind a stopped one has 1.5-4 s);
2. a critically damped second-order filter (time constant T_f = ``filter_s``):
   yr'' = (r - yr)/T_f² - 2 yr'/T_f, integrated by semi-implicit Euler in sub-steps
   h <= T_f/10 (T_f = 0: yr = r, yr' = dr/dt).

yr, yr', yr'' are continuous; a change of r_raw mid-way redirects the ramp. yr starts
at the measured offset, at rest. A non-finite r_raw holds the previous one.

Weight schedule: Cy = c_y + (``c_y_engaged`` - c_y) (1 - cos(pi phi))/2 (C¹ in time),
phi in [0, 1] ramping linearly over ``weight_time_s`` toward 1 while a reference is
engaged and toward 0 otherwise. Engaged: from r_raw != 0 until, with r_raw back at 0,
both yr and the car are on it (within ``_YR_SETTLED_M`` and ``_CAR_SETTLED_M``).
Why and how the values were chosen: docs/two_loop.md "Lateral reference".

Lane corridor (:class:`LaneCorridor`): the lateral band [y_lo, y_hi] the OCP keeps the
plan's CG in (docs/two_loop.md, "Lane corridor"): the lane kept, centred on the
behaviour's reference r_raw (the centre of the lane the plan is in, exact on real nets),
its half width w/2 - b/2 - ``corridor_margin_m`` (w the lane width, b the ego's width);
from a change of r_raw (a lane change, pass, evasion, return or abort: the behaviour's
decision) the union of every lane r_raw named since, until the car and yr are settled in
the last one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from controllers.params import check_leaves, check_range, param

_YR_SETTLED_M = 0.05  # yr back on r_raw = 0 within this [m] ...
_CAR_SETTLED_M = 0.1  # ... and the car within this [m]: the reference disengages


@dataclass(frozen=True)
class LateralRefParams:
    """How the behaviour's lateral reference is smoothed before it reaches the OCP."""

    rate_mps: float = param(1.5, "m/s", "rate limit of the reference's ramp")
    filter_s: float = param(0.2, "s", "time constant of the critically damped filter (0: off)")
    heading_rad: float = param(0.1, "rad", "the rate limit is at most V times this")
    c_y_engaged: float = param(20.0, "1/(m² s)", "Cy while a lateral reference is engaged")
    weight_time_s: float = param(1.0, "s", "blend time of Cy from/to the OCP's c_y")
    evasive_rate_mps: float = param(2.5, "m/s", "rate limit while the move is evasive")
    evasive_heading_rad: float = param(0.25, "rad", "heading bound of that rate (V times this)")
    max_lat_acc_mps2: float = param(4.0, "m/s²",
                                    "lateral acceleration of a move plus the curve's V² kappa")
    min_move_lat_acc_mps2: float = param(0.4, "m/s²",
                                         "a move's own lateral acceleration on the tightest curve")
    corridor: bool = param(True, "-", "keep the plan in the lane corridor (the lanes the "
                           "behaviour allows)")
    corridor_margin_m: float = param(0.15, "m", "the lane corridor's margin: the ego's box "
                                     "stays this far inside the lane's edges")

    def __post_init__(self) -> None:
        check_leaves(self)
        for name in ("rate_mps", "heading_rad", "weight_time_s", "evasive_rate_mps",
                     "evasive_heading_rad", "max_lat_acc_mps2", "min_move_lat_acc_mps2"):
            check_range(self, name, gt=0.0)
        for name in ("filter_s", "c_y_engaged", "corridor_margin_m"):
            check_range(self, name, ge=0.0)


class LateralReferenceShaper:
    """State: r_raw held, ramp r, yr, yr' [m, m/s], weight blend phi, engaged flag.

    ``update`` once per control period; ``reference_m``, ``rate_mps`` and
    :meth:`weight` read the current yr, yr' and Cy.
    """

    def __init__(self, params: LateralRefParams) -> None:
        self.params = params
        self.reset()

    def reset(self) -> None:
        """Not started: the next ``update`` starts at the measured offset."""
        self._raw = math.nan
        self._ramp = math.nan
        self._yr = math.nan
        self._yr_rate = math.nan
        self._phi = math.nan
        self._engaged = math.nan
        self._evasive = False
        self._curvature = 0.0

    @property
    def raw_m(self) -> float:
        """The reference being approached (r_raw, the last finite one; NaN before)."""
        return self._raw

    @property
    def reference_m(self) -> float:
        """yr [m]."""
        return self._yr

    @property
    def rate_mps(self) -> float:
        """yr' [m/s]."""
        return self._yr_rate

    def weight(self, c_y: float) -> float:
        """Cy [1/(m² s)] now, blending from the OCP's ``c_y`` to ``c_y_engaged``."""
        blend = 0.5 * (1.0 - math.cos(math.pi * self._phi))  # C¹ in time
        return c_y + (self.params.c_y_engaged - c_y) * blend

    def restart(self, y_now_m: float) -> None:
        """Ramp and yr restart at the car's offset y_now_m, at rest (launch hand-over)."""
        self._ramp = self._yr = float(y_now_m)
        self._yr_rate = 0.0

    def update(self, raw_m: float, dt_s: float | None, y_now_m: float, speed_mps: float,
               rate_scale: float, evasive: bool = False, curvature_1pm: float = 0.0) -> float:
        """Advance by dt_s (None: first step, start at y_now_m at rest); returns yr [m].

        raw_m: the behaviour's reference; y_now_m: the car's lateral offset [m];
        speed_mps: its speed; rate_scale: the planner's relative horizon length in [0, 1];
        evasive: the move evades an obstacle (the evasive rate limits apply, the weight
        blends in four times faster); curvature_1pm: the reference path's curvature at
        the car [1/m] (its V² kappa bounds the move's rate, module doc).
        """
        self._curvature = float(curvature_1pm) if math.isfinite(curvature_1pm) else 0.0
        self._evasive = bool(evasive)
        if math.isfinite(raw_m):
            self._raw = raw_m
        elif not math.isfinite(self._raw):
            self._raw = 0.0
        y_ok = y_now_m if math.isfinite(y_now_m) else 0.0
        if dt_s is None or not math.isfinite(self._yr):
            self._ramp = self._yr = y_ok
            self._yr_rate = 0.0
            self._engaged = 1.0 if self._raw != 0.0 else 0.0
            self._phi = self._engaged
            return self._yr
        self._update_weight(dt_s, y_ok)
        self._advance(dt_s, speed_mps, rate_scale)
        return self._yr

    def _update_weight(self, dt_s: float, y_ok: float) -> None:
        # Engaged from a non-zero reference until both yr and the car are back on it.
        engaged = self._raw != 0.0 or (self._engaged > 0.5 and (
            abs(self._yr - self._raw) > _YR_SETTLED_M or abs(y_ok - self._raw) > _CAR_SETTLED_M))
        self._engaged = 1.0 if engaged else 0.0
        step = dt_s / self.params.weight_time_s * (4.0 if self._evasive else 1.0)
        self._phi = min(self._phi + step, 1.0) if engaged else max(self._phi - step, 0.0)

    def move_rate_bound_mps(self, speed_mps: float) -> float:
        """The ramp's rate bound [m/s] from the lateral acceleration the curve leaves:
        a_move T_f e (module doc); unbounded without the filter (T_f = 0)."""
        p = self.params
        if p.filter_s <= 0.0:
            return math.inf
        curve = speed_mps * speed_mps * abs(self._curvature)
        a_move = max(p.max_lat_acc_mps2 - curve, p.min_move_lat_acc_mps2)
        return a_move * p.filter_s * math.e

    def _advance(self, dt_s: float, speed_mps: float, rate_scale: float) -> None:
        p = self.params
        tf = p.filter_s
        n_sub = 1 if tf <= 0.0 else max(1, math.ceil(dt_s / (0.1 * tf)))
        h = dt_s / n_sub
        v = speed_mps if math.isfinite(speed_mps) and speed_mps > 0.0 else 0.0
        if self._evasive:
            rate = min(p.evasive_rate_mps, v * p.evasive_heading_rad)
        else:
            rate = min(p.rate_mps, v * p.heading_rad, self.move_rate_bound_mps(v))
        rate *= 1.0 if self._evasive else rate_scale
        max_step = rate * h
        r, yr, yd = self._ramp, self._yr, self._yr_rate
        for _ in range(n_sub):
            r_prev = r
            r += min(max(self._raw - r, -max_step), max_step)
            if tf <= 0.0:
                yd = (r - r_prev) / h
                yr = r
            else:
                yd += h * ((r - yr) / (tf * tf) - 2.0 * yd / tf)
                yr += h * yd
        self._ramp, self._yr, self._yr_rate = r, yr, yd


_CORRIDOR_MIN_HALF_M = 0.1  # the corridor's least half width [m] (a lane barely the car's)
_CORRIDOR_SAME_LANE_M = 0.05  # r_raw moving less than this is the same lane [m]


class LaneCorridor:
    """The lane corridor [y_lo, y_hi] [m, left +] of the OCP (module doc).

    ``update`` once per control period with the behaviour's r_raw, the car's offset and
    the shaper's yr; ``bounds_m`` reads it. The corridor only widens while a change is
    under way (a parameter step of an exterior penalty is no step in the residual of a
    plan inside it) and narrows to the target lane once the car is inside it and yr has
    settled on r_raw.
    """

    def __init__(self, params: LateralRefParams) -> None:
        self.params = params
        self.half_width_m = math.inf
        self.reset(math.inf, 0.0)

    def reset(self, lane_width_m: float, ego_width_m: float) -> None:
        """Not started; the half width from the lane's and the ego's widths [m]."""
        half = 0.5 * lane_width_m - 0.5 * ego_width_m - self.params.corridor_margin_m
        self.half_width_m = max(half, _CORRIDOR_MIN_HALF_M) if math.isfinite(half) else math.inf
        self._centre = math.nan
        self._lo = -math.inf
        self._hi = math.inf
        self._changing = False

    @property
    def bounds_m(self) -> tuple[float, float]:
        """(y_lo, y_hi) [m] ((-inf, inf) before the first update or when turned off)."""
        return self._lo, self._hi

    @property
    def changing(self) -> bool:
        """A change of lane is under way (the corridor spans its lanes)."""
        return self._changing

    def update(self, raw_m: float, y_now_m: float, yr_m: float) -> tuple[float, float]:
        """Advance with the behaviour's reference r_raw, the car's offset and yr [m]."""
        h = self.half_width_m
        if not self.params.corridor or not math.isfinite(h):
            self._lo, self._hi = -math.inf, math.inf
            return self.bounds_m
        raw = raw_m if math.isfinite(raw_m) else (self._centre if math.isfinite(
            self._centre) else 0.0)
        y = y_now_m if math.isfinite(y_now_m) else raw
        if not math.isfinite(self._centre):  # start: the lane, and the car where it is
            self._centre = raw
            self._lo, self._hi = min(raw - h, y), max(raw + h, y)
            self._changing = not (raw - h <= y <= raw + h)
        elif abs(raw - self._centre) > _CORRIDOR_SAME_LANE_M or self._changing:
            self._changing = True
            self._lo, self._hi = min(self._lo, raw - h), max(self._hi, raw + h)
            self._centre = raw
        else:  # the same lane (its centre may drift slowly along a real road)
            self._centre = raw
            self._lo, self._hi = raw - h, raw + h
        if self._changing and abs(y - raw) <= h and abs(yr_m - raw) <= _YR_SETTLED_M:
            self._changing = False
            self._lo, self._hi = raw - h, raw + h
        return self.bounds_m
