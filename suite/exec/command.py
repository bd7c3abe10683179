"""What a command that runs scenarios shares, whoever starts it (the CLI, ``paper --run``,
the search): exit codes, the input error, the printer, the ``--plugin`` modules and the
output directory's lock.

The command line (:mod:`suite.cli`) parses into typed options and hands them, with a
:class:`Printer`, to the run layer (:mod:`suite.exec.catalog_run`,
:mod:`suite.search.run`); both speak these names, so nothing below the CLI imports it.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator, Sequence
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Protocol, TextIO

if TYPE_CHECKING:
    from controllers import registry

__all__ = ["EXIT_FAIL", "EXIT_INPUT", "EXIT_OK", "OUT_MODES", "Output", "Plugins", "Printer",
           "UsageError", "err", "load_plugins", "writing_to"]

EXIT_OK = 0
EXIT_FAIL = 1
EXIT_INPUT = 2
# What a command does with an output directory that holds files: refuse it (fresh), keep
# what finished (resume), or empty it (overwrite); :mod:`suite.exec.outdir`.
OUT_MODES = ("fresh", "resume", "overwrite")


class UsageError(ValueError):
    """Invalid input of a command (exit code 2, the message without a traceback)."""


class Printer(Protocol):
    """Where a command's lines go: :meth:`line` to its output, :meth:`err` to its error
    stream (``hwyeval: `` before the message)."""

    def line(self, text: str = "") -> None: ...

    def err(self, msg: str) -> None: ...


def err(msg: str) -> None:
    print(f"hwyeval: {msg}", file=sys.stderr)


class Output:
    """Lines to stdout that survive a closed pipe (``hwyeval list | head``): once the
    reader has gone, further lines are dropped and the command goes on (a run still
    writes its reports). Errors go to stderr (:func:`err`). A :class:`Printer`."""

    def __init__(self, stream: TextIO | None = None) -> None:
        self.stream = stream if stream is not None else sys.stdout
        self.closed = False

    def line(self, text: str = "") -> None:
        if self.closed:
            return
        try:
            self.stream.write(text + "\n")
            self.stream.flush()
        except BrokenPipeError:
            self.closed = True
            # stdout's buffer still holds data; point fd 1 at /dev/null so the
            # interpreter's final flush does not raise again
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, self.stream.fileno())
            os.close(devnull)

    def err(self, msg: str) -> None:
        err(msg)


@contextmanager
def writing_to(out: Path) -> Iterator[None]:
    """Hold the lock of the directory ``out`` the command writes
    (:mod:`suite.exec.out_lock`, keyed on its real path) while the block runs: when
    another process holds it, a UsageError (exit 2) naming the directory and that
    process's pid, before anything is written. When not even the folder holding ``out``
    can be created the block runs without the lock: the command cannot write there
    either, and its own check of ``out`` says why."""
    from suite.exec.out_lock import OutDirBusy, lock_path, out_dir_lock, real_out

    try:
        real_out(out).parent.mkdir(parents=True, exist_ok=True)
    except OSError:
        yield
        return
    with ExitStack() as stack:
        try:
            stack.enter_context(out_dir_lock(out))
        except OutDirBusy as exc:
            raise UsageError(str(exc)) from exc
        except OSError as exc:
            raise UsageError(f"--out {out}: cannot create its lock file {lock_path(out)} "
                             f"({exc.strerror or exc}); choose an --out in a writable "
                             "folder") from exc
        yield


@dataclass(frozen=True)
class Plugins:
    """The ``--plugin`` modules of a command, loaded in this process."""

    modules: tuple[registry.PluginModule, ...] = ()

    def __post_init__(self) -> None:
        if not isinstance(self.modules, tuple):
            raise TypeError(f"Plugins.modules: expected a tuple, got {self.modules!r}")

    @property
    def labels(self) -> tuple[str, ...]:
        return tuple(m.label for m in self.modules)


def load_plugins(specs: Sequence[str] | None) -> Plugins:
    """Import every ``--plugin`` (path of a .py file or a module name) here; a plug-in
    that does not import is a UsageError naming it and its last error line."""
    from controllers import registry

    modules = []
    for spec in specs or []:
        try:
            module = registry.plugin_module(spec)
            registry.load_plugin(module)
        except Exception as exc:  # noqa: BLE001 - any import error is the user's input
            raise UsageError(f"--plugin {spec}: {type(exc).__name__}: {exc}") from exc
        modules.append(module)
    return Plugins(tuple(modules))
