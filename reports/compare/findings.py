"""Findings of a comparison: run matching, status changes, metric and timing changes.

Matching (:func:`match_runs`): when every scenario name appears once on each side (a
catalog's names are unique), runs are matched by scenario name, so a scenario whose
controller changed in the catalog is compared run for run (its key then reads
``scenario [a → b]``); otherwise by (scenario, controller). Two run directories of one
side with the same key raise :class:`DuplicateRuns`. An unreadable run directory is
matched by its directory name.

Finding kinds and what they do (``CompareRow.gate`` says whether it fails the
comparison):

=====================  =========================================================
``missing``            in base only (gates unless ``missing_is_regression = false``)
``new_failure``        base passed, new did not (gates)
``worse_status``       fail → error/timeout (gates)
``new_criterion``      both failed, new fails a criterion base did not (gates)
``metric_regression``  a gated-kind metric moved the worse way beyond tolerance (gates)
``timing_slower``      a timing metric slower beyond its ratio in this run (warns; the
                       timing gate looks at the catalog's median ratio instead), or a
                       timing count (``deadline_misses``) up (gates with the timing gate)
``health_change``      a health metric worse beyond tolerance (warns)
``xpass``              a known failure (xfail) passed: "fixed: remove the xfail"
                       (gates with ``strict = true``)
``xfailed``            a known failure failed as expected (informational)
``limit_changed``,     a criterion's limit differs, switched off (``criterion_off``):
``criterion_off``      the new run's value under both limits (informational)
``test_changed``,      the test, the system under test changed (informational; the
``sut_changed``        behaviour findings of the run say what it did)
``metric_not_in_base``  a metric the new run has and the base run has not (a metric
``metric_not_in_new``  added since; or removed): "not in base", never compared, never a
                       regression (informational)
``new``, ``fixed``, ``status_change``, ``metric_improvement``, ``timing_faster``,
``metric_nan``         informational
=====================  =========================================================

Metrics of error/timeout runs are not compared (their status already is). Each finding's
category — why the run differs — is :mod:`reports.compare.kinds`'s.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from reports.compare.tolerances import HIGHER_IS_WORSE, Tolerances
from reports.record import Failure, MetricValue
from reports.tables import UNKNOWN, RunEntry

STATUS_RANK = {"pass": 0, "fail": 1, "timeout": 2, "error": 2}
BEHAVIOUR_GATES = frozenset({"new_failure", "worse_status", "new_criterion",
                             "metric_regression"})
WARNING_KINDS = frozenset({"timing_slower", "health_change"})
GOOD_KINDS = frozenset({"fixed", "metric_improvement", "timing_faster"})


@dataclass(frozen=True)
class CompareRow:
    """One finding; values in ``unit``; ``metric_kind`` the metric's kind ('' for a
    status finding); ``limit``: the new run's limit (or a timing ratio's limit),
    ``base_limit``: the base run's where they differ (NaN otherwise); ``gate``: it
    fails the comparison; ``category``: why the run differs
    (:data:`reports.compare.kinds.CATEGORIES`)."""

    key: str
    scenario: str
    controller: str
    kind: str
    metric: str = ""
    unit: str = ""
    metric_kind: str = ""
    base: float = math.nan
    new: float = math.nan
    delta: float = math.nan
    ratio: float = math.nan
    limit: float = math.nan
    note: str = ""
    gate: bool = False
    category: str = "info"
    base_limit: float = math.nan

    @property
    def regression(self) -> bool:
        """Whether this finding makes the comparison fail (exit 1)."""
        return self.gate

    @property
    def warning(self) -> bool:
        """A finding reported as a warning (timing or health, not gating)."""
        return self.kind in WARNING_KINDS and not self.gate


@dataclass(frozen=True)
class Judgement:
    """A run's status and failed criteria under some limits (its own, or another
    run's: :func:`reports.compare.kinds.under_limits`)."""

    status: str
    failures: tuple[Failure, ...] = ()


def own_judgement(entry: RunEntry) -> Judgement:
    """The run's stored verdict."""
    return Judgement(entry.status, entry.failures)


class DuplicateRuns(ValueError):
    """Two run directories of one side are the same run (scenario and controller): a
    comparison would silently keep one of them (the CLI exits 2)."""


@dataclass(frozen=True)
class Matched:
    """A run key and its run on each side (None: that side has none)."""

    key: str
    base: RunEntry | None
    new: RunEntry | None

    def __post_init__(self) -> None:
        if self.base is None and self.new is None:
            raise ValueError(f"Matched {self.key!r}: neither side has the run")


def _unique_names(runs: Sequence[RunEntry]) -> bool:
    names = [r.scenario for r in runs if r.record is not None]
    return len(names) == len(set(names))


