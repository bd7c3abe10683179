"""What one search did (:class:`SearchOutput`) and how it ends: the summary lines, the
runs without a verdict and the exit code (:func:`verdict_lines`).

Exit codes: 1 a failure was found, 0 none within the budget and every run judged, 3
none found but some runs ended in error or timeout (their points say nothing: the
summary names them).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from suite.exec.command import EXIT_FAIL, EXIT_OK
from suite.search.loop import FamilyResult, TrialResult
from suite.search.shrink import Shrunk

__all__ = ["EXIT_UNJUDGED", "UNJUDGED", "SearchOutput", "summary_lines", "unjudged",
           "verdict_lines"]

EXIT_UNJUDGED = 3  # no failure found, but some runs ended in error or timeout
UNJUDGED = ("error", "timeout")  # run statuses without a verdict


@dataclass
class SearchOutput:
    """What one search did: per family its result and shrink, whether stopped."""

    results: list[FamilyResult] = field(default_factory=list)
    shrinks: dict[str, tuple[list[Shrunk], list[TrialResult]]] = field(default_factory=dict)
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


def summary_lines(res: SearchOutput) -> list[str]:
    """Per family its runs, failures, modes and best robustness, and the search's
    overhead; then the wall time and the overhead per run."""
    lines = []
    for fr in res.results:
        best = fr.best()
        modes = sorted({t.mode for t in fr.failures})
        shrunk = len(res.shrinks.get(fr.family.name, ([], []))[1])
        lines.append(f"{fr.family.name}: {len(fr.runs)} runs"
                     + (f" + {shrunk} shrinking runs beside the budget" if shrunk else "")
                     + f", {fr.refused} refused, {len(fr.failures)} failed in {len(modes)} "
                     f"mode(s)" + (f": {', '.join(modes)}" if modes else "")
                     + (f"; best robustness {best.robustness:.4g} ({best.criterion}, "
                        f"{best.run})" if best else ""))
        n = max(len(fr.trials), 1)
        lines.append(f"  search overhead outside the runs: {1e3 * fr.overhead_s / n:.1f} ms "
                     f"per trial ({n} trials)")
    lines.append(f"wall {res.wall_s:.1f} s for {res.n_runs} runs on {res.workers} worker(s), "
                 f"the runs' own {res.run_wall_s:.1f} s: {1e3 * res.overhead_per_run_s:.0f} ms "
                 "per run beyond the run (process start, files, the search)")
    return lines


def unjudged(res: SearchOutput) -> list[TrialResult]:
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
