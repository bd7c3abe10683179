"""The search's Optuna storage: a journal file written once per batch.

Optuna's :class:`~optuna.storages.JournalStorage` keeps a study as a log of operations
(create trial, set a parameter, tell, ...). Its file backend appends and fsyncs every
operation (~4 ms each here, ~7 per trial); :class:`BatchedJournal` keeps the log in
memory and appends what is new to the file, in one write and one fsync, at
:meth:`BatchedJournal.flush`: the loop flushes after a batch's asks (so the points of a
batch that is interrupted are on disk before it runs) and after its tells. A process
killed between its tells and the flush loses those tells only: their trials read back
as still running and are run again (their run directories are kept by ``--resume``).

One process owns the file (the search); the format is Optuna's journal (one JSON object
per line), readable by ``optuna.storages.journal.JournalFileBackend`` too. A last line
cut short by a kill is ignored on reading.

Anything else that is not a journal the search wrote is a :class:`JournalError` naming
the file and the line (``hwyeval search --resume`` exits 2 with it, before anything is
written): a line that is not UTF-8 JSON, not an object, not an Optuna operation or
missing its fields, one naming a study or trial that does not exist yet, one Optuna
cannot replay; and (:mod:`suite.search.journal_check`) a journal cut inside a batch's
asks. To tell such a cut from an interruption the loop marks each study
(:data:`ASKS_MARKED`) and, once a batch's points are all asked, the batch
(:func:`asked_key`); both are study attributes, so the file stays Optuna's format.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import optuna
import optuna.storages.journal

__all__ = ["ASKS_MARKED", "BatchedJournal", "JournalError", "asked_key", "open_journal"]

# A study attribute: this study marks each batch whose asks are complete (asked_key).
ASKS_MARKED = "hwyeval_asks_marked"

# The fields each Optuna journal operation needs besides op_code and worker_id
# (optuna.storages.journal._storage.JournalOperation, Optuna 4 and 5).
_FIELDS: dict[int, tuple[str, ...]] = {
    0: ("study_name", "directions"),  # create study
    1: ("study_id",),  # delete study
    2: ("study_id", "user_attr"),
    3: ("study_id", "system_attr"),
    4: ("study_id", "datetime_start"),  # create trial
    5: ("trial_id", "param_name", "param_value_internal", "distribution"),
    6: ("trial_id", "state", "values"),  # tell
    7: ("trial_id", "step", "intermediate_value"),
    8: ("trial_id", "user_attr"),
    9: ("trial_id", "system_attr"),
}
_CREATE_STUDY, _CREATE_TRIAL = 0, 4


def asked_key(batch: int) -> str:
    """The study attribute written once every point of ``batch`` is asked."""
    return f"hwyeval_asked_{batch}"


class JournalError(ValueError):
    """The search journal is not one the search wrote (the message names file and
    line, and what to do)."""

    def __init__(self, path: Path, line: int | None, why: str) -> None:
        where = f"{path}:{line}" if line is not None else f"{path}"
        super().__init__(f"{where}: {why}; the search journal is damaged: --overwrite "
                         "starts the search again (or restore the file)")
        self.path = path
        self.line = line


def _parse(path: Path, number: int, raw: bytes) -> dict[str, Any]:
    """Line ``number`` of the journal as an operation; JournalError if it is not one."""
    try:
        log = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        raise JournalError(path, number, "not a line of UTF-8 JSON") from None
    if not isinstance(log, dict):
        raise JournalError(path, number, f"a JSON {type(log).__name__}, not an operation")
    op = log.get("op_code")
    if isinstance(op, bool) or not isinstance(op, int) or op not in _FIELDS:
        raise JournalError(path, number, f"op_code {op!r} is no Optuna journal operation")
    missing = [k for k in ("worker_id", *_FIELDS[op]) if k not in log]
    if missing:
        raise JournalError(path, number, f"operation {op} without {', '.join(missing)}")
    return log


class _Ids:
    """The studies and trials the operations read so far have created (Optuna numbers
    them in order), to refuse an operation on one that does not exist yet."""

    def __init__(self) -> None:
        self.studies: set[str] = set()
        self.trials = 0

    def check(self, path: Path, number: int, log: dict[str, Any]) -> None:
        op = log["op_code"]
        for key, known in (("study_id", len(self.studies)), ("trial_id", self.trials)):
            value = log.get(key)
            if key in log and (isinstance(value, bool) or not isinstance(value, int)
                               or not 0 <= value < known):
                raise JournalError(path, number, f"{key} {value!r} does not exist at this "
                                   "line")
        if op == _CREATE_STUDY:
            self.studies.add(str(log["study_name"]))
        elif op == _CREATE_TRIAL:
            self.trials += 1


class BatchedJournal(optuna.storages.journal.BaseJournalBackend):
    """A journal in memory, appended to ``path`` at :meth:`flush` (module doc).
    JournalError when the file holds a line that is not an operation the search wrote;
    ``repair``: cut a torn last line off the file (a reader that only checks passes
    False and writes nothing)."""

    def __init__(self, path: str | Path, *, repair: bool = True) -> None:
        self.path = Path(path)
        self._logs: list[dict[str, Any]] = []
        self._lines: list[int] = []  # the file's line number of each operation
        self._trial_lines: list[int] = []  # the line creating each trial, by trial id
        self._written = 0
        self.replaying = -1  # the operation Optuna is replaying (reading), by index
        if self.path.is_file():
            self._load(repair)

    def _load(self, repair: bool) -> None:
        with self.path.open("rb") as fh:
            data = fh.read()
        complete = data[:data.rfind(b"\n") + 1]
        ids = _Ids()
        for number, raw in enumerate(complete.splitlines(), start=1):
            if not raw.strip():
                continue
            log = _parse(self.path, number, raw)
            ids.check(self.path, number, log)
            if log["op_code"] == _CREATE_TRIAL:
                self._trial_lines.append(number)
            self._logs.append(log)
            self._lines.append(number)
        if repair and len(complete) != len(data):  # a torn last line: cut it off
            with self.path.open("r+b") as fh:
                fh.truncate(len(complete))
        self._written = len(self._logs)

    def line_of(self, index: int) -> int | None:
        """The file's line number of operation ``index`` (None: not from the file)."""
        return self._lines[index] if 0 <= index < len(self._lines) else None

    def line_of_trial(self, trial_id: int) -> int | None:
        """The line that created trial ``trial_id`` (Optuna's storage id), None when it
        was not read from the file."""
        return self._trial_lines[trial_id] if 0 <= trial_id < len(self._trial_lines) \
            else None

    @property
    def last_line(self) -> int | None:
        """The number of the file's last operation line (None: empty)."""
        return self._lines[-1] if self._lines else None

    def read_logs(self, log_number_from: int) -> Iterable[dict[str, Any]]:
        return self._replay(log_number_from)

    def _replay(self, start: int) -> Iterator[dict[str, Any]]:
        for index in range(start, len(self._logs)):
            self.replaying = index
            yield self._logs[index]

    def append_logs(self, logs: list[dict[str, Any]]) -> None:
        self._logs.extend(logs)

    def flush(self) -> None:
        """Append the operations not yet on disk (one write, one fsync)."""
        new = self._logs[self._written:]
        if not new:
            return
        text = "".join(json.dumps(log, separators=(",", ":")) + "\n" for log in new)
        with self.path.open("ab") as fh:
            fh.write(text.encode("utf-8"))
            fh.flush()
            os.fsync(fh.fileno())
        self._written = len(self._logs)


def open_journal(path: str | Path, *, repair: bool = True
                 ) -> tuple[optuna.storages.BaseStorage, BatchedJournal]:
    """The storage over a :class:`BatchedJournal` at ``path``, and the journal;
    JournalError (naming the line) when Optuna cannot replay it."""
    backend = BatchedJournal(path, repair=repair)
    try:
        storage = optuna.storages.JournalStorage(backend)
    except Exception as exc:  # noqa: BLE001 - whatever Optuna meets in the file
        raise JournalError(backend.path, backend.line_of(backend.replaying),
                           f"Optuna cannot replay this operation ({type(exc).__name__}: "
                           f"{exc})") from exc
    return storage, backend
