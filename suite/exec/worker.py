"""Scenario processes and their process groups: never an orphan.

A scenario process calls :func:`become_worker` first: it leads a process group of its
own (so that whatever it starts is signalled with it, and a Ctrl-C at the terminal
reaches only the parent, which then stops the catalog in order), ignores SIGINT and
the terminal's job-control stops, and keeps the default SIGTERM (it dies at once: its
run directory is written under a staging name, so nothing half-written is ever
published). A daemon thread waits on the pipe its parent holds open
(``multiprocessing.parent_process()``): when the parent is gone, however it died
(``kill -9`` included), the process kills its group and itself.

The parent signals a worker with :func:`signal_worker` (its group and the process
itself, in case it has not made its group yet) and :func:`terminate_workers`: SIGTERM,
a grace period, then SIGKILL.
"""

from __future__ import annotations

import gc
import multiprocessing as mp
import os
import signal
import threading
import time
from collections.abc import Sequence
from typing import Any

__all__ = ["SCENARIO_CPUS_ENV", "TERM_GRACE_S", "become_worker", "signal_worker",
           "terminate_workers"]

TERM_GRACE_S = 2.0  # SIGTERM, then this long [s], then SIGKILL
# CPUs (comma-separated indices) every scenario process pins itself to: how
# `hwyeval bench --isolated` gives the timed runs a core of their own (docs/bench.md)
SCENARIO_CPUS_ENV = "HWYEVAL_SCENARIO_CPUS"


def become_worker() -> None:
    """Set up this scenario process (module doc). Call first thing in the worker."""
    # prepare_process() resumes the collector in the process we were forked from; enabled
    # again here whatever that process did with it
    gc.enable()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    for sig in (signal.SIGTTOU, signal.SIGTTIN, signal.SIGTSTP):
        signal.signal(sig, signal.SIG_IGN)
    try:
        os.setpgid(0, 0)
    except OSError:  # already a group leader (or not allowed): the parent signals the pid
        pass
    parent = mp.parent_process()
    if parent is not None:
        threading.Thread(target=_die_with_parent, args=(parent,), name="hwyeval-parent-watch",
                         daemon=True).start()
    _pin_to_scenario_cpus()


def _pin_to_scenario_cpus() -> None:
    """Pin this process to the CPUs of :data:`SCENARIO_CPUS_ENV`, if set (ignored when
    malformed or not allowed: pinning is for measuring, never a reason to fail a run)."""
    text = os.environ.get(SCENARIO_CPUS_ENV, "").strip()
    if not text:
        return
    try:
        os.sched_setaffinity(0, {int(c) for c in text.split(",")})
    except (ValueError, OSError):
        pass


def _die_with_parent(parent: Any) -> None:
    parent.join()  # returns when the parent's end of our pipe closes: it is gone
    if os.getpgrp() == os.getpid():
        try:
            os.killpg(os.getpid(), signal.SIGKILL)
        except OSError:
            pass
    os.kill(os.getpid(), signal.SIGKILL)


def signal_worker(proc: Any, sig: int) -> None:
    """Send ``sig`` to a running scenario process's group and to the process itself."""
    if proc.pid is None or not proc.is_alive():
        return
    for send in (os.killpg, os.kill):
        try:
            send(proc.pid, sig)
        except (ProcessLookupError, PermissionError):
            pass


def terminate_workers(procs: Sequence[Any], grace_s: float = TERM_GRACE_S) -> None:
    """SIGTERM every process (and group) of ``procs``, SIGKILL those still alive after
    ``grace_s`` [s]; returns when all have ended."""
    for proc in procs:
        signal_worker(proc, signal.SIGTERM)
    deadline = time.monotonic() + grace_s
    for proc in procs:
        proc.join(max(0.0, deadline - time.monotonic()))
    for proc in procs:
        if proc.is_alive():
            signal_worker(proc, signal.SIGKILL)
    for proc in procs:
        proc.join(grace_s)
