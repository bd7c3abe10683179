"""The search loop: ask Optuna for a batch of points, run them, tell how near they failed.

For each family (:class:`~suite.search.space.Family`, in catalog order) one Optuna study
(named after the family) in the search's storage minimises the run's robustness
(:mod:`reports.metrics.robustness`; negative = the run failed), through a smooth
stand-in (step 3):

1. batch ``b``: the study's sampler is made anew with a seed derived from
   (``seed``, family index, ``b``) (:func:`~suite.search.samplers.make_sampler`; a
   Sobol sequence keeps one seed per study and is indexed by the points drawn), so what
   it draws depends only on the seed and on the trials told so far, never on this
   process's history: a resumed search draws what an uninterrupted one draws;
2. it asks until it has ``min(batch_size, budget - runs)`` points the catalog accepts
   (:func:`~suite.search.space.build_point`); a refused point is told as failed with
   its reason and counted (at most ``max_refusals`` per family);
3. the batch runs (``run_batch``: the executor, J at a time) and each trial is told in
   trial order (an error or timeout: told as failed). The value told is the soft minimum
   of the run's criterion margins (:func:`objective`, temperature 1): at most the
   robustness and within ln(criteria) of it, but lowered by every margin near the
   smallest. With the hard minimum one comfort margin capped every quiet run at the same
   value and TPE saw a plateau; measured on the three families of
   ``catalogs/search_families.toml`` the soft minimum reached the first failure in about
   half the runs. Whether a run failed is its verdict (the robustness < 0), never this.

Every trial's outcome is stored in the study's user attributes (status, robustness,
criterion, failure mode, reason): the storage alone rebuilds the search. A batch
interrupted (``run_batch`` returns None) leaves its trials RUNNING; resuming runs
exactly those again (their points are in the storage) before asking anew.

A trial's *failure mode* (:func:`failure_mode`): its failed criteria (sorted, joined by
'+') and the manoeuvre phase at the earliest failure's step, as the metrics recorded it
in the verdict (``Failure.phase``, from the trace's decision ``side``: left / right:
passing on that side, lane: keeping its lane, follow: following a car it cannot pass;
``whole_run`` for failures without a step; ``unknown`` for a run.json written before
the phase was recorded). The trace is not read again.
"""

from __future__ import annotations

import json
import math
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import optuna

from reports.metrics.robustness import robustness
from reports.record import RunRecord
from suite.catalog import Scenario
from suite.exec.signals import StopRequest
from suite.search.journal import ASKS_MARKED, BatchedJournal, asked_key, open_journal
from suite.search.samplers import SAMPLERS, make_sampler
from suite.search.space import Family, Param, Refused, build_point, trial_name

__all__ = ["SAMPLERS", "BatchRunner", "FamilyResult", "SearchSettings", "TrialResult",
           "failure_mode", "make_sampler", "open_storage", "search_family"]

REFUSED = "refused"
INTERRUPTED = "interrupted"
VALUE_CAP = 1e9  # +inf robustness (no criterion in force) is told as this
# The optimiser is told the soft minimum of the margins at this temperature (None: the
# robustness itself); see :func:`objective`.
SOFTMIN_TAU: float | None = 1.0

# The batch of scenarios -> their records in the same order; None: stopped.
BatchRunner = Callable[[Sequence[Scenario]], "list[RunRecord] | None"]


@dataclass(frozen=True)
class SearchSettings:
    """budget_runs: runs per family (refused points do not count); sampler: one of
    :data:`SAMPLERS`; seed >= 0; batch_size: points asked and run together (--jobs);
    max_refusals: refused points per family before it gives up (default 10 x budget)."""

    budget_runs: int
    sampler: str = "tpe"
    seed: int = 0
    batch_size: int = 1
    max_refusals: int = -1

    def __post_init__(self) -> None:
        if self.budget_runs < 1:
            raise ValueError(f"SearchSettings.budget_runs must be >= 1, got {self.budget_runs}")
        if self.sampler not in SAMPLERS:
            raise ValueError(f"SearchSettings.sampler must be one of {SAMPLERS}, "
                             f"got {self.sampler!r}")
        if self.seed < 0 or self.batch_size < 1:
            raise ValueError(f"SearchSettings: seed >= 0 and batch_size >= 1, got "
                             f"{self.seed}, {self.batch_size}")
        if self.max_refusals < 0:
            object.__setattr__(self, "max_refusals", 10 * self.budget_runs)


