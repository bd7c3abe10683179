"""``hwyeval search CATALOG --out DIR --budget N``: find where a controller fails
(docs/search.md).

The steps: load plug-ins and the catalog's search families
(:func:`suite.search.space.load_search_catalog`; bad input exits 2 before anything is
written), check DIR (new or empty; ``--resume`` continues the search in it, with the
same sampler, seed and ``--jobs``; ``--overwrite`` replaces an earlier output), make the
executor as ``run`` does, then per family the ask-and-tell loop
(:mod:`suite.search.loop`), every trial a normal run directory of DIR built and
dispatched by ``run``'s own :func:`~suite.cli.run.build_jobs` and executors; then the
shrinking (:mod:`suite.search.shrink`), ``found.toml``, ``search.csv``, ``run``'s
reports and ``search.html``.

Exit codes: 1 a failure was found, 0 none within the budget and every run judged, 3
none found but some runs ended in error or timeout (their points say nothing: the
summary names them), 2 bad input (a damaged journal for ``--resume`` included, named
with its line; another command writing DIR), 130 / 143 interrupted (what finished is
kept and told; ``--resume`` goes on from there and ends as the uninterrupted search
would have).
"""

from __future__ import annotations

import argparse
import io
import json
import math
import shlex
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from suite.cli.common import (
    EXIT_FAIL,
    EXIT_OK,
    MEMORY_HELP,
    RAY_ADDRESS_HELP,
    Output,
    Plugins,
    UsageError,
    executor_flags,
    load_plugins,
    memory_cap_of,
    memory_mib,
    positive_int,
    positive_seconds,
    writing_to,
)

SETTINGS_JSON = "search.json"
JOURNAL = "search.journal"
SETTINGS_KEYS = ("catalog", "sampler", "seed", "jobs")
EXIT_UNJUDGED = 3  # no failure found, but some runs ended in error or timeout
UNJUDGED = ("error", "timeout")  # run statuses without a verdict


