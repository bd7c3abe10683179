"""Robustness: one signed number per run, from the criteria that judge it.

Every criterion in force (a limit ``L`` that is not None, a metric value ``v`` that is
not NaN: exactly the criteria :meth:`reports.metrics.criteria.Criteria.check` tests)
gives a *margin* ``rho_c``, normalised by the criterion's scale ``s_c``
(:data:`SCALES`, in the criterion's unit: the catalogue's ``Criterion.scale``)::

    bound 'max' (fails when v > L):   rho_c = (L - v) / s_c
    bound 'min' (fails when v < L):   rho_c = (v - L) / s_c

The cumulative criteria (:data:`CUMULATIVE`: counts and durations, whose value is a
sum of per-step increments >= 0 and whose limit is usually 0) would give 0 to every run
that meets them, so they add a *headroom* ``h`` in [0, 1] while met, and a *severity*
``d`` >= 0 once failed::

    v <= L:  rho_c = (L - v) / s_c + h        v > L:  rho_c = -((v - L) / s_c + d)

* collisions (``max_at_fault_collisions``, ``max_collision``): ``h = g / 1 m`` with
  ``g`` the run's smallest box-to-box gap ``min_gap_m`` [m] (+inf when never measured),
  so a near miss scores near 0; ``d = dv / 1 m/s`` with ``dv`` the ego's delta-v of its
  worst at-fault collision ``max_at_fault_delta_v_mps`` [m/s] (0 if none or NaN), so a
  crash is more negative than a graze;
* ``max_offroad_s``: ``h = (0.3 m - e) / 0.1 m`` with ``e`` the largest corner excess
  ``max_offroad_m`` [m] (0 when always inside; a corner counts as off beyond the 0.3 m
  tolerance, so ``h`` is 3 on the road and 0 at the tolerance), ``d = e / 1 m`` once off;
* the others (``max_shoulder_s``, ``max_deadline_misses``, ``max_fallbacks``): counts
  with no measure of how near they came, ``h = +inf`` (they never attain the minimum
  while met), ``d = 0``.

A failure the criteria table has no metric for (``min_steps``, a run without trace
rows) gives its own ``(value - limit) / 1`` or ``(limit - value) / 1``.

The run's robustness is the minimum over these margins and its criterion the one that
attains it (the first in :data:`~reports.metrics.criteria.CRITERIA_METRICS` order on a
tie): ``rho < 0`` exactly when some criterion failed, i.e. when the verdict is 'fail'
(a margin that rounding would make 0 or positive for a failed criterion is set to the
largest negative float, ``-5e-324``). With no criterion in force it is ``+inf``. A run
that did not end normally (status 'error' or 'timeout') has robustness NaN and its
status as criterion: it was not judged to the end.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from reports.metrics.catalogue import CRITERIA, CRITERIA_METRICS
from reports.metrics.drivable import OFFROAD_TOLERANCE_M
from reports.record import Verdict

__all__ = ["CUMULATIVE", "DEFAULT_SCALE", "SCALES", "Margin", "Robustness", "margin_of",
           "robustness"]

# criterion -> scale s_c in the criterion's unit: its catalogue entry's ``Criterion.scale``.
# Safety: its natural unit (1 s of time to collision, 1 m of gap), so that these margins
# follow the scenario (how close, how soon) and guide a search. Comfort and progress:
# about a tenth of the default limit, so that while the car cruises (accelerations near
# 0) their margins (~10) stay above the safety margins instead of capping every quiet
# run at the same value.
SCALES: dict[str, float] = {c: s.criterion.scale for c, s in CRITERIA.items()
                            if s.criterion is not None}
# a criterion the catalogue does not know (a stored run's): max(|L|, 1) in its unit
DEFAULT_SCALE = 1.0
CUMULATIVE = ("max_at_fault_collisions", "max_collision", "max_offroad_s", "max_shoulder_s",
              "max_deadline_misses", "max_fallbacks", "max_r157_gap_shortfall_s")
COLLISION_CRITERIA = ("max_at_fault_collisions", "max_collision")
GAP_SCALE_M = 1.0
DELTA_V_SCALE_MPS = 1.0
OFFROAD_EXCESS_SCALE_M = 1.0
OFFROAD_HEADROOM_SCALE_M = 0.1
_NEG_TINY = -5e-324  # the negative float nearest 0


@dataclass(frozen=True)
class Margin:
    """One criterion's signed, normalised margin ``rho_c`` [-] (module doc)."""

    criterion: str
    margin: float

    def __post_init__(self) -> None:
        if not self.criterion:
            raise ValueError("Margin.criterion must be a criterion name")
        if math.isnan(self.margin):
            raise ValueError(f"Margin.margin of {self.criterion!r} must not be NaN")


