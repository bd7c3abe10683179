"""The small commands: list, report, compare, view, bench, controllers."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from suite.cli.common import (
    EXIT_FAIL,
    EXIT_INPUT,
    EXIT_OK,
    Output,
    UsageError,
    err,
    load_catalog_for,
    load_plugins,
    route_text,
    route_warnings,
    writing_to,
)


def cmd_list(args: argparse.Namespace) -> int:
    load_plugins(args.plugin)
    _, scenarios = load_catalog_for(args.catalog, args.filter)
    out = Output()
    verbose = bool(getattr(args, "verbose", False))
    for line in route_warnings(scenarios):
        err(line)
    for sc in scenarios:
        out.line(f"{sc.name}  {route_text(sc)}" if verbose else sc.name)
        if out.closed:
            break
    return EXIT_OK


def cmd_report(args: argparse.Namespace) -> int:
    from reports import write_reports
    from suite.exec.outdir import OutputDirError, check_report_targets

    out = Path(args.dir)
    if not out.is_dir():
        raise UsageError(f"{out}: no such run directory")
    with writing_to(out):  # not while a run or search writes its own reports there
        try:
            check_report_targets(out)
        except OutputDirError as exc:
            raise UsageError(str(exc)) from exc
        paths = write_reports(out)
    Output().line(f"report:  {paths.report_html}\nresults: {paths.results_csv}")
    return EXIT_OK


def default_compare_dir(new: Path) -> Path:
    """Where compare writes compare.csv/.html without ``--out``: beside the new night's
    folder (``<new>.compare``), so the night's own output stays as its run wrote it."""
    new = new.resolve()
    return new.parent / f"{new.name}.compare"


