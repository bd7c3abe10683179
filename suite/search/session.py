"""One search into a prepared output: its options (:class:`SearchOptions`), its batches
on the executor (built by the run layer's :func:`~suite.exec.build.build_jobs`, as a
catalog run builds its jobs), the families' ask-and-tell loops (:mod:`suite.search.loop`),
the shrinking (:mod:`suite.search.shrink`) and the files it hands over (``search.json``,
the journal, ``found.toml`` and ``search.csv``: :mod:`suite.search.found`).

:func:`suite.search.run.run_search` runs it as a command; the output's plan
(:func:`plan_out`) checks a resumed search's settings and journal first.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from reports.record import RunRecord
from suite.catalog import Scenario
from suite.exec.build import RunSettings, build_jobs
from suite.exec.command import OUT_MODES, Plugins, Printer, UsageError
from suite.exec.jobs import Executor, RunJob
from suite.exec.outdir import OutPlan
from suite.exec.signals import StopRequest
from suite.search.loop import FamilyResult
from suite.search.outcome import SearchOutput
from suite.search.space import Family, SearchCatalog

__all__ = ["JOURNAL", "SETTINGS_JSON", "SearchOptions", "Where", "plan_out",
           "search_into"]

SETTINGS_JSON = "search.json"
JOURNAL = "search.journal"
SETTINGS_KEYS = ("catalog", "sampler", "seed", "jobs")


def _one_search_settings() -> RunSettings:
    return RunSettings(jobs=1)


@dataclass(frozen=True)
class SearchOptions:
    """What to search and how. ``catalog`` and ``out`` as given (printed and repeated by
    the resume command); ``budget``: runs per family; ``settings.jobs``: points asked and
    run together (>= 1: the search is deterministic for a seed and jobs); ``mode``:
    fresh, resume or overwrite; ``shrink``: the line searches toward the nominal point,
    ``shrink_points`` candidates per parameter; ``compare``: samplers to compare instead,
    each with seeds ``0..seeds-1`` (empty: one search)."""

    catalog: str
    out: str
    budget: int
    settings: RunSettings = field(default_factory=_one_search_settings)
    sampler: str = "tpe"
    seed: int = 0
    mode: str = "fresh"
    shrink: bool = True
    shrink_points: int = 4
    compare: tuple[str, ...] = ()
    seeds: int = 5

    def __post_init__(self) -> None:
        from suite.search.samplers import SAMPLERS

        if not self.catalog or not self.out:
            raise ValueError("SearchOptions: catalog and out must be non-empty paths")
        for name in ("budget", "shrink_points", "seeds"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"SearchOptions.{name}: expected a whole number >= 1, got "
                                 f"{value!r}")
        if self.settings.jobs < 1:
            raise ValueError(f"SearchOptions.settings.jobs: expected >= 1, got "
                             f"{self.settings.jobs}")
        if not 0 <= self.seed < 2 ** 31:
            raise ValueError(f"SearchOptions.seed: expected [0, 2**31), got {self.seed}")
        if self.mode not in OUT_MODES:
            raise ValueError(f"SearchOptions.mode: expected one of {OUT_MODES}, got {self.mode!r}")
        bad = [s for s in (self.sampler, *self.compare) if s not in SAMPLERS]
        if bad:
            raise ValueError(f"SearchOptions: unknown sampler(s) {bad}; expected {SAMPLERS}")

    @property
    def jobs(self) -> int:
        return self.settings.jobs


@dataclass
class _Runs:
    """Dispatch of batches to the executor, as a catalog run dispatches a catalog; counts
    the runs' own wall time (for the overhead figure)."""

    out: Path
    catalog_stem: str
    settings: RunSettings
    plugins: Plugins
    executor: Executor
    stop: StopRequest
    text: Printer
    label: str = ""
    done: int = 0
    total: int = 0
    run_wall_s: float = 0.0
    names: list[str] = field(default_factory=list)

    def on_done(self, record: RunRecord) -> None:
        from reports.metrics.robustness import robustness

        self.done += 1
        rob = robustness(record.verdict) if record.verdict is not None else None
        rtext = f"robustness {rob.value:.4g} ({rob.criterion})" if rob is not None else ""
        self.text.line(f"[{self.label} {self.done}/{self.total}] {record.status.upper():7s} "
                       f"{record.info.scenario}  {rtext}")

    def __call__(self, scenarios: Sequence[Scenario]) -> list[RunRecord] | None:
        from suite.exec.outdir import resume_plan

        s = self.settings
        jobs = build_jobs(list(scenarios), self.out, self.catalog_stem, s.no_log, self.plugins,
                          s.timeout_s, s.memory_cap())
        todo = resume_plan(jobs)
        for record in todo.kept:
            self.on_done(record)
        results = self.executor.run(list(todo.to_run), self.on_done, self.stop)
        if self.stop.requested:
            return None
        by_name = {r.info.scenario: r for r in [*todo.kept, *results]}
        return [self._counted(job, by_name.get(job.name)) for job in jobs]

    def _counted(self, job: RunJob, record: RunRecord | None) -> RunRecord:
        """The job's record (an error record when the executor returned none), its run
        directory set, its wall time counted."""
        from suite.exec.jobs import record_in_memory

        record = record or record_in_memory(job, "error", "no record")
        if record.run_dir is None:
            record.run_dir = job.run_dir
        w = record.outcome.wall_s
        self.run_wall_s += w if math.isfinite(w) else 0.0
        self.names.append(job.name)
        return record


