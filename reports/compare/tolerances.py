"""What counts as a change worth reporting: per-metric tolerances, timing ratios, gates.

The defaults are the metric catalogue's (:mod:`reports.metrics.catalogue`: each entry's
``tolerance`` and, for a timing metric, ``timing_ratio``). Behaviour metrics (kinds
:data:`GATE_KINDS`, default safety, comfort, tracking) fail the
comparison when they move in their worse direction by more than
max(abs, rel·|base|); the direction is the metric's own ``better`` unless the TOML
names one. Timing metrics (kind ``timing``: wall-clock, noisy) are compared by ratio
new/base (base/new for a metric where higher is better, e.g. ``realtime_factor``)
and only warn, unless ``timing_gate`` is set (``--timing-gate``). Health metrics warn.

Tolerances TOML (``--tolerances FILE``), every key optional::

    missing_is_regression = true
    timing_floor_ms = 0.05      # timings below this on both sides are not compared
    timing_gate = false         # true: a timing slowdown fails, like --timing-gate
    gate_kinds = ["safety", "comfort", "tracking"]
    [metrics.min_gap_m]         # merged into the default entry
    abs = 0.5
    rel = 0.1
    direction = "lower_is_worse"  # or "higher_is_worse"; default: the metric's own
    [timing]
    step_ms_p99 = 1.5           # max ratio new/base before a warning (or a failure)
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from reports.metrics.catalogue import CATALOGUE

HIGHER_IS_WORSE = "higher_is_worse"
LOWER_IS_WORSE = "lower_is_worse"
DIRECTIONS = (HIGHER_IS_WORSE, LOWER_IS_WORSE)
KINDS = ("safety", "comfort", "tracking", "timing", "health")
GATE_KINDS = ("safety", "comfort", "tracking")


@dataclass(frozen=True)
class MetricTolerance:
    """A change is beyond tolerance when |new − base| > max(abs, rel·|base|);
    ``direction`` ('' = the metric's ``better``) says which way is worse."""

    abs: float = 0.0
    rel: float = 0.0
    direction: str = ""

    def __post_init__(self) -> None:
        if self.direction not in ("", *DIRECTIONS):
            raise ValueError(f"direction must be one of {DIRECTIONS}, got {self.direction!r}")
        for name in ("abs", "rel"):
            value = getattr(self, name)
            if not isinstance(value, int | float) or isinstance(value, bool) or value < 0 \
                    or not math.isfinite(value):
                raise ValueError(f"tolerance {name} must be a finite number >= 0, got {value!r}")

    def threshold(self, base: float) -> float:
        """Allowed change for a base value (in the metric's unit)."""
        if math.isfinite(base):
            return max(self.abs, self.rel * abs(base))
        return self.abs

    def worse_direction(self, better: str) -> str:
        """The direction of a regression: explicit, else from the metric's ``better``
        ('' for an informational metric)."""
        if self.direction:
            return self.direction
        return {"lower": HIGHER_IS_WORSE, "higher": LOWER_IS_WORSE}.get(better, "")


# Tolerance of a behaviour metric the table does not name: 1e-6 absolute or 5 %.
DEFAULT_TOLERANCE = MetricTolerance(1e-6, 0.05)


def default_metric_tolerances() -> dict[str, MetricTolerance]:
    """Default per-metric tolerances (units of each metric): the catalogue's
    ``tolerance`` role (:mod:`reports.metrics.catalogue`)."""
    return {s.name: MetricTolerance(s.tolerance.abs, s.tolerance.rel)
            for s in CATALOGUE if s.tolerance is not None}


def default_timing_ratios() -> dict[str, float]:
    """Default max timing ratios (new/base; base/new where higher is better): the
    catalogue's ``timing_ratio`` role."""
    return {s.name: s.timing_ratio for s in CATALOGUE if s.timing_ratio is not None}


@dataclass(frozen=True)
class Tolerances:
    """Per-metric tolerances, timing ratios, which kinds gate, missing runs."""

    metrics: Mapping[str, MetricTolerance] = field(default_factory=default_metric_tolerances)
    timing: Mapping[str, float] = field(default_factory=default_timing_ratios)
    timing_floor_ms: float = 0.05
    missing_is_regression: bool = True
    timing_gate: bool = False
    gate_kinds: tuple[str, ...] = GATE_KINDS
    # the metric names a tolerances file set ([metrics.NAME], [timing] NAME): each must
    # be a metric of the runs compared (a typo would silently change nothing)
    named: tuple[str, ...] = ()

    def tolerance(self, metric: str) -> MetricTolerance:
        return self.metrics.get(metric, DEFAULT_TOLERANCE)

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], base: Tolerances | None = None) -> Tolerances:
        """Defaults (or ``base``) updated from a dict shaped like the TOML file."""
        base = base if base is not None else cls()
        known = {"metrics", "timing", "timing_floor_ms", "missing_is_regression",
                 "timing_gate", "gate_kinds"}
        for key in data:
            if key not in known:
                raise ValueError(f"unknown tolerances key {key!r}; "
                                 f"valid: {', '.join(sorted(known))}")
        for key in ("metrics", "timing"):
            if not isinstance(data.get(key) or {}, Mapping):
                raise ValueError(f"{key}: expected a table ([{key}] or [{key}.<name>]), "
                                 f"got {data[key]!r}")
        return cls(metrics=_metrics(data.get("metrics") or {}, base.metrics),
                   timing=_timing(data.get("timing") or {}, base.timing),
                   timing_floor_ms=_floor(data.get("timing_floor_ms", base.timing_floor_ms)),
                   missing_is_regression=_flag(data, "missing_is_regression",
                                               base.missing_is_regression),
                   timing_gate=_flag(data, "timing_gate", base.timing_gate),
                   gate_kinds=_kinds(data.get("gate_kinds", base.gate_kinds)),
                   named=tuple(sorted({*base.named, *(data.get("metrics") or {}),
                                       *(data.get("timing") or {})})))

    def unknown_names(self, metrics: set[str]) -> list[str]:
        """The names this file set that are none of ``metrics``, each with the closest
        known name when there is one (``no_such_metric (did you mean min_gap_m?)``)."""
        import difflib

        out = []
        for name in self.named:
            if name in metrics:
                continue
            close = difflib.get_close_matches(name, sorted(metrics), n=1)
            out.append(name + (f" (did you mean {close[0]}?)" if close else ""))
        return out

    @classmethod
    def from_toml(cls, path: str | Path) -> Tolerances:
        """Defaults updated from a TOML file (see the module doc)."""
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
        return cls.from_mapping(data)


