"""``hwyeval run CATALOG --out DIR``: run a catalog, write its reports, say how it went.

The steps, each one function: load plug-ins and the catalog (input errors exit 2
before anything runs), build the jobs, write the manifest with the provenance,
run them on an executor with progress, write the reports, finish the manifest,
print the short summary. Exit 0 when every scenario passed, 1 otherwise.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import Any

from suite.cli.common import EXIT_FAIL, EXIT_OK, Output, Plugins, load_catalog_for, load_plugins
from suite.cli.progress import RunProgress, short_summary

WARMUP_NOTE = ("starting {n} worker(s): importing modules and loading numba kernels "
               "(they compile once after an install or a change, about 20 s)")


def build_jobs(scenarios: list[Any], out: Path, catalog_name: str, no_log: bool,
               plugins: Plugins) -> list[Any]:
    from suite.exec.executors import RunJob
    from suite.run.runner import RunOptions

    return [RunJob(sc, out.resolve(),
                   RunOptions(write_rrd=not no_log, catalog_name=catalog_name,
                              timeout_s=sc.timeout_s),
                   sc.timeout_s, plugins.modules)
            for sc in scenarios]


def make_executor(args: argparse.Namespace, n_jobs: int) -> tuple[Any, int]:
    """The executor and how many scenarios it runs at once."""
    from suite.exec.executors import LocalExecutor, RayExecutor

    if args.executor == "ray":
        return RayExecutor(address=args.ray_address), n_jobs
    workers = min(args.jobs or os.cpu_count() or 1, n_jobs) or 1
    return LocalExecutor(jobs=workers), workers


def start_manifest(args: argparse.Namespace, scenarios: list[Any], workers: int,
                   plugins: Plugins) -> Any:
    from controllers import registry
    from reports.manifest import Manifest, now_iso
    from reports.provenance import collect

    used = sorted({sc.controller.name for sc in scenarios})
    plugin_names = tuple(f"{name} ({registry.origin(name)})" for name in used
                         if registry.origin(name) != "built in")
    return Manifest(catalog=str(Path(args.catalog).resolve()),
                    catalog_name=Path(args.catalog).stem,
                    scenarios=tuple(sc.name for sc in scenarios), started=now_iso(),
                    jobs=workers, executor=args.executor, plugins=plugins.labels,
                    provenance=collect(plugin_names))


def cmd_run(args: argparse.Namespace) -> int:
    from reports import write_reports
    from reports.manifest import write_manifest

    out_text = Output()
    plugins = load_plugins(args.plugin)
    _, scenarios = load_catalog_for(args.catalog, args.filter)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    jobs = build_jobs(scenarios, out, Path(args.catalog).stem, args.no_log, plugins)
    executor, workers = make_executor(args, len(jobs))
    manifest = start_manifest(args, scenarios, workers, plugins)
    write_manifest(out, manifest)
    prov = manifest.provenance
    out_text.line(f"hwyeval {prov.hwyeval_version} ({prov.short_sha}) on {prov.host}: "
                  f"{len(jobs)} scenario(s) of {args.catalog} → {out} with {workers} "
                  f"{args.executor} worker(s)")
    if args.executor == "local":
        out_text.line(WARMUP_NOTE.format(n=workers))
    t0 = time.perf_counter()
    with RunProgress(out_text, len(jobs), workers, sys.stdout.isatty()) as progress:
        results = executor.run(jobs, progress.finished)
    paths = write_reports(out)
    write_manifest(out, manifest.finish())
    for line in short_summary(results, time.perf_counter() - t0):
        out_text.line(line)
    out_text.line(f"report:  {paths.report_html}\nresults: {paths.results_csv}")
    return EXIT_OK if all(r.status == "pass" for r in results) else EXIT_FAIL
