"""The local executor: up to ``jobs`` scenario processes at once on this machine.

One scenario per process (libsumo hosts one simulation per process), started by a
``forkserver`` with the heavy modules preloaded (:data:`suite.exec.forkserver.PRELOAD`:
:func:`suite.exec.prepare.prepare_process`), so a catalog pays imports and numba cache
loading once. The forkserver is started (and its preload
awaited) before the first scenario, in a thread, so that the parent stays responsive
to signals and no scenario's budget is spent on the warm-up;
:func:`suite.exec.forkserver.prestart_forkserver` starts it earlier still, while the
parent validates the catalog and prepares the output (the preload runs in its own
process, the command's fixed costs overlap).

For each job: an older run directory of it is removed before it starts (what is
found there afterwards is this run's), a process over its wall-clock budget is
killed (``timeout``), a process that died without publishing a record is an
``error`` with its exit code. On a stop request (:mod:`suite.exec.signals`) nothing
more is dispatched, the running processes and their groups get SIGTERM then SIGKILL
(:mod:`suite.exec.worker`), their staging directories are removed, no record is
written for them (they did not finish: ``--resume`` runs them again), and the
forkserver is stopped.

The forkserver dying mid-run loses no result: a running scenario process keeps the
write end of its own status pipe, so the parent hears of it when it ends, not when the
forkserver dies (exit code 255, its published record kept:
tests/test_reliability_forkserver.py kills the forkserver mid-run), and the next start
brings up a new forkserver. A start that meets a forkserver still dying (its pipe
closed: EOFError, ConnectionError) is tried once more on a new one, so that its death is
not blamed on the scenario.
"""

from __future__ import annotations

import multiprocessing as mp
import multiprocessing.connection
import signal
import sys
import time
import traceback
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

from reports.record import RecordError, RunRecord, write_run_json
from reports.record.codec import write_text_atomic
from reports.record.run import TRACEBACK, discard_staging, remove_path
from suite.exec.forkserver import stop_forkserver, warm_up
from suite.exec.jobs import OnDone, RunJob, read_result, record_in_memory, run_job, write_failure
from suite.exec.memory import apply_memory_cap, memory_note, ran_out_of_memory
from suite.exec.signals import POLL_S, StopRequest
from suite.exec.worker import become_worker, signal_worker, terminate_workers

__all__ = ["KILL_GRACE_S", "LocalExecutor"]

KILL_GRACE_S = 10.0  # a process still alive this long after its budget is killed [s]


def _worker_main(job: RunJob, memory_limit: int | None = None) -> None:
    """The scenario process: its group and signals, its memory cap (``memory_limit``
    [bytes], None: none; :mod:`suite.exec.memory`), then the run. A run that ran out of
    memory under the cap says so in its error's last line."""
    become_worker()
    try:
        apply_memory_cap(memory_limit)
        record = run_job(job)
    except Exception:
        record = write_failure(job, "error", traceback.format_exc())
        if memory_limit is not None:
            note_out_of_memory(record, memory_limit)
        raise
    if memory_limit is not None:
        note_out_of_memory(record, memory_limit)
    if record.run_dir is None:  # not even its record could be written (a full disk)
        lines = [li for li in (record.outcome.error or "").splitlines() if li.strip()]
        sys.stderr.write(f"hwyeval: {job.name}: its run directory could not be written: "
                         f"{lines[-1].strip() if lines else '?'}\n")
        sys.exit(UNPUBLISHED)


def note_out_of_memory(record: RunRecord, limit: int) -> None:
    """If ``record`` (published) ended in a failed allocation, add :func:`memory_note`
    as the last line of its error (the line the terminal and the reports show), in its
    traceback.txt and run.json (each replaced atomically)."""
    if record.run_dir is None or not ran_out_of_memory(record.outcome.error):
        return
    error = f"{(record.outcome.error or '').rstrip()}\n{memory_note(limit)}\n"
    record.outcome = replace(record.outcome, error=error)
    try:
        write_text_atomic(record.run_dir / TRACEBACK, error)
        write_run_json(record, record.run_dir)
    except OSError:  # a full disk: the run's own error stays, as written
        pass


