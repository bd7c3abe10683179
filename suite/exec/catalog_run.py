"""A catalog run: :func:`run_catalog`, what ``hwyeval run`` and ``hwyeval paper --run`` do.

The steps, each one function: load plug-ins and the catalog, check the output
directory (:mod:`suite.exec.outdir`; input errors raise a UsageError, exit 2, before
anything is written), build the jobs (:mod:`suite.exec.build`), make the executor,
prepare the directory (``overwrite`` empties it, ``resume`` keeps what finished), write
the manifest with the provenance, run the jobs with progress
(:mod:`suite.exec.progress`), write the reports, finish the manifest, print the short
summary, add the night to the history if asked (the caller's ``add_night``: the history
is a command of its own). The exit code is 0 when no scenario of the manifest fails the
night (or with ``no_fail``), 1 otherwise: a known failure (``xfail``) that failed as
expected does not fail it, a strict one that passed does; 2 when the night could not be
added to the history (the output is complete).

SIGINT and SIGTERM stop the run in order (:mod:`suite.exec.signals`): nothing more
starts, the running scenarios are ended, the reports are written for what finished,
``interrupted: k of N done; resume with: ...`` is printed and the exit code is 130
(SIGINT) or 143 (SIGTERM).
"""

from __future__ import annotations

import shlex
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from suite.exec.build import (
    RunSettings,
    build_jobs,
    load_catalog_for,
    make_executor,
    route_warnings,
    start_manifest,
)
from suite.exec.command import (
    EXIT_FAIL,
    EXIT_INPUT,
    EXIT_OK,
    OUT_MODES,
    Plugins,
    Printer,
    UsageError,
    load_plugins,
    writing_to,
)

if TYPE_CHECKING:
    from reports.manifest import Manifest
    from reports.record import RunRecord
    from reports.write import ReportPaths
    from suite.catalog import Scenario
    from suite.exec.jobs import Executor, RunJob
    from suite.exec.outdir import OutPlan, ResumePlan

__all__ = ["WARMUP_NOTE", "AddNight", "CatalogRun", "CatalogRunOptions", "exit_of",
           "resume_command", "run_catalog", "write_reports"]

WARMUP_NOTE = ("starting {n} worker(s): importing modules and loading numba kernels "
               "(they compile once after an install or a change, about 20 s)")

AddNight = Callable[[str, Path], bool]
"""Adds a finished output to a history database (db, out): False when it cannot."""


@dataclass(frozen=True)
class CatalogRunOptions:
    """What to run and how. ``catalog`` and ``out`` as given (printed, and repeated by
    the resume command, as typed); ``filter``: a glob on scenario names or families;
    ``mode``: fresh (``out`` new or empty), resume or overwrite; ``history``: the
    database the finished night is added to (None: none); ``no_fail``: exit 0 although
    scenarios did not pass."""

    catalog: str
    out: str
    settings: RunSettings = field(default_factory=RunSettings)
    filter: str | None = None
    mode: str = "fresh"
    history: str | None = None
    no_fail: bool = False

    def __post_init__(self) -> None:
        if not self.catalog or not self.out:
            raise ValueError("CatalogRunOptions: catalog and out must be non-empty paths")
        if self.mode not in OUT_MODES:
            raise ValueError(f"CatalogRunOptions.mode: expected one of {OUT_MODES}, got "
                             f"{self.mode!r}")
        if not isinstance(self.settings, RunSettings):
            raise TypeError(f"CatalogRunOptions.settings: expected RunSettings, got "
                            f"{self.settings!r}")


@dataclass(frozen=True)
class CatalogRun:
    """How a catalog run ended: its exit code, the records of the runs that finished
    (kept by a resume included), the reports' files (None: not written) and whether a
    signal stopped it."""

    exit_code: int
    records: tuple[RunRecord, ...]
    reports: ReportPaths | None
    stopped: bool = False


@dataclass(frozen=True)
class _Prepared:
    """A run checked and ready: nothing written yet."""

    scenarios: list[Scenario]
    plan: OutPlan
    jobs: list[RunJob]
    executor: Executor
    workers: int


