"""Pass/fail criteria on run metrics.

Defaults are nuPlan's comfort bounds (long acc in [−4.05, 2.40] m/s², |lat acc| ≤ 4.89
m/s², |yaw acc| ≤ 1.93 rad/s², |yaw rate| ≤ 0.95 rad/s, |long jerk| ≤ 4.13 m/s³,
|jerk| ≤ 8.37 m/s³) plus: no collision, no drivable-area violation (``offroad_s`` ≤ 0),
TTC ≥ 0.95 s, and progress ≥ 0.5 × expected progress.

* TTC: ``min_ttc_s`` only counts steps where the ego moves (≥ 0.5 m/s) and vehicles not
  behind it (see :mod:`reports.metrics.safety`): a short TTC while standing behind a
  stopped car, or while being caught up from behind, does not fail the run.
* Progress: ``progress_ratio`` = progress along the reference path / the distance the
  speed set-point would cover over the run, capped at the route length remaining at
  the start (so a run longer than the route is not asked to drive past its end, and a
  run shorter than the route is judged on its own duration). The set-point is the one
  given each step, which the runner lowers to follow a blocking car when no side is
  free — following is not a progress failure.
* A criterion whose metric is NaN (not measurable, e.g. no comfort signal) is skipped;
  a run with no trace rows fails with ``steps=0<1``.

Overrides: ``run.json["criteria"]`` (from the catalog) maps field names of
:class:`Criteria` to numbers; ``null`` disables a criterion. Unknown names raise.
Each failure reads ``metric=value>limit`` (upper bound exceeded) or
``metric=value<limit`` (lower bound not reached).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields, replace
from typing import Any

# criterion field -> (metric name, bound kind: "max" fails if value > limit,
#                     "min" fails if value < limit)
CRITERIA_METRICS: dict[str, tuple[str, str]] = {
    "max_collision": ("collision", "max"),
    "max_offroad_s": ("offroad_s", "max"),
    "min_ttc_s": ("min_ttc_s", "min"),
    "min_progress_fraction": ("progress_ratio", "min"),
    "min_long_acc_mps2": ("min_long_acc_mps2", "min"),
    "max_long_acc_mps2": ("max_long_acc_mps2", "max"),
    "max_abs_lat_acc_mps2": ("max_abs_lat_acc_mps2", "max"),
    "max_abs_yaw_rate_radps": ("max_abs_yaw_rate_radps", "max"),
    "max_abs_yaw_acc_radps2": ("max_abs_yaw_acc_radps2", "max"),
    "max_abs_long_jerk_mps3": ("max_abs_long_jerk_mps3", "max"),
    "max_abs_jerk_mps3": ("max_abs_jerk_mps3", "max"),
    "min_gap_m": ("min_gap_m", "min"),
    "min_ellipse_margin": ("min_ellipse_margin", "min"),
    "max_shoulder_s": ("shoulder_s", "max"),
    "max_rms_lat_dev_m": ("rms_lat_dev_m", "max"),
    "max_final_abs_lat_dev_m": ("final_abs_lat_dev_m", "max"),
    "max_deadline_misses": ("deadline_misses", "max"),
    "max_fallbacks": ("fallbacks", "max"),
    "max_residual": ("residual_max", "max"),
}


@dataclass(frozen=True)
class Criteria:
    """Limits; ``None`` disables a criterion. Units are in the names."""

    max_collision: float | None = 0.0
    max_offroad_s: float | None = 0.0
    min_ttc_s: float | None = 0.95
    min_progress_fraction: float | None = 0.5
    min_long_acc_mps2: float | None = -4.05
    max_long_acc_mps2: float | None = 2.40
    max_abs_lat_acc_mps2: float | None = 4.89
    max_abs_yaw_rate_radps: float | None = 0.95
    max_abs_yaw_acc_radps2: float | None = 1.93
    max_abs_long_jerk_mps3: float | None = 4.13
    max_abs_jerk_mps3: float | None = 8.37
    # off by default; a catalog may enable them
    min_gap_m: float | None = None
    min_ellipse_margin: float | None = None
    max_shoulder_s: float | None = None
    max_rms_lat_dev_m: float | None = None
    max_final_abs_lat_dev_m: float | None = None
    max_deadline_misses: float | None = None
    max_fallbacks: float | None = None
    max_residual: float | None = None

    @classmethod
    def names(cls) -> list[str]:
        """Valid criterion (override) names."""
        return [f.name for f in fields(cls)]

    @classmethod
    def from_overrides(cls, overrides: Mapping[str, Any] | None = None,
                       base: Criteria | None = None) -> Criteria:
        """Defaults (or ``base``) with ``overrides`` applied; validates names and values.

        Raises ValueError naming an unknown key (and listing the valid ones) or a value
        that is neither a finite number nor null.
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
            if value is None:
                changes[key] = None
                continue
            if isinstance(value, bool) or not isinstance(value, int | float) \
                    or not math.isfinite(float(value)):
                raise ValueError(f"criterion {key!r}: expected a finite number or null, "
                                 f"got {value!r}")
            changes[key] = float(value)
        return replace(base, **changes)

    def as_dict(self) -> dict[str, float | None]:
        """Field name -> limit (for run.json)."""
        return asdict(self)

    def check(self, metrics: Mapping[str, float]) -> list[str]:
        """Failed criteria as ``metric=value>limit`` / ``metric=value<limit`` strings."""
        failed: list[str] = []
        for name, (metric, kind) in CRITERIA_METRICS.items():
            limit = getattr(self, name)
            if limit is None:
                continue
            value = metrics.get(metric, float("nan"))
            try:
                value = float(value)
            except (TypeError, ValueError):
                continue
            if math.isnan(value):
                continue
            if kind == "max" and value > limit:
                failed.append(f"{metric}={fmt_value(value)}>{fmt_value(limit)}")
            elif kind == "min" and value < limit:
                failed.append(f"{metric}={fmt_value(value)}<{fmt_value(limit)}")
        return failed


def fmt_value(value: float) -> str:
    """Compact number for failure strings (4 significant digits)."""
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    return f"{value:.4g}"


def parse_failure(text: str) -> tuple[str, float, str, float] | None:
    """``"name=value>limit"`` -> (name, value, op, limit); None if it doesn't parse."""
    if "=" not in text:
        return None
    name, rest = text.split("=", 1)
    for op in (">", "<"):
        if op in rest:
            value, limit = rest.split(op, 1)
            try:
                return name, float(value), op, float(limit)
            except ValueError:
                return None
    return None
