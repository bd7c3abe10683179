"""The small commands: list, report, compare, view, bench, controllers."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from suite.cli.common import EXIT_INPUT, EXIT_OK, Output, UsageError, load_catalog_for, load_plugins


def cmd_list(args: argparse.Namespace) -> int:
    load_plugins(args.plugin)
    _, scenarios = load_catalog_for(args.catalog, args.filter)
    out = Output()
    for sc in scenarios:
        out.line(sc.name)
        if out.closed:
            break
    return EXIT_OK


def cmd_report(args: argparse.Namespace) -> int:
    from reports import write_reports
    from suite.exec.outdir import OutputDirError, check_report_targets

    out = Path(args.dir)
    if not out.is_dir():
        raise UsageError(f"{out}: no such run directory")
    try:
        check_report_targets(out)
    except OutputDirError as exc:
        raise UsageError(str(exc)) from exc
    paths = write_reports(out)
    Output().line(f"report:  {paths.report_html}\nresults: {paths.results_csv}")
    return EXIT_OK


def cmd_compare(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from reports.compare import DuplicateRuns, NothingToCompare, Tolerances, compare_runs
    from reports.compare.render import as_json

    try:
        tol = Tolerances.from_toml(Path(args.tolerances)) if args.tolerances else Tolerances()
    except (OSError, ValueError) as exc:
        raise UsageError(f"--tolerances {args.tolerances}: {exc}") from exc
    if args.timing_gate:
        tol = replace(tol, timing_gate=True)
    for side in (args.base, args.new):
        if not Path(side).is_dir():
            raise UsageError(f"{side}: no such directory")
    out = Path(args.out) if args.out else Path(args.new) / "compare"
    try:
        result = compare_runs(Path(args.base), Path(args.new), out, tol)
    except (NothingToCompare, DuplicateRuns) as exc:
        raise UsageError(str(exc)) from exc
    Output().line(as_json(result) if args.json else result.summary_text())
    return int(result.exit_code)


def cmd_view(args: argparse.Namespace) -> int:
    from suite.rerun.viewer import failed_runs, open_logs, serve_web

    target = Path(args.dir)
    if not target.exists():
        raise UsageError(f"{target}: no such run directory, output directory or .rrd file")
    items = [target]
    if args.failed:
        items = failed_runs(target)
        if not items:
            Output().line(f"{target}: every run passed, nothing to open")
            return EXIT_OK
    if args.web:
        return serve_web(items, port=args.port, bind=args.bind)
    return open_logs(items)


def cmd_bench(args: argparse.Namespace) -> int:
    from suite.bench import run_all, summary_lines

    figures = run_all(include_runner=not args.controller_only,
                      include_ipopt=not args.controller_only)
    out = Output()
    for line in summary_lines(figures):
        out.line(line)
    if args.out:
        Path(args.out).write_text(json.dumps(figures, indent=1, default=str))
        out.line(f"figures: {args.out}")
    return EXIT_OK


def cmd_controllers(args: argparse.Namespace) -> int:
    from controllers import registry

    load_plugins(args.plugin)
    out = Output()
    if args.name:
        if args.name not in registry.names():
            raise UsageError(f"no controller {args.name!r}; registered: "
                             f"{', '.join(registry.names())}")
        out.line(f"{args.name} ({registry.origin(args.name)})")
        for opt in registry.options(args.name):
            unit = f" [{opt.unit}]" if opt.unit and opt.unit != "-" else ""
            out.line(f"  {opt.path}{unit} = {opt.default!r} ({opt.type}): {opt.doc}")
        return EXIT_OK
    names = registry.names()
    width = max(len(n) for n in names)
    for name in names:
        out.line(f"{name:<{width}}  {registry.origin(name)}")
    errors = registry.plugin_errors()
    for name, why in sorted(errors.items()):
        out.line(f"{name:<{width}}  BROKEN: {why}")
    return EXIT_INPUT if errors and not names else EXIT_OK