def resume_command(options: CatalogRunOptions) -> str:
    """The command that resumes this run (same catalog, output, filter and options)."""
    parts = ["hwyeval", "run", options.catalog, "--out", options.out, "--resume"]
    if options.filter:
        parts += ["--filter", options.filter]
    if options.settings.jobs:
        parts += ["--jobs", str(options.settings.jobs)]
    if options.settings.no_log:
        parts.append("--no-log")
    parts += options.settings.flags()
    if options.history:
        parts += ["--history", options.history]
    if options.no_fail:
        parts.append("--no-fail")
    return shlex.join(parts)


def _import_reports() -> None:
    """Import what the reports need (pandas, the HTML pages: 0.3-0.5 s) while the runs
    go on, so the command does not wait for it after the last run; a failure here is
    left for :func:`write_reports` to meet and report. It waits for the workers'
    warm-up first: the first run waits for that preload, which must have the machine."""
    from suite.exec.forkserver import wait_for_warm_ups

    try:
        wait_for_warm_ups()
        import reports.write  # noqa: F401
    except Exception:  # noqa: BLE001, S110 - write_reports imports it again and says why
        pass


def write_reports(out: Path, printer: Printer) -> ReportPaths | None:
    """The reports of ``out``; None (and the reason on the printer's error stream) if
    they cannot be written: the run directories are complete, ``hwyeval report`` can
    retry."""
    from reports import write_reports as write

    try:
        return write(out)
    except Exception as exc:  # noqa: BLE001 - the runs are kept whatever the reports do
        printer.err(f"could not write the reports of {out}: {type(exc).__name__}: {exc} (the "
                    f"run directories are complete; 'hwyeval report {out}' tries again)")
        return None


class EarlyWarmUp:
    """The workers' forkserver, started before the catalog is read (its preload of
    imports and numba kernels overlaps this process's catalog validation and output
    preparation); stopped again if the command hands no job to the executor."""

    def __init__(self, executor: str) -> None:
        from suite.exec.forkserver import prestart_forkserver

        self.running = executor == "local" and prestart_forkserver()
        self.used = False

    def close(self) -> None:
        if self.running and not self.used:
            from suite.exec.forkserver import stop_forkserver

            stop_forkserver()


def run_catalog(options: CatalogRunOptions, printer: Printer,
                add_night: AddNight | None = None) -> CatalogRun:
    """Run a catalog into its output, write its reports, say how it went (module doc);
    under the output directory's lock (suite.exec.out_lock): a second command into the
    same output, or a link to it, is refused (UsageError) before it writes anything.
    ``add_night``: how the night is added to ``options.history`` (needed with it)."""
    if options.history and add_night is None:
        raise ValueError("run_catalog: options.history needs add_night")
    warm = EarlyWarmUp(options.settings.executor)
    plugins = load_plugins(options.settings.plugins)
    try:
        with writing_to(Path(options.out)):
            return _locked_run(options, printer, plugins, warm, add_night)
    finally:
        warm.close()


def _prepare(options: CatalogRunOptions, printer: Printer, plugins: Plugins) -> _Prepared:
    """The scenarios, the output's plan, the jobs and the executor: every input error
    raised here, before anything is written."""
    from suite.exec.outdir import OutputDirError, check_out_dir

    _, scenarios = load_catalog_for(options.catalog, options.filter)
    for line in route_warnings(scenarios):
        printer.err(line)
    out = Path(options.out)
    try:
        plan = check_out_dir(out, options.mode, [sc.name for sc in scenarios])
    except OutputDirError as exc:
        raise UsageError(str(exc)) from exc
    settings = options.settings
    jobs = build_jobs(scenarios, out, Path(options.catalog).stem, settings.no_log, plugins,
                      settings.timeout_s, settings.memory_cap())
    executor, workers = make_executor(settings, len(jobs))
    return _Prepared(scenarios, plan, jobs, executor, workers)


def _announce(options: CatalogRunOptions, printer: Printer, manifest: Manifest,
              ready: _Prepared, todo: ResumePlan) -> None:
    """The run's first lines: what runs where, what a resume keeps, the workers' start."""
    prov = manifest.provenance
    n, workers, executor = len(ready.jobs), ready.workers, options.settings.executor
    printer.line(f"hwyeval {prov.hwyeval_version} ({prov.short_sha}) on {prov.host}: "
                 f"{n} scenario(s) of {options.catalog} → {Path(options.out)} with {workers} "
                 f"{executor} worker(s)")
    if ready.plan.mode == "resume":
        printer.line(f"resume: {len(todo.kept)} of {n} kept (finished with the same "
                     "scenario, hwyeval sources, controller source and complete files), "
                     f"{len(todo.to_run)} to run:")
        for line in todo.why:
            printer.line(f"  {line}")
    if executor == "local" and todo.to_run:
        printer.line(WARMUP_NOTE.format(n=min(workers, len(todo.to_run))))


