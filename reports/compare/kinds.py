"""Why a matched pair of runs differs: the set-up change (:mod:`reports.identity`: the
test, the limits, the system under test), each finding's category and whether it gates.

A pair whose **test** is unchanged is compared run for run, and its behaviour findings
gate whatever happened to the **system under test** (SUT: the controller, its options,
its code): that is what the gate is for; such a finding says what changed in the SUT.
A pair whose test changed is not comparable run for run: its findings are labelled and
do not gate. When a **limit** changed (a criterion's limit differs, or it is switched
off: a waiver), the new run is judged under both limits: under the base's limits it is
compared with base as any run (a behaviour regression gates), and what differs only
under the new limits is labelled and does not gate. A waiver is a limit change, never a
fix. A **known failure** (``xfail``, :mod:`reports.expectation`) that passes is "fixed:
remove the xfail" (gates with ``strict``); one that fails as expected is listed.

Categories (``CompareRow.category``; ``compare --json`` calls it ``kind``):

========================  ==========================================================
``behaviour_regression``  a gating finding with the test unchanged: gates
``known_failure``         xfail findings: an unexpected pass (gates when strict), an
                          expected failure, a new failure marked xfail
``limits_changed``        a criterion's limit differs: the run's values under both
                          limits, and what differs only under the new ones
``waived``                the same for a criterion switched off in new
``test_changed``          the test differs: the findings of the pair, not gating
``sut_changed``           the SUT differs (controller, options, code): what changed
``removed_scenario``      in base only: gates unless ``missing_is_regression = false``
``new_scenario``          in new only: informational
``unreadable``            a run directory that cannot be read (run.json malformed, a
                          file missing, changed or corrupt; the note names it): gates
                          on the new side, is reported on the base side
``timing``                wall-clock findings: warn (gate with ``--timing-gate``)
``improvement``           fixed runs and metrics better beyond tolerance
``info``                  the rest (status changes that are not worse, NaN metrics)
========================  ==========================================================
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

from reports.compare.findings import (
    BEHAVIOUR_GATES,
    GOOD_KINDS,
    CompareRow,
    Judgement,
    own_judgement,
    status_rows,
)
from reports.expectation import XFAILED, XPASSED
from reports.identity import LimitChange, SetupChange, setup_change
from reports.metrics.criteria import CRITERIA_METRICS, STEPS_CRITERION, Criteria
from reports.metrics.values import Measured
from reports.record import Failure
from reports.tables import RunEntry

__all__ = ["CATEGORIES", "GATING_CATEGORIES", "pair_change", "pair_findings", "under_limits",
           "unreadable_rows"]

CATEGORIES = ("behaviour_regression", "known_failure", "limits_changed", "waived",
              "test_changed", "sut_changed", "removed_scenario", "new_scenario", "unreadable",
              "timing", "improvement", "info")
# categories whose findings may gate (timing too, with --timing-gate)
GATING_CATEGORIES = ("behaviour_regression", "known_failure", "removed_scenario",
                     "unreadable")
TIMING_KINDS = frozenset({"timing_slower", "timing_faster"})
TEST_TEXT = ("the test changed (net, route, ego start, stalled cars, actors, traffic, "
             "replay tracks, duration or step): not comparable run for run, does not gate")


def pair_change(b: RunEntry, n: RunEntry) -> SetupChange | None:
    """What differs in the set-up of a matched pair (None: a side is unreadable)."""
    sb, sn = b.setup, n.setup
    return setup_change(sb, sn) if sb is not None and sn is not None else None


def under_limits(entry: RunEntry, limits: tuple[tuple[str, float | None], ...]) -> Judgement:
    """The run's stored metrics judged under other ``limits`` (criterion -> limit, None
    off; a criterion they do not name is off), by :meth:`Criteria.check`: the same rule
    that judged it. A run that did not end pass/fail keeps its status."""
    if entry.status not in ("pass", "fail") or entry.verdict is None:
        return own_judgement(entry)
    known = set(Criteria.names())
    given = dict(limits)
    criteria = Criteria.from_overrides({k: given.get(k) for k in known})
    failures: tuple[Failure, ...] = tuple(
        f for f in entry.failures if f.criterion == STEPS_CRITERION)
    failures += criteria.check([Measured(m) for m in entry.metrics])
    return Judgement("fail" if failures else "pass", failures)


def _gate_row(row: CompareRow, change: SetupChange | None) -> CompareRow:
    """A behaviour finding of a pair whose test is unchanged: it gates; it names what
    changed in the system under test."""
    note = row.note
    if change is not None and change.sut is not None:
        note = (f"{note}; " if note else "") + f"system under test changed: {change.sut.text}"
    return replace(row, category="behaviour_regression", note=note)


def categorised(row: CompareRow, change: SetupChange | None) -> CompareRow:
    """``row`` with its category (module doc)."""
    if row.kind in TIMING_KINDS:
        return replace(row, category="timing")
    if change is not None and change.test and (row.kind in BEHAVIOUR_GATES
                                               or row.kind in GOOD_KINDS):
        return replace(row, category="test_changed", gate=False)
    if row.kind in BEHAVIOUR_GATES:
        return _gate_row(row, change)
    if row.kind in GOOD_KINDS:
        return replace(row, category="improvement")
    return replace(row, category="info")


def _limit_only(row: CompareRow, change: SetupChange) -> CompareRow:
    """A status finding that exists only under the new limits: labelled, not gating."""
    waived = all(c.waived for c in change.limits)
    why = ", ".join(c.text for c in change.limits)
    note = f"{row.note} — only under the new limits ({why})"
    if row.kind == "fixed":
        note += ": a limit change, not a fix" if not waived else ": a waiver, not a fix"
    return replace(row, category="waived" if waived else "limits_changed", gate=False,
                   note=note)


def _status_findings(key: str, b: RunEntry, n: RunEntry, change: SetupChange | None
                     ) -> list[CompareRow]:
    """Status findings: under the base's limits (behaviour), and those that differ only
    under the new limits (labelled)."""
    actual = status_rows(key, b, n)
    if change is None or not change.limits or change.test:
        return [categorised(r, change) for r in actual]
    judged = status_rows(key, b, n, under_limits(n, b.setup.limits if b.setup else ()))
    rows = [categorised(replace(r, note=f"{r.note} [judged under the base's limits]"),
                        change) for r in judged]
    seen = {(r.kind, r.metric) for r in judged}
    rows += [_limit_only(r, change) for r in actual if (r.kind, r.metric) not in seen]
    return rows


def _bound_verdict(value: float, limit: float | None, bound: str) -> str:
    """'passes', 'fails' or 'off' for a value against one limit."""
    if limit is None:
        return "off"
    if math.isnan(value):
        return "not measured"
    bad = value > limit if bound == "max" else value < limit
    return "fails" if bad else "passes"


def _limit_row(key: str, b: RunEntry, n: RunEntry, c: LimitChange) -> CompareRow:
    """A changed criterion and the new run's value judged under both limits (and the
    base's under its own), so a reader sees whether behaviour or only the limit moved."""
    metric, bound = CRITERIA_METRICS.get(c.criterion, (c.criterion, "max"))
    vb, vn = b.value(metric), n.value(metric)
    mv = n.verdict.metric(metric) if n.verdict is not None else None
    unit = mv.unit if mv is not None else ""
    u = "" if unit in ("", "-") else f" {unit}"
    note = (f"{c.text}: base {vb:.4g}{u} {_bound_verdict(vb, c.base, bound)} its limit; new "
            f"{vn:.4g}{u} {_bound_verdict(vn, c.base, bound)} under the old limit, "
            f"{_bound_verdict(vn, c.new, bound)} under the new")
    return CompareRow(key=key, scenario=n.scenario, controller=n.controller,
                      kind="criterion_off" if c.waived else "limit_changed", metric=metric,
                      unit=unit, base=vb, new=vn,
                      base_limit=math.nan if c.base is None else c.base,
                      limit=math.nan if c.new is None else c.new, note=note,
                      category="waived" if c.waived else "limits_changed")