def _keyed(runs: Sequence[RunEntry], other: Sequence[RunEntry], key: Any
           ) -> dict[str, RunEntry]:
    """``runs`` by their matching key; an unreadable run directory knows only its name:
    it takes the key of the other side's run in the directory of that name."""
    by_dir = {r.run_id: key(r) for r in other if r.record is not None}
    out: dict[str, RunEntry] = {}
    for r in runs:
        k = by_dir.get(r.run_id, key(r)) if r.record is None else key(r)
        if k in out:
            raise DuplicateRuns(f"{out[k].run_dir} and {r.run_dir} are both {k}: "
                                "which one to compare is ambiguous (remove one, or "
                                "compare outputs of one catalog run each)")
        out[k] = r
    return out


def match_runs(base: Sequence[RunEntry], new: Sequence[RunEntry]) -> list[Matched]:
    """The runs of both sides matched (see the module doc), sorted by key."""
    base_ctrls = {r.controller for r in base if r.record is not None}
    new_ctrls = {r.controller for r in new if r.record is not None}
    catalog_swap = len(base_ctrls) == 1 and len(new_ctrls) == 1 and base_ctrls != new_ctrls
    by_name = catalog_swap or (_unique_names(base) and _unique_names(new))

    def key(r: RunEntry) -> str:
        return r.scenario if by_name else f"{r.scenario} [{r.controller}]"

    bm, nm = _keyed(base, new, key), _keyed(new, base, key)

    def label(k: str, b: RunEntry | None, n: RunEntry | None) -> str:
        if catalog_swap or not by_name:
            return k
        # an unreadable run.json names no controller: the other side's says it
        known = [r.controller for r in (b, n) if r is not None and r.controller != UNKNOWN]
        if len(known) == 2 and known[0] != known[1]:
            return f"{k} [{known[0]} → {known[1]}]"
        return f"{k} [{known[-1] if known else UNKNOWN}]"

    return [Matched(label(k, bm.get(k), nm.get(k)), bm.get(k), nm.get(k))
            for k in sorted(set(bm) | set(nm))]


def _last_line(text: str) -> str:
    lines = text.strip().splitlines()
    return lines[-1] if lines else ""


def status_rows(key: str, b: RunEntry, n: RunEntry, nj: Judgement | None = None
                ) -> list[CompareRow]:
    """Status changes of one matched run, and criteria new fails that base did not;
    ``nj``: the new run's judgement to compare (default: its own verdict)."""
    nj = nj if nj is not None else own_judgement(n)
    rows = []
    common: dict[str, Any] = {"key": key, "scenario": n.scenario, "controller": n.controller}
    rb, rn = STATUS_RANK.get(b.status, 2), STATUS_RANK.get(nj.status, 2)
    note = f"{b.status} → {nj.status}"
    if nj.failures and nj.status != "pass":
        note += ": " + "; ".join(f.text for f in nj.failures)
    elif n.error and nj.status in ("error", "timeout"):
        note += ": " + (_last_line(n.error) or nj.status)
    if b.status == "pass" and nj.status != "pass":
        rows.append(CompareRow(kind="new_failure", note=note, gate=True, **common))
    elif nj.status == "pass" and b.status != "pass":
        rows.append(CompareRow(kind="fixed", note=note, **common))
    elif rn > rb:
        rows.append(CompareRow(kind="worse_status", note=note, gate=True, **common))
    elif b.status != nj.status:
        rows.append(CompareRow(kind="status_change", note=note, **common))
    if b.status == "fail" and nj.status == "fail":
        base_criteria = {f.criterion for f in b.failures}
        for failure in nj.failures:
            if failure.criterion not in base_criteria:
                rows.append(CompareRow(kind="new_criterion", metric=failure.metric,
                                       unit=failure.unit, base=b.value(failure.metric),
                                       new=failure.value, limit=failure.limit,
                                       note=failure.text, gate=True, **common))
    return rows


def _metric_pairs(b: RunEntry, n: RunEntry) -> list[tuple[MetricValue, MetricValue]]:
    base = {m.name: m for m in b.metrics}
    return [(base[m.name], m) for m in n.metrics if m.name in base]


def _tolerance_row(key: str, n: RunEntry, mb: MetricValue, mn: MetricValue,
                   tol: Tolerances) -> CompareRow | None:
    """A behaviour/health metric (or a timing count) against its tolerance."""
    mt = tol.tolerance(mn.name)
    direction = mt.worse_direction(mn.better)
    vb, vn = mb.value, mn.value
    if not direction or vb == vn or (math.isnan(vb) and math.isnan(vn)):
        return None
    common: dict[str, Any] = {"key": key, "scenario": n.scenario, "controller": n.controller,
                              "metric": mn.name, "unit": mn.unit, "metric_kind": mn.kind,
                              "base": vb, "new": vn}
    if math.isnan(vb) or math.isnan(vn):
        return CompareRow(kind="metric_nan", note="only measured in one run", **common)
    if math.isinf(vb) and math.isinf(vn):
        return None
    worse = (vn - vb) if direction == HIGHER_IS_WORSE else (vb - vn)
    limit = mt.threshold(vb)
    if not math.isfinite(worse):  # ∞ → finite (a conflict appeared) or back
        worse = math.copysign(math.inf, worse)
    if abs(worse) <= limit:
        return None
    return _beyond_tolerance_row(mn, tol, vn - vb, worse, limit, common)


