"""How ``hwyeval run`` reports while it runs and when it ends.

* A line per finished scenario: ``[k/N] STATUS name  why``: for a failure the first
  failed criteria with where they were violated, for an error the exception's last
  line, for a pass the closest gap and progress; a run a collision ended early says so
  (whoever hit whom: a recorded car that ran into the ego ends the run too). A known
  failure (``xfail``) reads ``XFAIL`` when it failed as expected, ``XPASS`` when it
  passed.
* On a terminal, a progress bar under those lines (rich): done, failed, running,
  elapsed and ETA (mean wall time per finished scenario × remaining / workers'
  concurrency, as observed). Elsewhere (CI logs, pipes) a plain
  ``progress: ...`` line every :data:`HEARTBEAT_S` seconds while nothing else was
  printed, so a log never goes silent (the workers' start, while numba loads or
  compiles its kernels, takes ~20 s the first time).
* At the end, a pytest-like short summary: one line per scenario that fails the night,
  one per known failure, then the counts and what the exit code means.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from types import TracebackType
from typing import Any

from reports.expectation import XPASSED, expectation, fails_night, xfail_of
from reports.record import RunRecord
from suite.exec.command import Printer

HEARTBEAT_S = 15.0
MAX_REASONS = 2


def _last_line(text: str | None) -> str:
    lines = (text or "").strip().splitlines()
    return lines[-1].strip() if lines else ""


def stop_note(record: RunRecord) -> str:
    """``; ended early: collision at t = 4.20 s (rec_12 hit ego)`` when a collision
    ended the run (the stop rule's reason, and SUMO's first report of who hit whom);
    '' otherwise. Said whoever was at fault: a recorded car running into the ego ends
    the run without failing an at-fault criterion, and the run's shortness (progress)
    is then explained here."""
    why = record.outcome.stop_reason
    if not why.startswith("collision"):
        return ""
    hits = record.outcome.sumo_collisions
    who = f" ({hits[0].collider} hit {hits[0].victim})" if hits else ""
    return f"; ended early: {why}{who}"


def reason(record: RunRecord) -> str:
    """Why a run ended as it did, in one line."""
    status = record.status
    verdict = record.verdict
    if status in ("error", "timeout"):
        return _last_line(record.outcome.error) or status
    if verdict is None:
        return "not judged"
    if verdict.failures:
        shown = [f.line for f in verdict.failures[:MAX_REASONS]]
        more = len(verdict.failures) - MAX_REASONS
        return "; ".join(shown) + (f" (+{more} more)" if more > 0 else "") + stop_note(record)
    gap, progress = verdict.value("min_gap_m"), verdict.value("progress_m")
    return f"min gap {gap:.2f} m, progress {progress:.0f} m{stop_note(record)}"


def shown_status(record: RunRecord) -> str:
    """The status as printed: ``XFAIL`` / ``XPASS`` for a known failure's run."""
    seen = expectation(record.status, xfail_of(record.info.scenario_spec))
    return (seen or record.status).upper()


def log_note(record: RunRecord) -> str:
    """`` [no Rerun log: <the exception's last line>]`` when writing the run's log
    failed (the verdict stands; the traceback is in run.json's ``outcome.log_error``),
    else ''."""
    if not record.outcome.log_error:
        return ""
    return f"  [no Rerun log: {_last_line(record.outcome.log_error) or 'failed'}]"


def status_line(record: RunRecord, done: int, total: int) -> str:
    wall = record.outcome.wall_s
    took = f"  ({wall:.1f} s)" if wall == wall else ""
    return (f"[{done}/{total}] {shown_status(record):7s} {record.info.scenario}  "
            f"{reason(record)}{took}{log_note(record)}")


def _clock(seconds: float) -> str:
    if seconds != seconds or seconds == float("inf"):
        return "–"
    m, s = divmod(int(round(seconds)), 60)
    h, m = divmod(m, 60)
    return f"{h}h{m:02d}m{s:02d}s" if h else (f"{m}m{s:02d}s" if m else f"{s}s")


