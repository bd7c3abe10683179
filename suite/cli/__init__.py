"""``hwyeval`` command line (docs/cli.md).

    hwyeval list CATALOG [--filter GLOB] [--plugin MODULE ...]
    hwyeval run CATALOG --out DIR [--resume | --overwrite] [--jobs N] [--filter GLOB]
                [--no-log] [--timeout SECONDS] [--executor local|ray] [--ray-address ADDR]
                [--max-memory-mb MB] [--plugin MODULE ...]
    hwyeval search CATALOG --out DIR --budget N [--sampler tpe|cmaes|random|qmc] [--seed S]
                   [--jobs J] [--resume | --overwrite] [--no-log] [--executor local|ray]
    hwyeval history add DB RUNDIR ... | hwyeval history DB [--out DIR] [--json] [--sql Q]
    hwyeval import commonroad FILE.xml [FILE.xml ...] --out DIR
    hwyeval report DIR
    hwyeval compare BASE NEW [--out DIR] [--tolerances FILE] [--timing-gate] [--json]
    hwyeval view PATH [--failed] [--web [--port N] [--bind ADDR]]
    hwyeval bench [--out FILE] [--quick] [--seeds N] [--catalog-runs M] [--no-fail]
                  [--controller-only] [--isolated]
    hwyeval controllers [NAME] [--plugin MODULE ...]
    hwyeval --version

Exit codes: 0 success (``run``: every scenario passed; ``compare``: no regression;
``search``: no failure found within the budget; ``bench``: every target met), 1 a
scenario failed, errored or timed out (``search``: a failure was found; ``bench``: a
target missed; ``compare``: a behaviour regression, or a timing slowdown with
``--timing-gate``), 2 invalid input: nothing was run or compared (a bad argument,
catalog or plug-in, a missing path, an empty baseline, an output directory that is not
empty without ``--resume`` or ``--overwrite``, or that another hwyeval command is
writing, a Ray address that does not answer, a damaged search journal); ``search``: 3
no failure found but some runs ended in error or timeout (not conclusive); ``run``
stopped by SIGINT (Ctrl-C) or SIGTERM: 130 or 143, after writing the reports of what
finished (``--resume`` runs the rest; docs/reliability.md).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import NoReturn

from suite.cli.commands import (
    cmd_bench,
    cmd_compare,
    cmd_controllers,
    cmd_list,
    cmd_report,
    cmd_view,
)
from suite.cli.common import (
    EXIT_FAIL,
    EXIT_INPUT,
    EXIT_OK,
    MEMORY_HELP,
    RAY_ADDRESS_HELP,
    UsageError,
    err,
    memory_mib,
    plain_help,
    positive_int,
    positive_seconds,
)
from suite.cli.history import add_history_parser
from suite.cli.importer import add_import_parser
from suite.cli.paper import add_paper_parser
from suite.cli.r157 import add_r157_parser
from suite.cli.run import cmd_run
from suite.cli.search import add_search_parser

__all__ = ["EXIT_FAIL", "EXIT_INPUT", "EXIT_OK", "UsageError", "build_parser", "main"]

PLUGIN_HELP = ("a controller plug-in: a .py file or an importable module that calls "
               "controllers.registry.register() (repeatable; entry points load by themselves)")


def version_text() -> str:
    from reports.provenance import git_revision, version_of
    from suite import __version__

    sha, dirty = git_revision()
    rev = f", git {sha[:10]}{'+dirty' if dirty else ''}" if sha else ""
    return (f"hwyeval {__version__}{rev} (SUMO {version_of('eclipse-sumo') or '?'}, "
            f"rerun-sdk {version_of('rerun-sdk') or '?'}, numba {version_of('numba') or '?'})")


class _Version(argparse.Action):
    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: object, option_string: str | None = None) -> None:
        print(version_text())
        parser.exit()


def _add_plugin(s: argparse.ArgumentParser) -> None:
    s.add_argument("--plugin", action="append", default=[], metavar="MODULE", help=PLUGIN_HELP)


def _run_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    s = sub.add_parser("run", help="run a catalog (exit 1 unless every scenario passes)")
    s.add_argument("catalog")
    s.add_argument("--out", required=True, help="output directory (new or empty, unless "
                   "--resume or --overwrite)")
    again = s.add_mutually_exclusive_group()
    again.add_argument("--resume", action="store_true",
                       help="keep the runs of DIR that finished with the same scenario content "
                            "and hwyeval version, run the others")
    again.add_argument("--overwrite", action="store_true",
                       help="empty DIR (an earlier hwyeval output) first")
    s.add_argument("--jobs", type=positive_int, default=0,
                   help="parallel scenario processes (default: cores)")
    s.add_argument("--filter", default=None, help="glob on scenario names or families")
    s.add_argument("--no-log", action="store_true", help="do not write Rerun .rrd logs")
    s.add_argument("--timeout", type=positive_seconds, default=None, metavar="SECONDS",
                   help="wall-clock budget of every scenario (default: the catalog's "
                        "timeout_s, else 60 s + 10 x duration_s, at most 1 h)")
    s.add_argument("--executor", choices=["local", "ray"], default="local")
    s.add_argument("--ray-address", default=None, help=RAY_ADDRESS_HELP)
    s.add_argument("--max-memory-mb", type=memory_mib, default=None, metavar="MB",
                   help=MEMORY_HELP)
    s.add_argument("--history", default=None, metavar="DB",
                   help="add the finished night to this history database (docs/history.md)")
    s.add_argument("--no-fail", action="store_true",
                   help="exit 0 when scenarios did not pass (2 stays bad input): for set -e")
    _add_plugin(s)
    s.set_defaults(func=cmd_run)


def _compare_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    s = sub.add_parser("compare", help="compare two run directories; exit 1 on a behaviour "
                                       "regression, 2 when nothing can be compared")
    s.add_argument("base", nargs="?", default=None, help="BASE (not with --history)")
    s.add_argument("new")
    s.add_argument("--history", default=None, metavar="DB",
                   help="compare NEW with a night of this history database (no BASE)")
    s.add_argument("--baseline", choices=["last", "last-pass"], default=None,
                   help="with --history: the last night of NEW's catalog (default) or the "
                        "last in which every run passed")
    s.add_argument("--out", default=None, help="where compare.csv/.html go (default NEW/compare)")
    s.add_argument("--tolerances", default=None, help="TOML file of per-metric tolerances")
    s.add_argument("--timing-gate", action="store_true",
                   help="a catalog-wide timing slowdown fails too (default: it warns)")
    s.add_argument("--json", action="store_true", help="print the comparison as JSON")
    s.set_defaults(func=cmd_compare)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="hwyeval", description=plain_help(__doc__),
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action=_Version, nargs=0, help="print versions and exit")
    sub = p.add_subparsers(dest="command", required=True)
    s = sub.add_parser("list", help="print the expanded scenario names of a catalog")
    s.add_argument("catalog")
    s.add_argument("--filter", default=None, help="glob on scenario names or families")
    s.add_argument("-v", "--verbose", action="store_true",
                   help="also each scenario's net and route (link edges marked)")
    _add_plugin(s)
    s.set_defaults(func=cmd_list)
    _run_parser(sub)
    s = sub.add_parser("report", help="(re)write results.csv, summary.csv, junit.xml, report.html")
    s.add_argument("dir")
    s.set_defaults(func=cmd_report)
    _compare_parser(sub)
    s = sub.add_parser("view", help="open Rerun logs (or print the command without a display)")
    s.add_argument("dir", help="a run directory, an output directory or an .rrd file")
    s.add_argument("--failed", action="store_true", help="every non-passing run of DIR")
    s.add_argument("--web", action="store_true", help="serve Rerun's web viewer over HTTP")
    s.add_argument("--port", type=positive_int, default=9090, help="web viewer port (--web)")
    s.add_argument("--bind", default="127.0.0.1", help="address to serve on (--web)")
    s.set_defaults(func=cmd_view)
    s = sub.add_parser("bench", help="the speed targets, measured in one run and judged "
                                     "(exit 1 when one is missed, docs/bench.md)")
    s.add_argument("--out", default=None, help="write every figure as JSON")
    s.add_argument("--quick", action="store_true",
                   help="a reduced set (2 dense runs of 4 s, one solver repeat, no "
                        "extrapolation, no-log or matrix commands): exercises every target, "
                        "its figures are not for quoting")
    s.add_argument("--seeds", type=positive_int, default=None, metavar="N",
                   help="dense runs (traffic seeds) of the one-run figures and the floor "
                        "study (default 4; --quick 2)")
    s.add_argument("--catalog-runs", type=positive_int, default=None, metavar="M",
                   help="dense runs of the whole-command catalog, --jobs 1 and 2 "
                        "(default 24; --quick 2)")
    s.add_argument("--no-fail", action="store_true",
                   help="exit 0 when a target is missed (2 stays bad input): for exploration")
    s.add_argument("--controller-only", action="store_true",
                   help="only the plant-only controller timing (no SUMO, no Ipopt, no target "
                        "judged)")
    s.add_argument("--isolated", action="store_true",
                   help="pin the dense runs to one core (taskset), list the other load, and "
                        "judge the step max (otherwise only reported)")
    s.set_defaults(func=cmd_bench)
    s = sub.add_parser("controllers", help="list registered controllers (NAME: its options)")
    s.add_argument("name", nargs="?", default=None)
    _add_plugin(s)
    s.set_defaults(func=cmd_controllers)
    add_paper_parser(sub)
    add_r157_parser(sub)
    add_search_parser(sub)
    add_import_parser(sub)
    add_history_parser(sub)
    return p


def os_error_text(exc: OSError) -> str:
    """``PATH: No space left on device (ENOSPC); nothing already written was lost``."""
    import errno
    import os

    code = errno.errorcode.get(exc.errno or 0, "")
    what = os.strerror(exc.errno) if exc.errno else str(exc)
    where = exc.filename or "?"
    return (f"{where}: {what}{f' ({code})' if code else ''}; files already written are "
            "complete (every file is written atomically), this command stopped")


def main(argv: Sequence[str] | None = None) -> int:
    from suite.catalog import CatalogError

    args = build_parser().parse_args(argv)  # argument errors: usage and exit 2
    try:
        return int(args.func(args))
    except (CatalogError, UsageError, FileNotFoundError) as exc:
        # catalog and input errors carry file/scenario/key in their message
        err(str(exc))
        return EXIT_INPUT
    except OSError as exc:  # a full disk, a read-only output: the environment, not a verdict
        err(os_error_text(exc))
        return EXIT_INPUT
    except KeyboardInterrupt:
        err("interrupted")
        return 130
    except BrokenPipeError:
        # the reader of our output went away (hwyeval list | head): not an error
        return EXIT_OK


def entry() -> NoReturn:
    """The ``hwyeval`` executable: :func:`main`, then
    :func:`suite.exec.quick_exit.exit_without_teardown` (the atexit handlers run and the
    streams are flushed; the 0.7 s destruction of every module's objects is skipped)."""
    from suite.exec.quick_exit import exit_without_teardown

    try:
        code = main()
    except SystemExit as exc:  # argparse's usage errors and --version
        if exc.code is None or isinstance(exc.code, int):
            code = exc.code or 0
        else:  # as the interpreter does with sys.exit("message")
            print(exc.code, file=sys.stderr)
            code = 1
    exit_without_teardown(code)


if __name__ == "__main__":
    entry()
