"""Open run logs (``run.rrd``) with the Rerun viewer shipped in rerun-sdk.

``hwyeval view DIR/<scenario>`` and ``hwyeval view DIR --failed`` call
:func:`open_logs`. With a display (``DISPLAY`` or ``WAYLAND_DISPLAY`` set) the viewer
is started in the background; otherwise a portable command is printed: ``rerun``
(the viewer of rerun-sdk) with the logs' paths relative to the current directory, so
it works on any machine with the output copied or mounted at the same relative place,
and never names this host's interpreter or absolute paths.

``hwyeval view ... --web`` (:func:`serve_web`) serves the logs with Rerun's web viewer
over HTTP from this machine (``rerun --serve-web``): open the printed address in a
browser, through an SSH tunnel from a headless server.
"""

from __future__ import annotations

import importlib.util
import os
import shlex
import shutil
import signal
import subprocess
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING

from reports.record import RRD, RUN_JSON, iter_run_dirs

if TYPE_CHECKING:  # the reports' reader (pandas) is imported when runs are listed
    from reports.tables import RunEntry

VIEWER_HINT = "rerun is the viewer of rerun-sdk 0.41: pip install 'rerun-sdk==0.41.*'"


def portable_path(path: Path, cwd: Path | None = None) -> str:
    """``path`` relative to ``cwd`` (default: the current directory)."""
    return os.path.relpath(Path(path).absolute(), (cwd or Path.cwd()).absolute())


def view_command(paths: list[Path], cwd: Path | None = None) -> list[str]:
    """The portable command that opens these .rrd files (module doc)."""
    return ["rerun", *(portable_path(p, cwd) for p in paths)]


def _rerun_executable() -> list[str]:
    """This environment's Rerun viewer binary itself (rerun-sdk's ``rerun_cli/rerun``; the
    ``rerun`` script on PATH is a wrapper that would outlive a terminate)."""
    spec = importlib.util.find_spec("rerun_cli")
    if spec is not None and spec.origin is not None:
        binary = Path(spec.origin).parent / "rerun"
        if binary.is_file():
            return [str(binary)]
    found = shutil.which("rerun")
    return [found] if found else [sys.executable, "-m", "rerun_cli"]


def web_command(paths: list[Path], port: int, bind: str) -> list[str]:
    """``rerun --serve-web`` of these files: web viewer on ``port``, gRPC on port + 1."""
    return [*_rerun_executable(), "--serve-web", "--web-viewer-port", str(port), "--port",
            str(port + 1), "--bind", bind, *(str(p) for p in paths)]


def web_url(port: int, bind: str) -> str:
    """The address that opens the served logs in a browser."""
    host = "localhost" if bind in ("0.0.0.0", "127.0.0.1", "::") else bind
    return (f"http://{host}:{port}/?url=rerun%2Bhttp%3A%2F%2F{host}%3A{port + 1}%2Fproxy")


def run_status(run_dir: Path) -> str:
    """pass | fail | error | timeout of a run directory as the reports read it
    (:func:`reports.tables.read_entry`: an unreadable one, or a run never judged, is
    'error')."""
    from reports.tables import read_entry

    return read_entry(Path(run_dir)).status


def unreadable_reason(run_dir: Path) -> str | None:
    """Why the run directory ``run_dir`` cannot be read as the reports read it (run.json
    malformed, a file it lists missing, changed or corrupt), or None: a single run
    opened with ``view`` says so before its log is shown."""
    from reports.tables import read_entry

    if not (Path(run_dir) / "run.json").is_file():
        return None  # an output directory or an .rrd file: nothing to check here
    return read_entry(Path(run_dir)).unreadable or None


def failed_entries(out_dir: Path) -> list[RunEntry]:
    """The runs under a catalog output directory whose status is not 'pass', read as
    the reports and ``compare`` read them (:func:`reports.tables.collect_runs`): a run
    directory that cannot be read (run.json malformed, a file missing, changed or
    corrupt) is among them, ``RunEntry.unreadable`` saying why."""
    from reports.tables import collect_runs

    return [entry for entry in collect_runs(out_dir) if entry.status != "pass"]


def failed_runs(out_dir: Path) -> list[Path]:
    """Run directories under a catalog output directory whose status is not 'pass'
    (:func:`failed_entries`)."""
    return [entry.run_dir for entry in failed_entries(out_dir)]


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
              failed_only_from: Path | None = None, web_hint: str = "") -> int:
    """Open logs in the viewer (or print the command when there is no display).

    ``failed_only_from``: a catalog output directory; its failed runs are added.
    ``web_hint``: the ``hwyeval view ... --web`` command to suggest without a display
    (default: ``hwyeval view PATH --web`` for a single item; ``view`` takes one PATH,
    so for several the caller says which command serves them, e.g. ``--failed``).
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
        print("no display (DISPLAY/WAYLAND_DISPLAY unset); on a machine with a screen, from "
              "this directory (or with the output copied to the same relative place):")
        print("  " + shlex.join(cmd))
        print(f"  ({VIEWER_HINT})")
        hint = web_hint or (shlex.join(["hwyeval", "view", portable_path(Path(items[0])),
                                        "--web"]) if len(items) == 1 else "")
        if hint:
            print(f"or serve them here to a browser: {hint}")
        return 0
    try:
        subprocess.Popen([*_rerun_executable(), *(str(p) for p in paths)],
                         start_new_session=True)
    except OSError as exc:
        print(f"cannot start the viewer ({exc}); run:\n{shlex.join(cmd)}", file=sys.stderr)
        return 1
    print(f"opened {len(paths)} log(s) in the Rerun viewer")
    return 0


def serve_web(items: Iterable[Path | str], *, port: int = 9090, bind: str = "127.0.0.1") -> int:
    """Serve the logs with Rerun's web viewer until interrupted; returns an exit code
    (1 when there is nothing to serve or the server does not start)."""
    paths = resolve_logs(list(items))
    if not paths:
        print("no Rerun logs to serve", file=sys.stderr)
        return 1
    url = web_url(port, bind)
    print(f"serving {len(paths)} log(s) with Rerun's web viewer: open {url}")
    if bind in ("127.0.0.1", "localhost"):
        print(f"  (from another machine: ssh -L {port}:localhost:{port} -L {port + 1}:localhost:"
              f"{port + 1} THIS_HOST, then open the address there; Ctrl-C stops)")
    try:
        child = subprocess.Popen(web_command(paths, port, bind))
    except OSError as exc:
        print(f"cannot start the web viewer: {exc}", file=sys.stderr)
        return 1

    def stop(signum: int, frame: object) -> None:
        raise SystemExit(128 + signum)

    previous = signal.signal(signal.SIGTERM, stop)
    try:
        return child.wait()
    except KeyboardInterrupt:
        return 0
    finally:
        signal.signal(signal.SIGTERM, previous)
        if child.poll() is None:  # our server: stopped with us
            child.terminate()
            try:
                child.wait(timeout=10)
            except subprocess.TimeoutExpired:
                child.kill()
