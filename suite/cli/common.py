"""What every command shares: argument types and help texts; the exit codes, input
errors, plug-ins, output and output lock of the run layer (:mod:`suite.exec.command`)
and its catalog loading (:mod:`suite.exec.build`), handed on."""

from __future__ import annotations

import argparse
import math
from typing import Any

from suite.exec.build import load_catalog_for, route_warnings
from suite.exec.command import (
    EXIT_FAIL,
    EXIT_INPUT,
    EXIT_OK,
    Output,
    Plugins,
    UsageError,
    err,
    load_plugins,
    writing_to,
)

__all__ = ["EXIT_FAIL", "EXIT_INPUT", "EXIT_OK", "MEMORY_HELP", "RAY_ADDRESS_HELP", "Output",
           "Plugins", "UsageError", "add_import_output", "err", "load_catalog_for",
           "load_plugins", "memory_mib", "plain_help", "positive_int", "positive_seconds",
           "route_text", "route_warnings", "whole_number", "writing_to"]


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