def change_rows(key: str, b: RunEntry, n: RunEntry, change: SetupChange | None
                ) -> list[CompareRow]:
    """One row per changed limit, one for a changed test, one for a changed system under
    test, whether or not the verdict moved: a reader sees every change."""
    if change is None:
        return []
    common: dict[str, Any] = {"key": key, "scenario": n.scenario, "controller": n.controller}
    rows = [_limit_row(key, b, n, c) for c in change.limits]
    if change.test:
        rows.append(CompareRow(kind="test_changed", note=TEST_TEXT, category="test_changed",
                               **common))
    if change.sut is not None:
        rows.append(CompareRow(kind="sut_changed", category="sut_changed",
                               note=f"system under test changed: {change.sut.text}",
                               **common))
    return rows


def _xfail_rows(key: str, n: RunEntry, rows: list[CompareRow]) -> list[CompareRow]:
    """The findings of a run marked xfail: an unexpected pass replaces 'fixed' ("fixed:
    remove the xfail", gating when strict); a new failure that is the expected one is a
    known failure, not a regression; an expected failure is listed."""
    mark = n.xfail
    seen = n.expectation
    if mark is None or not seen:
        return rows
    common: dict[str, Any] = {"key": key, "scenario": n.scenario, "controller": n.controller,
                              "category": "known_failure"}
    out = []
    for r in rows:
        if seen == XPASSED and r.kind == "fixed":
            continue  # said by the xpass row below
        if seen == XFAILED and r.kind == "new_failure":
            r = replace(r, category="known_failure", gate=False,
                        note=f"{r.note}; expected failure ({mark.text})")
        out.append(r)
    if seen == XPASSED:
        strict = "; strict: an unexpected pass fails the night" if mark.strict else ""
        out.append(CompareRow(kind="xpass", gate=mark.strict,
                              note=f"fixed: remove the xfail ({mark.reason}){strict}",
                              **common))
    else:
        out.append(CompareRow(kind="xfailed", note=f"expected failure ({mark.text}): "
                              + "; ".join(f.text for f in n.failures), **common))
    return out


def pair_findings(key: str, b: RunEntry, n: RunEntry, metric_rows: list[CompareRow]
                  ) -> list[CompareRow]:
    """Every finding of a matched pair, categorised: status (under both limits when they
    differ), the metric rows given (limit-independent), the xfail findings, the set-up
    changes."""
    change = pair_change(b, n)
    rows = _status_findings(key, b, n, change)
    rows += [categorised(r, change) for r in metric_rows]
    rows = _xfail_rows(key, n, rows)
    return rows + change_rows(key, b, n, change)


def unreadable_rows(key: str, b: RunEntry | None, n: RunEntry | None) -> list[CompareRow]:
    """One ``unreadable`` finding per side whose run directory cannot be read (the note
    says which side and why, naming the file): on the new side it gates (a night whose
    runs cannot be read has not shown that it did not regress), on the base side it is
    reported and does not gate (there is nothing to regress from)."""
    rows = []
    for side, entry in (("base", b), ("new", n)):
        if entry is not None and entry.unreadable:
            rows.append(CompareRow(key=key, scenario=entry.scenario, controller=entry.controller,
                                   kind="unreadable", note=f"{side}: {entry.unreadable}",
                                   gate=side == "new", category="unreadable"))
    return rows
