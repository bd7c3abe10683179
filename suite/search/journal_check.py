"""Before a search resumes: is its journal one the search wrote, up to a batch's end?

:func:`check_journal` reads the journal without writing it (:mod:`suite.search.journal`
refuses lines that are not Optuna operations), replays it, and checks each family's
study trial by trial. A :class:`~suite.search.journal.JournalError` names the line of:

* a trial told without a readable outcome (the loop stores one with every tell), or
  finished without any;
* a trial still running (its batch interrupted) whose point is incomplete: a parameter
  or its batch number missing, so the journal ends inside that trial's ask;
* a running trial of a batch whose asks were never marked complete
  (:func:`suite.search.journal.asked_key`; studies marked with
  :data:`~suite.search.journal.ASKS_MARKED` only): the journal was cut between two of
  the batch's asks. The loop writes a batch's asks and their mark in one write, so
  neither an interruption nor a kill leaves this; resuming from it would run a batch
  the uninterrupted search never ran.

A batch interrupted after its asks (trials running, asks marked) is what ``--resume``
is for and passes.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import optuna

from suite.search.journal import ASKS_MARKED, BatchedJournal, JournalError, asked_key, open_journal
from suite.search.loop import OUTCOME, _from_attrs
from suite.search.space import Family

__all__ = ["check_journal"]


def _check_trial(family: Family, ft: optuna.trial.FrozenTrial, journal: BatchedJournal
                 ) -> None:
    line = journal.line_of_trial(ft._trial_id)
    what = f"trial {ft.number} of family {family.name}"
    running = ft.state == optuna.trial.TrialState.RUNNING
    if OUTCOME in ft.user_attrs:
        try:
            _from_attrs(family, ft)
        except (KeyError, TypeError, ValueError) as exc:
            raise JournalError(journal.path, line, f"{what}: its outcome is unreadable "
                               f"({type(exc).__name__}: {exc})") from exc
    elif not running:
        raise JournalError(journal.path, line, f"{what} is finished without an outcome")
    if not running:
        return
    missing = [p.path for p in family.params if p.path not in ft.params]
    batch = ft.user_attrs.get("batch")
    if missing or isinstance(batch, bool) or not isinstance(batch, int):
        lacking = ", ".join(missing) or "its batch number"
        raise JournalError(journal.path, line, f"{what} was asked but its point lacks "
                           f"{lacking}: the journal ends inside that ask")


def _check_study(family: Family, study: optuna.Study, journal: BatchedJournal) -> None:
    trials = study.get_trials(deepcopy=False)
    for ft in trials:
        _check_trial(family, ft, journal)
    if not study.user_attrs.get(ASKS_MARKED):
        return  # a journal of an earlier hwyeval: its batches carry no marks
    for ft in trials:
        if ft.state != optuna.trial.TrialState.RUNNING:
            continue
        batch = int(ft.user_attrs["batch"])
        if asked_key(batch) not in study.user_attrs:
            raise JournalError(journal.path, journal.last_line,
                               f"family {family.name}: batch {batch} (from trial "
                               f"{ft.number}, line {journal.line_of_trial(ft._trial_id)}) "
                               "was never completely asked: the journal was cut inside "
                               "its asks")


def check_journal(path: Path, families: Sequence[Family]) -> None:
    """JournalError unless the journal at ``path`` can be resumed (module doc); nothing
    is written. A missing file passes (nothing was searched yet)."""
    if not Path(path).is_file():
        return
    storage, journal = open_journal(path, repair=False)
    names = {s.study_name for s in storage.get_all_studies()}
    for family in families:
        if family.name in names:
            study = optuna.load_study(study_name=family.name, storage=storage)
            _check_study(family, study, journal)
