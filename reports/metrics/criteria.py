"""Pass/fail criteria on run metrics, and the typed failures they produce.

Each criterion bounds one metric: its catalogue entry's
:class:`~reports.metrics.spec.Criterion` (:mod:`reports.metrics.catalogue`, which
:data:`CRITERIA_METRICS` lists, criterion -> (metric, bound), in check order) gives its
name, bound and default limit: ``max`` fails when the value exceeds the limit, ``min``
when it is below it. A criterion whose limit is
``None`` is off; one whose metric is NaN (not measurable in this run) is skipped.
Defaults and the reasoning behind them are in ``docs/metrics.md``.

Where a failure happened (``Failure.step``, a trace row, and ``Failure.t_s``):

* cumulative metrics (durations and counts: collision, at_fault_collisions, offroad_s,
  shoulder_s, deadline_misses, fallbacks) carry per-step increments; the step is the first row
  at which their running total exceeds the limit (with the default limit 0: the
  first collision, the first step off the road, ...);
* extremes (accelerations, jerks, TTC, gaps, margins, residual, ...) fail where the
  extreme was attained: their ``worst_step``;
* aggregates (rms_lat_dev_m, progress_ratio) have no step (None).

At that step the failure also records the manoeuvre phase (``Failure.phase``: the
trace's decision ``side`` named by :data:`reports.record.verdict.PHASES`) and whether a
safe fallback had replaced the controller's plan (``Failure.fell_back``: the trace's
``fallback`` column), so that what was going on when it failed (the search's failure
mode) is read from the verdict, never from the trace again.

Overrides: the catalog's ``criteria`` table (``info.criteria``) maps field names of
:class:`Criteria` to numbers; the string ``"off"`` (:data:`OFF`; TOML has no null) or
``None`` disables a criterion; unknown names raise. :func:`override_problem` is the
one check both the catalog loader and :meth:`Criteria.from_overrides` apply.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from reports.metrics.catalogue import CRITERIA, CRITERIA_METRICS
from reports.metrics.values import Measured
from reports.record import Failure
from reports.record.verdict import phase_name

__all__ = ["CRITERIA_METRICS", "OFF", "STEPS_CRITERION", "Criteria", "fell_back_at",
           "override_limit", "override_problem", "phase_at", "steps_failure",
           "violation_step"]

# Not a Criteria field: a run without trace rows has nothing to judge and fails this.
STEPS_CRITERION = "min_steps"

# The override value that switches a criterion off (TOML has no null).
OFF = "off"


def override_problem(value: Any) -> str | None:
    """Why ``value`` is not a valid criterion override (None when it is): a finite
    number, :data:`OFF` or ``None``."""
    if value is None or value == OFF:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float) \
            or not math.isfinite(float(value)):
        return f'a finite number or "{OFF}"'
    return None


def override_limit(value: Any) -> float | None:
    """The limit an accepted override sets: None (off) for :data:`OFF`/None, else the
    number as float. Raises ValueError for a value :func:`override_problem` refuses."""
    problem = override_problem(value)
    if problem is not None:
        raise ValueError(f"expected {problem}, got {value!r}")
    return None if value is None or value == OFF else float(value)


@dataclass(frozen=True, init=False)
class Criteria:
    """The limit of every criterion of the catalogue (:data:`CRITERIA_METRICS` order);
    ``None`` disables one. ``Criteria(min_ttc_s=1.2, max_collision=None)``: the
    catalogue's defaults with those replaced (TypeError for a name the catalogue has no
    criterion of); ``criteria.min_ttc_s`` reads one limit [the metric's unit]."""

    limits: tuple[tuple[str, float | None], ...]

    def __init__(self, **limits: float | None) -> None:
        unknown = sorted(set(limits) - set(CRITERIA))
        if unknown:
            raise TypeError(f"Criteria: unknown criteria {unknown}")
        object.__setattr__(self, "limits", tuple(
            (name, limits[name] if name in limits else entry.criterion.default
             if entry.criterion is not None else None) for name, entry in CRITERIA.items()))
        self.__post_init__()

    def __post_init__(self) -> None:
        for name, limit in self.limits:
            if limit is not None and (isinstance(limit, bool)
                                      or not isinstance(limit, int | float)
                                      or math.isnan(limit)):
                raise ValueError(f"Criteria.{name}: a number or None, got {limit!r}")

    def __getattr__(self, name: str) -> float | None:
        for key, limit in object.__getattribute__(self, "limits"):
            if key == name:
                return limit  # type: ignore[no-any-return]
        raise AttributeError(f"Criteria has no criterion {name!r}")

    def limit(self, criterion: str) -> float | None:
        """The limit of ``criterion`` (None: off); KeyError for an unknown name."""
        for key, limit in self.limits:
            if key == criterion:
                return limit
        raise KeyError(criterion)

    @classmethod
    def names(cls) -> list[str]:
        """Valid criterion (override) names."""
        return list(CRITERIA)

    @classmethod
    def from_overrides(cls, overrides: Mapping[str, Any] | None = None,
                       base: Criteria | None = None) -> Criteria:
        """Defaults (or ``base``) with ``overrides`` applied; validates names and values.

        Raises ValueError naming an unknown key (and listing the valid ones) or a value
        that is neither a finite number nor ``"off"``/None (:func:`override_problem`).
        """
        base = base if base is not None else cls()
        if not overrides:
            return base
        if not isinstance(overrides, Mapping):
            raise ValueError("criteria overrides must be a mapping, got "
                             f"{type(overrides).__name__}")
        valid = cls.names()
        changes: dict[str, float | None] = {}
        for key, value in overrides.items():
            if key not in valid:
                raise ValueError(f"unknown criterion {key!r}; valid criteria: {', '.join(valid)}")
            problem = override_problem(value)
            if problem is not None:
                raise ValueError(f"criterion {key!r}: expected {problem}, got {value!r}")
            changes[key] = override_limit(value)
        return cls(**{**base.as_dict(), **changes})

    def as_dict(self) -> dict[str, float | None]:
        """Criterion name -> limit (stored as ``Verdict.criteria``)."""
        return dict(self.limits)

    def check(self, metrics: Sequence[Measured], t_s: np.ndarray | None = None, *,
              side: np.ndarray | None = None, fallback: np.ndarray | None = None
              ) -> tuple[Failure, ...]:
        """The failed criteria, in :data:`CRITERIA_METRICS` order, each located (see the
        module doc); the trace's columns (T,) give their times (``t_s`` [s]), phases
        (``side``: decision side codes) and fallbacks (``fallback``: bool); one not
        given leaves that field unknown."""
        by_name = {m.name: m for m in metrics}
        failed: list[Failure] = []
        for criterion, limit in self.limits:
            name, bound = CRITERIA_METRICS[criterion]
            found = by_name.get(name)
            if limit is None or found is None or math.isnan(found.metric.value):
                continue
            value = found.metric.value
            if (bound == "max" and value > limit) or (bound == "min" and value < limit):
                step = violation_step(found, limit, bound)
                failed.append(Failure(criterion=criterion, metric=name, value=value,
                                      limit=float(limit), bound=bound, unit=found.metric.unit,
                                      step=step, t_s=_time_at(t_s, step),
                                      phase=phase_at(side, step),
                                      fell_back=fell_back_at(fallback, step)))
        return tuple(failed)


def violation_step(found: Measured, limit: float, bound: str) -> int | None:
    """The trace row where a failed criterion was violated (see the module doc)."""
    inc = found.increments
    if inc is not None and bound == "max" and inc.size:
        over = np.flatnonzero(np.cumsum(np.nan_to_num(inc)) > limit)
        if over.size:
            return int(over[0])
        # rounding put the total a hair under the limit: the last contributing row
        contributing = np.flatnonzero(np.nan_to_num(inc) > 0)
        return int(contributing[-1]) if contributing.size else None
    return found.metric.worst_step


def _time_at(t_s: np.ndarray | None, step: int | None) -> float | None:
    if t_s is None or step is None or not 0 <= step < t_s.size:
        return None
    value = float(t_s[step])
    return value if math.isfinite(value) else None


def _row(column: np.ndarray | None, step: int | None) -> Any:
    """``column[step]`` (None without the column, the step, or past its end)."""
    if column is None or step is None or not 0 <= step < column.shape[0]:
        return None
    return column[step]


def phase_at(side: np.ndarray | None, step: int | None) -> str:
    """The manoeuvre phase at trace row ``step``: ``phase_name`` of the decision
    ``side`` code there (:mod:`reports.record.verdict`); '' when unknown."""
    code = _row(side, step)
    return phase_name(int(code)) if code is not None else ""


def fell_back_at(fallback: np.ndarray | None, step: int | None) -> bool | None:
    """Whether a safe fallback replaced the plan at trace row ``step`` (None: unknown)."""
    flag = _row(fallback, step)
    return bool(flag) if flag is not None else None


def steps_failure() -> Failure:
    """The failure of a run without trace rows (``steps=0<1``)."""
    return Failure(criterion=STEPS_CRITERION, metric="steps", value=0.0, limit=1.0,
                   bound="min", unit="-")
