"""Executors: where scenarios run. One scenario per process (libsumo: one simulation each).

* :class:`LocalExecutor` runs up to ``jobs`` scenario processes at once on this
  machine (``forkserver`` start method with the heavy modules preloaded, so a
  catalog pays imports and numba cache loading once), kills a scenario that
  exceeds its wall-clock budget (status ``timeout``) and records a process
  that died without writing its result (status ``error`` with the exit code).
* :class:`RayExecutor` sends each scenario to a Ray cluster as a task in a fresh
  worker process (``max_calls=1``); the worker runs into a local temporary
  directory and ships the run directory back as a tar archive, so no shared
  filesystem is needed.
"""

from __future__ import annotations

import io
import json
import multiprocessing as mp
import multiprocessing.connection
import tarfile
import tempfile
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from reports import run_record as rr
from suite.run.runner import RunOptions, write_json

PRELOAD = ["numpy", "pandas", "numba", "libsumo", "suite.run.runner", "suite.catalog",
           "controllers.builtin", "suite.exec.warmup"]
_KILL_GRACE_S = 10.0


@dataclass(frozen=True)
class RunJob:
    """One scenario to run: found again by name in its catalog inside the worker."""

    catalog_path: Path
    scenario_name: str
    out_dir: Path
    options: RunOptions = field(default_factory=RunOptions)
    timeout_s: float | None = None


def run_job(job: RunJob) -> dict[str, Any]:
    """Worker entry point: load the catalog, run the named scenario, return its run.json."""
    from suite.catalog import load_catalog
    from suite.run.runner import run_scenario

    catalog = load_catalog(job.catalog_path)
    by_name = {s.name: s for s in catalog.scenarios}
    scenario = by_name[job.scenario_name]
    return run_scenario(scenario, job.out_dir, job.options)


def _worker_main(job: RunJob) -> None:
    try:
        run_job(job)
    except BaseException:  # noqa: BLE001 - recorded for the parent
        _write_failure(job, "error", traceback.format_exc())
        raise


def _write_failure(job: RunJob, status: str, message: str) -> dict[str, Any]:
    run_dir = job.out_dir / job.scenario_name
    run_dir.mkdir(parents=True, exist_ok=True)
    meta_path = run_dir / rr.RUN_JSON
    meta: dict[str, Any] = {}
    if meta_path.is_file():
        try:
            meta = json.loads(meta_path.read_text())
        except ValueError:
            meta = {}
    meta.update({"scenario": job.scenario_name, "status": status, "error": message})
    meta.setdefault("controller", "")
    meta.setdefault("family", job.scenario_name.split("__")[0])
    meta.setdefault("catalog", str(job.catalog_path))
    write_json(meta_path, meta)
    (run_dir / rr.TRACEBACK).write_text(message)
    return meta


def _read_result(job: RunJob) -> dict[str, Any]:
    return dict(json.loads((job.out_dir / job.scenario_name / rr.RUN_JSON).read_text()))


class Executor(Protocol):
    """Runs jobs and calls ``on_done(run_json)`` as each finishes (any order)."""

    def run(self, jobs: Sequence[RunJob],
            on_done: Callable[[dict[str, Any]], None] | None = None) -> list[dict[str, Any]]: ...


