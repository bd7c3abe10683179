"""``hwyeval run CATALOG --out DIR``: run a catalog, write its reports, say how it went.

The steps, each one function: load plug-ins and the catalog, check the output
directory (:mod:`suite.exec.outdir`; input errors exit 2 before anything is written),
build the jobs (each with its wall-clock budget, :mod:`suite.exec.budget`, and its
scenario's content hash), make the executor, prepare the directory (``--overwrite``
empties it, ``--resume`` keeps what finished), write the manifest with the provenance,
run the jobs with progress, write the reports, finish the manifest, print the short
summary, add the night to ``--history DB`` if asked. Exit 0 when no scenario of the
manifest fails the night (or with ``--no-fail``), 1 otherwise: a known failure
(``xfail``) that failed as expected does not fail it, a strict one that passed does; 2
when the night could not be added to the history (the output is complete).

SIGINT and SIGTERM stop the run in order (:mod:`suite.exec.signals`): nothing more
starts, the running scenarios are ended, the reports are written for what finished,
``interrupted: k of N done; resume with: ...`` is printed and the exit code is 130
(SIGINT) or 143 (SIGTERM).
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
import threading
import time
from pathlib import Path
from typing import Any

from suite.cli.common import (
    EXIT_FAIL,
    EXIT_INPUT,
    EXIT_OK,
    Output,
    Plugins,
    UsageError,
    err,
    executor_flags,
    load_catalog_for,
    load_plugins,
    memory_cap_of,
    route_warnings,
    writing_to,
)

WARMUP_NOTE = ("starting {n} worker(s): importing modules and loading numba kernels "
               "(they compile once after an install or a change, about 20 s)")


def build_jobs(scenarios: list[Any], out: Path, catalog_name: str, no_log: bool,
               plugins: Plugins, timeout_s: float | None = None,
               memory: Any = None) -> list[Any]:
    """One job per scenario: its budget (``--timeout``, else the catalog's, else the
    default from its duration), its content hash (each network and tracks file read once)
    and the hashes of the code and of a plug-in controller (:mod:`suite.run.code_identity`);
    ``memory``: every scenario process's :class:`~suite.exec.memory.MemoryCap` (None:
    the default)."""
    from suite.exec.budget import run_budget_s
    from suite.exec.executors import RunJob
    from suite.exec.memory import MemoryCap
    from suite.run.code_identity import controller_sha256, hwyeval_code_sha256
    from suite.run.info import file_sha256, scenario_content_sha256, scenario_tracks_path
    from suite.run.options import RunOptions

    file_hashes: dict[Path, str] = {}

    def digest(path: Path, what: str, scenario: str) -> str:
        if path not in file_hashes:
            try:
                file_hashes[path] = file_sha256(path)
            except OSError as exc:
                raise UsageError(f"{path}: cannot read the {what} of scenario {scenario!r} "
                                 f"({exc})") from exc
        return file_hashes[path]

    code = hwyeval_code_sha256()
    controllers = {name: controller_sha256(name)
                   for name in sorted({sc.controller.name for sc in scenarios})}
    jobs = []
    for sc in scenarios:
        net = digest(sc.net_path, "network", sc.name)
        tracks = scenario_tracks_path(sc)
        content = scenario_content_sha256(
            sc, net, digest(tracks, "tracks file", sc.name) if tracks is not None else None)
        budget = run_budget_s(sc.duration_s, sc.timeout_s, timeout_s)
        options = RunOptions(write_rrd=not no_log, catalog_name=catalog_name, timeout_s=budget,
                             content_sha256=content, code_sha256=code,
                             controller_sha256=controllers[sc.controller.name])
        jobs.append(RunJob(sc, out.resolve(), options, budget, plugins.modules,
                           memory if memory is not None else MemoryCap()))
    return jobs


def make_executor(args: argparse.Namespace, n_jobs: int) -> tuple[Any, int]:
    """The executor and how many scenarios it runs at once."""
    from suite.exec.executors import LocalExecutor, RayExecutor

    if args.executor == "ray":
        try:
            return RayExecutor(address=args.ray_address), n_jobs
        except (RuntimeError, ConnectionError, ValueError) as exc:
            raise UsageError(f"--executor ray: {exc}") from exc
    if args.ray_address:
        raise UsageError(f"--ray-address {args.ray_address}: only with --executor ray")
    workers = max(1, min(args.jobs or os.cpu_count() or 1, n_jobs))
    return LocalExecutor(jobs=workers), workers


def start_manifest(args: argparse.Namespace, scenarios: list[Any], workers: int,
                   plugins: Plugins) -> Any:
    from controllers import registry
    from reports.manifest import ControllerCode, Manifest, catalog_identity, now_iso
    from reports.provenance import collect
    from suite.run.code_identity import controller_sha256

    used = sorted({sc.controller.name for sc in scenarios})
    plugin_names = tuple(f"{name} ({registry.origin(name)})" for name in used
                         if registry.origin(name) != "built in")
    catalog = Path(args.catalog).resolve()
    identity = catalog_identity(catalog)  # what the history files the night under
    return Manifest(catalog=str(catalog), catalog_name=Path(args.catalog).stem,
                    scenarios=tuple(sc.name for sc in scenarios), started=now_iso(),
                    jobs=workers, executor=args.executor, plugins=plugins.labels,
                    provenance=collect(plugin_names), catalog_id=identity.name,
                    catalog_origin=identity.origin,
                    controllers=tuple(ControllerCode(n, controller_sha256(n)) for n in used))


def resume_command(args: argparse.Namespace) -> str:
    """The command that resumes this run (same catalog, output, filter and options)."""
    parts = ["hwyeval", "run", str(args.catalog), "--out", str(args.out), "--resume"]
    if args.filter:
        parts += ["--filter", args.filter]
    if args.jobs:
        parts += ["--jobs", str(args.jobs)]
    if args.no_log:
        parts.append("--no-log")
    parts += executor_flags(args)
    if getattr(args, "history", None):
        parts += ["--history", args.history]
    if getattr(args, "no_fail", False):
        parts.append("--no-fail")
    return shlex.join(parts)


def _mode(args: argparse.Namespace) -> str:
    return "resume" if args.resume else "overwrite" if args.overwrite else "fresh"


def _import_reports() -> None:
    """Import what the reports need (pandas, the HTML pages: 0.3-0.5 s) while the runs
    go on, so the command does not wait for it after the last run; a failure here is
    left for :func:`_write_reports` to meet and report. It waits for the workers'
    warm-up first: the first run waits for that preload, which must have the machine."""
    from suite.exec.forkserver import wait_for_warm_ups

    try:
        wait_for_warm_ups()
        import reports.write  # noqa: F401
    except Exception:  # noqa: BLE001, S110 - _write_reports imports it again and says why
        pass


def _write_reports(out: Path) -> Any:
    """The reports of ``out``; None (and the reason on stderr) if they cannot be
    written: the run directories are complete, ``hwyeval report`` can retry."""
    from reports import write_reports

    try:
        return write_reports(out)
    except Exception as exc:  # noqa: BLE001 - the runs are kept whatever the reports do
        err(f"could not write the reports of {out}: {type(exc).__name__}: {exc} (the run "
            f"directories are complete; 'hwyeval report {out}' tries again)")
        return None


class _EarlyWarmUp:
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


def cmd_run(args: argparse.Namespace) -> int:
    out_text = Output()
    warm = _EarlyWarmUp(args.executor)
    plugins = load_plugins(args.plugin)
    try:
        return _run(args, out_text, plugins, warm)
    finally:
        warm.close()


def _run(args: argparse.Namespace, out_text: Output, plugins: Plugins,
         warm: _EarlyWarmUp) -> int:
    """The run under the output directory's lock (suite.exec.out_lock): a second command
    into the same --out, or a link to it, is refused (exit 2) before it writes anything."""
    with writing_to(Path(args.out)):
        return _locked_run(args, out_text, plugins, warm)


def _locked_run(args: argparse.Namespace, out_text: Output, plugins: Plugins,
                warm: _EarlyWarmUp) -> int:
    from reports.manifest import write_manifest
    from suite.cli.progress import RunProgress, short_summary
    from suite.exec.outdir import (
        OutputDirError,
        ResumePlan,
        check_out_dir,
        prepare_out_dir,
        resume_plan,
    )
    from suite.exec.signals import stop_on_signals

    _, scenarios = load_catalog_for(args.catalog, args.filter)
    for line in route_warnings(scenarios):
        err(line)
    out = Path(args.out)
    try:
        plan = check_out_dir(out, _mode(args), [sc.name for sc in scenarios])
    except OutputDirError as exc:
        raise UsageError(str(exc)) from exc
    jobs = build_jobs(scenarios, out, Path(args.catalog).stem, args.no_log, plugins,
                      args.timeout, memory_cap_of(args))
    executor, workers = make_executor(args, len(jobs))
    with stop_on_signals() as stop:
        prepare_out_dir(plan)
        todo = resume_plan(jobs) if plan.mode == "resume" else ResumePlan((), tuple(jobs))
        manifest = start_manifest(args, scenarios, workers, plugins)
        write_manifest(out, manifest)
        prov = manifest.provenance
        out_text.line(f"hwyeval {prov.hwyeval_version} ({prov.short_sha}) on {prov.host}: "
                      f"{len(jobs)} scenario(s) of {args.catalog} → {out} with {workers} "
                      f"{args.executor} worker(s)")
        if plan.mode == "resume":
            out_text.line(f"resume: {len(todo.kept)} of {len(jobs)} kept (finished with the "
                          "same scenario, hwyeval sources, controller source and complete "
                          f"files), {len(todo.to_run)} to run:")
            for line in todo.why:
                out_text.line(f"  {line}")
        if args.executor == "local" and todo.to_run:
            out_text.line(WARMUP_NOTE.format(n=min(workers, len(todo.to_run))))
        t0 = time.perf_counter()
        warm.used = bool(todo.to_run)
        # The parent idles while workers run; the reports' imports can happen then.
        threading.Thread(target=_import_reports, name="hwyeval-import-reports",
                         daemon=True).start()
        with RunProgress(out_text, len(todo.to_run), workers, sys.stdout.isatty()) as progress:
            results = executor.run(list(todo.to_run), progress.finished, stop)
        records = [*todo.kept, *results]
        paths = _write_reports(out)
    if stop.requested:
        err(f"stopped by {stop.signal_name}: the running scenarios were ended, the reports "
            "cover the runs that finished")
        out_text.line(f"interrupted: {len(records)} of {len(jobs)} done; resume with: "
                      f"{resume_command(args)}")
        return stop.exit_code
    write_manifest(out, manifest.finish())
    wall_s = time.perf_counter() - t0
    if paths is not None:
        out_text.line(f"report:  {paths.report_html}\nresults: {paths.results_csv}")
    history_ok = True
    if getattr(args, "history", None):
        from suite.cli.history import add_run_to_history

        history_ok = add_run_to_history(args.history, out, out_text)
    code, meaning = exit_of(records, reports_written=paths is not None,
                            history_ok=history_ok, no_fail=getattr(args, "no_fail", False),
                            out=out)
    for line in short_summary(records, wall_s, meaning):  # last: it says what the code means
        out_text.line(line)
    return code


def exit_of(records: list[Any], *, reports_written: bool, history_ok: bool, no_fail: bool,
            out: Path) -> tuple[int, str | None]:
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
