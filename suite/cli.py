"""``hwyeval`` command line.

    hwyeval list CATALOG [--filter GLOB]
    hwyeval run CATALOG --out DIR [--jobs N] [--filter GLOB] [--no-log] [--executor local|ray]
    hwyeval report DIR
    hwyeval compare BASE NEW [--out DIR] [--tolerances FILE]
    hwyeval view DIR[/SCENARIO] [--failed]
    hwyeval bench [--out FILE]
    hwyeval controllers

Exit codes: 0 success (for ``run``: every scenario passed), 1 a scenario failed,
errored or timed out (``compare``: a regression), 2 invalid input (nothing run).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

EXIT_OK = 0
EXIT_FAIL = 1
EXIT_INPUT = 2


class UsageError(ValueError):
    """Invalid command-line input (exit code 2)."""


def _err(msg: str) -> None:
    print(f"hwyeval: {msg}", file=sys.stderr)


def _load(catalog: str, pattern: str | None) -> Any:
    from suite.catalog import expand_filter, load_catalog

    cat = load_catalog(Path(catalog))
    scenarios = cat.scenarios
    if pattern:
        scenarios = expand_filter(scenarios, pattern)
        if not scenarios:
            raise UsageError(f"{catalog}: --filter {pattern!r} matches no scenario")
    return cat, scenarios


def cmd_list(args: argparse.Namespace) -> int:
    _, scenarios = _load(args.catalog, args.filter)
    for sc in scenarios:
        print(sc.name)
    return EXIT_OK


def _status_line(record: Any, done: int, total: int) -> str:
    status = record.status
    verdict = record.verdict
    extra = ""
    if verdict is not None:
        extra = (f" gap={verdict.value('min_gap_m'):.2f}m "
                 f"progress={verdict.value('progress_m'):.0f}m")
        if verdict.failures:
            extra += " failed: " + "; ".join(f.text for f in verdict.failures[:3])
    return f"[{done}/{total}] {status.upper():7s} {record.info.scenario}{extra}"


def cmd_run(args: argparse.Namespace) -> int:
    from reports import write_reports
    from reports.record.codec import write_json_atomic
    from suite.exec.executors import LocalExecutor, RayExecutor, RunJob
    from suite.run.runner import RunOptions

    cat, scenarios = _load(args.catalog, args.filter)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    jobs_n = args.jobs or os.cpu_count() or 1
    catalog_name = Path(args.catalog).stem
    run_jobs = [
        RunJob(sc, out.resolve(),
               RunOptions(write_rrd=not args.no_log, catalog_name=catalog_name,
                          timeout_s=sc.timeout_s),
               sc.timeout_s)
        for sc in scenarios
    ]
    write_json_atomic(out / "manifest.json", {
        "catalog": str(Path(args.catalog).resolve()), "catalog_name": catalog_name,
        "scenarios": [sc.name for sc in scenarios], "started": time.strftime("%Y-%m-%dT%H:%M:%S"),
        "jobs": jobs_n, "executor": args.executor,
    })
    executor: Any
    if args.executor == "ray":
        executor = RayExecutor(address=args.ray_address)
    else:
        executor = LocalExecutor(jobs=min(jobs_n, len(run_jobs)) or 1)
    done = 0
    t0 = time.perf_counter()

    def on_done(record: Any) -> None:
        nonlocal done
        done += 1
        print(_status_line(record, done, len(run_jobs)), flush=True)

    results = executor.run(run_jobs, on_done)
    paths = write_reports(out)
    wall = time.perf_counter() - t0
    counts: dict[str, int] = {}
    for record in results:
        counts[record.status] = counts.get(record.status, 0) + 1
    summary = ", ".join(f"{k}={v}" for k, v in sorted(counts.items()))
    print(f"{len(results)} scenarios in {wall:.1f} s: {summary}")
    print(f"results: {paths.results_csv}\nreport:  {paths.report_html}")
    return EXIT_OK if counts.get("pass", 0) == len(results) else EXIT_FAIL


def cmd_report(args: argparse.Namespace) -> int:
    from reports import write_reports

    out = Path(args.dir)
    if not out.is_dir():
        raise UsageError(f"{out}: no such run directory")
    paths = write_reports(out)
    print(f"results: {paths.results_csv}\nreport:  {paths.report_html}")
    return EXIT_OK


def cmd_compare(args: argparse.Namespace) -> int:
    from reports.compare import Tolerances, compare_runs

    tol = Tolerances.from_toml(Path(args.tolerances)) if args.tolerances else None
    out = Path(args.out) if args.out else Path(args.new) / "compare"
    result = compare_runs(Path(args.base), Path(args.new), out, tol)
    print(result.summary_text())
    return int(result.exit_code)


def cmd_view(args: argparse.Namespace) -> int:
    from suite.rerun.viewer import failed_runs, open_logs

    target = Path(args.dir)
    if args.failed:
        runs = failed_runs(target)
        if not runs:
            print(f"{target}: no failed runs")
            return EXIT_OK
        return open_logs(runs)
    return open_logs([target])


def cmd_bench(args: argparse.Namespace) -> int:
    from suite.bench import run_all, summary_lines

    figures = run_all(include_runner=not args.controller_only,
                      include_ipopt=not args.controller_only)
    for line in summary_lines(figures):
        print(line)
    if args.out:
        Path(args.out).write_text(json.dumps(figures, indent=1, default=str))
        print(f"figures: {args.out}")
    return EXIT_OK


def cmd_controllers(args: argparse.Namespace) -> int:
    from controllers import registry

    for name in registry.names():
        print(name)
    return EXIT_OK


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="hwyeval", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True)
    s = sub.add_parser("list", help="print the expanded scenario names of a catalog")
    s.add_argument("catalog")
    s.add_argument("--filter", default=None, help="glob on scenario names")
    s.set_defaults(func=cmd_list)
    s = sub.add_parser("run", help="run a catalog")
    s.add_argument("catalog")
    s.add_argument("--out", required=True, help="output directory")
    s.add_argument("--jobs", type=int, default=0,
                   help="parallel scenario processes (default: cores)")
    s.add_argument("--filter", default=None, help="glob on scenario names")
    s.add_argument("--no-log", action="store_true", help="do not write Rerun .rrd logs")
    s.add_argument("--executor", choices=["local", "ray"], default="local")
    s.add_argument("--ray-address", default=None, help="ray.init address (e.g. auto)")
    s.set_defaults(func=cmd_run)
    s = sub.add_parser("report", help="(re)write results.csv, summary.csv, junit.xml, report.html")
    s.add_argument("dir")
    s.set_defaults(func=cmd_report)
    s = sub.add_parser("compare", help="compare two run directories; exit 1 on regression")
    s.add_argument("base")
    s.add_argument("new")
    s.add_argument("--out", default=None)
    s.add_argument("--tolerances", default=None, help="TOML file of per-metric tolerances")
    s.set_defaults(func=cmd_compare)
    s = sub.add_parser("view", help="open Rerun logs (or print the command without a display)")
    s.add_argument("dir")
    s.add_argument("--failed", action="store_true", help="open every non-passing run of DIR")
    s.set_defaults(func=cmd_view)
    s = sub.add_parser("bench", help="speed and memory benchmark (ratios, one run)")
    s.add_argument("--out", default=None, help="write every figure as JSON")
    s.add_argument("--controller-only", action="store_true",
                   help="only the plant-only controller timing (no SUMO, no Ipopt)")
    s.set_defaults(func=cmd_bench)
    s = sub.add_parser("controllers", help="list registered controllers")
    s.set_defaults(func=cmd_controllers)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    from suite.catalog import CatalogError

    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except (CatalogError, UsageError, FileNotFoundError) as exc:
        # Catalog and input errors carry file/scenario/key in their message.
        _err(str(exc))
        return EXIT_INPUT


if __name__ == "__main__":
    sys.exit(main())