@dataclass(frozen=True)
class Robustness:
    """value [-]: min of the margins (+inf with none; NaN for an error/timeout);
    criterion: the one attaining it ('' with none; the status for error/timeout)."""

    value: float
    criterion: str
    margins: tuple[Margin, ...] = ()

    @property
    def failed(self) -> bool:
        return self.value < 0.0


def _scale(criterion: str, limit: float) -> float:
    return SCALES.get(criterion, max(abs(limit), DEFAULT_SCALE))


def _finite_or(value: float, default: float) -> float:
    return value if math.isfinite(value) else default


def _headroom(criterion: str, verdict: Verdict) -> float:
    if criterion in COLLISION_CRITERIA:
        gap = verdict.value("min_gap_m")
        return math.inf if math.isnan(gap) else max(gap, 0.0) / GAP_SCALE_M
    if criterion == "max_offroad_s":
        excess = _finite_or(verdict.value("max_offroad_m"), 0.0)
        return max(0.0, OFFROAD_TOLERANCE_M - max(excess, 0.0)) / OFFROAD_HEADROOM_SCALE_M
    return math.inf


def _severity(criterion: str, verdict: Verdict) -> float:
    if criterion in COLLISION_CRITERIA:
        return max(_finite_or(verdict.value("max_at_fault_delta_v_mps"), 0.0), 0.0) \
            / DELTA_V_SCALE_MPS
    if criterion == "max_offroad_s":
        return max(_finite_or(verdict.value("max_offroad_m"), 0.0), 0.0) \
            / OFFROAD_EXCESS_SCALE_M
    return 0.0


def margin_of(criterion: str, value: float, limit: float, bound: str,
              verdict: Verdict | None = None) -> float:
    """``rho_c`` of one criterion (module doc); ``verdict`` supplies the headroom and
    severity metrics of the cumulative criteria (None: h = +inf, d = 0)."""
    scale = _scale(criterion, limit)
    failed = value > limit if bound == "max" else value < limit
    rho = (limit - value) / scale if bound == "max" else (value - limit) / scale
    if criterion in CUMULATIVE and bound == "max":
        if failed:
            rho -= _severity(criterion, verdict) if verdict is not None else 0.0
        else:
            rho += _headroom(criterion, verdict) if verdict is not None else math.inf
    if failed and not rho < 0.0:
        return _NEG_TINY
    return rho


def robustness(verdict: Verdict) -> Robustness:
    """The run's robustness from its verdict: metric values, limits, bounds (module doc)."""
    if verdict.status not in ("pass", "fail"):
        return Robustness(math.nan, verdict.status)
    margins: list[Margin] = []
    covered: set[str] = set()
    for criterion, (metric, bound) in CRITERIA_METRICS.items():
        limit = verdict.criteria.get(criterion)
        value = verdict.value(metric)
        if limit is None or math.isnan(value):
            continue
        covered.add(criterion)
        margins.append(Margin(criterion, margin_of(criterion, value, float(limit), bound,
                                                   verdict)))
    for failure in verdict.failures:
        if failure.criterion not in covered and not math.isnan(failure.value):
            margins.append(Margin(failure.criterion, margin_of(
                failure.criterion, failure.value, failure.limit, failure.bound)))
    if not margins:
        return Robustness(math.inf, "")
    worst = min(margins, key=lambda m: m.margin)  # first on a tie
    return Robustness(worst.margin, worst.criterion, tuple(margins))
