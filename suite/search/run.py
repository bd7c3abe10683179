"""A search run: :func:`run_search`, what ``hwyeval search`` does (docs/search.md).

The steps: load plug-ins and the catalog's search families
(:func:`suite.search.space.load_search_catalog`; bad input raises a UsageError, exit 2,
before anything is written), check the output (new or empty; ``resume`` continues the
search in it, with the same sampler, seed and jobs; ``overwrite`` replaces an earlier
output: :func:`suite.search.session.plan_out`), make the executor as a catalog run does
(:mod:`suite.exec.build`), write the manifest, then the search
(:func:`suite.search.session.search_into`), the run reports
(:func:`suite.exec.catalog_run.write_reports`) and ``search.html``. With
``options.compare``, one quiet search per sampler and seed, then their table.

Exit codes (:mod:`suite.search.outcome`): 1 a failure was found, 0 none within the
budget and every run judged, 3 none found but some runs ended in error or timeout, 2 bad
input (a damaged journal for ``resume`` included, named with its line; another command
writing the output), 130 / 143 interrupted (what finished is kept and told; ``resume``
goes on from there and ends as the uninterrupted search would have).
"""

from __future__ import annotations

import io
import shlex
from dataclasses import replace
from pathlib import Path

from suite.exec.build import make_executor, start_manifest
from suite.exec.command import (
    EXIT_OK,
    Output,
    Plugins,
    Printer,
    UsageError,
    load_plugins,
    writing_to,
)
from suite.exec.outdir import OutPlan
from suite.search.compare import SearchOutcome
from suite.search.outcome import EXIT_UNJUDGED, summary_lines, unjudged, verdict_lines
from suite.search.session import SearchOptions, Where, plan_out, search_into
from suite.search.space import SearchCatalog

__all__ = ["resume_command", "run_search"]


def resume_command(options: SearchOptions) -> str:
    """The command that resumes this search (same catalog, output and settings)."""
    parts = ["hwyeval", "search", options.catalog, "--out", options.out, "--budget",
             str(options.budget), "--sampler", options.sampler, "--seed", str(options.seed),
             "--jobs", str(options.jobs), "--resume"]
    if options.settings.no_log:
        parts.append("--no-log")
    if not options.shrink:
        parts.append("--no-shrink")
    if options.shrink_points != 4:
        parts += ["--shrink-points", str(options.shrink_points)]
    return shlex.join(parts + options.settings.flags())


def _write_reports(out: Path, text: Printer) -> None:
    from reports.html.search import write_search_page
    from reports.record.search import SEARCH_CSV
    from suite.exec.catalog_run import write_reports

    paths = write_reports(out, text)
    page = write_search_page(out)
    if paths is not None:
        text.line(f"report:  {paths.report_html}\nresults: {paths.results_csv}")
    text.line(f"search:  {page}\n         {out / SEARCH_CSV}")


def run_search(options: SearchOptions, printer: Printer) -> int:
    """The search (or the samplers' comparison) under the output's lock
    (suite.exec.out_lock): another command writing it (or a link to it) is refused
    (UsageError, exit 2) before anything is read or written. Its exit code."""
    from suite.search.journal import JournalError

    with writing_to(Path(options.out)):
        try:
            return _search(options, printer)
        except JournalError as exc:  # resume of a damaged journal: bad input
            raise UsageError(str(exc)) from exc


def _header(options: SearchOptions, cat: SearchCatalog) -> str:
    n = len(cat.families)
    return (f"search {options.catalog}: {n} famil{'y' if n == 1 else 'ies'} "
            f"({', '.join(f.name for f in cat.families)}), {options.budget} runs each, "
            f"sampler {options.sampler}, seed {options.seed}, {options.jobs} at a time → "
            f"{Path(options.out)}"
            + (f"; without a search table (not searched): {', '.join(cat.skipped)}"
               if cat.skipped else ""))