def _metrics(table: Mapping[str, Any], base: Mapping[str, MetricTolerance]
             ) -> dict[str, MetricTolerance]:
    metrics = dict(base)
    for name, spec in table.items():
        if not isinstance(spec, Mapping):
            raise ValueError(f"metrics.{name}: expected a table with abs/rel/direction")
        bad = set(spec) - {"abs", "rel", "direction"}
        if bad:
            raise ValueError(f"metrics.{name}: unknown keys {sorted(bad)}; "
                             "valid: abs, rel, direction")
        current = metrics.get(name, DEFAULT_TOLERANCE)
        try:
            kwargs: dict[str, Any] = {k: (float(v) if k != "direction" else v)
                                      for k, v in spec.items()}
            metrics[name] = replace(current, **kwargs)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"metrics.{name}: {exc}") from exc
    return metrics


def _timing(table: Mapping[str, Any], base: Mapping[str, float]) -> dict[str, float]:
    timing = dict(base)
    for name, ratio in table.items():
        if isinstance(ratio, bool) or not isinstance(ratio, int | float) or ratio < 1.0:
            raise ValueError(f"timing.{name}: expected a ratio >= 1, got {ratio!r}")
        timing[name] = float(ratio)
    return timing


def _floor(value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or value < 0:
        raise ValueError(f"timing_floor_ms: expected a number >= 0, got {value!r}")
    return float(value)


def _flag(data: Mapping[str, Any], key: str, default: bool) -> bool:
    value = data.get(key, default)
    if not isinstance(value, bool):
        raise ValueError(f"{key}: expected true/false, got {value!r}")
    return value


def _kinds(value: Any) -> tuple[str, ...]:
    if not isinstance(value, list | tuple) or any(k not in KINDS or k == "timing"
                                                  for k in value):
        allowed = ", ".join(k for k in KINDS if k != "timing")
        raise ValueError(f"gate_kinds: expected a list of {allowed} (timing gates with "
                         f"timing_gate), got {value!r}")
    return tuple(value)
