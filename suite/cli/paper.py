"""``hwyeval paper DIR [--run [--catalog FILE] [--jobs N]]``: the paper's findings from
the runs of catalogs/paper.toml (docs/paper.md).

Reads the paper's runs in DIR and writes ``DIR/paper.html`` (the figures, their
numbers, the paper's values beside ours and which findings hold), ``DIR/paper.json``
and ``DIR/paper.csv``, then prints the README's Results block (the numbers and the
findings as Markdown tables) exactly as the README shows it. With ``--run`` it first
runs the catalog into DIR as ``hwyeval run CATALOG --out DIR --overwrite --no-log``
does (:func:`suite.exec.catalog_run.run_catalog`): one command regenerates the README's
numbers.

Exit codes: 0 the page was written (whether or not each finding holds: that is the
result, not an error); 2 DIR holds no paper run, or the run's input was invalid; 130 /
143 the run was interrupted (nothing is drawn from a partial run).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from suite.cli.common import EXIT_FAIL, EXIT_OK, Output, UsageError, positive_int, writing_to

# The checkout's catalog (an editable install's source tree), the default of --catalog.
PAPER_CATALOG = Path(__file__).resolve().parents[2] / "catalogs" / "paper.toml"


def add_paper_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The ``paper`` sub-command's arguments."""
    s = sub.add_parser("paper", help="the paper's figures and findings from the runs of "
                                     "catalogs/paper.toml (--run: run it first)")
    s.add_argument("dir", help="output directory of a paper catalog run")
    s.add_argument("--run", action="store_true",
                   help="first run the catalog into DIR (--overwrite, --no-log)")
    s.add_argument("--catalog", default=str(PAPER_CATALOG),
                   help="the catalog --run runs (default: catalogs/paper.toml)")
    s.add_argument("--jobs", type=positive_int, default=2,
                   help="parallel scenario processes of --run (default 2)")
    s.set_defaults(func=cmd_paper)


def _run_catalog(catalog: str, out: Path, jobs: int) -> int:
    """``hwyeval run CATALOG --out DIR --overwrite --no-log --jobs N`` (run's defaults for
    everything else): :func:`suite.exec.catalog_run.run_catalog`, its exit code."""
    from suite.exec.build import RunSettings
    from suite.exec.catalog_run import CatalogRunOptions, run_catalog

    options = CatalogRunOptions(catalog=catalog, out=str(out), mode="overwrite",
                                settings=RunSettings(jobs=jobs, no_log=True))
    return run_catalog(options, Output()).exit_code


def cmd_paper(args: argparse.Namespace) -> int:
    """The command under DIR's lock (suite.exec.out_lock), --run's run included."""
    with writing_to(Path(args.dir)):
        return _paper(args)


def _paper(args: argparse.Namespace) -> int:
    from reports.paper import PaperError, results_markdown, write_paper

    out = Path(args.dir)
    run_code = EXIT_OK
    if args.run:
        run_code = _run_catalog(args.catalog, out, args.jobs)
        if run_code not in (EXIT_OK, EXIT_FAIL):  # bad input, or interrupted: nothing to draw
            return run_code
    if not out.is_dir():
        raise UsageError(f"{out}: no such output directory (run catalogs/paper.toml into it, "
                         "or pass --run)")
    try:
        report, paths = write_paper(out)
    except PaperError as exc:
        raise UsageError(str(exc)) from exc
    text = Output()
    text.line(f"page:    {paths.page}\nnumbers: {paths.json}, {paths.csv}")
    held = sum(f.holds is True for f in report.findings)
    not_held = [f for f in report.findings if f.holds is False]
    text.line(f"findings: {held} of {len(report.findings)} hold"
              + "".join(f"\n  does not hold: {f.figure}: {f.claim}" for f in not_held))
    for name, why in report.unreadable:
        text.line(f"  not read: {name}: {why}")
    text.line("")
    text.line(results_markdown(report))
    if run_code == EXIT_FAIL:  # the page is drawn, but a run it rests on did not pass
        text.line("exit 1: some run of the paper catalog did not pass (see its report)")
        return EXIT_FAIL
    return EXIT_OK
