"""The StopRule role: when a run ends before its duration."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

from suite.run.ego import EgoState
from suite.run.safety import SafetySample

COLLISION_GRACE_S = 0.5  # keep recording this long after the first geometric contact
END_OF_ROUTE_MARGIN_M = 30.0  # stop this far before the reference path's end


class ScenarioTimeout(Exception):
    """The run's wall-clock budget is spent."""


class StopRule(Protocol):
    def check(self, t_s: float, ego: EgoState, safety: SafetySample) -> str | None:
        """A reason to stop after this step, or None; may raise ScenarioTimeout."""
        ...


@dataclass
class StandardStop:
    """Stop 0.5 s after the first collision, near the end of the route, or raise
    :class:`ScenarioTimeout` once ``wall_budget_s`` [s] of wall time is spent.

    A collision here is a geometric contact: the monitor's 2-D box overlap
    (:attr:`SafetySample.collided`). A collision SUMO reports without one (its 1-D,
    along-the-lane check) neither starts the grace period nor ends the run."""

    reference_length_m: float
    wall_budget_s: float | None = None
    wall_start_s: float = field(default_factory=time.perf_counter)
    _first_collision_t: float | None = None

    def check(self, t_s: float, ego: EgoState, safety: SafetySample) -> str | None:
        if self.wall_budget_s is not None and \
                time.perf_counter() - self.wall_start_s > self.wall_budget_s:
            raise ScenarioTimeout(f"wall-clock budget of {self.wall_budget_s} s exceeded "
                                  f"at t = {t_s:.2f} s")
        if safety.collided and self._first_collision_t is None:
            self._first_collision_t = t_s
        if self._first_collision_t is not None and \
                t_s - self._first_collision_t >= COLLISION_GRACE_S:
            return f"collision at t = {self._first_collision_t:.2f} s"
        if ego.s_m >= self.reference_length_m - END_OF_ROUTE_MARGIN_M:
            return "end of route"
        return None


@dataclass
class StoryboardStop:
    """``inner``'s reasons first, then the scenario's OpenSCENARIO storyboard: the run
    ends at the step after its stop trigger fired (``stopped_at_s()``: that run time
    [s], None while it has not; docs/openscenario.md)."""

    inner: StopRule
    stopped_at_s: Callable[[], float | None]

    def check(self, t_s: float, ego: EgoState, safety: SafetySample) -> str | None:
        reason = self.inner.check(t_s, ego, safety)
        if reason is not None:
            return reason
        at = self.stopped_at_s()
        return None if at is None else f"storyboard stop trigger at t = {at:.2f} s"
