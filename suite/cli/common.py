"""What every command shares: exit codes, input errors, plug-ins, catalogs, safe output."""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

EXIT_OK = 0
EXIT_FAIL = 1
EXIT_INPUT = 2


class UsageError(ValueError):
    """Invalid command-line input (exit code 2, the message without a traceback)."""


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


class Output:
    """Lines to stdout that survive a closed pipe (``hwyeval list | head``): once the
    reader has gone, further lines are dropped and the command goes on (a run still
    writes its reports)."""

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


def add_import_output(parser: argparse.ArgumentParser, doc_page: str) -> None:
    """An import format's ``--out`` and ``--overwrite`` (the output-folder rules both
    importers share: ``suite/importers/common/out_guard.py``; ``doc_page`` the format's
    page, e.g. ``docs/recorded.md``)."""
    parser.add_argument("--out", required=True, help="the folder to write (created; files "
                        "of earlier imports stay; one holding files the import did not "
                        "write, or an edited catalog.toml, needs --overwrite)")
    parser.add_argument("--overwrite", action="store_true",
                        help="import into an --out that holds files the import did not "
                        "write (they stay untouched) and replace its catalog.toml even if "
                        f"it was edited or hand-written ({doc_page})")


def err(msg: str) -> None:
    print(f"hwyeval: {msg}", file=sys.stderr)


def whole_number(text: str, minimum: int, what: str = "a whole number") -> int:
    """An integer >= ``minimum`` parsed from ``text``, else argparse's type error saying
    ``what`` was expected."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {what} >= {minimum}, got {text!r}") \
            from None
    if value < minimum:
        raise argparse.ArgumentTypeError(f"expected {what} >= {minimum}, got {value}")
    return value


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    return whole_number(text, 1)


def memory_mib(text: str) -> int:
    """argparse type: a whole number of MiB >= 0 (``--max-memory-mb``; 0: no cap)."""
    return whole_number(text, 0, "a whole number of MiB (0: no cap)")


RAY_ADDRESS_HELP = ("the Ray cluster of --executor ray: host:port, ray://host:port or auto "
                    "(the one Ray finds), checked before anything runs (exit 2 when it "
                    "does not answer); default $RAY_ADDRESS, else a private local Ray")
MEMORY_HELP = ("address-space cap of every scenario process [MiB]; a run over it is that "
               "run's error (default: $HWYEVAL_MAX_MEMORY_MB, else half the machine's "
               "memory, at least 8192; 0: no cap)")


def memory_cap_of(args: argparse.Namespace) -> Any:
    """The :class:`suite.exec.memory.MemoryCap` of a command: ``--max-memory-mb``, else
    ``HWYEVAL_MAX_MEMORY_MB``, else the default; a bad variable is a UsageError."""
    from suite.exec.memory import memory_cap_from

    try:
        return memory_cap_from(getattr(args, "max_memory_mb", None), os.environ)
    except ValueError as exc:
        raise UsageError(str(exc)) from exc


def positive_seconds(text: str) -> float:
    """argparse type: a finite number of seconds > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds > 0, got {text!r}") \
            from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"expected a finite number of seconds > 0, got {text}")
    return value


@dataclass(frozen=True)
class Plugins:
    """The ``--plugin`` modules of a command, loaded in this process."""

    modules: tuple[Any, ...] = ()  # controllers.registry.PluginModule

    @property
    def labels(self) -> tuple[str, ...]:
        return tuple(m.label for m in self.modules)


def executor_flags(args: argparse.Namespace) -> list[str]:
    """The flags a resume command repeats for how runs execute: ``--timeout``,
    ``--executor``, ``--ray-address``, ``--max-memory-mb`` and every ``--plugin`` given."""
    parts: list[str] = []
    if args.timeout is not None:
        parts += ["--timeout", f"{args.timeout:g}"]
    if args.executor != "local":
        parts += ["--executor", args.executor]
    if args.ray_address:
        parts += ["--ray-address", args.ray_address]
    if getattr(args, "max_memory_mb", None) is not None:
        parts += ["--max-memory-mb", str(args.max_memory_mb)]
    for plugin in args.plugin or []:
        parts += ["--plugin", plugin]
    return parts


def load_plugins(specs: list[str] | None) -> Plugins:
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


def load_catalog_for(catalog: str, pattern: str | None) -> tuple[Any, list[Any]]:
    """The catalog and its scenarios (``--filter`` applied; none matching is an error)."""
    from suite.catalog import expand_filter, load_catalog

    cat = load_catalog(Path(catalog))
    scenarios = list(cat.scenarios)
    if pattern:
        scenarios = list(expand_filter(scenarios, pattern))
        if not scenarios:
            raise UsageError(f"{catalog}: --filter {pattern!r} matches no scenario")
    return cat, scenarios


def route_warnings(scenarios: list[Any]) -> list[str]:
    """One line per scenario whose route uses link edges (ramps, exits: an OpenStreetMap
    ``*_link`` type): positions along it then mean another place than on the through
    carriageway the default route follows (suite.road.network)."""
    from suite.road.network import RoadNetwork

    lines = []
    for sc in scenarios:
        links = RoadNetwork.load(sc.net_path).link_edges(sc.route)
        if links:
            lines.append(f"warning: scenario {sc.name}: its route uses link edges (ramps, "
                         f"exits) {links}; the default route keeps to the through carriageway")
    return lines


def route_text(scenario: Any) -> str:
    """``net: route e0 → e1 → e2 (1234 m)`` with link edges marked ``[link]``."""
    from suite.road.network import RoadNetwork

    net = RoadNetwork.load(scenario.net_path)
    edges = " → ".join(f"{e} [link]" if net.is_link(e) else e for e in scenario.route)
    return f"{scenario.net_path.name}: route {edges} ({net.route_length_m(scenario.route):.0f} m)"


def plain_help(text: str | None) -> str:
    """A docstring as ``--help`` text: reStructuredText's double backticks and
    ``:role:`target``` markup removed (``:func:`x``` becomes ``x``)."""
    import re

    out = re.sub(r":[a-z]+:`~?([^`]+)`", r"\1", text or "")
    return out.replace("``", "")
