"""One writer per output directory: a lock beside it for the whole command.

Two ``hwyeval run`` (or ``search``) commands into one ``--out`` mixed their results in
one results.csv and lost runs, and both exited 0; two ``--resume`` ran the same
scenarios twice. The command holds an exclusive ``flock`` on ``.<name>.lock`` next to
the output directory (not inside: an ``--overwrite`` empties the directory, and a lock
file there would make an empty output look used) from before it checks the directory
until it ends; a second command finds it held and stops with
:class:`suite.exec.outdir.OutputDirError` (exit 2) naming the holder's pid, having
written nothing. The kernel drops the lock with the process, so a killed run never
leaves a stale one; the file itself stays (removing it would race with a new holder).
"""

from __future__ import annotations

import fcntl
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["OutDirBusy", "lock_path", "out_dir_lock"]


class OutDirBusy(RuntimeError):
    """Another process holds the output directory's lock."""


def lock_path(out: Path) -> Path:
    """``.<name>.lock`` beside ``out``."""
    absolute = Path(os.path.abspath(out))
    return absolute.parent / f".{absolute.name}.lock"


@contextmanager
def out_dir_lock(out: Path) -> Iterator[Path]:
    """Hold ``out``'s lock while the block runs; OutDirBusy (naming the holder's pid)
    if another process holds it. The directory holding ``out`` must exist."""
    path = lock_path(out)
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 64, 0).decode(errors="replace").strip() or "?"
            raise OutDirBusy(f"--out {out}: another hwyeval command (pid {holder}) is "
                             f"writing to it (lock {path}); wait for it to end, or choose "
                             "another --out") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        try:
            yield path
        finally:
            fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)