def _beyond_tolerance_row(mn: MetricValue, tol: Tolerances, delta: float, worse: float,
                          limit: float, common: dict[str, Any]) -> CompareRow:
    """The row of metric ``mn`` changed by ``delta`` (new - base), ``worse`` (in its
    worse direction) beyond its tolerance ``limit``: an improvement, a slower timing, a
    gated regression or a health change."""
    if worse < 0:
        kind = "timing_faster" if mn.kind == "timing" else "metric_improvement"
        return CompareRow(kind=kind, delta=delta, limit=limit, **common)
    unit = "" if mn.unit in ("", "-") else f" {mn.unit}"
    note = f"worse by {abs(delta):.4g}{unit}, tolerance {limit:.4g}{unit}"
    if mn.kind == "timing":
        return CompareRow(kind="timing_slower", delta=delta, limit=limit, note=note,
                          gate=tol.timing_gate, **common)
    if mn.kind in tol.gate_kinds:
        return CompareRow(kind="metric_regression", delta=delta, limit=limit, note=note,
                          gate=True, **common)
    return CompareRow(kind="health_change", delta=delta, limit=limit, note=note, **common)


def timing_ratio(mb: MetricValue, mn: MetricValue) -> float:
    """new/base, or base/new for a metric where higher is better (> 1: slower); NaN
    when either is not a finite positive number."""
    vb, vn = mb.value, mn.value
    if not (math.isfinite(vb) and math.isfinite(vn)) or vb <= 0 or vn <= 0:
        return math.nan
    return vb / vn if mn.better == "higher" else vn / vb


def _ratio_row(key: str, n: RunEntry, mb: MetricValue, mn: MetricValue,
               tol: Tolerances) -> CompareRow | None:
    """A timing metric by its ratio (warning; failure with the timing gate)."""
    max_ratio = tol.timing[mn.name]
    ratio = timing_ratio(mb, mn)
    if math.isnan(ratio):
        return None
    if mn.unit == "ms" and max(mb.value, mn.value) < tol.timing_floor_ms:
        return None
    common: dict[str, Any] = {"key": key, "scenario": n.scenario, "controller": n.controller,
                              "metric": mn.name, "unit": mn.unit, "metric_kind": mn.kind,
                              "base": mb.value, "new": mn.value, "delta": mn.value - mb.value,
                              "ratio": ratio, "limit": max_ratio}
    if ratio > max_ratio:
        # one run's ratio never gates: the timing gate is the catalog's median ratio
        # (reports.compare.timing), so one noisy run cannot fail a night
        return CompareRow(kind="timing_slower", note=f"×{ratio:.2f} slower (limit ×{max_ratio:g})",
                          **common)
    if ratio < 1.0 / max_ratio:
        return CompareRow(kind="timing_faster", note=f"×{1 / ratio:.2f} faster", **common)
    return None


NOT_IN_BASE = "metric_not_in_base"
NOT_IN_NEW = "metric_not_in_new"


def unpaired_rows(key: str, b: RunEntry, n: RunEntry) -> list[CompareRow]:
    """The metrics stored on one side of a matched run only (e.g. a metric the catalogue
    gained after base ran): informational, never compared."""
    names_b, names_n = {m.name for m in b.metrics}, {m.name for m in n.metrics}
    common: dict[str, Any] = {"key": key, "scenario": n.scenario, "controller": n.controller}
    rows = [CompareRow(kind=NOT_IN_BASE, metric=m.name, unit=m.unit, metric_kind=m.kind,
                       new=m.value, note="not in base: not compared", **common)
            for m in n.metrics if m.name not in names_b]
    rows += [CompareRow(kind=NOT_IN_NEW, metric=m.name, unit=m.unit, metric_kind=m.kind,
                        base=m.value, note="not in new: not compared", **common)
             for m in b.metrics if m.name not in names_n]
    return rows


def metric_rows(key: str, b: RunEntry, n: RunEntry, tol: Tolerances) -> list[CompareRow]:
    """Every metric change of one matched run beyond its tolerance or ratio, then the
    metrics of one side only (:func:`unpaired_rows`)."""
    rows = []
    for mb, mn in _metric_pairs(b, n):
        if mn.kind == "timing" and mn.name in tol.timing:
            row = _ratio_row(key, n, mb, mn, tol)
        elif mn.kind == "timing" and mn.name not in tol.metrics:
            continue  # the other timing figures (p95, max, variance): in the reports
        else:
            row = _tolerance_row(key, n, mb, mn, tol)
        if row is not None:
            rows.append(row)
    return rows + (unpaired_rows(key, b, n) if b.metrics and n.metrics else [])
