"""The long-lived Ray worker: one actor runs one scenario at a time, each in a forked
child, as the local executor's forkserver does.

At its start the actor imports what a run needs, loads the numba kernels and freezes
the garbage collector's view of them (:func:`suite.exec.prepare.prepare_process`, what
the forkserver's preload does): every scenario it runs afterwards is a ``fork`` of a
warm process, not an interpreter start. A run goes through a one-job
:class:`~suite.exec.local.LocalExecutor` with the ``fork`` start method, so it is a
child process of the actor: libsumo hosts one simulation per process, the wall-clock
backstop kills a run hung beyond its budget (a step stuck in C holds the GIL: no thread
of the actor could stop it) and records it as a ``timeout``, and a crash of the child is
that run's ``error``, the actor going on with the next.

The files a run reads arrive through Ray's object store (:mod:`suite.exec.shipping`):
the actor fetches each content once, into its own store folder, and runs on those
copies; it never reads a path of the driver's machine. The run directory travels back
as an archive (:mod:`suite.exec.ray.archive`) with the driver's paths put back.
"""

from __future__ import annotations

import os
import shutil
import socket
import tempfile
import time
import traceback
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from reports.record import RUN_JSON
from suite.exec.jobs import RunJob, write_failure
from suite.exec.local import LocalExecutor
from suite.exec.prepare import prepare_process
from suite.exec.ray.archive import pack_run
from suite.exec.shipping import ShippedFile, localise, restore_paths

__all__ = ["HOME_PREFIX", "ScenarioActor", "preload", "remove_stale_homes"]


def preload() -> float:
    """Prepare this process as the forkserver is (:func:`prepare_process`: imports,
    kernels, the collector's view of them frozen); returns the time it took [s]."""
    t0 = time.monotonic()
    prepare_process()
    return time.monotonic() - t0


HOME_PREFIX = "hwyeval-ray-"  # an actor's folder: <tmp>/hwyeval-ray-<pid>-<random>


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process: alive
        return True
    return True


def remove_stale_homes(tmp: Path) -> list[Path]:
    """Remove the folders of actors that ended without :meth:`ScenarioActor.close`
    (killed with their node, or by ``ray.kill``): ``<tmp>/hwyeval-ray-<pid>-*`` whose
    process is gone. Returns what was removed."""
    removed = []
    for home in tmp.glob(f"{HOME_PREFIX}*-*"):
        pid_text = home.name[len(HOME_PREFIX):].split("-", 1)[0]
        if pid_text.isdigit() and home.is_dir() and not _alive(int(pid_text)):
            shutil.rmtree(home, ignore_errors=True)
            removed.append(home)
    return removed


class ScenarioActor:
    """A Ray actor's class (the executor applies ``ray.remote``): module doc."""

    def __init__(self) -> None:
        remove_stale_homes(Path(tempfile.gettempdir()))
        self.home = Path(tempfile.mkdtemp(prefix=f"{HOME_PREFIX}{os.getpid()}-"))
        self.store = self.home / "files"
        self.preload_s = preload()
        self.runs = 0

    def ready(self) -> dict[str, Any]:
        """Where this actor runs: Ray's node id, host name, pid, its preload [s], and
        the hwyeval installed there (``version``, the hash of its code ``code``)."""
        import ray

        from suite import __version__
        from suite.run.code_identity import hwyeval_code_sha256

        return {"node_id": ray.get_runtime_context().get_node_id(),
                "host": socket.gethostname(), "pid": os.getpid(),
                "preload_s": self.preload_s, "version": __version__,
                "code": hwyeval_code_sha256()}

    def run(self, job: RunJob, files: Sequence[ShippedFile], refs: Mapping[str, Any]) -> bytes:
        """Run ``job`` on local copies of ``files`` (``refs``: each content's object
        reference by SHA-256, nested so that Ray hands them over unresolved); returns the
        run directory as an archive, with the driver's paths in its record."""
        import ray

        def fetch(sha256: str) -> bytes:
            data = ray.get(refs[sha256])
            return bytes(data)

        out = Path(tempfile.mkdtemp(prefix="out-", dir=self.home))
        try:
            local, back = localise(job, files, fetch, self.store, out)
            try:
                LocalExecutor(jobs=1, start_method="fork").run([local])
            except Exception:  # noqa: BLE001 - the run's error, the actor goes on
                write_failure(local, "error", traceback.format_exc())
            if not (local.run_dir / RUN_JSON).is_file():
                write_failure(local, "error", "the scenario process left no record")
            restore_paths(local.run_dir, back)
            self.runs += 1
            return pack_run(local.run_dir, job.name)
        finally:
            shutil.rmtree(out, ignore_errors=True)

    def close(self) -> None:
        """Remove this actor's folder (its file copies); called before it is killed."""
        shutil.rmtree(self.home, ignore_errors=True)