class RunProgress:
    """Progress of a catalog run (module doc). Use as a context manager."""

    def __init__(self, out: Printer, total: int, workers: int, tty: bool) -> None:
        self.out = out
        self.total = total
        self.workers = max(1, min(workers, total))
        self.tty = tty
        self.done = 0
        self.failed = 0
        self.t0 = time.monotonic()
        self._last_print = self.t0
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._bar: Any = None
        self._task: Any = None
        self._thread: threading.Thread | None = None

    @property
    def running(self) -> int:
        return min(self.workers, self.total - self.done)

    def eta_s(self) -> float:
        """Remaining wall time at the pace so far (NaN before the first finish)."""
        if self.done == 0:
            return float("nan")
        rate = self.done / max(time.monotonic() - self.t0, 1e-9)
        return (self.total - self.done) / rate

    def counts(self) -> str:
        elapsed = _clock(time.monotonic() - self.t0)
        return (f"{self.done}/{self.total} done, {self.failed} not passed, {self.running} "
                f"running, elapsed {elapsed}, ETA {_clock(self.eta_s())}")

    def __enter__(self) -> RunProgress:
        if self.tty:
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                SpinnerColumn,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self._bar = Progress(SpinnerColumn(), TextColumn("{task.description}"), BarColumn(),
                                 MofNCompleteColumn(), TextColumn("{task.fields[extra]}"),
                                 TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn(),
                                 transient=True)
            self._task = self._bar.add_task("warming up", total=self.total,
                                            extra=self._extra())
            self._bar.start()
        else:
            self._thread = threading.Thread(target=self._heartbeat, daemon=True)
            self._thread.start()
        return self

    def _extra(self) -> str:
        return f"[red]{self.failed} not passed[/] · {self.running} running"

    def _heartbeat(self) -> None:
        while not self._stop.wait(1.0):
            with self._lock:
                if time.monotonic() - self._last_print >= HEARTBEAT_S:
                    self._print(f"progress: {self.counts()}")

    def _print(self, text: str) -> None:
        self._last_print = time.monotonic()
        if self._bar is not None:
            self._bar.console.print(text, markup=False, highlight=False)
        else:
            self.out.line(text)

    def finished(self, record: RunRecord) -> None:
        """One scenario finished (called by the executor, in the main thread)."""
        with self._lock:
            self.done += 1
            if record.status != "pass":
                self.failed += 1
            self._print(status_line(record, self.done, self.total))
            if self._bar is not None:
                self._bar.update(self._task, completed=self.done, description="running",
                                 extra=self._extra())

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self._stop.set()
        if self._bar is not None:
            self._bar.stop()


def _count(n: int, noun: str) -> str:
    """``1 scenario``, ``2 scenarios``."""
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def _summary_lines(bad: Sequence[RunRecord], known: Sequence[RunRecord],
                   marks: dict[int, Any]) -> list[str]:
    """One line per run that fails the night (errors first), then one per known
    failure."""
    lines = [" short summary ".center(72, "=")]
    order = {"error": 0, "timeout": 1, "fail": 2}
    for r in sorted(bad, key=lambda r: (order.get(r.status, 3), r.info.scenario)):
        lines.append(_summary_line(r, marks[id(r)]))
    for r in sorted(known, key=lambda r: r.info.scenario):
        lines.append(_summary_line(r, marks[id(r)]))
    return lines


def _summary_line(r: RunRecord, mark: Any) -> str:
    """``STATUS name: why``; a known failure's says its mark (and, passed, to remove it)."""
    if mark is None:
        return f"{shown_status(r):7s} {r.info.scenario}: {reason(r)}{log_note(r)}"
    what = "passed: fixed, remove the xfail" if r.status == "pass" else reason(r)
    return f"{shown_status(r):7s} {r.info.scenario}: {what} ({mark.text}){log_note(r)}"


def _meaning(bad: Sequence[RunRecord], marks: dict[int, Any], expected: int) -> str:
    """What the exit code means."""
    if bad and all(expectation(r.status, marks[id(r)]) == XPASSED for r in bad):
        return "exit 1: a strict known failure passed (remove its xfail)"
    if bad:
        return "exit 1: some scenario did not pass (see above; the reports say why)"
    return "exit 0: every scenario passed" + (" or failed as expected" if expected else "")


def short_summary(records: Sequence[RunRecord], wall_s: float,
                  meaning: str | None = None) -> list[str]:
    """The end of a run's output (module doc); ``meaning``: what the exit code means when
    something other than the runs decides it (the reports could not be written,
    ``--no-fail``), so that the last line and the exit code always agree."""
    marks = {id(r): xfail_of(r.info.scenario_spec) for r in records}
    bad = [r for r in records if fails_night(r.status, marks[id(r)])]
    bad_ids = {id(r) for r in bad}
    known = [r for r in records if marks[id(r)] is not None and id(r) not in bad_ids]
    lines = _summary_lines(bad, known, marks) if bad or known else []
    unlogged = sorted(r.info.scenario for r in records if r.outcome.log_error)
    if unlogged:
        lines.append(f"NO LOG  {_count(len(unlogged), 'run')} without a Rerun log (writing it "
                     f"failed; run.json outcome.log_error has why): {', '.join(unlogged)}")
    counts: dict[str, int] = {}
    for r in records:
        counts[r.status] = counts.get(r.status, 0) + 1
    words = {"pass": "passed", "fail": "failed", "error": "errors", "timeout": "timed out"}
    text = ", ".join(f"{counts[s]} {words[s]}" for s in ("pass", "fail", "error", "timeout")
                     if s in counts)
    expected = sum(1 for r in known if r.status != "pass")
    if expected:
        text += f" ({expected} of them expected: xfail)"
    lines.append(f"{_count(len(records), 'scenario')} in {wall_s:.1f} s: {text or 'nothing run'} — "
                 f"{meaning or _meaning(bad, marks, expected)}")
    return lines