@dataclass(frozen=True)
class TrialResult:
    """One trial: ``values`` per param of the family; status pass | fail | error |
    timeout | refused; robustness [-] (NaN when not judged); criterion: the one that
    attains it; failed: the failed criteria; mode: the failure mode ('' unless failed);
    reason: why refused; run: its run directory name ('' when refused)."""

    family: str
    trial: int
    run: str
    values: tuple[Any, ...]
    status: str
    robustness: float = math.nan
    criterion: str = ""
    failed: tuple[str, ...] = ()
    mode: str = ""
    reason: str = ""
    batch: int = 0
    objective: float = math.nan

    @property
    def is_failure(self) -> bool:
        return self.status == "fail"

    @property
    def ran(self) -> bool:
        return self.status != REFUSED


@dataclass
class FamilyResult:
    """What a family's search did: every trial in trial order, whether it was stopped,
    and the seconds spent outside ``run_batch`` (the search's own overhead) and inside."""

    family: Family
    trials: list[TrialResult] = field(default_factory=list)
    stopped: bool = False
    overhead_s: float = 0.0
    run_s: float = 0.0

    @property
    def runs(self) -> list[TrialResult]:
        return [t for t in self.trials if t.ran]

    @property
    def refused(self) -> int:
        return sum(1 for t in self.trials if not t.ran)

    @property
    def failures(self) -> list[TrialResult]:
        return [t for t in self.trials if t.is_failure]

    def best(self) -> TrialResult | None:
        judged = [t for t in self.trials if not math.isnan(t.robustness)]
        return min(judged, key=lambda t: (t.robustness, t.trial)) if judged else None


def open_storage(path: str) -> tuple[optuna.storages.BaseStorage, BatchedJournal]:
    """The search's Optuna storage and its journal (:mod:`suite.search.journal`)."""
    warnings.filterwarnings("ignore", category=optuna.exceptions.ExperimentalWarning)
    warnings.filterwarnings("ignore", category=FutureWarning, module="optuna")
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    return open_journal(path)


def _suggest(trial: optuna.Trial, p: Param) -> Any:
    if p.kind == "choice":
        return trial.suggest_categorical(p.path, list(range(len(p.choices))))
    if p.kind == "int":
        return trial.suggest_int(p.path, int(p.low), int(p.high))
    return trial.suggest_float(p.path, p.low, p.high)


def failure_mode(record: RunRecord) -> str:
    """The failure mode of a failed run (module doc); '' for one that did not fail."""
    verdict = record.verdict
    if verdict is None or not verdict.failures:
        return ""
    criteria = "+".join(sorted({f.criterion for f in verdict.failures}))
    steps = [(f.step, i) for i, f in enumerate(verdict.failures) if f.step is not None]
    if not steps:
        return f"{criteria}@whole_run"
    earliest = verdict.failures[min(steps)[1]]  # failures at one step share its phase
    return f"{criteria}@{earliest.phase or 'unknown'}"


def objective(margins: Sequence[float], tau: float | None = SOFTMIN_TAU) -> float:
    """What the optimiser is told: the soft minimum ``m - tau ln sum_c exp(-(rho_c - m) /
    tau)`` of the finite margins ``rho_c`` (``m`` their minimum, the robustness): at most
    the robustness, within ``tau ln n`` of it, and lowered by every margin near the
    smallest, so that a quiet run's landscape is not flat where one criterion caps the
    minimum. NaN without a finite margin; the robustness itself for ``tau`` None."""
    finite = [m for m in margins if math.isfinite(m)]
    if not finite:
        return math.nan
    m = min(finite)
    if tau is None:
        return m
    return m - tau * math.log(sum(math.exp(-(r - m) / tau) for r in finite))


