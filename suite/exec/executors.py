"""Executors: where scenarios run. One scenario per process (libsumo: one simulation each).

The catalog is validated once, in the parent; every job carries its resolved
:class:`suite.catalog.Scenario` (no worker re-reads the catalog file).

* :class:`LocalExecutor` runs up to ``jobs`` scenario processes at once on this machine
  (``forkserver`` with the heavy modules preloaded, so a catalog pays imports and numba
  cache loading once), kills a scenario that exceeds its wall-clock budget (status
  ``timeout``) and records a process that died without writing its result (``error``
  with the exit code).
* :class:`RayExecutor` sends each scenario to a Ray cluster as a task in a fresh worker
  process (``max_calls=1``) with only the network file it needs; the worker runs into a
  local temporary directory and ships the run directory back as a tar archive, so no
  shared filesystem is needed.
"""

from __future__ import annotations

import dataclasses
import io
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

from controllers import registry
from controllers.plant.vehicle_model import VehicleParams
from reports.record import (
    ControllerArrays,
    NeighbourColumns,
    RecordError,
    RoadRecord,
    RunOutcome,
    RunRecord,
    Trace,
    load_run,
    write_run,
)
from suite.catalog import Scenario
from suite.run.info import scenario_info
from suite.run.runner import RunOptions, run_scenario

PRELOAD = ["numpy", "pandas", "numba", "libsumo", "suite.run.runner", "suite.catalog",
           "controllers.builtin", "suite.exec.warmup"]
KILL_GRACE_S = 10.0
MAX_NET_BYTES = 256 * 1024 * 1024  # a network larger than this is not shipped to Ray

OnDone = Callable[[RunRecord], None]


@dataclass(frozen=True)
class RunJob:
    """One scenario to run into ``out_dir/<scenario.name>``. ``plugins``: the
    ``--plugin`` modules (with a file's source), imported by the worker before it
    builds the controller (entry-point plug-ins load themselves)."""

    scenario: Scenario
    out_dir: Path
    options: RunOptions = field(default_factory=RunOptions)
    timeout_s: float | None = None
    plugins: tuple[registry.PluginModule, ...] = ()

    @property
    def run_dir(self) -> Path:
        return self.out_dir / self.scenario.name


def run_job(job: RunJob) -> RunRecord:
    """Worker entry point: load the job's plug-ins, run its scenario (``run_scenario``
    never raises; a plug-in that fails to import here raises, and is recorded as the
    run's error by the caller)."""
    registry.load_plugin_modules(job.plugins)
    return run_scenario(job.scenario, job.out_dir, job.options)


def _worker_main(job: RunJob) -> None:
    try:
        run_job(job)
    except BaseException:
        write_failure(job, "error", traceback.format_exc())
        raise


def write_failure(job: RunJob, end: str, message: str) -> RunRecord:
    """A fresh record for a run that did not finish (nothing kept from an older one)."""
    from reports.metrics import evaluate

    sc = job.scenario
    record = RunRecord(info=scenario_info(sc, job.options.catalog_name, VehicleParams()),
                       outcome=RunOutcome(end=end, error=message), road=RoadRecord(),
                       trace=Trace.empty(), neighbours=NeighbourColumns.allocate(0),
                       arrays=ControllerArrays())
    try:
        evaluation = evaluate(record)
        record.verdict, record.series = evaluation.verdict, evaluation.series
    except Exception:  # noqa: BLE001 - the record must be written whatever happens
        pass
    write_run(record, job.run_dir)
    record.run_dir = job.run_dir
    return record


def read_result(job: RunJob) -> RunRecord:
    """The job's record as written (run.json and road only)."""
    return load_run(job.run_dir, trace=False, neighbours=False, arrays=False, series=False)


class Executor(Protocol):
    """Runs jobs and calls ``on_done(record)`` as each finishes (any order)."""

    def run(self, jobs: Sequence[RunJob], on_done: OnDone | None = None) -> list[RunRecord]: ...


