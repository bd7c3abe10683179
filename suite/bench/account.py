"""Where a ``--jobs 1`` command's wall time goes, every part of it (issue 25).

From one :class:`suite.bench.command.CommandTiming`: the command's own output lines,
stamped as they arrived, and its files' modification times, all on the bench's wall
clock. In order along the command's life:

1. ``to_first_line_s``: process start to the command's first line: the interpreter, the
   CLI's imports, the catalog's validation, the jobs with their code hashes, the
   manifest (the forkserver's preload runs beside this, started first);
2. ``to_first_run_s``: that line to the first run's start: what of the forkserver's
   preload (imports, numba kernels) is left to wait for, and the first fork;
3. per run, from its start to its run.json: ``runs_wall_s``, the runs' own results.csv
   ``wall_s`` summed (building and the loop, until SUMO's close), then after it
   ``runs_log_s`` (the Rerun log: run.json's ``log_s``) and ``runs_after_loop_s`` (the
   rest: judging, the parquet/npz/json files, run.json);
4. ``between_runs_s``: from one run's run.json to the next run's start: the result sent
   back to the parent, its progress line, the next fork, the next run before its clock;
5. ``reports_s``: the last run.json to the manifest's last write: the last result back,
   the reports (run pages, report.html, results.csv, summary.csv, junit.xml), the
   manifest;
6. ``exit_s``: the manifest to the end of the process: the summary lines, the exit.

The parts add up to the command by construction; each boundary is an event measured
on its own (a line's arrival, a file's time), so no part is a remainder of the others,
except that a run's start is its loop's end minus its ``wall_s``. File times have the
kernel's granularity (~4 ms).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from suite.bench.command import CommandTiming

__all__ = ["WallAccount", "account"]


@dataclass(frozen=True)
class WallAccount:
    """A ``--jobs 1`` command's wall time in parts [s] (module docstring)."""

    command_s: float
    runs: int
    to_first_line_s: float
    to_first_run_s: float
    runs_wall_s: float
    runs_log_s: float
    runs_after_loop_s: float
    between_runs_s: float
    reports_s: float
    exit_s: float

    def __post_init__(self) -> None:
        if not self.command_s > 0:
            raise ValueError(f"command_s must be > 0, got {self.command_s}")
        if self.runs < 1:
            raise ValueError(f"runs must be >= 1, got {self.runs}")
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name.endswith("_s") and not math.isfinite(value):
                raise ValueError(f"{f.name} must be finite, got {value}")

    @property
    def parts_s(self) -> tuple[tuple[str, float], ...]:
        """(what, seconds) of every part, in the command's order."""
        return (("process start -> first line (interpreter, imports, catalog, jobs, manifest)",
                 self.to_first_line_s),
                ("first line -> first run (the forkserver's preload left to wait for, the "
                 "fork)", self.to_first_run_s),
                ("the runs' own wall_s (build and loop, results.csv)", self.runs_wall_s),
                ("the runs' Rerun logs (log_s)", self.runs_log_s),
                ("the runs' judging, files and run.json", self.runs_after_loop_s),
                ("between runs (result to the parent, its line, the next fork)",
                 self.between_runs_s),
                ("last run.json -> reports and manifest written", self.reports_s),
                ("manifest -> end of the process (summary, exit)", self.exit_s))

    @property
    def accounted_s(self) -> float:
        return sum(v for _, v in self.parts_s)

    @property
    def unaccounted_s(self) -> float:
        return self.command_s - self.accounted_s

    @property
    def outside_runs_wall_s(self) -> float:
        """The command's time outside its runs' own ``wall_s``."""
        return self.command_s - self.runs_wall_s


def account(timing: CommandTiming) -> WallAccount:
    """The parts of a ``--jobs 1`` command with at least one run (ValueError otherwise:
    with more workers the runs overlap and their times do not add up to the command)."""
    if timing.jobs != 1:
        raise ValueError(f"the wall-time account is of --jobs 1 commands, got --jobs {timing.jobs}")
    runs = sorted(timing.runs, key=lambda r: r.start_epoch_s)
    if not runs or any(not math.isfinite(r.span_s) for r in runs):
        raise ValueError("the command has no run with known start and end times")
    t0 = timing.start_epoch_s
    first_line = timing.lines[0].at_s if timing.lines else 0.0
    first_start, last_end = runs[0].start_epoch_s - t0, runs[-1].end_epoch_s - t0
    end = timing.wall_s
    manifest = timing.manifest_epoch_s - t0 if math.isfinite(timing.manifest_epoch_s) else end
    log = sum(r.log_s for r in runs if math.isfinite(r.log_s))
    spans = sum(r.span_s for r in runs)
    wall = sum(r.wall_s for r in runs)
    return WallAccount(
        command_s=end, runs=len(runs), to_first_line_s=first_line,
        to_first_run_s=first_start - first_line, runs_wall_s=wall, runs_log_s=log,
        runs_after_loop_s=spans - wall - log, between_runs_s=(last_end - first_start) - spans,
        reports_s=manifest - last_end, exit_s=end - manifest)
