"""The judgement of a run: typed metric values, typed failures, one status.

Computed once, by :func:`reports.metrics.evaluate`, right after the run; stored in
``run.json`` under ``verdict``; read (never recomputed) by the reports, the JUnit
file, the comparison and the Rerun log.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

KINDS = ("safety", "comfort", "tracking", "timing", "health")
BETTER = ("lower", "higher", "none")
BOUNDS = ("max", "min")
CROSSING_KINDS = ("lane", "junction")
CROSSING_SIDES = ("left", "right", "end", "start")
CORNERS = ("front-left", "rear-left", "rear-right", "front-right")


@dataclass(frozen=True)
class BoundaryCrossing:
    """Which boundary of the drivable area the ego's box crossed, and by how much: the
    edge nearest to its farthest corner at the row of the largest excess.

    kind: 'lane' (a lane or internal junction lane of road.json: ``lane_id`` on
        ``edge_id``) or 'junction' (the area between route edge ``edge_id``'s lane ends
        and route edge ``to_edge_id``'s lane starts, where a lane ends or begins
        beside another; ``lane_id`` '').
    side: 'left' | 'right' edge (in the driving direction), 'end' | 'start' (the cross
        section where the lane, or the junction's ``edge_id``, ends / begins).
    excess_m: how far the corner was beyond it [m] (> 0); step / t_s: the trace row and
        its time [s]; corner: which corner of the box (front-left, ...).
    """

    kind: str
    lane_id: str
    edge_id: str
    side: str
    excess_m: float
    step: int
    t_s: float
    corner: str
    to_edge_id: str = ""

    def __post_init__(self) -> None:
        if self.kind not in CROSSING_KINDS:
            raise ValueError(f"BoundaryCrossing.kind must be one of {CROSSING_KINDS}, "
                             f"got {self.kind!r}")
        if self.side not in CROSSING_SIDES:
            raise ValueError(f"BoundaryCrossing.side must be one of {CROSSING_SIDES}, "
                             f"got {self.side!r}")
        if self.corner not in CORNERS:
            raise ValueError(f"BoundaryCrossing.corner must be one of {CORNERS}, "
                             f"got {self.corner!r}")
        if not (math.isfinite(self.excess_m) and self.excess_m > 0.0):
            raise ValueError(f"BoundaryCrossing.excess_m must be finite and > 0, "
                             f"got {self.excess_m!r}")
        if self.step < 0:
            raise ValueError(f"BoundaryCrossing.step must be >= 0, got {self.step!r}")

    @property
    def text(self) -> str:
        """``right edge of lane a_0 by 0.42 m`` (for reading only, never parsed)."""
        where = (f"lane {self.lane_id}" if self.kind == "lane"
                 else f"junction {self.edge_id} \u2192 {self.to_edge_id}")
        what = f"{self.side} edge" if self.side in ("left", "right") else self.side
        return f"{what} of {where} by {fmt_value(self.excess_m)} m"


@dataclass(frozen=True)
class MetricValue:
    """One metric of one run.

    value: in ``unit`` (NaN: not measurable in this run, e.g. no obstacle ever seen).
    kind: safety | comfort | tracking | timing | health; timing metrics are wall-clock
        measurements (noisy across machines and load), the others are behaviour.
    better: which direction is an improvement ('none': informational).
    worst_step: trace row where the value was attained (None for aggregates).
    series: the ``SeriesColumns``/trace column it is an extreme of ('' if none).
    crossing: for the off-road metrics, the drivable-area boundary crossed farthest
        (None when the ego stayed inside; :class:`BoundaryCrossing`).
    """

    name: str
    value: float
    unit: str
    kind: str
    better: str = "none"
    worst_step: int | None = None
    series: str = ""
    crossing: BoundaryCrossing | None = None

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"MetricValue.kind must be one of {KINDS}, got {self.kind!r}")
        if self.better not in BETTER:
            raise ValueError(f"MetricValue.better must be one of {BETTER}, got {self.better!r}")


# The manoeuvre phase a trace row's decision ``side`` code names (the trace's
# ``DecisionColumns.side``, controllers.behaviour.types.Side): passing on the left or
# right, keeping its lane, following a car it cannot pass. Another code is ``side<code>``.
PHASES: dict[int, str] = {1: "left", -1: "right", 0: "lane", 2: "follow"}


def phase_name(side: int) -> str:
    """The phase of decision ``side`` code ``side`` (:data:`PHASES`; ``side<code>``
    for a code it does not list)."""
    return PHASES.get(side, f"side{side}")


@dataclass(frozen=True)
class Failure:
    """A criterion the run did not meet: ``value`` of ``metric`` beyond ``limit``.

    bound: 'max' (fails when value > limit) or 'min' (fails when value < limit);
    step / t_s: the trace row and time [s] where it was first (or worst) violated
    (None: an aggregate over the whole run).
    phase: the manoeuvre phase at ``step`` (:func:`phase_name` of the trace's decision
        ``side`` at that row: 'left', 'right', 'lane', 'follow'), recorded by the
        metrics when the run is judged; '' without a step or in a run.json written
        before it was recorded.
    fell_back: whether a safe fallback had replaced the controller's plan at ``step``
        (the trace's ``fallback`` column; False for a driver without one); None without
        a step or in a run.json written before it was recorded.
    """

    criterion: str
    metric: str
    value: float
    limit: float
    bound: str
    unit: str = ""
    step: int | None = None
    t_s: float | None = None
    phase: str = ""
    fell_back: bool | None = None

    def __post_init__(self) -> None:
        if self.bound not in BOUNDS:
            raise ValueError(f"Failure.bound must be one of {BOUNDS}, got {self.bound!r}")
        if self.step is None and (self.phase or self.fell_back is not None):
            raise ValueError("Failure: a failure without a step has no phase and no "
                             f"fell_back, got {self.phase!r}, {self.fell_back!r}")

    @property
    def text(self) -> str:
        """``metric=value>limit`` (or ``<``), 4 significant digits: for tables only."""
        op = ">" if self.bound == "max" else "<"
        return f"{self.metric}={fmt_value(self.value)}{op}{fmt_value(self.limit)}"

    @property
    def line(self) -> str:
        """:attr:`text` and where it was violated (or that it is an aggregate)."""
        if self.step is None:
            return f"{self.text} (whole run)"
        when = f"t={self.t_s:.2f} s, " if self.t_s is not None else ""
        return f"{self.text} ({when}step {self.step})"


@dataclass(frozen=True)
class Verdict:
    """status: pass | fail | error | timeout; metrics in report order; failures in
    criteria order (a run without trace rows fails ``steps``)."""

    status: str
    metrics: tuple[MetricValue, ...] = ()
    failures: tuple[Failure, ...] = ()
    criteria: dict[str, float | None] = field(default_factory=dict)
    # where SUMO's collision report and the 2-D box test disagree (metrics.md)
    collision_disagreements: tuple[CollisionDisagreement, ...] = ()

    def __post_init__(self) -> None:
        # anything else (a hand-edited "pass<script>") would be copied into results.csv
        # and counted by one report as passed and by another as failed
        if self.status not in VERDICT_STATUSES:
            raise ValueError(f"Verdict.status must be one of {VERDICT_STATUSES}, "
                             f"got {self.status!r}")

    def metric(self, name: str) -> MetricValue | None:
        for m in self.metrics:
            if m.name == name:
                return m
        return None

    def value(self, name: str) -> float:
        """The value of metric ``name`` (NaN if absent)."""
        m = self.metric(name)
        return m.value if m is not None else math.nan

    def values(self) -> dict[str, float]:
        return {m.name: m.value for m in self.metrics}

    @property
    def failed_text(self) -> str:
        """Failures joined by ';' (results.csv's ``failed_criteria``)."""
        return ";".join(f.text for f in self.failures)


VERDICT_STATUSES = ("pass", "fail", "error", "timeout")


def fmt_value(value: float) -> str:
    """Compact number (4 significant digits; inf/-inf/nan spelled out)."""
    if math.isnan(value):
        return "nan"
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    return f"{value:.4g}"


# Where SUMO's collision report and the 2-D box test of the ego disagree
# (reports.metrics.collisions; docs/metrics.md "How a collision is judged").
SUMO_ONLY = "sumo_only"
GEOMETRY_ONLY = "geometry_only"
DISAGREEMENT_KINDS = (SUMO_ONLY, GEOMETRY_ONLY)
SUMO_ROLES = ("collider", "victim", "")


@dataclass(frozen=True)
class CollisionDisagreement:
    """A collision of the ego that SUMO's report and the 2-D box test disagree on.

    kind: 'sumo_only': SUMO reported a collision of the ego with ``other_id`` that the
        boxes do not show (without its sublane model SUMO judges along the lane only:
        the same lane and overlapping lane positions), so it is not counted in the
        verdict; 'geometry_only': the boxes of the ego and ``other_id`` overlapped (or
        touched between two trace rows) and SUMO reported no collision with it; it is
        counted.
    step / t_s: the trace row and its time [s] of the first evidence (SUMO's first
        report, or the first contact); last_t_s [s]: the time of the last (>= t_s).
    sumo_reports: SUMO's reports in it (a SUMO flag without its report counts one);
        0 for 'geometry_only'.
    sumo_role / sumo_type: the ego's role in SUMO's first report ('collider',
        'victim'; '' without a report) and SUMO's collision type.
    min_gap_m: the smallest box-to-box distance [m] between the ego and ``other_id``
        over the rows from ``t_s`` to ``last_t_s`` (0 for 'geometry_only'; NaN where
        the other vehicle was not recorded then).
    ego_lane_index / other_lane_index: SUMO's lane indices of both at ``step`` (-1:
        unknown).
    """

    kind: str
    other_id: str
    step: int
    t_s: float
    last_t_s: float
    sumo_reports: int = 0
    sumo_role: str = ""
    sumo_type: str = ""
    min_gap_m: float = math.nan
    ego_lane_index: int = -1
    other_lane_index: int = -1

    def __post_init__(self) -> None:
        if self.kind not in DISAGREEMENT_KINDS:
            raise ValueError(f"CollisionDisagreement.kind must be one of "
                             f"{DISAGREEMENT_KINDS}, got {self.kind!r}")
        if self.sumo_role not in SUMO_ROLES:
            raise ValueError(f"CollisionDisagreement.sumo_role must be one of {SUMO_ROLES}, "
                             f"got {self.sumo_role!r}")
        if self.step < 0 or self.sumo_reports < 0:
            raise ValueError("CollisionDisagreement: step and sumo_reports must be >= 0, "
                             f"got {self.step!r}, {self.sumo_reports!r}")
        if not (math.isfinite(self.t_s) and math.isfinite(self.last_t_s)
                and self.last_t_s >= self.t_s):
            raise ValueError("CollisionDisagreement: t_s and last_t_s must be finite with "
                             f"last_t_s >= t_s, got {self.t_s!r}, {self.last_t_s!r}")
        if self.min_gap_m < 0.0:  # NaN (not recorded) passes
            raise ValueError(f"CollisionDisagreement.min_gap_m must be >= 0 or NaN, "
                             f"got {self.min_gap_m!r}")
        if self.kind == GEOMETRY_ONLY and (self.sumo_reports or self.sumo_role):
            raise ValueError("CollisionDisagreement: a 'geometry_only' one has no SUMO "
                             f"report, got {self.sumo_reports!r} ({self.sumo_role!r})")
        if self.kind == SUMO_ONLY and self.sumo_reports < 1:
            raise ValueError("CollisionDisagreement: a 'sumo_only' one has at least one "
                             f"SUMO report, got {self.sumo_reports!r}")
