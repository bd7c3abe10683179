"""Judge one run record: every metric, its per-step series, the criteria, one verdict.

:func:`evaluate` is called once per run, by the runner, right after the run; the
:class:`Evaluation` it returns is stored in the run directory (``run.json``'s
``verdict`` and ``series.parquet``) and only read from then on.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from reports.metrics.catalogue import REQUIRED_METRICS
from reports.metrics.collisions import CollisionJudgement, collision_metrics, judge_collisions
from reports.metrics.comfort import comfort_metrics, comfort_series, fallback_metrics
from reports.metrics.context import build_context
from reports.metrics.criteria import Criteria, steps_failure
from reports.metrics.drac import drac_metrics, drac_series
from reports.metrics.drivable import drivable_metrics, offroad_excess_series
from reports.metrics.r157 import gap_shortfall_metrics
from reports.metrics.safety import ellipse_margin_series, safety_metrics
from reports.metrics.timing import health_metrics, timing_metrics
from reports.metrics.tracking import tracking_metrics
from reports.metrics.ttc import ttc_pairs, ttc_series
from reports.metrics.values import Measured
from reports.record import RunRecord, SeriesColumns, Verdict
from reports.record.meta import END_OK

__all__ = ["REQUIRED_METRICS", "Evaluation", "criteria_for", "evaluate", "measure",
           "measure_all"]


@dataclass(frozen=True)
class Evaluation:
    """The verdict of a run and the series its metrics are extremes of (T rows)."""

    verdict: Verdict
    series: SeriesColumns

    def apply(self, record: RunRecord) -> RunRecord:
        """A copy of ``record`` carrying this verdict and series (ready for ``write_run``)."""
        return dataclasses.replace(record, verdict=self.verdict, series=self.series)


def criteria_for(record: RunRecord, criteria_overrides: Mapping[str, Any] | None = None
                 ) -> Criteria:
    """Criteria of a run: defaults, then ``info.criteria`` (the catalog's), then
    ``criteria_overrides``. Raises ValueError on an unknown name or a bad value."""
    own = Criteria.from_overrides(record.info.criteria or None)
    return Criteria.from_overrides(criteria_overrides, base=own)


def measure(record: RunRecord) -> tuple[list[Measured], SeriesColumns]:
    """Every metric of a record (NaN where not measurable) and its series."""
    found, series, _ = measure_all(record)
    return found, series


def measure_all(record: RunRecord) -> tuple[list[Measured], SeriesColumns, CollisionJudgement]:
    """:func:`measure` and the collision judgement its collision metrics come from (the
    disagreements with SUMO's report go into the verdict)."""
    ctx = build_context(record)
    comfort = comfort_series(ctx)
    pairs = ttc_pairs(ctx)
    ahead, behind = ttc_series(ctx, pairs, ahead=True), ttc_series(ctx, pairs, ahead=False)
    excess = offroad_excess_series(ctx)
    margin = ellipse_margin_series(ctx)
    drac = drac_series(ctx, pairs)
    series = SeriesColumns(
        long_acc_mps2=comfort.long_acc_mps2, lat_acc_mps2=comfort.lat_acc_mps2,
        yaw_rate_radps=comfort.yaw_rate_radps, yaw_acc_radps2=comfort.yaw_acc_radps2,
        long_jerk_mps3=comfort.long_jerk_mps3, jerk_mps3=comfort.jerk_mps3,
        ttc_s=ahead, ttc_rear_s=behind, offroad_excess_m=excess, ellipse_margin=margin,
        drac_mps2=drac)
    collisions = judge_collisions(ctx)
    found = (safety_metrics(ctx, ahead, behind, margin) + drac_metrics(ctx, drac)
             + gap_shortfall_metrics(ctx, pairs)
             + collision_metrics(ctx, collisions) + drivable_metrics(ctx, excess)
             + comfort_metrics(comfort) + tracking_metrics(ctx) + timing_metrics(ctx)
             + health_metrics(ctx)
             + fallback_metrics(comfort, ctx.record.trace.controller.fallback))
    return _report_order(found), series, collisions


def _report_order(found: list[Measured]) -> list[Measured]:
    by_name = {m.name: m for m in found}
    if len(by_name) != len(found):
        raise RuntimeError("metrics: two modules produce the same metric name")
    missing = [name for name in REQUIRED_METRICS if name not in by_name]
    if missing:
        raise RuntimeError(f"metrics: required metrics not computed: {missing}")
    rest = sorted(set(by_name) - set(REQUIRED_METRICS))
    return [by_name[name] for name in (*REQUIRED_METRICS, *rest)]


def evaluate(record: RunRecord, criteria_overrides: Mapping[str, Any] | None = None
             ) -> Evaluation:
    """Judge a run (see the module doc).

    Criteria: :func:`criteria_for`. Status: ``record.outcome.end`` when the run did not
    end 'ok' ('error' or 'timeout', judged on what was recorded), else 'fail' when any
    criterion failed and 'pass' otherwise. A run without trace rows fails ``steps``
    first. Each failure records its step's manoeuvre phase and whether the controller
    had fallen back there (:meth:`Criteria.check`). The collision metrics rest on the
    2-D boxes; where SUMO's collision report disagrees with them is listed in
    ``Verdict.collision_disagreements`` (:mod:`reports.metrics.collisions`). Raises
    ValueError for invalid criteria.
    """
    limits = criteria_for(record, criteria_overrides)
    found, series, collisions = measure_all(record)
    trace = record.trace
    failures = limits.check(found, np.asarray(trace.t_s, dtype=np.float64),
                            side=trace.decision.side, fallback=trace.controller.fallback)
    if len(trace) == 0:
        failures = (steps_failure(), *failures)
    if record.outcome.end != END_OK:
        status = record.outcome.end
    else:
        status = "fail" if failures else "pass"
    verdict = Verdict(status=status, metrics=tuple(m.metric for m in found),
                      failures=failures, criteria=limits.as_dict(),
                      collision_disagreements=collisions.disagreements)
    return Evaluation(verdict=verdict, series=series)
