"""``hwyeval r157 DIR [--reference REF_DIR]``: an R157 pack's runs judged by the
regulation's acceptance logic, grouped by Annex 5 section, with the reference driver's
outcome beside each scenario's (:mod:`reports.r157`, docs/r157.md).

Writes ``DIR/r157.html`` and ``DIR/r157.csv`` and prints the per-section summary. Exit
codes: 0 every run meets the acceptance logic; 1 some run does not; 2 DIR holds no run
of a scenario labelled with an R157 section (or a folder does not exist).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from suite.cli.common import EXIT_FAIL, EXIT_OK, Output, UsageError, writing_to


def add_r157_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The ``r157`` sub-command's arguments."""
    s = sub.add_parser("r157", help="an R157 pack's runs by Annex 5 section, the reference "
                                    "driver's beside (exit 1 unless the acceptance holds)")
    s.add_argument("dir", help="output directory of a run of the pack (hwyeval import "
                               "openscenario --r157, then hwyeval run)")
    s.add_argument("--reference", default=None, metavar="REF_DIR",
                   help="output directory of the same pack run with r157_reference "
                        "(default: its runs in DIR, if any)")
    s.set_defaults(func=cmd_r157)


def cmd_r157(args: argparse.Namespace) -> int:
    """Judge and write under DIR's lock (suite.exec.out_lock)."""
    from reports.r157 import R157Error, summary_markdown, write_r157

    out = Path(args.dir)
    if not out.is_dir():
        raise UsageError(f"{out}: no such run directory")
    with writing_to(out):
        try:
            report = write_r157(out, args.reference)
        except R157Error as exc:
            raise UsageError(str(exc)) from exc
    text = Output()
    text.line(f"page:  {report.page}\ntable: {report.table}\n")
    text.line(summary_markdown(report.summaries))
    return EXIT_OK if report.met else EXIT_FAIL