@dataclass
class _Running:
    job: RunJob
    proc: Any
    started: float  # time.monotonic() at start [s]
    memory_limit: int | None = None  # the process's address-space cap [bytes]


# The exit code of a scenario process that ran but could not write its run directory
# (it said why on stderr, which it shares with the command).
UNPUBLISHED = 3

# Exit codes of a scenario process that was stopped, not broken: killed by a stop
# signal, or 255 (multiprocessing's code when the forkserver that reports the child's
# status is gone).
STOPPED_FROM_OUTSIDE = (-signal.SIGTERM, -signal.SIGINT, -signal.SIGHUP, 255)


class LocalExecutor:
    """Scenario processes on this machine, at most ``jobs`` at once (module docstring)."""

    def __init__(self, jobs: int = 1, start_method: str = "forkserver") -> None:
        if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
            raise ValueError(f"jobs must be a whole number >= 1, got {jobs!r}")
        self.jobs = jobs
        self.ctx: Any = mp.get_context(start_method)
        self.start_method = start_method  # a forkserver's preload is set by warm_up

    # ------------------------------------------------------------------ the loop
    def run(self, jobs: Sequence[RunJob], on_done: OnDone | None = None,
            stop: StopRequest | None = None) -> list[RunRecord]:
        stop = stop if stop is not None else StopRequest()
        pending = deque(jobs)
        running: dict[Any, _Running] = {}
        results: list[RunRecord] = []

        def done(record: RunRecord | None) -> None:
            if record is None:  # stopped from outside before it finished: not a result
                return
            results.append(record)
            if on_done is not None:
                on_done(record)

        if not pending or not self._warm_up(stop):
            self._after(stop)
            return results
        ended: list[_Running] = []  # processes that ended, their records not read yet
        try:
            while (pending or running or ended) and not stop.requested:
                self._dispatch(pending, running, done, stop)
                # Read the ended runs' records only now: the next scenario processes
                # start meanwhile instead of after it (15-30 ms of every run).
                while ended:
                    done(self._finish(ended.pop(0), None))
                if not running:
                    continue
                for sentinel in mp.connection.wait(list(running), timeout=POLL_S):
                    ended.append(running.pop(sentinel))
                self._kill_overdue(running, done)
        finally:
            self._wind_down(ended, running, done, stop)
        return results

    def _dispatch(self, pending: deque[RunJob], running: dict[Any, _Running],
                  done: Callable[[RunRecord | None], None], stop: StopRequest) -> None:
        """Start pending jobs, in order, while fewer than ``jobs`` run and no stop is
        requested; ``running`` gets each started process by its sentinel, ``done`` the
        error record of a job that could not start."""
        while pending and len(running) < self.jobs and not stop.requested:
            job = pending.popleft()
            started = self._start(job)
            if isinstance(started, RunRecord):
                done(started)
            else:
                running[started.proc.sentinel] = started

    def _wind_down(self, ended: list[_Running], running: dict[Any, _Running],
                   done: Callable[[RunRecord | None], None], stop: StopRequest) -> None:
        """The end of :meth:`run`, however it ends: the records of the processes that
        ended are read, the ones still running are abandoned, the forkserver stopped
        on a stop request."""
        for item in ended:  # finished and published before the stop: kept
            done(self._finish(item, None))
        if running:  # a stop request, or the parent itself failed: no orphan
            self._abandon(list(running.values()), done)
        self._after(stop)

    def _warm_up(self, stop: StopRequest) -> bool:
        """Start the forkserver and wait for its preload in a thread, polling ``stop``;
        False when stopped meanwhile."""
        thread = warm_up(self.start_method)
        while thread.is_alive():
            if stop.requested:
                return False
            thread.join(POLL_S)
        return True

    def _after(self, stop: StopRequest) -> None:
        if stop.requested and self.start_method == "forkserver":
            stop_forkserver()

    # ------------------------------------------------------------------ one job
    def _start(self, job: RunJob) -> _Running | RunRecord:
        """Start the job's process (its older run directory removed first), or the
        error record when it cannot be started."""
        try:
            remove_path(job.run_dir)
            discard_staging(job.out_dir, job.name)
            limit = job.memory.limit_bytes()  # this machine's, as the process will have it
            proc = self._start_process(job, limit)
        except Exception:  # noqa: BLE001 - one job that cannot start is that job's error
            return write_failure(job, "error", "could not start the scenario process:\n"
                                 + traceback.format_exc())
        return _Running(job, proc, time.monotonic(), limit)

    def _start_process(self, job: RunJob, limit: int | None) -> Any:
        """The started process of ``job`` (address space capped at ``limit`` [bytes]),
        tried once more on a new forkserver when the old one is gone or dying (module
        doc)."""
        proc = self.ctx.Process(target=_worker_main, args=(job, limit), name=job.name)
        try:
            proc.start()
        except (EOFError, ConnectionError):
            if self.start_method != "forkserver":
                raise
            stop_forkserver()
            proc = self.ctx.Process(target=_worker_main, args=(job, limit), name=job.name)
            proc.start()
        return proc

    def _finish(self, item: _Running, killed: str | None) -> RunRecord | None:
        """The record of a process that ended (or was killed: ``killed`` says why); None
        for one stopped from outside before it published a record (:func:`_published`)."""
        job, proc = item.job, item.proc
        try:
            proc.join(timeout=KILL_GRACE_S)
            discard_staging(job.out_dir, job.name)
            if killed is not None:
                return write_failure(job, "timeout", killed)
            return self._published(job, proc.exitcode, item.memory_limit)
        except Exception:  # noqa: BLE001 - the parent must go on with the other jobs
            return record_in_memory(job, "error", "the executor failed on this run:\n"
                                    + traceback.format_exc())

    @staticmethod
    def _published(job: RunJob, exitcode: int | None,
                   memory_limit: int | None = None) -> RunRecord | None:
        """The run's published record; None when the process was stopped from outside
        (SIGTERM, SIGINT or SIGHUP, as a CI cancel sends to the whole process group; or
        exit code 255, the forkserver gone with the status unknown) before it published
        one: the run did not end, ``--resume`` runs it again. A record published before
        such an end is kept whatever the exit code; any other end without a valid
        record is the run's error (one killed by a signal under a memory cap
        ``memory_limit`` [bytes] may have run out of memory in C: the message says so)."""
        try:
            record = read_result(job)
        except (FileNotFoundError, RecordError) as exc:
            if exitcode in STOPPED_FROM_OUTSIDE:
                return None
            hint = ""
            if exitcode == UNPUBLISHED:
                hint = "; it could not write its run directory (why: on stderr above)"
            if memory_limit is not None and exitcode is not None and exitcode < 0:
                hint = (f"; it may have run out of memory ({memory_limit / 2**20:.0f} MiB "
                        "cap, --max-memory-mb): an allocation that fails in C code can "
                        "end the process this way")
            return write_failure(job, "error", f"scenario process exited with code "
                                 f"{exitcode} without a valid record ({exc}){hint}")
        if exitcode not in (0, *STOPPED_FROM_OUTSIDE) and record.outcome.end == "ok":
            return write_failure(job, "error", f"scenario process exited with code {exitcode}")
        return record

    def _kill_overdue(self, running: dict[Any, _Running],
                      done: Callable[[RunRecord | None], None]) -> None:
        """The backstop for a hung process: the runner stops itself at its budget."""
        now = time.monotonic()
        for sentinel, item in list(running.items()):
            budget = item.job.timeout_s
            if budget is None or now - item.started <= budget + KILL_GRACE_S:
                continue
            signal_worker(item.proc, signal.SIGKILL)
            running.pop(sentinel)
            done(self._finish(item, f"killed after {now - item.started:.1f} s (wall-clock "
                                    f"budget {budget:g} s)"))

    def _abandon(self, items: list[_Running],
                 done: Callable[[RunRecord | None], None]) -> None:
        """End the running processes of a stopped run; a run one of them published
        before it ended is kept, the others leave nothing behind."""
        terminate_workers([item.proc for item in items])
        for item in items:
            discard_staging(item.job.out_dir, item.job.name)
            try:
                record = read_result(item.job)
            except (FileNotFoundError, RecordError, OSError):
                remove_path(item.job.run_dir)
                continue
            done(record)