class LocalExecutor:
    """Scenario processes on this machine, at most ``jobs`` at once (see module docstring)."""

    def __init__(self, jobs: int = 1, start_method: str = "forkserver") -> None:
        if jobs < 1:
            raise ValueError(f"jobs must be >= 1, got {jobs}")
        self.jobs = jobs
        self.ctx: Any = mp.get_context(start_method)
        if start_method == "forkserver":
            self.ctx.set_forkserver_preload(PRELOAD)

    def run(self, jobs: Sequence[RunJob],
            on_done: Callable[[dict[str, Any]], None] | None = None) -> list[dict[str, Any]]:
        pending = list(jobs)
        running: dict[Any, tuple[RunJob, Any, float]] = {}
        results: list[dict[str, Any]] = []

        def finish(job: RunJob, proc: Any, status: str | None, message: str) -> None:
            proc.join(timeout=_KILL_GRACE_S)
            meta_path = job.out_dir / job.scenario_name / rr.RUN_JSON
            if status is not None:
                meta = _write_failure(job, status, message)
            elif proc.exitcode != 0 or not meta_path.is_file():
                meta = (_read_result(job) if meta_path.is_file() else {})
                if meta.get("status") not in ("error", "timeout"):
                    meta = _write_failure(
                        job, "error", f"scenario process exited with code {proc.exitcode}"
                        + (f"\n{meta.get('error')}" if meta.get("error") else ""))
            else:
                meta = _read_result(job)
            results.append(meta)
            if on_done is not None:
                on_done(meta)

        while pending or running:
            while pending and len(running) < self.jobs:
                job = pending.pop(0)
                proc = self.ctx.Process(target=_worker_main, args=(job,), name=job.scenario_name)
                proc.start()
                running[proc.sentinel] = (job, proc, time.monotonic())
            ready = mp.connection.wait(list(running), timeout=0.5)
            for sentinel in ready:
                job, proc, _ = running.pop(sentinel)
                finish(job, proc, None, "")
            now = time.monotonic()
            for sentinel, (job, proc, started) in list(running.items()):
                # The runner stops itself at timeout_s; this is the backstop for a hung process.
                if job.timeout_s is not None and now - started > job.timeout_s + _KILL_GRACE_S:
                    proc.kill()
                    running.pop(sentinel)
                    finish(job, proc, "timeout",
                           f"killed after {now - started:.1f} s (budget {job.timeout_s} s)")
        return results


class RayExecutor:
    """Runs each scenario as a Ray task in a fresh worker process.

    ``address`` is passed to ``ray.init`` (None: start or join a local Ray; "auto":
    join the cluster this machine belongs to).
    """

    def __init__(self, address: str | None = None, num_cpus_per_task: float = 1.0) -> None:
        try:
            import ray
        except ImportError as exc:
            raise RuntimeError(
                "the Ray executor needs the 'cluster' extra: pip install 'hwyeval[cluster]'"
            ) from exc
        self.ray = ray
        if not ray.is_initialized():
            ray.init(address=address, include_dashboard=False, log_to_driver=False)
        self._remote = ray.remote(num_cpus=num_cpus_per_task, max_calls=1)(_ray_task)

    def run(self, jobs: Sequence[RunJob],
            on_done: Callable[[dict[str, Any]], None] | None = None) -> list[dict[str, Any]]:
        catalog_bytes: dict[Path, bytes] = {}
        refs = {}
        for job in jobs:
            if job.catalog_path not in catalog_bytes:
                catalog_bytes[job.catalog_path] = _pack_catalog(job.catalog_path)
            refs[self._remote.remote(job, catalog_bytes[job.catalog_path])] = job
        results = []
        remaining = list(refs)
        while remaining:
            done, remaining = self.ray.wait(remaining, num_returns=1)
            job = refs[done[0]]
            try:
                archive = self.ray.get(done[0])
                _unpack_run(archive, job.out_dir)
                meta = _read_result(job)
            except Exception:  # noqa: BLE001 - a lost task is an error, the rest go on
                meta = _write_failure(job, "error", traceback.format_exc())
            results.append(meta)
            if on_done is not None:
                on_done(meta)
        return results


def _pack_catalog(catalog_path: Path) -> bytes:
    """The catalog file and every file beside it (nets referenced by relative path)."""
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w:gz") as tar:
        folder = catalog_path.parent
        for p in folder.rglob("*"):
            if p.is_file() and p.stat().st_size < 64 * 1024 * 1024:
                tar.add(p, arcname=str(p.relative_to(folder)))
    return buf.getvalue()


def _ray_task(job: RunJob, catalog_archive: bytes) -> bytes:
    with tempfile.TemporaryDirectory() as tmp:
        tmp_path = Path(tmp)
        cat_dir = tmp_path / "catalog"
        with tarfile.open(fileobj=io.BytesIO(catalog_archive), mode="r:gz") as tar:
            tar.extractall(cat_dir, filter="data")
        out = tmp_path / "out"
        local = RunJob(cat_dir / job.catalog_path.name, job.scenario_name, out, job.options,
                       job.timeout_s)
        try:
            run_job(local)
        except Exception:  # noqa: BLE001
            _write_failure(local, "error", traceback.format_exc())
        buf = io.BytesIO()
        with tarfile.open(fileobj=buf, mode="w:gz") as tar:
            tar.add(out / job.scenario_name, arcname=job.scenario_name)
        return buf.getvalue()


def _unpack_run(archive: bytes, out_dir: Path) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    with tarfile.open(fileobj=io.BytesIO(archive), mode="r:gz") as tar:
        tar.extractall(out_dir, filter="data")
