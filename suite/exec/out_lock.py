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

**Nested directories.** A command writing ``X`` and another writing ``X/sub`` (or
``X``'s parent) mix their files as surely as two writers of one directory (an
``--overwrite`` of ``X`` empties ``X/sub`` under the other's feet). Each holder
therefore also takes, in a per-user registry in the temporary folder
(:func:`registry_lock`, one small file per real path, named by its SHA-256), an
exclusive lock for its own directory and a shared lock for every ancestor of it: a
writer of an ancestor (exclusive on its entry) then finds a shared holder, and a writer
of a descendant (shared on this directory's entry) finds the exclusive one; both are
refused like a second writer of the same directory. Ancestors this process holds itself
are skipped (re-entrant). The registry lives outside the tree, so nothing is written
beside ``/`` or ``$HOME``; the kernel drops its locks with the process too.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import tempfile
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path

__all__ = ["OutDirBusy", "lock_path", "out_dir_lock", "real_out", "registry_lock"]

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


def registry_lock(real: Path) -> Path:
    """The registry file of the real directory ``real`` (module doc, "Nested
    directories"): ``<tmp>/hwyeval-locks-<uid>/<sha256 of the path>.lock``."""
    folder = Path(tempfile.gettempdir()) / f"hwyeval-locks-{os.getuid()}"
    folder.mkdir(mode=0o700, exist_ok=True)
    return folder / f"{hashlib.sha256(str(real).encode()).hexdigest()[:32]}.lock"


class _RegistryConflict(Exception):
    """Another process holds a registry lock that conflicts with this one: ``path``, the
    directory whose entry it is."""

    def __init__(self, path: Path) -> None:
        super().__init__(str(path))
        self.path = path


@contextmanager
def _registry_hold(fd_path: Path, mode: int, label: Path) -> Iterator[None]:
    """Hold ``mode`` (LOCK_EX or LOCK_SH) on the registry file ``fd_path``;
    :class:`_RegistryConflict` naming ``label`` when another process's lock conflicts."""
    fd = os.open(fd_path, os.O_RDWR | os.O_CREAT, 0o600)
    try:
        try:
            fcntl.flock(fd, mode | fcntl.LOCK_NB)
        except BlockingIOError:
            raise _RegistryConflict(label) from None
        try:
            yield
        finally:
            fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)


def _nested_holds(stack: ExitStack, out: Path, real: Path) -> None:
    """The registry locks of ``real`` (exclusive) and of its ancestors (shared, but those
    this process holds itself): OutDirBusy naming the directory when another command
    writes an ancestor or a descendant of it."""
    try:
        stack.enter_context(_registry_hold(registry_lock(real), fcntl.LOCK_EX, real))
        for parent in real.parents:
            if parent not in _HELD:
                stack.enter_context(_registry_hold(registry_lock(parent), fcntl.LOCK_SH,
                                                   parent))
    except _RegistryConflict as busy:
        where = ("a directory inside it" if busy.path == real
                 else f"the directory {busy.path} that contains it")
        raise OutDirBusy(f"{_shown(out, real)}: another hwyeval command is writing to "
                         f"{where}; wait for it to end, or choose another output "
                         "directory") from None


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
        try:
            with ExitStack() as nested:
                _nested_holds(nested, out, real)
                os.ftruncate(fd, 0)
                os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
                _HELD[real] = 1
                try:
                    yield path
                finally:
                    del _HELD[real]
        finally:
            fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)