class LocalExecutor:
    """Scenario processes on this machine, at most ``jobs`` at once (module docstring)."""

    def __init__(self, jobs: int = 1, start_method: str = "forkserver") -> None:
        if jobs < 1:
            raise ValueError(f"jobs must be >= 1, got {jobs}")
        self.jobs = jobs
        self.ctx: Any = mp.get_context(start_method)
        if start_method == "forkserver":
            self.ctx.set_forkserver_preload(PRELOAD)

    def _finish(self, job: RunJob, proc: Any, killed: str | None) -> RunRecord:
        proc.join(timeout=KILL_GRACE_S)
        if killed is not None:
            return write_failure(job, "timeout", killed)
        try:
            record = read_result(job)
        except (FileNotFoundError, RecordError) as exc:
            return write_failure(job, "error", f"scenario process exited with code "
                                 f"{proc.exitcode} without a valid record ({exc})")
        if proc.exitcode != 0 and record.outcome.end == "ok":
            return write_failure(job, "error", f"scenario process exited with code "
                                 f"{proc.exitcode}")
        return record

    def run(self, jobs: Sequence[RunJob], on_done: OnDone | None = None) -> list[RunRecord]:
        pending = list(jobs)
        running: dict[Any, tuple[RunJob, Any, float]] = {}
        results: list[RunRecord] = []

        def done(record: RunRecord) -> None:
            results.append(record)
            if on_done is not None:
                on_done(record)

        while pending or running:
            while pending and len(running) < self.jobs:
                job = pending.pop(0)
                proc = self.ctx.Process(target=_worker_main, args=(job,),
                                        name=job.scenario.name)
                proc.start()
                running[proc.sentinel] = (job, proc, time.monotonic())
            for sentinel in mp.connection.wait(list(running), timeout=0.5):
                job, proc, _ = running.pop(sentinel)
                done(self._finish(job, proc, None))
            now = time.monotonic()
            for sentinel, (job, proc, started) in list(running.items()):
                # The runner stops itself at timeout_s; this is the backstop for a hung process.
                if job.timeout_s is not None and now - started > job.timeout_s + KILL_GRACE_S:
                    proc.kill()
                    running.pop(sentinel)
                    done(self._finish(job, proc, f"killed after {now - started:.1f} s "
                                                 f"(budget {job.timeout_s} s)"))
        return results


class RayExecutor:
    """Runs each scenario as a Ray task in a fresh worker process.

    ``address`` is passed to ``ray.init`` (None: start or join a local Ray; "auto": join
    the cluster this machine belongs to).
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

    def run(self, jobs: Sequence[RunJob], on_done: OnDone | None = None) -> list[RunRecord]:
        nets: dict[Path, bytes] = {}
        refs = {}
        for job in jobs:
            net = job.scenario.net_path
            if net not in nets:
                nets[net] = _read_net(net)
            refs[self._remote.remote(job, nets[net])] = job
        results = []
        remaining = list(refs)
        while remaining:
            ready, remaining = self.ray.wait(remaining, num_returns=1)
            job = refs[ready[0]]
            try:
                _unpack_run(self.ray.get(ready[0]), job.out_dir)
                record = read_result(job)
            except Exception:  # noqa: BLE001 - a lost task is an error, the rest go on
                record = write_failure(job, "error", traceback.format_exc())
            results.append(record)
            if on_done is not None:
                on_done(record)
        return results


def _read_net(path: Path) -> bytes:
    size = path.stat().st_size
    if size > MAX_NET_BYTES:
        raise ValueError(f"{path}: {size} bytes is more than the {MAX_NET_BYTES} bytes the Ray "
                         "executor ships per network")
    return path.read_bytes()


def _ray_task(job: RunJob, net_bytes: bytes) -> bytes:
    """On the worker: the scenario's network into a temporary folder, run, tar back."""
    with tempfile.TemporaryDirectory() as tmp:
        tmp_path = Path(tmp)
        net = tmp_path / "net" / job.scenario.net_path.name
        net.parent.mkdir()
        net.write_bytes(net_bytes)
        scenario = dataclasses.replace(job.scenario, net_path=net)
        local = RunJob(scenario, tmp_path / "out", job.options, job.timeout_s, job.plugins)
        try:
            run_job(local)
        except Exception:  # noqa: BLE001
            write_failure(local, "error", traceback.format_exc())
        buf = io.BytesIO()
        with tarfile.open(fileobj=buf, mode="w:gz") as tar:
            tar.add(local.run_dir, arcname=scenario.name)
        return buf.getvalue()


def _unpack_run(archive: bytes, out_dir: Path) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    with tarfile.open(fileobj=io.BytesIO(archive), mode="r:gz") as tar:
        tar.extractall(out_dir, filter="data")