def _locked_run(options: CatalogRunOptions, printer: Printer, plugins: Plugins,
                warm: EarlyWarmUp, add_night: AddNight | None) -> CatalogRun:
    from reports.manifest import write_manifest
    from suite.exec.outdir import ResumePlan, prepare_out_dir, resume_plan
    from suite.exec.progress import RunProgress
    from suite.exec.signals import stop_on_signals

    ready = _prepare(options, printer, plugins)
    out = Path(options.out)
    with stop_on_signals() as stop:
        prepare_out_dir(ready.plan)
        todo = resume_plan(ready.jobs) if ready.plan.mode == "resume" \
            else ResumePlan((), tuple(ready.jobs))
        manifest = start_manifest(options.catalog, options.settings.executor, ready.scenarios,
                                  ready.workers, plugins)
        write_manifest(out, manifest)
        _announce(options, printer, manifest, ready, todo)
        t0 = time.perf_counter()
        warm.used = bool(todo.to_run)
        # The parent idles while workers run; the reports' imports can happen then.
        threading.Thread(target=_import_reports, name="hwyeval-import-reports",
                         daemon=True).start()
        with RunProgress(printer, len(todo.to_run), ready.workers,
                         sys.stdout.isatty()) as progress:
            results = ready.executor.run(list(todo.to_run), progress.finished, stop)
        records = (*todo.kept, *results)
        paths = write_reports(out, printer)
    if stop.requested:
        printer.err(f"stopped by {stop.signal_name}: the running scenarios were ended, the "
                    "reports cover the runs that finished")
        printer.line(f"interrupted: {len(records)} of {len(ready.jobs)} done; resume with: "
                     f"{resume_command(options)}")
        return CatalogRun(stop.exit_code, records, paths, stopped=True)
    write_manifest(out, manifest.finish())
    wall_s = time.perf_counter() - t0
    return _finish(options, printer, records, paths, wall_s, add_night)


def _finish(options: CatalogRunOptions, printer: Printer, records: tuple[RunRecord, ...],
            paths: ReportPaths | None, wall_s: float, add_night: AddNight | None) -> CatalogRun:
    """The end of a finished run: where the reports are, the history, the short summary
    and the exit code it ends with."""
    from suite.exec.progress import short_summary

    out = Path(options.out)
    if paths is not None:
        printer.line(f"report:  {paths.report_html}\nresults: {paths.results_csv}")
    history_ok = True
    if options.history and add_night is not None:
        history_ok = add_night(options.history, out)
    code, meaning = exit_of(records, reports_written=paths is not None,
                            history_ok=history_ok, no_fail=options.no_fail, out=out)
    for line in short_summary(records, wall_s, meaning):  # last: it says what the code means
        printer.line(line)
    return CatalogRun(code, records, paths)


def exit_of(records: Sequence[RunRecord], *, reports_written: bool, history_ok: bool,
            no_fail: bool, out: Path) -> tuple[int, str | None]:
    """The exit code of a finished run and, when not the runs alone decide it, what it
    means (None: the summary's own words). A known failure that failed as expected does
    not fail the night; a strict one that passed does (reports.expectation)."""
    from reports.expectation import fails_night, xfail_of

    if not history_ok:
        return EXIT_INPUT, ("exit 2: the night could not be added to --history (see above; "
                            "the output is complete)")
    if not reports_written:
        return EXIT_FAIL, (f"exit 1: the reports could not be written (see above; 'hwyeval "
                           f"report {out}' tries again)")
    if not any(fails_night(r.status, xfail_of(r.info.scenario_spec)) for r in records):
        return EXIT_OK, None
    if no_fail:
        return EXIT_OK, "exit 0 (--no-fail) although some scenario did not pass"
    return EXIT_FAIL, None
