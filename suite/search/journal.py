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
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import optuna
import optuna.storages.journal

__all__ = ["BatchedJournal", "open_journal"]


class BatchedJournal(optuna.storages.journal.BaseJournalBackend):
    """A journal in memory, appended to ``path`` at :meth:`flush` (module doc)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._logs: list[dict[str, Any]] = []
        self._written = 0
        if self.path.is_file():
            with self.path.open("rb") as fh:
                data = fh.read()
            complete = data[:data.rfind(b"\n") + 1]
            for line in complete.splitlines():
                if line.strip():
                    self._logs.append(json.loads(line))
            if len(complete) != len(data):  # a torn last line: cut it off
                with self.path.open("r+b") as fh:
                    fh.truncate(len(complete))
            self._written = len(self._logs)

    def read_logs(self, log_number_from: int) -> Iterable[dict[str, Any]]:
        return self._logs[log_number_from:]

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


def open_journal(path: str | Path) -> tuple[optuna.storages.BaseStorage, BatchedJournal]:
    """The storage over a :class:`BatchedJournal` at ``path``, and the journal."""
    backend = BatchedJournal(path)
    return optuna.storages.JournalStorage(backend), backend
