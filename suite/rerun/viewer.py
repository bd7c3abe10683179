"""Open run logs (``run.rrd``) with the Rerun viewer shipped in rerun-sdk.

``hwyeval view DIR/<scenario>`` and ``hwyeval view DIR --failed`` call
:func:`open_logs`. With a display (``DISPLAY`` or ``WAYLAND_DISPLAY`` set) the viewer
is started in the background; otherwise the exact command is printed, to run on a
machine with a screen (after copying the files, or with the same paths mounted).
"""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
from collections.abc import Iterable
from pathlib import Path

from reports.record import RRD, RUN_JSON, RecordError, iter_run_dirs
from reports.record.meta import END_OK
from reports.record.run import read_run_json


def view_command(paths: list[Path]) -> list[str]:
    """The command that opens these .rrd files in the viewer bundled with rerun-sdk."""
    return [sys.executable, "-m", "rerun_cli", *(str(Path(p)) for p in paths)]


def run_status(run_dir: Path) -> str:
    """pass | fail | error | timeout of a run directory from its run.json (an unreadable
    one, or a run never judged, is 'error')."""
    try:
        _, outcome, verdict = read_run_json(run_dir)
    except RecordError:
        return "error"
    if outcome.end != END_OK:
        return outcome.end
    return verdict.status if verdict is not None else "error"


def failed_runs(out_dir: Path) -> list[Path]:
    """Run directories under a catalog output directory whose status is not 'pass'."""
    return [run_dir for run_dir in iter_run_dirs(out_dir) if run_status(run_dir) != "pass"]


def _rrd_for_run(run_dir: Path) -> Path | None:
    """run_dir/run.rrd, writing it from the recorded arrays if it is missing."""
    rrd = run_dir / RRD
    if rrd.is_file():
        return rrd
    if (run_dir / RUN_JSON).is_file():
        from suite.rerun.log import write_rrd

        try:
            return write_rrd(run_dir)
        except Exception as exc:  # a broken run dir must not stop the others opening
            print(f"{run_dir}: cannot write {RRD}: {exc}", file=sys.stderr)
    return None


def resolve_logs(items: Iterable[Path | str]) -> list[Path]:
    """.rrd files for a mix of .rrd paths, run directories and catalog output directories."""
    out: list[Path] = []
    for item in items:
        path = Path(item)
        if path.is_file() and path.suffix == ".rrd":
            out.append(path)
        elif path.is_dir() and (path / RUN_JSON).is_file():
            rrd = _rrd_for_run(path)
            if rrd is not None:
                out.append(rrd)
        elif path.is_dir():
            for run_dir in iter_run_dirs(path):
                rrd = _rrd_for_run(run_dir)
                if rrd is not None:
                    out.append(rrd)
        else:
            print(f"{path}: not an .rrd file, run directory or output directory", file=sys.stderr)
    seen: set[Path] = set()
    unique = []
    for p in out:
        key = p.resolve()
        if key not in seen:
            seen.add(key)
            unique.append(p)
    return unique


def has_display() -> bool:
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def open_logs(run_dirs_or_rrds: Iterable[Path | str], *,
              failed_only_from: Path | None = None) -> int:
    """Open logs in the viewer (or print the command when there is no display).

    ``failed_only_from``: a catalog output directory; its failed runs are added.
    Returns a process exit code: 0 when the viewer was started or the command printed,
    1 when there was nothing to open or the viewer could not start.
    """
    items = list(run_dirs_or_rrds)
    if failed_only_from is not None:
        items += failed_runs(Path(failed_only_from))
    paths = resolve_logs(items)
    if not paths:
        print("no Rerun logs to open", file=sys.stderr)
        return 1
    cmd = view_command(paths)
    if not has_display():
        print("no display (DISPLAY/WAYLAND_DISPLAY unset); open the logs with:")
        print(shlex.join(cmd))
        return 0
    try:
        subprocess.Popen(cmd, start_new_session=True)
    except OSError as exc:
        print(f"cannot start the viewer ({exc}); run:\n{shlex.join(cmd)}", file=sys.stderr)
        return 1
    print(f"opened {len(paths)} log(s) in the Rerun viewer")
    return 0
