"""``hwyeval import openscenario FILE.xosc [...] --out DIR``: OpenSCENARIO 1.0-1.3
scenarios (and parameter variation files) on OpenDRIVE roads -> SUMO nets, typed
storyboards and a ``catalog.toml`` that ``hwyeval run`` reads (docs/openscenario.md;
:mod:`suite.importers.openscenario`).

One line per file, the errors on stderr. Exit codes: 0 every file imported; 2 a file
could not be (named with its element and line: unsupported, a violated constraint, a
refused XML construct), or an --out the import may not write
(:mod:`suite.importers.common.out_guard`, refused before anything is written). The files
that did import are in DIR/catalog.toml all the same.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from suite.cli.common import (
    EXIT_INPUT,
    EXIT_OK,
    Output,
    UsageError,
    add_import_output,
    err,
    whole_number,
    writing_to,
)

__all__ = ["add_openscenario_parser"]


def _seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds > 0, got {text!r}") from None
    if not 0.0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a finite duration > 0, got {text}")
    return value


def _parameter(text: str) -> tuple[str, str]:
    name, sep, value = text.partition("=")
    if not sep or not name.strip():
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    return name.strip(), value.strip()


def add_openscenario_parser(fmt: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The ``openscenario`` format of ``hwyeval import``."""
    c = fmt.add_parser("openscenario", help="OpenSCENARIO 1.x files -> nets, storyboards, "
                                            "catalog.toml")
    c.add_argument("files", nargs="+", metavar="FILE.xosc")
    add_import_output(c, "docs/openscenario.md")
    c.add_argument("--ego", default=None, metavar="NAME",
                   help="the entity the controller drives (default: the one named Ego/Hero)")
    c.add_argument("--ignore-constraints", action="store_true",
                   help="import parameter values that violate their declared constraints")
    c.add_argument("--duration-s", type=_seconds, default=None, metavar="S",
                   help="run length when the stop trigger is not a plain simulation time "
                   "(default 60)")
    c.add_argument("--variants", type=lambda t: whole_number(t, 0, "a count >= 0"),
                   default=0, metavar="N", help="also import N parameter sets of each "
                   "variation file as scenarios (default 0: count and list them only)")
    c.add_argument("--r157", action="store_true",
                   help="judge the scenarios by UN R157's acceptance criteria too (the "
                        "minimum following time gap, docs/metrics.md) and label each with "
                        "its Annex 5 section (hwyeval r157)")
    c.add_argument("--param", action="append", type=_parameter, default=[],
                   metavar="NAME=VALUE", help="replace the declared value of the top-level "
                   "parameter NAME in every file (repeatable; a variation's sets too; with "
                   "--ignore-constraints to go beyond its constraints)")
    c.add_argument("--search-ranges", action="store_true",
                   help="a variation file's logical scenario searches each DistributionRange "
                   "between its ends (a range) rather than its steps (choices; the default; "
                   "hwyeval search, docs/openscenario.md)")
    c.set_defaults(func=cmd_import_openscenario)


def cmd_import_openscenario(args: argparse.Namespace) -> int:
    """Parse the options and import under DIR's lock (suite.exec.out_lock): another
    command writing DIR is refused (exit 2) before anything is read or written."""
    from suite.importers.openscenario import ImportOptions, OutputRefused, import_files

    out = Output()
    try:
        options = ImportOptions(ego=args.ego, ignore_constraints=args.ignore_constraints,
                                duration_s=args.duration_s, variants=args.variants,
                                r157=args.r157, parameters=tuple(args.param),
                                search_ranges=args.search_ranges)
    except ValueError as exc:
        raise UsageError(f"--param: {exc}") from None
    try:
        with writing_to(Path(args.out)):
            outcome = import_files([Path(f) for f in args.files], Path(args.out), options,
                                   overwrite=args.overwrite)
    except OutputRefused as exc:
        err(str(exc))
        return EXIT_INPUT
    for r in outcome.results:
        sets = f", {r.sets} parameter sets ({r.invalid_sets} violate constraints)" \
            if r.sets else ""
        out.line(f"{r.source.name} -> {', '.join(r.names)}{sets} [{r.wall_s:.2f} s]")
        for note in r.notes:
            if "not imported" in note:
                err(f"warning: {r.source.name}: {note}")
    for f in outcome.failures:
        err(str(f))
    if outcome.catalog is not None:
        out.line(f"catalog: {outcome.catalog}")
    return EXIT_INPUT if outcome.failures else EXIT_OK