def result_of(family: Family, trial: int, values: Sequence[Any], record: RunRecord,
              batch: int) -> TrialResult:
    """The trial's result from its run's record."""
    rob = robustness(record.verdict) if record.verdict is not None else None
    verdict = record.verdict
    failed = tuple(sorted({f.criterion for f in verdict.failures})) if verdict else ()
    return TrialResult(family.name, trial, trial_name(family.name, trial), tuple(values),
                       record.status, rob.value if rob is not None else math.nan,
                       rob.criterion if rob is not None else record.status,
                       failed if record.status == "fail" else (),
                       failure_mode(record) if record.status == "fail" else "", batch=batch,
                       objective=objective([m.margin for m in rob.margins])
                       if rob is not None and rob.margins else math.nan)


# ------------------------------------------------------------------ storage of outcomes
OUTCOME = "outcome"  # the user attribute holding a told trial's outcome (JSON)


def _outcome(result: TrialResult) -> str:
    return json.dumps({"status": result.status, "robustness": result.robustness,
                       "criterion": result.criterion, "failed": list(result.failed),
                       "mode": result.mode, "reason": result.reason, "batch": result.batch,
                       "objective": result.objective, "values": list(result.values)},
                      allow_nan=True)


def _from_attrs(family: Family, ft: optuna.trial.FrozenTrial) -> TrialResult:
    a = json.loads(ft.user_attrs[OUTCOME])
    status = str(a["status"])
    return TrialResult(family.name, ft.number,
                       trial_name(family.name, ft.number) if status != REFUSED else "",
                       tuple(a["values"]), status, float(a["robustness"]),
                       str(a["criterion"]), tuple(a["failed"]), str(a["mode"]),
                       str(a["reason"]), int(a["batch"]),
                       float(a.get("objective", a["robustness"])))


class _Study:
    """A family's study with its storage ids (to write attributes of any trial)."""

    def __init__(self, storage: optuna.storages.BaseStorage, family: Family, seed: int,
                 kind: str, family_index: int) -> None:
        self.storage = storage
        self.family = family
        self.kind, self.seed, self.index = kind, seed, family_index
        self.study = optuna.create_study(study_name=family.name, storage=storage,
                                         direction="minimize", load_if_exists=True,
                                         sampler=make_sampler(kind, seed, family_index, 0))
        self.study_id = storage.get_study_id_from_name(family.name)
        if not self.study.get_trials(deepcopy=False):  # new: marks its asks (journal.asked_key)
            self.study.set_user_attr(ASKS_MARKED, 1)

    def reseed(self, batch: int) -> None:
        self.study.sampler = make_sampler(self.kind, self.seed, self.index, batch)

    def record(self, result: TrialResult) -> None:
        """Store the outcome and tell it (a value, or failed)."""
        tid = self.storage.get_trial_id_from_study_id_trial_number(self.study_id, result.trial)
        self.storage.set_trial_user_attr(tid, OUTCOME, _outcome(result))
        told = result.objective if math.isfinite(result.objective) else result.robustness
        if result.ran and not math.isnan(told):
            self.study.tell(result.trial, min(told, VALUE_CAP))
        else:
            self.study.tell(result.trial, state=optuna.trial.TrialState.FAIL)

    def existing(self) -> tuple[list[TrialResult], list[optuna.trial.FrozenTrial], int]:
        """Told trials' results, the trials still RUNNING (an interrupted batch), and
        the next batch index."""
        done: list[TrialResult] = []
        pending: list[optuna.trial.FrozenTrial] = []
        last = -1
        for ft in self.study.get_trials(deepcopy=False):
            if ft.state == optuna.trial.TrialState.RUNNING:
                pending.append(ft)
                last = max(last, int(ft.user_attrs.get("batch", last)))
            elif OUTCOME in ft.user_attrs:
                res = _from_attrs(self.family, ft)
                done.append(res)
                last = max(last, res.batch)
        return done, pending, last + 1


def _values_of(family: Family, params: dict[str, Any]) -> list[Any] | None:
    if any(p.path not in params for p in family.params):
        return None
    return [p.value(params[p.path]) for p in family.params]


