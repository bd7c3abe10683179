"""Stopping a catalog run on SIGINT (Ctrl-C) or SIGTERM (a CI cancel), in order.

:func:`stop_on_signals` installs handlers that only *record* the request in a
:class:`StopRequest`; the executors poll it (every :data:`POLL_S`), stop dispatching,
terminate their scenario processes (and everything in their process groups) and
return what finished; the command line then writes the reports of what finished and
exits 128 + the signal's number (130 for SIGINT, 143 for SIGTERM). A second signal of
the same kind while the first is being handled is not polite any more: the default
action is restored and the signal re-raised, which ends this process at once (the
scenario processes notice their parent is gone and end themselves,
:mod:`suite.exec.worker`).
"""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

__all__ = ["POLL_S", "STOP_SIGNALS", "StopRequest", "stop_on_signals"]

POLL_S = 0.2  # how often executors look at the stop request [s]
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class StopRequest:
    """Whether (and by which signal) a run was asked to stop. Set from a signal handler
    (or by :meth:`request` in tests); read by the executors."""

    def __init__(self) -> None:
        self._signum: int | None = None
        self._event = threading.Event()

    @property
    def requested(self) -> bool:
        return self._event.is_set()

    @property
    def signum(self) -> int | None:
        """The first signal that asked to stop (None: not asked)."""
        return self._signum

    def request(self, signum: int) -> None:
        """Ask to stop (the first request's signal is kept)."""
        if not isinstance(signum, int) or signum <= 0:
            raise ValueError(f"StopRequest.request: expected a signal number > 0, got {signum!r}")
        if self._signum is None:
            self._signum = signum
        self._event.set()

    @property
    def exit_code(self) -> int:
        """128 + the signal number, as a shell reports a process that a signal ended
        (130 SIGINT, 143 SIGTERM); 0 when not requested."""
        return 128 + self._signum if self._signum is not None else 0

    @property
    def signal_name(self) -> str:
        return signal.Signals(self._signum).name if self._signum is not None else ""


@contextmanager
def stop_on_signals(stop: StopRequest | None = None) -> Iterator[StopRequest]:
    """Within the block, SIGINT and SIGTERM set ``stop`` (created if None) instead of
    ending the process; the previous handlers come back afterwards. Only the main
    thread may install handlers: elsewhere the block runs without them."""
    stop = stop if stop is not None else StopRequest()
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return

    def handler(signum: int, frame: FrameType | None) -> None:
        del frame
        if stop.requested and stop.signum == signum:
            # asked twice: stop being polite (default action, now)
            signal.signal(signum, signal.SIG_DFL)
            os.kill(os.getpid(), signum)
            return
        stop.request(signum)

    previous = {sig: signal.signal(sig, handler) for sig in STOP_SIGNALS}
    try:
        yield stop
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