def _search(options: SearchOptions, printer: Printer) -> int:
    from reports.manifest import write_manifest
    from suite.catalog import load_catalog
    from suite.exec.outdir import prepare_out_dir
    from suite.exec.signals import stop_on_signals
    from suite.search.space import load_search_catalog

    plugins = load_plugins(options.settings.plugins)
    cat = load_search_catalog(options.catalog)
    options.settings.memory_cap()  # a bad HWYEVAL_MAX_MEMORY_MB is bad input, before any run
    if options.compare:
        return _compare(options, cat, plugins, printer)
    out = Path(options.out)
    plan = plan_out(options, options.sampler, options.seed, cat.families)
    executor, workers = make_executor(options.settings, options.jobs)
    nominal = list(load_catalog(options.catalog).scenarios)
    with stop_on_signals() as stop:
        prepare_out_dir(plan)
        manifest = start_manifest(options.catalog, options.settings.executor, nominal,
                                  workers, plugins)
        write_manifest(out, manifest)
        printer.line(_header(options, cat))
        res = search_into(options, cat, plugins, Where(out, executor, stop, printer),
                          sampler=options.sampler, seed=options.seed, shrink=options.shrink)
        names = tuple(d.name for d in sorted(out.iterdir()) if (d / "run.json").is_file())
        manifest = replace(manifest, scenarios=names)
        write_manifest(out, manifest)
        _write_reports(out, printer)
    if res.stopped:
        printer.line(f"interrupted; resume with: {resume_command(options)}")
        return int(stop.exit_code)
    write_manifest(out, manifest.finish())
    code, lines = verdict_lines(res, out)
    for line in [*summary_lines(res), f"found:   {out / 'found.toml'}", *lines]:
        printer.line(line)
    return code


def _compare(options: SearchOptions, cat: SearchCatalog, plugins: Plugins,
             printer: Printer) -> int:
    """One search per sampler of ``options.compare`` and seed, into
    ``out/<sampler>_seed<k>``, then the table (compare.md)."""
    from suite.exec.outdir import prepare_out_dir
    from suite.exec.signals import stop_on_signals
    from suite.search.compare import compare_rows, compare_table

    out = Path(options.out)
    if options.mode == "resume":
        raise UsageError("--compare runs fresh searches: --resume does not apply")
    plan = plan_out(options, "compare", 0)
    executor, _ = make_executor(options.settings, options.jobs)
    outcomes: list[SearchOutcome] = []
    not_judged = 0
    with stop_on_signals() as stop:
        prepare_out_dir(plan)
        (out / "manifest.json").write_text("{}")  # marks the output as an hwyeval output
        for sampler in options.compare:
            for seed in range(options.seeds):
                sub = _compare_one(options, cat, plugins, Where(out, executor, stop, printer),
                                   sampler, seed)
                if sub is None:
                    printer.line("interrupted")
                    return int(stop.exit_code)
                outcomes += sub[0]
                not_judged += sub[1]
    table = compare_table(compare_rows(outcomes), options.budget)
    (out / "compare.md").write_text(table + "\n")
    printer.line(table)
    if not_judged:
        printer.line(f"exit 3: {not_judged} run(s) ended in error or timeout (no verdict): the "
                     "table counts them as runs without a failure; see each search's summary")
        return EXIT_UNJUDGED
    return EXIT_OK


def _compare_one(options: SearchOptions, cat: SearchCatalog, plugins: Plugins, where: Where,
                 sampler: str, seed: int) -> tuple[list[SearchOutcome], int] | None:
    """One search of the comparison, quiet, into ``<sampler>_seed<seed>``: its families'
    outcomes (each told in a line) and its runs without a verdict; None when stopped."""
    from suite.exec.outdir import prepare_out_dir
    from suite.search.compare import outcome_of

    sub = where.out / f"{sampler}_seed{seed}"
    prepare_out_dir(OutPlan(sub, "fresh"))
    quiet = Output(io.StringIO())
    res = search_into(options, cat, plugins, Where(sub, where.executor, where.stop, quiet),
                      sampler=sampler, seed=seed, shrink=False)
    if res.stopped:
        return None
    outcomes = []
    for fr in res.results:
        o = outcome_of(fr, sampler, seed, options.budget)
        outcomes.append(o)
        where.text.line(f"{fr.family.name} {sampler} seed {seed}: first failure at run "
                        f"{o.first_failure_run if o.found else '>' + str(options.budget)}, "
                        f"{len(o.modes)} mode(s), {o.failed_runs}/{o.runs} failed "
                        f"({res.wall_s:.0f} s)")
    return outcomes, len(unjudged(res))
