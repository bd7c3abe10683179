"""The output directory of ``hwyeval run``: what may be written where, and ``--resume``.

Rules (checked by :func:`check_out_dir` before anything is written; a violation is an
:class:`OutputDirError`, exit 2, and the directory is left as it was):

* ``--out`` must be a directory or not exist yet, and no part of its path a file.
* Without ``--resume`` or ``--overwrite`` it must be empty (or not exist): re-running
  into an earlier output would mix its runs into the reports.
* ``--overwrite`` empties it first, but only if it looks like an hwyeval output (a
  ``manifest.json``, or nothing but run directories and report files): a mistyped
  ``--out $HOME`` is refused, not wiped.
* ``--resume`` keeps every run finished with a verdict (pass or fail) whose scenario has
  the same content hash (:func:`suite.run.info.scenario_content_sha256`), whose record
  was written by the same hwyeval version and sources and the same plug-in controller
  source (:mod:`suite.run.code_identity`), and that :func:`reports.record.load_run` (the
  one reader of run directories) reads: every file run.json lists there with its
  checksum; it runs the others (the terminal says which and why); their old
  directories (an error, a timeout, another scenario content, a symbolic link) are
  removed first. A run directory of a scenario that is not among those to run is
  refused: the reports must cover exactly the runs of this manifest.
* The report files (``results.csv``, ``summary.csv``, ``junit.xml``, ``report.html``,
  ``manifest.json``, ``report-runs/``) must be regular files (a directory) if present.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from reports.record import RunRecord, iter_run_dirs, load_run
from reports.record.run import (
    STAGING_PREFIX,
    TRASH_PREFIX,
    discard_staging,
    remove_path,
)
from suite import __version__
from suite.exec.command import OUT_MODES
from suite.exec.jobs import RunJob
from suite.run.code_identity import CODE_KEY, CONTROLLER_KEY
from suite.run.info import CONTENT_KEY

__all__ = ["MODES", "REPORT_DIRS", "REPORT_FILES", "OutPlan", "OutputDirError", "ResumePlan",
           "check_out_dir", "check_report_targets", "prepare_out_dir", "resume_plan"]

MODES = OUT_MODES
REPORT_FILES = ("manifest.json", "results.csv", "summary.csv", "junit.xml", "report.html")
REPORT_DIRS = ("report-runs",)
FINISHED = ("pass", "fail")  # statuses --resume keeps


class OutputDirError(ValueError):
    """The output directory cannot be used as asked (the message says why and what to do)."""


@dataclass(frozen=True)
class OutPlan:
    """What :func:`prepare_out_dir` will do: ``out`` the directory, ``mode`` one of
    :data:`MODES`, ``clear`` whether it empties a non-empty directory (``--overwrite``)."""

    out: Path
    mode: str
    clear: bool = False

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"OutPlan.mode: expected one of {MODES}, got {self.mode!r}")
        object.__setattr__(self, "out", Path(self.out))


def _check_path(out: Path) -> None:
    if out.is_symlink() and not out.exists():
        raise OutputDirError(f"--out {out}: a symbolic link to nothing")
    if out.exists():
        if not out.is_dir():
            raise OutputDirError(f"--out {out}: exists and is not a directory")
        if not os.access(out, os.W_OK | os.X_OK):
            raise OutputDirError(f"--out {out}: not writable")
        return
    for parent in out.absolute().parents:
        if parent.exists():
            if not parent.is_dir():
                raise OutputDirError(f"--out {out}: {parent} is a file, not a directory")
            if not os.access(parent, os.W_OK | os.X_OK):
                raise OutputDirError(f"--out {out}: cannot create it in {parent} (not writable)")
            return


def check_report_targets(out: Path) -> None:
    """The report files of ``out`` are regular files (``report-runs`` a directory) or
    absent; OutputDirError naming the first that is not (nothing is written)."""
    for name in REPORT_FILES:
        path = out / name
        if (path.is_symlink() or path.exists()) and (path.is_symlink() or not path.is_file()):
            raise OutputDirError(f"{path}: hwyeval writes a report file there, but it is "
                                 f"{_kind(path)}; move it away")
    for name in REPORT_DIRS:
        path = out / name
        if (path.is_symlink() or path.exists()) and (path.is_symlink() or not path.is_dir()):
            raise OutputDirError(f"{path}: hwyeval writes its run pages there, but it is "
                                 f"{_kind(path)}; move it away")


def _kind(path: Path) -> str:
    if path.is_symlink():
        return "a symbolic link"
    return "a directory" if path.is_dir() else "not a regular file"


def _looks_like_output(out: Path) -> bool:
    """Whether every entry of ``out`` is something hwyeval writes."""
    if (out / "manifest.json").is_file():
        return True
    runs = {d.name for d in iter_run_dirs(out)}
    for child in out.iterdir():
        name = child.name
        if name in runs or name in REPORT_FILES or name in REPORT_DIRS \
                or name.startswith((STAGING_PREFIX, TRASH_PREFIX)):
            continue
        return False
    return True


def check_out_dir(out: Path, mode: str, names: Sequence[str]) -> OutPlan:
    """Check ``out`` for a run of the scenarios ``names`` in ``mode`` (module doc);
    nothing is written. Raises OutputDirError."""
    out = Path(out)
    if mode not in MODES:
        raise ValueError(f"mode: expected one of {MODES}, got {mode!r}")
    _check_path(out)
    if not out.exists() or not any(out.iterdir()):
        return OutPlan(out, mode)
    if mode == "fresh":
        raise OutputDirError(f"--out {out}: not empty (an earlier run?); pass --resume to "
                             "finish it, --overwrite to replace it, or choose another --out")
    if mode == "overwrite":
        if not _looks_like_output(out):
            raise OutputDirError(f"--out {out}: not empty and not an hwyeval output (no "
                                 "manifest.json); refusing to delete it with --overwrite: "
                                 "choose another --out or empty it yourself")
        return OutPlan(out, mode, clear=True)
    check_report_targets(out)
    wanted = set(names)
    foreign = [d.name for d in iter_run_dirs(out) if d.name not in wanted]
    if foreign:
        shown = ", ".join(foreign[:5]) + (f" (+{len(foreign) - 5} more)" if len(foreign) > 5
                                          else "")
        raise OutputDirError(f"--out {out}: holds runs that are not among the scenarios to "
                             f"run ({shown}); --resume continues the same catalog and "
                             "--filter: pass those, or --overwrite, or another --out")
    return OutPlan(out, mode)


def prepare_out_dir(plan: OutPlan) -> None:
    """Create the directory, empty it for ``--overwrite`` (links unlinked, never
    followed), and remove what killed writers left (staging directories)."""
    plan.out.mkdir(parents=True, exist_ok=True)
    if plan.clear:
        for child in list(plan.out.iterdir()):
            remove_path(child)
    discard_staging(plan.out)


@dataclass(frozen=True)
class ResumePlan:
    """``kept``: the records of runs already finished (not run again); ``to_run``: the
    jobs to run; ``removed``: old run directories removed because they did not count;
    ``why``: for every job, why it was kept or why it runs again (one line each, in job
    order: what the terminal shows)."""

    kept: tuple[RunRecord, ...]
    to_run: tuple[RunJob, ...]
    removed: tuple[Path, ...] = ()
    why: tuple[str, ...] = ()


def finished_record(job: RunJob) -> tuple[RunRecord | None, str]:
    """(the job's existing record if ``--resume`` may keep it, else None; why): kept
    only when it finished with a verdict, for the same scenario content, with the same
    hwyeval version and sources and the same plug-in controller source
    (:mod:`suite.run.code_identity`), and :func:`reports.record.load_run` reads it: every
    file run.json lists is there with its checksum (a run written before run.json
    listed them: its parquet files read whole)."""
    run_dir = job.run_dir
    if run_dir.is_symlink():
        return None, "a symbolic link, not a run directory"
    if not run_dir.is_dir():
        return None, "not run yet"
    try:
        record = load_run(run_dir, trace=False, neighbours=False, arrays=False, series=False)
    except Exception as exc:  # noqa: BLE001 - any unreadable record is run again
        return None, f"unreadable ({type(exc).__name__}: {_without_dir(exc, run_dir)})"
    problem = _stale(record, job)
    if problem:
        return None, problem
    return record, (f"kept: {record.status}, same scenario content, hwyeval sources "
                    f"{job.options.code_sha256[:10]}"
                    + (f", controller source {job.options.controller_sha256[:10]}"
                       if job.options.controller_sha256 else "")
                    + ", files complete")


def _without_dir(exc: Exception, run_dir: Path) -> str:
    """The error's text with the run directory's path left out (the line names the run)."""
    return str(exc).replace(f"{run_dir}/", "").replace(f"{run_dir}: ", "")


def _stale(record: RunRecord, job: RunJob) -> str:
    """Why ``record`` is not the result ``job`` would give ('' when it is): the first
    check that fails, in order."""
    info, spec = record.info, record.info.scenario_spec
    options = job.options
    checks = (
        (record.status not in FINISHED, f"ended {record.status}"),
        (info.scenario != job.name, f"holds scenario {info.scenario!r}"),
        (info.hwyeval_version != __version__,
         f"made by hwyeval {info.hwyeval_version or '?'}"),
        (not options.content_sha256 or spec.get(CONTENT_KEY) != options.content_sha256,
         "the scenario changed (content hash)"),
        (spec.get(CODE_KEY, "") != options.code_sha256, "hwyeval's code changed (source hash)"),
        (spec.get(CONTROLLER_KEY, "") != options.controller_sha256,
         f"controller {info.controller}'s source changed"),
    )
    return next((why for failed, why in checks if failed), "")


def resume_plan(jobs: Sequence[RunJob]) -> ResumePlan:
    """Split ``jobs`` into finished runs to keep and jobs to run; the old directories of
    the latter are removed now (a symbolic link is unlinked, never followed)."""
    kept: list[RunRecord] = []
    to_run: list[RunJob] = []
    removed: list[Path] = []
    why: list[str] = []
    for job in jobs:
        record, reason = finished_record(job)
        why.append(f"{job.name}: {reason if record is not None else 'runs again: ' + reason}")
        if record is not None:
            kept.append(record)
            continue
        to_run.append(job)
        if job.run_dir.is_symlink() or job.run_dir.exists():
            remove_path(job.run_dir)
            removed.append(job.run_dir)
    return ResumePlan(tuple(kept), tuple(to_run), tuple(removed), tuple(why))