def _seed(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 0, got {text!r}") from None
    if not 0 <= value < 2 ** 31:
        raise argparse.ArgumentTypeError(f"expected a whole number in [0, 2**31), got {value}")
    return value


def _samplers(text: str) -> list[str]:
    from suite.search.samplers import SAMPLERS

    names = [t.strip() for t in text.split(",") if t.strip()]
    bad = [n for n in names if n not in SAMPLERS]
    if not names or bad:
        raise argparse.ArgumentTypeError(f"expected a comma-separated list of {SAMPLERS}, "
                                         f"got {text!r}")
    return names


def add_search_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The ``search`` sub-command's arguments."""
    from suite.search.samplers import SAMPLERS

    s = sub.add_parser("search", help="search a catalog's [scenario.search] spaces for "
                                      "failures (exit 1 when one is found)")
    s.add_argument("catalog")
    s.add_argument("--out", required=True, help="output directory (new or empty, unless "
                   "--resume or --overwrite)")
    s.add_argument("--budget", type=positive_int, required=True,
                   help="runs per family (refused points do not count; the shrinking of "
                        "what failed runs more, announced: --no-shrink skips it)")
    s.add_argument("--sampler", choices=SAMPLERS, default="tpe")
    s.add_argument("--seed", type=_seed, default=0)
    s.add_argument("--jobs", type=positive_int, default=1,
                   help="points asked and run together, in parallel (default 1); the "
                        "search is deterministic for a seed and --jobs")
    again = s.add_mutually_exclusive_group()
    again.add_argument("--resume", action="store_true",
                       help="continue the search in DIR (same sampler, seed and --jobs)")
    again.add_argument("--overwrite", action="store_true",
                       help="empty DIR (an earlier hwyeval output) first")
    s.add_argument("--no-log", action="store_true", help="do not write Rerun .rrd logs")
    s.add_argument("--timeout", type=positive_seconds, default=None, metavar="SECONDS",
                   help="wall-clock budget of every run (as run's)")
    s.add_argument("--executor", choices=["local", "ray"], default="local")
    s.add_argument("--ray-address", default=None, help=RAY_ADDRESS_HELP)
    s.add_argument("--max-memory-mb", type=memory_mib, default=None, metavar="MB",
                   help=MEMORY_HELP)
    s.add_argument("--no-shrink", action="store_true",
                   help="skip the line searches toward the nominal point")
    s.add_argument("--shrink-points", type=positive_int, default=4,
                   help="candidates per parameter of the line search (default 4)")
    s.add_argument("--compare", type=_samplers, default=None, metavar="S1,S2",
                   help="compare samplers instead: one search per sampler and seed "
                        "0..--seeds-1 into DIR/<sampler>_seed<k>, then the table")
    s.add_argument("--seeds", type=positive_int, default=5, help="seeds of --compare")
    s.add_argument("--plugin", action="append", default=[], metavar="MODULE",
                   help="a controller plug-in (as run's)")
    s.set_defaults(func=cmd_search)


@dataclass
class _Runs:
    """Dispatch of batches to the executor, as ``run`` dispatches a catalog; counts
    the runs' own wall time (for the overhead figure)."""

    out: Path
    catalog_stem: str
    args: argparse.Namespace
    plugins: Plugins
    executor: Any
    stop: Any
    text: Output
    label: str = ""
    done: int = 0
    total: int = 0
    run_wall_s: float = 0.0
    names: list[str] = field(default_factory=list)

    def on_done(self, record: Any) -> None:
        from reports.metrics.robustness import robustness

        self.done += 1
        rob = robustness(record.verdict) if record.verdict is not None else None
        rtext = f"robustness {rob.value:.4g} ({rob.criterion})" if rob is not None else ""
        self.text.line(f"[{self.label} {self.done}/{self.total}] {record.status.upper():7s} "
                       f"{record.info.scenario}  {rtext}")

    def __call__(self, scenarios: Sequence[Any]) -> list[Any] | None:
        from suite.cli.run import build_jobs
        from suite.exec.executors import record_in_memory
        from suite.exec.outdir import resume_plan

        jobs = build_jobs(list(scenarios), self.out, self.catalog_stem, self.args.no_log,
                          self.plugins, self.args.timeout, memory_cap_of(self.args))
        todo = resume_plan(jobs)
        for record in todo.kept:
            self.on_done(record)
        results = self.executor.run(list(todo.to_run), self.on_done, self.stop)
        if self.stop.requested:
            return None
        by_name = {r.info.scenario: r for r in [*todo.kept, *results]}
        records = []
        for job in jobs:
            record = by_name.get(job.name) or record_in_memory(job, "error", "no record")
            if record.run_dir is None:
                record.run_dir = job.run_dir
            w = record.outcome.wall_s
            self.run_wall_s += w if math.isfinite(w) else 0.0
            self.names.append(job.name)
            records.append(record)
        return records


def _settings(args: argparse.Namespace, sampler: str, seed: int) -> dict[str, Any]:
    return {"catalog": str(Path(args.catalog).resolve()), "sampler": sampler, "seed": seed,
            "jobs": args.jobs, "budget": args.budget}


def _plan(out: Path, args: argparse.Namespace, sampler: str, seed: int,
          families: Sequence[Any] = ()) -> Any:
    """The output plan; ``--resume`` needs DIR's search.json to match and its journal
    to be one the search wrote (checked against ``families``: JournalError, exit 2)."""
    from suite.exec.outdir import OutPlan, OutputDirError, check_out_dir, check_report_targets
    from suite.search.journal_check import check_journal

    if not args.resume:
        try:
            return check_out_dir(out, "overwrite" if args.overwrite else "fresh", [])
        except OutputDirError as exc:
            raise UsageError(str(exc)) from exc
    settings_path = out / SETTINGS_JSON
    if not settings_path.is_file():
        raise UsageError(f"--out {out}: no {SETTINGS_JSON} (not a search output): nothing "
                         "to resume")
    try:
        saved = json.loads(settings_path.read_text())
    except (OSError, ValueError) as exc:
        raise UsageError(f"{settings_path}: unreadable ({exc})") from exc
    now = _settings(args, sampler, seed)
    differ = [k for k in SETTINGS_KEYS if saved.get(k) != now[k]]
    if differ:
        raise UsageError(f"--resume {out}: {', '.join(differ)} differ from the search in it "
                         f"({', '.join(f'{k}={saved.get(k)!r}' for k in differ)}): pass "
                         "the same ones, or --overwrite")
    try:
        check_report_targets(out)
    except OutputDirError as exc:
        raise UsageError(str(exc)) from exc
    check_journal(out / JOURNAL, families)
    return OutPlan(out, "resume")


def resume_command(args: argparse.Namespace) -> str:
    parts = ["hwyeval", "search", str(args.catalog), "--out", str(args.out), "--budget",
             str(args.budget), "--sampler", args.sampler, "--seed", str(args.seed),
             "--jobs", str(args.jobs), "--resume"]
    for flag in ("no_log", "no_shrink"):
        if getattr(args, flag):
            parts.append("--" + flag.replace("_", "-"))
    if args.shrink_points != 4:
        parts += ["--shrink-points", str(args.shrink_points)]
    return shlex.join(parts + executor_flags(args))


@dataclass
class SearchOutput:
    """What one search did: per family its result and shrink, whether stopped."""

    results: list[Any] = field(default_factory=list)
    shrinks: dict[str, tuple[list[Any], list[Any]]] = field(default_factory=dict)
    stopped: bool = False
    wall_s: float = 0.0
    run_wall_s: float = 0.0
    workers: int = 1

    @property
    def n_runs(self) -> int:
        """Every run: the searches' and the shrinking's."""
        return (sum(len(fr.runs) for fr in self.results)
                + sum(len(tried) for _, tried in self.shrinks.values()))

    @property
    def overhead_per_run_s(self) -> float:
        """Worker time not spent inside a run, per run [s], >= 0: (wall x workers - the
        runs' own wall time) / runs. The runs overlap on ``workers`` processes, so their
        own times summed exceed the wall time with 2 or more; clamped at 0 where the
        clocks disagree by a hair."""
        n = max(self.n_runs, 1)
        return max(0.0, self.wall_s * self.workers - self.run_wall_s) / n

    @property
    def failed(self) -> bool:
        return any(r.failures for r in self.results)


def search_into(args: argparse.Namespace, cat: Any, plugins: Plugins, out: Path, executor: Any,
                stop: Any, text: Output, *, sampler: str, seed: int, shrink: bool
                ) -> SearchOutput:
    """Run every family's search into ``out`` (prepared), then shrink (``shrink``) and
    write found.toml and search.csv."""
    from suite.search.found import write_found, write_search
    from suite.search.loop import SearchSettings, open_storage, search_family
    from suite.search.shrink import Shrunk, start_points

    t0 = time.perf_counter()
    (out / SETTINGS_JSON).write_text(json.dumps(_settings(args, sampler, seed), indent=1))
    settings = SearchSettings(budget_runs=args.budget, sampler=sampler, seed=seed,
                              batch_size=args.jobs)
    storage, journal = open_storage(str(out / JOURNAL))
    runs = _Runs(out, Path(args.catalog).stem, args, plugins, executor, stop, text)
    result = SearchOutput()
    for index, family in enumerate(cat.families):
        runs.label, runs.done, runs.total = family.name, 0, args.budget

        def on_batch(fr: Any) -> None:
            best = fr.best()
            text.line(f"  {fr.family.name}: {len(fr.runs)}/{args.budget} runs, "
                      f"{len(fr.failures)} failed, {fr.refused} refused; best robustness "
                      + (f"{best.robustness:.4g} ({best.criterion}, {best.run})" if best
                         else "–"))

        fr = search_family(family, index, settings, storage, runs, stop, on_batch, journal)
        runs.done = len(fr.runs)
        result.results.append(fr)
        if fr.stopped:
            result.stopped = True
            break
    if not result.stopped and shrink:
        _shrink_all(args, result, runs, text)
    elif not result.stopped:
        for fr in result.results:
            if fr.failures:
                starts = start_points(fr.family, fr.failures)
                result.shrinks[fr.family.name] = (
                    [Shrunk(m, t, t) for m, t in starts.items()], [])
    write_search(result.results, result.shrinks, out)
    if not result.stopped:
        found = [(fr.family, c) for fr in result.results
                 for c in result.shrinks.get(fr.family.name, ([], []))[0]]
        write_found(found, out)
    result.wall_s = time.perf_counter() - t0
    result.run_wall_s = runs.run_wall_s
    result.workers = max(1, int(args.jobs))
    return result


def _shrink_all(args: argparse.Namespace, result: SearchOutput, runs: _Runs,
                text: Output) -> None:
    """Shrink each family's failures (:mod:`suite.search.shrink`), each announced with
    the runs it may take beside the budget; stops the search when interrupted."""
    from suite.search.shrink import shrink_bound, shrink_failures, start_points

    for fr in result.results:
        if not fr.failures:
            continue
        text.line(f"shrinking {fr.family.name}: {len(start_points(fr.family, fr.failures))} "
                  f"failure mode(s), at most "
                  f"{shrink_bound(fr.family, fr.failures, args.shrink_points)} more runs "
                  f"beside the budget of {args.budget} (--no-shrink skips them)")
        runs.label, runs.done, runs.total = f"{fr.family.name} shrink", 0, 0
        cases, tried, ok = shrink_failures(fr.family, fr.failures, _Counting(runs),
                                           points=args.shrink_points)
        result.shrinks[fr.family.name] = (cases, tried)
        if not ok:
            result.stopped = True
            return


class _Counting:
    """A batch runner whose progress total grows with each batch (the line searches)."""

    def __init__(self, runs: _Runs) -> None:
        self.runs = runs

    def __call__(self, scenarios: Sequence[Any]) -> list[Any] | None:
        self.runs.total += len(scenarios)
        return self.runs(scenarios)


def _summary(text: Output, res: SearchOutput, out: Path) -> None:
    for fr in res.results:
        best = fr.best()
        modes = sorted({t.mode for t in fr.failures})
        shrunk = len(res.shrinks.get(fr.family.name, ([], []))[1])
        text.line(f"{fr.family.name}: {len(fr.runs)} runs"
                  + (f" + {shrunk} shrinking runs beside the budget" if shrunk else "")
                  + f", {fr.refused} refused, {len(fr.failures)} failed in {len(modes)} mode(s)"
                  + (f": {', '.join(modes)}" if modes else "")
                  + (f"; best robustness {best.robustness:.4g} ({best.criterion}, {best.run})"
                     if best else ""))
        n = max(len(fr.trials), 1)
        text.line(f"  search overhead outside the runs: {1e3 * fr.overhead_s / n:.1f} ms per "
                  f"trial ({n} trials)")
    text.line(f"wall {res.wall_s:.1f} s for {res.n_runs} runs on {res.workers} worker(s), the "
              f"runs' own {res.run_wall_s:.1f} s: {1e3 * res.overhead_per_run_s:.0f} ms per run "
              "beyond the run (process start, files, the search)")


def _write_reports(out: Path, text: Output) -> None:
    from reports.html.search import write_search_page
    from suite.cli.run import _write_reports as write_run_reports

    paths = write_run_reports(out)
    page = write_search_page(out)
    if paths is not None:
        text.line(f"report:  {paths.report_html}\nresults: {paths.results_csv}")
    text.line(f"search:  {page}\n         {out / 'search.csv'}")


def unjudged(res: SearchOutput) -> list[Any]:
    """The runs of a search (its trials and line searches) that ended in error or
    timeout: they have no verdict, so their points say nothing."""
    tried = [t for _, extra in res.shrinks.values() for t in extra]
    return [t for fr in res.results for t in fr.trials if t.status in UNJUDGED] + \
        [t for t in tried if t.status in UNJUDGED]


def _why(out: Path, run: str) -> str:
    """The last line of a run's error, from its run.json ('' when unreadable)."""
    from reports.record.run import read_run_json

    try:
        _, outcome, _ = read_run_json(out / run)
    except Exception:  # noqa: BLE001 - the name and status still say which run
        return ""
    lines = [line for line in (outcome.error or "").splitlines() if line.strip()]
    return lines[-1].strip()[:200] if lines else ""


def verdict_lines(res: SearchOutput, out: Path) -> tuple[int, list[str]]:
    """The exit code of a finished search and the lines that end its output: the runs
    without a verdict (at most 5 named, with why) and what the code means."""
    bad = unjudged(res)
    lines = []
    if bad:
        lines.append(f"NOT JUDGED  {len(bad)} of {res.n_runs} runs ended in error or timeout "
                     "(no verdict: the search learnt nothing there):")
        lines += [f"  {t.status.upper():7s} {t.run}: {_why(out, t.run)}" for t in bad[:5]]
        if len(bad) > 5:
            lines.append(f"  ... and {len(bad) - 5} more (search.csv, report.html)")
    if res.failed:
        return EXIT_FAIL, [*lines, "exit 1: a failure was found (found.toml)"]
    if bad:
        return EXIT_UNJUDGED, [*lines, f"exit 3: no failure found, but {len(bad)} run(s) "
                               "had no verdict: the search is not conclusive (see above)"]
    return EXIT_OK, [*lines, "exit 0: no failure found within the budget"]


def cmd_search(args: argparse.Namespace) -> int:
    """The search under DIR's lock (suite.exec.out_lock): another command writing DIR
    (or a link to it) is refused (exit 2) before anything is read or written."""
    from suite.search.journal import JournalError

    with writing_to(Path(args.out)):
        try:
            return _search(args)
        except JournalError as exc:  # --resume of a damaged journal: bad input
            raise UsageError(str(exc)) from exc


def _search(args: argparse.Namespace) -> int:
    from reports.manifest import write_manifest
    from suite.catalog import load_catalog
    from suite.cli.run import make_executor, start_manifest
    from suite.exec.outdir import prepare_out_dir
    from suite.exec.signals import stop_on_signals
    from suite.search.space import load_search_catalog

    text = Output()
    plugins = load_plugins(args.plugin)
    cat = load_search_catalog(args.catalog)
    memory_cap_of(args)  # a bad HWYEVAL_MAX_MEMORY_MB is bad input, before anything runs
    if args.compare:
        return _compare(args, cat, plugins, text)
    out = Path(args.out)
    plan = _plan(out, args, args.sampler, args.seed, cat.families)
    executor, workers = make_executor(args, args.jobs)
    nominal = list(load_catalog(args.catalog).scenarios)
    with stop_on_signals() as stop:
        prepare_out_dir(plan)
        manifest = start_manifest(args, nominal, workers, plugins)
        write_manifest(out, manifest)
        text.line(f"search {args.catalog}: {len(cat.families)} famil"
                  f"{'y' if len(cat.families) == 1 else 'ies'} "
                  f"({', '.join(f.name for f in cat.families)}), {args.budget} runs each, "
                  f"sampler {args.sampler}, seed {args.seed}, {args.jobs} at a time → {out}"
                  + (f"; without a search table (not searched): {', '.join(cat.skipped)}"
                     if cat.skipped else ""))
        res = search_into(args, cat, plugins, out, executor, stop, text, sampler=args.sampler,
                          seed=args.seed, shrink=not args.no_shrink)
        names = tuple(d.name for d in sorted(out.iterdir()) if (d / "run.json").is_file())
        manifest = replace(manifest, scenarios=names)
        write_manifest(out, manifest)
        _write_reports(out, text)
    if res.stopped:
        text.line(f"interrupted; resume with: {resume_command(args)}")
        return int(stop.exit_code)
    write_manifest(out, manifest.finish())
    _summary(text, res, out)
    text.line(f"found:   {out / 'found.toml'}")
    code, lines = verdict_lines(res, out)
    for line in lines:
        text.line(line)
    return code


def _compare(args: argparse.Namespace, cat: Any, plugins: Plugins, text: Output) -> int:
    from suite.cli.run import make_executor
    from suite.exec.outdir import OutPlan, prepare_out_dir
    from suite.exec.signals import stop_on_signals
    from suite.search.compare import compare_rows, compare_table, outcome_of

    out = Path(args.out)
    if args.resume:
        raise UsageError("--compare runs fresh searches: --resume does not apply")
    plan = _plan(out, args, "compare", 0)
    executor, _ = make_executor(args, args.jobs)
    outcomes = []
    not_judged = 0
    with stop_on_signals() as stop:
        prepare_out_dir(plan)
        (out / "manifest.json").write_text("{}")  # marks DIR as an hwyeval output
        for sampler in args.compare:
            for seed in range(args.seeds):
                sub = out / f"{sampler}_seed{seed}"
                prepare_out_dir(OutPlan(sub, "fresh"))
                quiet = Output(io.StringIO())
                res = search_into(args, cat, plugins, sub, executor, stop, quiet,
                                  sampler=sampler, seed=seed, shrink=False)
                if res.stopped:
                    text.line("interrupted")
                    return int(stop.exit_code)
                not_judged += len(unjudged(res))
                for fr in res.results:
                    o = outcome_of(fr, sampler, seed, args.budget)
                    outcomes.append(o)
                    text.line(f"{fr.family.name} {sampler} seed {seed}: first failure at run "
                              f"{o.first_failure_run if o.found else '>' + str(args.budget)}"
                              f", {len(o.modes)} mode(s), {o.failed_runs}/{o.runs} failed "
                              f"({res.wall_s:.0f} s)")
    table = compare_table(compare_rows(outcomes), args.budget)
    (out / "compare.md").write_text(table + "\n")
    text.line(table)
    if not_judged:
        text.line(f"exit 3: {not_judged} run(s) ended in error or timeout (no verdict): the "
                  "table counts them as runs without a failure; see each search's summary")
        return EXIT_UNJUDGED
    return EXIT_OK
