"""Ending a process without the interpreter's teardown.

After a run the parent has pandas, numba, pyarrow and the reports loaded and the
forkserver everything it preloads: destroying every module's objects took 0.7 s and
0.55 s, and the forkserver holds the command's stdout meanwhile (docs/performance.md).
:func:`exit_without_teardown` does what matters of an exit and skips the rest: the
atexit handlers run (temporary directories, logging, Ray's shutdown, multiprocessing),
the output streams are flushed, then ``os._exit``. Every file is written and closed by
then (each writer closes its own), so nothing is lost.
"""

from __future__ import annotations

import atexit
import os
import sys
from typing import NoReturn

__all__ = ["exit_without_teardown"]


def exit_without_teardown(code: int) -> NoReturn:
    """Run the atexit handlers, flush stdout and stderr, end the process with ``code``."""
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe or stream: nothing left to say
            pass
    os._exit(code)