def _ask_batch(st: _Study, want: int, batch: int, out: FamilyResult, settings: SearchSettings
               ) -> list[tuple[int, list[Any], Scenario]]:
    """Points of one batch: ``want`` accepted ones (refused ones told and kept in
    ``out``), fewer if the family's refusals run out."""
    asked: list[tuple[int, list[Any], Scenario]] = []
    family = st.family
    while len(asked) < want and out.refused < settings.max_refusals:
        trial = st.study.ask()
        raw = {p.path: _suggest(trial, p) for p in family.params}
        values = [p.value(raw[p.path]) for p in family.params]
        st.storage.set_trial_user_attr(trial._trial_id, "batch", batch)
        built = build_point(family, values, trial_name(family.name, trial.number))
        if isinstance(built, Refused):
            res = TrialResult(family.name, trial.number, "", tuple(values), REFUSED,
                              reason=built.reason, batch=batch)
            st.record(res)
            out.trials.append(res)
            continue
        asked.append((trial.number, values, built))
    return asked


def _run(st: _Study, asked: list[tuple[int, list[Any], Scenario]], batch: int,
         run_batch: BatchRunner, out: FamilyResult) -> bool:
    """Run a batch and tell it; False when stopped (its trials stay RUNNING)."""
    t0 = time.perf_counter()
    records = run_batch([sc for _, _, sc in asked])
    out.run_s += time.perf_counter() - t0
    if records is None:
        return False
    for (number, values, _), record in zip(asked, records, strict=True):
        res = result_of(st.family, number, values, record, batch)
        st.record(res)
        out.trials.append(res)
    return True


def _resume_pending(st: _Study, pending: list[optuna.trial.FrozenTrial], run_batch: BatchRunner,
                    out: FamilyResult) -> bool:
    """Run an interrupted batch's trials again (their stored points)."""
    asked: list[tuple[int, list[Any], Scenario]] = []
    batch = 0
    for ft in sorted(pending, key=lambda t: t.number):
        values = _values_of(st.family, ft.params)
        batch = int(ft.user_attrs.get("batch", 0))
        built = build_point(st.family, values, trial_name(st.family.name, ft.number)) \
            if values is not None else Refused(INTERRUPTED)
        if isinstance(built, Refused):
            res = TrialResult(st.family.name, ft.number, "", tuple(values or ()), REFUSED,
                              reason=built.reason, batch=batch)
            st.record(res)
            out.trials.append(res)
        else:
            asked.append((ft.number, values or [], built))
    return _run(st, asked, batch, run_batch, out) if asked else True


def search_family(family: Family, family_index: int, settings: SearchSettings,
                  storage: optuna.storages.BaseStorage, run_batch: BatchRunner,
                  stop: StopRequest | None = None,
                  on_batch: Callable[[FamilyResult], None] | None = None,
                  journal: BatchedJournal | None = None) -> FamilyResult:
    """Search one family to its budget (module doc); resumes what the storage holds.
    ``journal``: flushed after each batch's asks and after its tells."""
    def flush() -> None:
        if journal is not None:
            journal.flush()

    t_start = time.perf_counter()
    st = _Study(storage, family, settings.seed, settings.sampler, family_index)
    done, pending, batch = st.existing()
    out = FamilyResult(family, trials=done)
    if pending and not _resume_pending(st, pending, run_batch, out):
        out.stopped = True
    flush()
    while not out.stopped and not (stop is not None and stop.requested):
        want = min(settings.batch_size, settings.budget_runs - len(out.runs))
        if want <= 0 or out.refused >= settings.max_refusals:
            break
        st.reseed(batch)
        asked = _ask_batch(st, want, batch, out, settings)
        st.study.set_user_attr(asked_key(batch), len(asked))  # in the same flush as the asks
        flush()
        if asked and not _run(st, asked, batch, run_batch, out):
            out.stopped = True
        flush()
        batch += 1
        if on_batch is not None:
            on_batch(out)
    if stop is not None and stop.requested:
        out.stopped = True
    out.trials.sort(key=lambda t: t.trial)
    out.overhead_s = time.perf_counter() - t_start - out.run_s
    return out
