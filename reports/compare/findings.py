"""Findings of a comparison: run matching, status changes, metric and timing changes.

Matching: runs are matched by (scenario, controller); two run directories of one side
with the same key raise :class:`DuplicateRuns`. When each directory holds exactly
one controller and they differ (comparing controller A against B), runs are matched by
scenario name alone. An unreadable run directory is matched by its directory name.

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
``new``, ``fixed``, ``status_change``, ``metric_improvement``, ``timing_faster``,
``metric_nan``         informational
=====================  =========================================================

Metrics of error/timeout runs are not compared (their status already is).

Categories (``CompareRow.category``; compare --json calls it ``kind`` and the finding
kind above ``finding``) say *why* a run differs, so that a changed test never reads as
a controller regression:

======================  ==========================================================
``behaviour_regression``  a gating finding on a run whose scenario and criteria are
                          unchanged (same content hash and resolved criteria): gates
``criteria_changed``      a criterion's limit differs between the two runs: the
                          findings of that run are listed under it and do not gate
``waived``                a criterion in force in base is switched off (``"off"``)
                          in new: listed, does not gate
``scenario_changed``      the scenario's content hash differs (anything but the
                          criteria: net, actors, speeds, seed): does not gate
``removed_scenario``      in base only: gates unless ``missing_is_regression = false``
``new_scenario``          in new only: informational
``timing``                wall-clock findings: warn (gate with ``--timing-gate``)
``improvement``           fixed runs and metrics better beyond tolerance
``info``                  the rest (status changes that are not worse, NaN metrics)
======================  ==========================================================

The exit code is 1 when a ``behaviour_regression`` or a gating ``removed_scenario``
finding exists (or, with the timing gate, a ``timing`` one), else 0.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from reports.compare.tolerances import HIGHER_IS_WORSE, Tolerances
from reports.record import MetricValue
from reports.tables import RunEntry

STATUS_RANK = {"pass": 0, "fail": 1, "timeout": 2, "error": 2}
BEHAVIOUR_GATES = frozenset({"new_failure", "worse_status", "new_criterion",
                             "metric_regression"})
WARNING_KINDS = frozenset({"timing_slower", "health_change"})
GOOD_KINDS = frozenset({"fixed", "metric_improvement", "timing_faster"})


@dataclass(frozen=True)
class CompareRow:
    """One finding; values in ``unit``; ``metric_kind`` the metric's kind ('' for a
    status finding); ``gate``: it fails the comparison."""

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

    @property
    def regression(self) -> bool:
        """Whether this finding makes the comparison fail (exit 1)."""
        return self.gate

    @property
    def warning(self) -> bool:
        """A finding reported as a warning (timing or health, not gating)."""
        return self.kind in WARNING_KINDS and not self.gate


CATEGORIES = ("behaviour_regression", "criteria_changed", "waived", "scenario_changed",
              "removed_scenario", "new_scenario", "timing", "improvement", "info")
GATING_CATEGORIES = ("behaviour_regression", "removed_scenario")  # timing: with the gate
CONTENT_KEY = "content_sha256"  # RunInfo.scenario_spec's content hash (suite.run.info)


@dataclass(frozen=True)
class PairChange:
    """What differs in the set-up of a matched pair of runs: the criteria whose limits
    differ (name, base limit, new limit; None = off), and whether the scenario's content
    hash differs (both known)."""

    criteria: tuple[tuple[str, float | None, float | None], ...] = ()
    scenario_changed: bool = False

    @property
    def waived(self) -> tuple[str, ...]:
        """Criteria in force in base and switched off in new."""
        return tuple(name for name, b, n in self.criteria if b is not None and n is None)

    @property
    def limits_changed(self) -> tuple[tuple[str, float | None, float | None], ...]:
        """Criteria whose limit changed (not only switched off)."""
        return tuple(c for c in self.criteria if not (c[1] is not None and c[2] is None))


def pair_change(b: RunEntry, n: RunEntry) -> PairChange:
    """The set-up differences of a matched pair (:class:`PairChange`) from the stored
    verdicts' resolved criteria and the runs' content hashes."""
    if b.verdict is None or n.verdict is None:  # an unreadable or unjudged run: unknown,
        changed: tuple[tuple[str, float | None, float | None], ...] = ()  # not changed
    else:
        cb, cn = b.verdict.criteria, n.verdict.criteria
        changed = tuple((name, cb.get(name), cn.get(name))
                        for name in sorted(set(cb) | set(cn))
                        if _limit(cb.get(name)) != _limit(cn.get(name)))
    hb = b.info.scenario_spec.get(CONTENT_KEY) if b.info is not None else None
    hn = n.info.scenario_spec.get(CONTENT_KEY) if n.info is not None else None
    return PairChange(changed, bool(hb and hn and hb != hn))


def _limit(value: float | None) -> float | None:
    return None if value is None else float(value)


def categorised(row: CompareRow, change: PairChange) -> CompareRow:
    """``row`` with its category (module doc); a gating behaviour finding of a pair
    whose criteria or scenario changed no longer gates."""
    from dataclasses import replace

    if row.kind in ("timing_slower", "timing_faster"):
        return replace(row, category="timing")
    if row.kind in BEHAVIOUR_GATES:
        if change.limits_changed:
            return replace(row, category="criteria_changed", gate=False)
        if change.scenario_changed:
            return replace(row, category="scenario_changed", gate=False)
        if change.waived:
            return replace(row, category="waived", gate=False)
        return replace(row, category="behaviour_regression")
    if row.kind in GOOD_KINDS:
        return replace(row, category="improvement")
    return replace(row, category="info")


def change_rows(key: str, n: RunEntry, change: PairChange) -> list[CompareRow]:
    """One row per changed criterion (``criteria_changed`` or ``waived``) and one for a
    changed scenario, whether or not the verdict moved: a reader sees every test that
    changed."""
    common: dict[str, Any] = {"key": key, "scenario": n.scenario, "controller": n.controller}
    rows = []
    for name, b, v in change.criteria:
        waived = b is not None and v is None
        text = "off" if v is None else f"{v:g}"
        rows.append(CompareRow(kind="criterion_off" if waived else "criterion_changed",
                               metric=name, base=math.nan if b is None else float(b),
                               new=math.nan if v is None else float(v),
                               note=f"{name}: {'off' if b is None else f'{b:g}'} → {text}",
                               category="waived" if waived else "criteria_changed", **common))
    if change.scenario_changed:
        rows.append(CompareRow(kind="scenario_changed", note="the scenario's content hash "
                               "differs (net, actors, speeds, seed or options)",
                               category="scenario_changed", **common))
    return rows


class DuplicateRuns(ValueError):
    """Two run directories of one side are the same run (scenario and controller): a
    comparison would silently keep one of them (the CLI exits 2)."""


def match_keys(base: Sequence[RunEntry], new: Sequence[RunEntry]
               ) -> tuple[dict[str, RunEntry], dict[str, RunEntry]]:
    """The runs of each side by their matching key (see the module doc)."""
    base_ctrls = {r.controller for r in base if r.record is not None}
    new_ctrls = {r.controller for r in new if r.record is not None}
    by_scenario = len(base_ctrls) == 1 and len(new_ctrls) == 1 and base_ctrls != new_ctrls

    def key(r: RunEntry) -> str:
        return r.scenario if by_scenario else f"{r.scenario} [{r.controller}]"

    def keyed(runs: Sequence[RunEntry], other: Sequence[RunEntry]) -> dict[str, RunEntry]:
        # an unreadable run directory knows only its name: it takes the key of the
        # other side's run in the directory of that name
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

    return keyed(base, new), keyed(new, base)


def _last_line(text: str) -> str:
    lines = text.strip().splitlines()
    return lines[-1] if lines else ""


def status_rows(key: str, b: RunEntry, n: RunEntry) -> list[CompareRow]:
    """Status changes of one matched run, and criteria new fails that base did not."""
    rows = []
    common: dict[str, Any] = {"key": key, "scenario": n.scenario, "controller": n.controller}
    rb, rn = STATUS_RANK.get(b.status, 2), STATUS_RANK.get(n.status, 2)
    note = f"{b.status} → {n.status}"
    if n.failures and n.status != "pass":
        note += ": " + "; ".join(f.text for f in n.failures)
    elif n.error and n.status in ("error", "timeout"):
        note += ": " + (_last_line(n.error) or n.status)
    if b.status == "pass" and n.status != "pass":
        rows.append(CompareRow(kind="new_failure", note=note, gate=True, **common))
    elif n.status == "pass" and b.status != "pass":
        rows.append(CompareRow(kind="fixed", note=note, **common))
    elif rn > rb:
        rows.append(CompareRow(kind="worse_status", note=note, gate=True, **common))
    elif b.status != n.status:
        rows.append(CompareRow(kind="status_change", note=note, **common))
    if b.status == "fail" and n.status == "fail":
        base_criteria = {f.criterion for f in b.failures}
        for failure in n.failures:
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
    delta = vn - vb
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


def metric_rows(key: str, b: RunEntry, n: RunEntry, tol: Tolerances) -> list[CompareRow]:
    """Every metric change of one matched run beyond its tolerance or ratio."""
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
    return rows
