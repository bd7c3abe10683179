"""The scenario processes' forkserver: its preload, an early start, a quick stop.

Light on purpose (multiprocessing and threading only): ``hwyeval run`` imports it and
calls :func:`prestart_forkserver` before anything heavy, so that the forkserver's
preload runs in its own process while the command itself imports, validates the catalog
and prepares the output; the :class:`suite.exec.local.LocalExecutor` then waits for that
warm-up instead of starting its own (both go through :func:`warm_up`).

The preload (:data:`PRELOAD`) is one module, :mod:`suite.exec.forkserver_preload`, which
calls :func:`suite.exec.prepare.prepare_process` (imports, pyarrow without pandas, numba
kernels, the collector frozen: its docstring says what and why, in order). The
forkserver takes module names to import, not a function to call: that module is the only
one with an effect at import.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import threading
from typing import Any

__all__ = ["PRELOAD", "prestart_forkserver", "start_and_wait", "stop_forkserver",
           "wait_for_warm_ups", "warm_up"]

# the forkserver's preload: the one module whose import calls prepare_process()
PRELOAD = ["suite.exec.forkserver_preload"]

_prestarted: dict[str, threading.Thread] = {}  # start method -> the warm-up thread


def _noop() -> None:
    """The warm-up process: its start makes the forkserver preload."""


def start_and_wait(ctx: Any) -> None:
    """Start the context's server (forkserver: with its preload) by starting a no-op
    process, and wait for it."""
    try:
        proc = ctx.Process(target=_noop, name="hwyeval-warm-up")
        proc.start()
        proc.join()
    except Exception:  # noqa: BLE001 - the first scenario will fail and say why
        pass


def warm_up(start_method: str) -> threading.Thread:
    """The warm-up of this start method's server: started now in a background thread
    (a forkserver with :data:`PRELOAD`) unless one already was; join it to wait."""
    thread = _prestarted.get(start_method)
    if thread is None:
        ctx: Any = mp.get_context(start_method)
        if start_method == "forkserver":
            ctx.set_forkserver_preload(PRELOAD)
        thread = threading.Thread(target=start_and_wait, args=(ctx,), name="hwyeval-warm-up",
                                  daemon=True)
        thread.start()
        _prestarted[start_method] = thread
    return thread


def wait_for_warm_ups(timeout_s: float | None = None) -> None:
    """Wait for the warm-ups started in this process (none: return at once)."""
    for thread in list(_prestarted.values()):
        thread.join(timeout_s)


def prestart_forkserver(start_method: str = "forkserver") -> bool:
    """Start the forkserver and its preload now (:func:`warm_up`); returns whether a
    warm-up is running. Call :func:`stop_forkserver` if the command ends before running
    anything."""
    if start_method != "forkserver":
        return False
    warm_up(start_method)
    return True


def stop_forkserver() -> None:
    """Kill this process's forkserver, if it has one (it may be in the middle of its
    preload, which would otherwise outlive us by as long as numba takes)."""
    from multiprocessing import forkserver

    _prestarted.clear()  # a later executor starts (and awaits) a new one
    server: Any = getattr(forkserver, "_forkserver", None)
    pid = getattr(server, "_forkserver_pid", None)
    if server is None or pid is None:
        return
    try:
        os.kill(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    try:
        server._stop()  # closes its pipe, reaps it; a later run starts a new one
    except (OSError, ChildProcessError):
        pass