def _settings(options: SearchOptions, sampler: str, seed: int) -> dict[str, Any]:
    return {"catalog": str(Path(options.catalog).resolve()), "sampler": sampler, "seed": seed,
            "jobs": options.jobs, "budget": options.budget}


def plan_out(options: SearchOptions, sampler: str, seed: int,
          families: Sequence[Family] = ()) -> OutPlan:
    """The output plan; ``resume`` needs the output's search.json to match and its
    journal to be one the search wrote (checked against ``families``: JournalError)."""
    from suite.exec.outdir import OutputDirError, check_out_dir

    out = Path(options.out)
    if options.mode != "resume":
        try:
            return check_out_dir(out, options.mode, [])
        except OutputDirError as exc:
            raise UsageError(str(exc)) from exc
    _check_resume(options, sampler, seed, families)
    return OutPlan(out, "resume")


def _check_resume(options: SearchOptions, sampler: str, seed: int,
                  families: Sequence[Family]) -> None:
    from suite.exec.outdir import OutputDirError, check_report_targets
    from suite.search.journal_check import check_journal

    out = Path(options.out)
    settings_path = out / SETTINGS_JSON
    if not settings_path.is_file():
        raise UsageError(f"--out {out}: no {SETTINGS_JSON} (not a search output): nothing "
                         "to resume")
    try:
        saved = json.loads(settings_path.read_text())
    except (OSError, ValueError) as exc:
        raise UsageError(f"{settings_path}: unreadable ({exc})") from exc
    now = _settings(options, sampler, seed)
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


@dataclass(frozen=True)
class Where:
    """Where a search runs: its output (prepared), the executor and the stop request."""

    out: Path
    executor: Executor
    stop: StopRequest
    text: Printer


