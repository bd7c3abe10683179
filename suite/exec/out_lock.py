"""One writer per output directory: a lock beside it for the whole command.

Two ``hwyeval run`` (or ``search``) commands into one ``--out`` mixed their results in
one results.csv and lost runs, and both exited 0; two ``--resume`` ran the same
scenarios twice. Every command that writes a directory (``run``, ``search``,
``import commonroad``, ``compare``, ``report``, ``paper``) holds an exclusive ``flock``
on ``.<name>.lock`` next to the directory (not inside: an ``--overwrite`` empties the
directory, and a lock file there would make an empty output look used) from before it
checks the directory until it ends; a second command finds it held and stops with
:class:`OutDirBusy` (exit 2) naming the directory and the holder's pid, having written
nothing.

The lock is keyed on the directory's **real** path (:func:`real_out`: every symbolic
link resolved, also for the part of the path that does not exist yet), so
``--out alias`` where ``alias`` links to a directory being written is refused like the
directory itself. The kernel drops the lock with the process, so a killed run never
leaves a stale one; the file itself stays (removing it would race with a new holder).
A process may take the lock of a directory it already holds again (``paper --run``
runs ``run`` inside its own lock): the lock is re-entrant within a process.
"""

from __future__ import annotations

import fcntl
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["OutDirBusy", "lock_path", "out_dir_lock", "real_out"]

# Real paths of the directories this process holds, with how many holders nest there.
_HELD: dict[Path, int] = {}


class OutDirBusy(RuntimeError):
    """Another process holds the output directory's lock."""


def real_out(out: Path) -> Path:
    """``out`` as an absolute path with every symbolic link resolved (the part that does
    not exist yet is kept as written): what the lock is keyed on."""
    return Path(os.path.realpath(out))


def lock_path(out: Path) -> Path:
    """``.<name>.lock`` beside the real directory of ``out``."""
    real = real_out(out)
    return real.parent / f".{real.name}.lock"


def _shown(out: Path, real: Path) -> str:
    """``out`` as given, and its real path where that differs (a link, ``..``)."""
    return f"{out}" if str(out) == str(real) else f"{out} (= {real})"


@contextmanager
def out_dir_lock(out: Path) -> Iterator[Path]:
    """Hold ``out``'s lock while the block runs; OutDirBusy (naming the directory and
    the holder's pid) if another process holds it. The directory holding the real
    ``out`` must exist; OSError if the lock file cannot be created there."""
    real = real_out(out)
    path = lock_path(out)
    if real in _HELD:  # this process holds it already (module doc)
        _HELD[real] += 1
        try:
            yield path
        finally:
            _HELD[real] -= 1
        return
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 64, 0).decode(errors="replace").strip() or "?"
            raise OutDirBusy(f"{_shown(out, real)}: another hwyeval command (pid {holder}) "
                             f"is writing to this directory (lock {path}); wait for it to "
                             "end, or choose another output directory") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        _HELD[real] = 1
        try:
            yield path
        finally:
            del _HELD[real]
            fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)
