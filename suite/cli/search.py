"""``hwyeval search CATALOG --out DIR --budget N``: find where a controller fails
(docs/search.md).

This module parses: the search itself is :func:`suite.search.run.run_search` (its
steps and exit codes are described there and in :mod:`suite.search.outcome`): 1 a
failure was found, 0 none within the budget and every run judged, 3 none found but some
runs ended in error or timeout, 2 bad input, 130 / 143 interrupted.
"""

from __future__ import annotations

import argparse

from suite.cli.common import (
    MEMORY_HELP,
    RAY_ADDRESS_HELP,
    Output,
    memory_mib,
    positive_int,
    positive_seconds,
)

__all__ = ["add_search_parser", "cmd_search"]


def _seed(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 0, got {text!r}") from None
    if not 0 <= value < 2 ** 31:
        raise argparse.ArgumentTypeError(f"expected a whole number in [0, 2**31), got {value}")
    return value


def _samplers(text: str) -> list[str]:
    from suite.search.samplers import SAMPLERS

    names = [t.strip() for t in text.split(",") if t.strip()]
    bad = [n for n in names if n not in SAMPLERS]
    if not names or bad:
        raise argparse.ArgumentTypeError(f"expected a comma-separated list of {SAMPLERS}, "
                                         f"got {text!r}")
    return names


def add_search_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The ``search`` sub-command's arguments."""
    from suite.search.samplers import SAMPLERS

    s = sub.add_parser("search", help="search a catalog's [scenario.search] spaces for "
                                      "failures (exit 1 when one is found)")
    s.add_argument("catalog")
    s.add_argument("--out", required=True, help="output directory (new or empty, unless "
                   "--resume or --overwrite)")
    s.add_argument("--budget", type=positive_int, required=True,
                   help="runs per family (refused points do not count; the shrinking of "
                        "what failed runs more, announced: --no-shrink skips it)")
    s.add_argument("--sampler", choices=SAMPLERS, default="tpe")
    s.add_argument("--seed", type=_seed, default=0)
    s.add_argument("--jobs", type=positive_int, default=1,
                   help="points asked and run together, in parallel (default 1); the "
                        "search is deterministic for a seed and --jobs")
    again = s.add_mutually_exclusive_group()
    again.add_argument("--resume", action="store_true",
                       help="continue the search in DIR (same sampler, seed and --jobs)")
    again.add_argument("--overwrite", action="store_true",
                       help="empty DIR (an earlier hwyeval output) first")
    s.add_argument("--no-log", action="store_true", help="do not write Rerun .rrd logs")
    s.add_argument("--timeout", type=positive_seconds, default=None, metavar="SECONDS",
                   help="wall-clock budget of every run (as run's)")
    s.add_argument("--executor", choices=["local", "ray"], default="local")
    s.add_argument("--ray-address", default=None, help=RAY_ADDRESS_HELP)
    s.add_argument("--max-memory-mb", type=memory_mib, default=None, metavar="MB",
                   help=MEMORY_HELP)
    s.add_argument("--no-shrink", action="store_true",
                   help="skip the line searches toward the nominal point")
    s.add_argument("--shrink-points", type=positive_int, default=4,
                   help="candidates per parameter of the line search (default 4)")
    s.add_argument("--compare", type=_samplers, default=None, metavar="S1,S2",
                   help="compare samplers instead: one search per sampler and seed "
                        "0..--seeds-1 into DIR/<sampler>_seed<k>, then the table")
    s.add_argument("--seeds", type=positive_int, default=5, help="seeds of --compare")
    s.add_argument("--plugin", action="append", default=[], metavar="MODULE",
                   help="a controller plug-in (as run's)")
    s.set_defaults(func=cmd_search)


def cmd_search(args: argparse.Namespace) -> int:
    """The search of ``args`` (:func:`suite.search.run.run_search`), its exit code."""
    from suite.cli.run import out_mode, run_settings
    from suite.search.run import run_search
    from suite.search.session import SearchOptions

    options = SearchOptions(catalog=str(args.catalog), out=str(args.out), budget=args.budget,
                            settings=run_settings(args), sampler=args.sampler, seed=args.seed,
                            mode=out_mode(args), shrink=not args.no_shrink,
                            shrink_points=args.shrink_points,
                            compare=tuple(args.compare or ()), seeds=args.seeds)
    return run_search(options, Output())
