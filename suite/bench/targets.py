"""The bench's targets, declared once (:data:`TARGETS`), and their verdicts.

A :class:`Target` is a name, a unit, a comparison and a target value; :func:`judge`
pairs it with the figure measured in this bench run (:class:`TargetResult`): met, not met,
or not measured (a figure the run could not produce is not met). ``hwyeval bench`` exits
1 when a result is not met (:func:`all_met`), unless ``--no-fail``.

Issue 25 (speed near the floor) gives six targets, on the dense target (two_loop,
3 lanes, 2400 veh/h, a stalled car, logs on); issue 11 gives the two solver ratios
(Ipopt against C/GMRES on the same OCP). Issue 11's whole-command target (x50), its
controller-alone p99 (0.25 ms) and its ``--jobs 2`` ratio (x1.7 on the whole command)
are replaced by issue 25's stricter ones.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from enum import Enum

__all__ = ["TARGETS", "Comparison", "Measured", "Target", "TargetResult", "all_met", "judge",
           "target"]


class Comparison(Enum):
    """How a measured value is held against its target value."""

    AT_LEAST = ">="
    AT_MOST = "<="


UNITS = ("x", "us", "ms")  # ratio (real-time factor, speed-up), microseconds, milliseconds


@dataclass(frozen=True)
class Target:
    """``name``'s measured value must be ``comparison`` ``target_value`` [``unit``];
    ``what`` says which figure is judged, ``issue`` which issue set it."""

    name: str
    unit: str
    comparison: Comparison
    target_value: float
    what: str
    issue: int

    def __post_init__(self) -> None:
        if not self.name.isidentifier():
            raise ValueError(f"target name must be an identifier, got {self.name!r}")
        if self.unit not in UNITS:
            raise ValueError(f"{self.name}: unit must be one of {UNITS}, got {self.unit!r}")
        if not isinstance(self.comparison, Comparison):
            raise TypeError(f"{self.name}: comparison must be a Comparison, "
                            f"got {self.comparison!r}")
        if not (math.isfinite(self.target_value) and self.target_value > 0):
            raise ValueError(f"{self.name}: target_value must be finite and > 0, "
                             f"got {self.target_value}")
        if self.issue < 1:
            raise ValueError(f"{self.name}: issue must be >= 1, got {self.issue}")

    def is_met_by(self, value: float) -> bool:
        """Whether ``value`` meets the target (NaN, i.e. not measured: never)."""
        if math.isnan(value):
            return False
        if self.comparison is Comparison.AT_LEAST:
            return value >= self.target_value
        return value <= self.target_value

    def text(self) -> str:
        """``>= x100`` / ``<= 100 us``."""
        if self.unit == "x":
            return f"{self.comparison.value} x{self.target_value:g}"
        return f"{self.comparison.value} {self.target_value:g} {self.unit}"


TARGETS: tuple[Target, ...] = (
    Target("one_run_realtime_factor", "x", Comparison.AT_LEAST, 100.0,
           "one dense run: simulated s / results.csv wall_s, median over the traffic seeds", 25),
    Target("python_between_sumo_and_kernel_us", "us", Comparison.AT_MOST, 100.0,
           "the Python between SUMO's step and the C/GMRES kernel, per control step "
           "(the floor study)", 25),
    Target("step_p99_ms_worst_run", "ms", Comparison.AT_MOST, 0.25,
           "behaviour + controller step p99 (results.csv step_ms_p99), worst dense run", 25),
    Target("step_max_ms_worst_run", "ms", Comparison.AT_MOST, 1.0,
           "behaviour + controller step max (results.csv step_ms_max), worst dense run", 25),
    Target("command_realtime_factor_jobs1", "x", Comparison.AT_LEAST, 70.0,
           "the whole hwyeval run command on the dense catalog, --jobs 1, logs on", 25),
    Target("jobs2_over_jobs1_scenario_phase", "x", Comparison.AT_LEAST, 1.8,
           "--jobs 1 / --jobs 2 time of the dense catalog's scenario phase", 25),
    Target("ipopt_over_cgmres_p50", "x", Comparison.AT_LEAST, 30.0,
           "Ipopt (barrier) / C/GMRES update time p50, same OCP", 11),
    Target("ipopt_over_cgmres_var", "x", Comparison.AT_LEAST, 1000.0,
           "Ipopt (barrier) / C/GMRES update-time variance, per-update minimum over the "
           "repeats", 11),
)


def target(name: str) -> Target:
    """The target of :data:`TARGETS` called ``name`` (KeyError if none)."""
    for t in TARGETS:
        if t.name == name:
            return t
    raise KeyError(name)


@dataclass(frozen=True)
class Measured:
    """A figure measured for the target ``name`` [the target's unit]; NaN with
    ``why_not`` when this run could not measure it."""

    name: str
    value: float
    why_not: str = ""

    def __post_init__(self) -> None:
        if math.isnan(self.value) and not self.why_not:
            raise ValueError(f"{self.name}: a value that was not measured needs why_not")


@dataclass(frozen=True)
class TargetResult:
    """A target and the value measured for it (NaN: not measured, ``why_not`` says why)."""

    target: Target
    value: float
    why_not: str = ""

    @property
    def measured(self) -> bool:
        return not math.isnan(self.value)

    @property
    def met(self) -> bool:
        return self.target.is_met_by(self.value)

    def line(self) -> str:
        """``TARGET name: value unit (target >= ...) -> met | NOT met``."""
        t = self.target
        if not self.measured:
            shown = f"not measured ({self.why_not})"
        elif t.unit == "x":
            shown = f"x{self.value:.2f}"
        else:
            shown = f"{self.value:.3f} {t.unit}" if t.unit == "ms" else f"{self.value:.1f} {t.unit}"
        verdict = "met" if self.met else "NOT met"
        return f"TARGET {t.name}: {shown} (target {t.text()}; issue #{t.issue}) -> {verdict}"


def judge(measured: Iterable[Measured], targets: tuple[Target, ...] = TARGETS
          ) -> tuple[TargetResult, ...]:
    """One result per target, in :data:`TARGETS`' order: its measured value, or not
    measured ("not part of this bench run") when ``measured`` has none for it."""
    names = {t.name for t in targets}
    by_name: dict[str, Measured] = {}
    for m in measured:
        if m.name not in names:  # a figure measured for no target is a bug
            raise KeyError(f"no target {m.name!r}")
        by_name[m.name] = m
    out = []
    for t in targets:
        found = by_name.get(t.name)
        if found is None:
            out.append(TargetResult(t, math.nan, "not part of this bench run"))
        else:
            out.append(TargetResult(t, found.value, found.why_not))
    return tuple(out)


def all_met(results: Iterable[TargetResult]) -> bool:
    """Whether every result is met (an empty set: vacuously)."""
    return all(r.met for r in results)
