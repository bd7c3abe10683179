"""Condition edges and delays, and triggers (groups OR'ed, conditions AND'ed).

A condition's *test* is sampled every step; with ``delay`` d its value at t is the
test's at t - d (false before the run had lasted d). Its edge turns the (delayed) value
into the condition: none = the value; rising = it was false at the previous step and
is true now; falling = the reverse; risingOrFalling = either. The first step has no
previous value: no edge fires there.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from suite.catalog import storyboard as sb

__all__ = ["ConditionMemory"]


@dataclass
class _Series:
    """A condition's test over time: (t, value) since the start."""

    samples: list[tuple[float, bool]] = field(default_factory=list)

    def at(self, t_s: float) -> bool | None:
        """The value at ``t_s`` (the last sample at or before it; None: none yet)."""
        out = None
        for t, v in reversed(self.samples):
            if t <= t_s + 1e-9:
                out = v
                break
        return out


@dataclass
class ConditionMemory:
    """Every condition's sampled tests, by the condition object's id."""

    series: dict[int, _Series] = field(default_factory=dict)
    last_t: dict[int, float] = field(default_factory=dict)

    def record(self, cond: sb.Condition, t_s: float, value: bool) -> None:
        s = self.series.setdefault(id(cond), _Series())
        if not s.samples or s.samples[-1][0] < t_s - 1e-12:
            s.samples.append((t_s, value))
            horizon = t_s - cond.delay_s - 1.0
            while len(s.samples) > 2 and s.samples[1][0] < horizon:
                s.samples.pop(0)

    def fires(self, cond: sb.Condition, t_s: float, dt_s: float) -> bool:
        """The condition at ``t_s`` (module docstring) after its test was recorded."""
        s = self.series.get(id(cond))
        if s is None:
            return False
        now = s.at(t_s - cond.delay_s)
        if cond.edge == "none":
            return bool(now)
        before = s.at(t_s - cond.delay_s - dt_s)
        if now is None or before is None:
            return False
        if cond.edge == "rising":
            return now and not before
        if cond.edge == "falling":
            return before and not now
        return now != before