def search_into(options: SearchOptions, cat: SearchCatalog, plugins: Plugins, where: Where,
                *, sampler: str, seed: int, shrink: bool) -> SearchOutput:
    """Run every family's search into ``where.out`` (prepared), then shrink (``shrink``)
    and write found.toml and search.csv."""
    from dataclasses import replace

    from suite.search.found import write_found, write_search
    from suite.search.logical import TRIALS_DIR
    from suite.search.loop import open_storage

    t0 = time.perf_counter()
    out = where.out
    # a logical scenario's points are imported under the output (suite.search.logical)
    cat = replace(cat, families=tuple(f.at(out / TRIALS_DIR) for f in cat.families))
    (out / SETTINGS_JSON).write_text(json.dumps(_settings(options, sampler, seed), indent=1))
    storage, journal = open_storage(str(out / JOURNAL))
    runs = _Runs(out, Path(options.catalog).stem, options.settings, plugins, where.executor,
                 where.stop, where.text)
    result = SearchOutput()
    _search_families(options, cat, runs, result, (storage, journal), sampler, seed)
    if not result.stopped and shrink:
        _shrink_all(options, result, runs)
    elif not result.stopped:
        _start_points(result)
    write_search(result.results, result.shrinks, out)
    if not result.stopped:
        write_found([(fr.family, c) for fr in result.results
                     for c in result.shrinks.get(fr.family.name, ([], []))[0]], out)
    result.wall_s = time.perf_counter() - t0
    result.run_wall_s = runs.run_wall_s
    result.workers = max(1, options.jobs)
    return result


def _search_families(options: SearchOptions, cat: SearchCatalog, runs: _Runs,
                     result: SearchOutput, store: tuple[Any, Any], sampler: str,
                     seed: int) -> None:
    """Each family's ask-and-tell loop, in catalog order, until one is stopped."""
    from suite.search.loop import SearchSettings, search_family

    settings = SearchSettings(budget_runs=options.budget, sampler=sampler, seed=seed,
                              batch_size=options.jobs)
    storage, journal = store

    def on_batch(fr: FamilyResult) -> None:
        best = fr.best()
        runs.text.line(f"  {fr.family.name}: {len(fr.runs)}/{options.budget} runs, "
                       f"{len(fr.failures)} failed, {fr.refused} refused; best robustness "
                       + (f"{best.robustness:.4g} ({best.criterion}, {best.run})" if best
                          else "–"))

    for index, family in enumerate(cat.families):
        runs.label, runs.done, runs.total = family.name, 0, options.budget
        fr = search_family(family, index, settings, storage, runs, runs.stop, on_batch,
                           journal)
        runs.done = len(fr.runs)
        result.results.append(fr)
        if fr.stopped:
            result.stopped = True
            return


def _start_points(result: SearchOutput) -> None:
    """Without the shrinking: each failure mode's first failure, unshrunk."""
    from suite.search.shrink import Shrunk, start_points

    for fr in result.results:
        if fr.failures:
            starts = start_points(fr.family, fr.failures)
            result.shrinks[fr.family.name] = ([Shrunk(m, t, t) for m, t in starts.items()], [])


def _shrink_all(options: SearchOptions, result: SearchOutput, runs: _Runs) -> None:
    """Shrink each family's failures (:mod:`suite.search.shrink`), each announced with
    the runs it may take beside the budget; stops the search when interrupted."""
    from suite.search.shrink import shrink_bound, shrink_failures, start_points

    for fr in result.results:
        if not fr.failures:
            continue
        runs.text.line(f"shrinking {fr.family.name}: "
                       f"{len(start_points(fr.family, fr.failures))} failure mode(s), at most "
                       f"{shrink_bound(fr.family, fr.failures, options.shrink_points)} more "
                       f"runs beside the budget of {options.budget} (--no-shrink skips them)")
        runs.label, runs.done, runs.total = f"{fr.family.name} shrink", 0, 0
        cases, tried, ok = shrink_failures(fr.family, fr.failures, _Counting(runs),
                                           points=options.shrink_points)
        result.shrinks[fr.family.name] = (cases, tried)
        if not ok:
            result.stopped = True
            return


class _Counting:
    """A batch runner whose progress total grows with each batch (the line searches)."""

    def __init__(self, runs: _Runs) -> None:
        self.runs = runs

    def __call__(self, scenarios: Sequence[Scenario]) -> list[RunRecord] | None:
        self.runs.total += len(scenarios)
        return self.runs(scenarios)
