"""Shrinking: per failure mode, the failing point nearest the family's nominal point.

1. The failures are grouped by mode (:func:`suite.search.loop.failure_mode`); each mode
   starts from its failing trial nearest the nominal point (:meth:`Family.distance`:
   Euclidean in range units; the lower trial number on a tie).
2. A short line search per parameter, one parameter after the other (coordinate
   descent, in the search table's order): for parameter ``i`` with nominal value
   ``n_i`` and current value ``x_i``, the candidates are ``n_i + t (x_i - n_i)`` for
   ``t = 0, 1/K, ..., (K-1)/K`` (``K`` = ``points``; integers rounded toward ``x_i``, a
   choice only tries ``n_i``); they are run (every mode's candidates in one batch) and
   the smallest ``t`` whose run fails *in the same mode* replaces ``x_i``; none does:
   ``x_i`` stays. A parameter without a nominal value (an optional key left unset) is
   kept.

Each candidate is a normal run named ``<family>__shrink<k>`` (k counts the candidates
built, in order, so a resumed search names and reuses the same runs). The result is a
point that fails in its mode with every parameter as near the nominal as this grid can
tell: a minimal counterexample to read.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

from suite.catalog import Scenario
from suite.search.loop import BatchRunner, TrialResult, result_of
from suite.search.space import Family, Refused, build_point, shrink_name

__all__ = ["Shrunk", "shrink_bound", "shrink_failures", "start_points"]


@dataclass(frozen=True)
class Shrunk:
    """A failure mode's case: ``origin`` the trial it started from, ``result`` the run
    it ends with (the origin itself when nothing nearer failed the same way) and
    ``steps`` how many parameters moved."""

    mode: str
    origin: TrialResult
    result: TrialResult
    steps: int = 0


def start_points(family: Family, failures: Sequence[TrialResult]) -> dict[str, TrialResult]:
    """Per failure mode its failing trial nearest the nominal point (step 1)."""
    best: dict[str, TrialResult] = {}
    for t in sorted(failures, key=lambda t: (family.distance(t.values), t.trial)):
        best.setdefault(t.mode, t)
    return dict(sorted(best.items()))


def shrink_bound(family: Family, failures: Sequence[TrialResult], points: int = 4) -> int:
    """At most how many runs the line searches of :func:`shrink_failures` take: per
    failure mode, per parameter with a nominal value, ``points`` candidates (1 for a
    choice). These runs come on top of the search's budget; announce them."""
    per_mode = sum(1 if p.kind == "choice" else points
                   for p, nominal in zip(family.params, family.nominal, strict=True)
                   if nominal is not None)
    return len(start_points(family, failures)) * per_mode


def _candidates(family: Family, i: int, values: tuple[Any, ...], points: int) -> list[list[Any]]:
    p, nominal, x = family.params[i], family.nominal[i], values[i]
    if nominal is None or x == nominal:
        return []
    ts = [0.0] if p.kind == "choice" else [k / points for k in range(points)]
    out: list[list[Any]] = []
    for t in ts:
        v = p.toward(nominal, x, t)
        cand = list(values)
        cand[i] = v
        if v != x and cand not in out:
            out.append(cand)
    return out


def shrink_failures(family: Family, failures: Sequence[TrialResult], run_batch: BatchRunner,
                    points: int = 4) -> tuple[list[Shrunk], list[TrialResult], bool]:
    """The shrunk case of every failure mode (module doc), every line-search run's
    result, and False when stopped (the cases then are as far as the searches got)."""
    current = start_points(family, failures)
    cases = {mode: Shrunk(mode, t, t) for mode, t in current.items()}
    counter = 0
    tried: list[TrialResult] = []
    for i in range(len(family.params)):
        batch: list[tuple[str, list[Any], Scenario]] = []
        for mode, case in cases.items():
            for cand in _candidates(family, i, case.result.values, points):
                built = build_point(family, cand, shrink_name(family.name, counter))
                if isinstance(built, Refused):
                    continue
                counter += 1
                batch.append((mode, cand, built))
        if not batch:
            continue
        records = run_batch([sc for _, _, sc in batch])
        if records is None:
            return list(cases.values()), tried, False
        chosen: dict[str, TrialResult] = {}
        for (mode, cand, sc), record in zip(batch, records, strict=True):
            res = replace(result_of(family, cases[mode].origin.trial, cand, record, -1),
                          run=sc.name)
            tried.append(res)
            if res.is_failure and res.mode == mode and mode not in chosen:
                chosen[mode] = res  # candidates are in increasing t: the first is nearest
        for mode, res in chosen.items():
            case = cases[mode]
            cases[mode] = Shrunk(mode, case.origin, res, case.steps + 1)
    return list(cases.values()), tried, True