def cmd_compare(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from reports.compare import (
        DuplicateRuns,
        NothingToCompare,
        Tolerances,
        UnknownTolerance,
        compare_runs,
    )
    from reports.compare.render import as_json

    try:
        tol = Tolerances.from_toml(Path(args.tolerances)) if args.tolerances else Tolerances()
    except (OSError, ValueError) as exc:
        raise UsageError(f"--tolerances {args.tolerances}: {exc}") from exc
    if args.timing_gate:
        tol = replace(tol, timing_gate=True)
    args.base = _compare_base(args)
    if args.base is None:  # the first night of a history: nothing before it
        return EXIT_OK
    for side in (args.base, args.new):
        if not Path(side).is_dir():
            raise UsageError(f"{side}: no such directory")
    if Path(args.base).resolve() == Path(args.new).resolve():
        raise UsageError(f"{args.base} and {args.new} are the same directory: a night "
                         "compared with itself shows nothing (give the baseline night)")
    out = Path(args.out) if args.out else default_compare_dir(Path(args.new))
    try:
        with writing_to(out):  # one writer per directory (suite.exec.out_lock)
            result = compare_runs(Path(args.base), Path(args.new), out, tol)
    except (NothingToCompare, DuplicateRuns) as exc:
        raise UsageError(str(exc)) from exc
    except UnknownTolerance as exc:
        raise UsageError(f"--tolerances {args.tolerances}: {exc}") from exc
    except OSError as exc:  # a read-only or full output: exit 2, not 1 ("regression")
        raise UsageError(f"{out}: cannot write the comparison ({exc.strerror or exc}); "
                         "give a writable --out") from exc
    Output().line(as_json(result) if args.json else result.summary_text())
    return int(result.exit_code)


def _compare_base(args: argparse.Namespace) -> str | None:
    """BASE as given, or with ``--history DB`` the output directory of the baseline night
    the database names (docs/history.md); None when the history holds no earlier night
    of NEW's catalog (said so: the first night has nothing to regress against); input
    errors are UsageErrors (exit 2)."""
    history, baseline = getattr(args, "history", None), getattr(args, "baseline", None)
    if history is None:
        if baseline is not None:
            raise UsageError("--baseline needs --history DB")
        if args.base is None:
            raise UsageError("compare: expected BASE NEW, or --history DB NEW")
        return str(args.base)
    if args.base is not None:
        raise UsageError("compare --history DB NEW: give NEW only (the database names BASE)")
    from reports.history import HistoryError, NoBaseline, baseline_night

    try:
        found = baseline_night(Path(history), Path(args.new), baseline or "last")
    except NoBaseline as exc:
        line = f"{exc}; the first night of this catalog in the history (exit 0)"
        if args.json:  # stdout stays JSON
            print(line, file=sys.stderr)
            Output().line('{"exit_code": 0, "baseline": null, "rows": []}')
        else:
            Output().line(line)
        return None
    except HistoryError as exc:
        raise UsageError(str(exc)) from exc
    line = (f"baseline: night {found.night.night_id} ({found.mode}, revision "
            f"{found.night.short_revision}) from {found.out_dir}")
    if args.json:  # stdout is the JSON alone
        print(line, file=sys.stderr)
    else:
        Output().line(line)
    return str(found.out_dir)


def cmd_view(args: argparse.Namespace) -> int:
    from suite.rerun.viewer import failed_entries, open_logs, serve_web, unreadable_reason

    target = Path(args.dir)
    if not target.exists():
        raise UsageError(f"{target}: no such run directory, output directory or .rrd file")
    items = [target]
    if target.is_dir() and (why := unreadable_reason(target)):
        err(f"{target}: unreadable run directory (status error): {why}")
    if args.failed:
        failed = failed_entries(target)
        if not failed:
            Output().line(f"{target}: every run passed, nothing to open")
            return EXIT_OK
        for entry in failed:  # listed to open (its log may still be there), and why
            if entry.unreadable:
                err(f"{entry.run_dir}: unreadable run directory (status error): "
                    f"{entry.unreadable}")
        items = [entry.run_dir for entry in failed]
    if args.web:
        return serve_web(items, port=args.port, bind=args.bind)
    # the --web command to suggest is this one again (view takes one PATH, not the
    # failed runs' directories it found)
    import shlex

    from suite.rerun.viewer import portable_path

    web = ["hwyeval", "view", portable_path(target), *(["--failed"] if args.failed else []),
           "--web"]
    return open_logs(items, web_hint=shlex.join(web))


def bench_options(args: argparse.Namespace) -> Any:
    """The :class:`suite.bench.BenchOptions` of ``hwyeval bench``'s arguments."""
    from dataclasses import replace

    from suite.bench import QUICK, BenchOptions

    opts = QUICK if args.quick else BenchOptions()
    if args.controller_only:
        opts = replace(opts, include_runner=False, include_ipopt=False)
    if args.seeds is not None:
        opts = replace(opts, seeds=args.seeds)
    if args.catalog_runs is not None:
        opts = replace(opts, catalog_runs=args.catalog_runs)
    if args.isolated:
        opts = replace(opts, isolated=True)
    return opts


def cmd_bench(args: argparse.Namespace) -> int:
    """Exit 0 when every target is met (or none judged, or ``--no-fail``), 1 when one is
    missed, 2 on bad input (an --out that cannot be written)."""
    from suite.bench import run_all, summary_lines, to_json

    out_path = Path(args.out) if args.out else None
    if out_path is not None and (out_path.is_dir() or not out_path.parent.is_dir()):
        raise UsageError(f"--out {out_path}: expected a file in an existing directory")
    opts = bench_options(args)
    out = Output()
    result = run_all(opts, print_fn=out.line)
    for line in summary_lines(result):
        out.line(line)
    if out_path is not None:
        out_path.write_text(to_json(result.figures))
        out.line(f"figures: {out_path}")
    if result.all_met:
        out.line("exit 0: " + ("every target was met" if result.results
                               else "no target judged"))
        return EXIT_OK
    if args.no_fail:
        out.line("--no-fail: exit 0 although a target was missed")
        return EXIT_OK
    out.line("exit 1: a target was missed (--no-fail for exploration)")
    return EXIT_FAIL


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
