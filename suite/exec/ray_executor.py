"""The Ray executor: each scenario as a Ray task in a fresh worker process.

What is shipped to the cluster is :func:`ray_payload`, nothing else: the job (its
resolved scenario, run options and the ``--plugin`` modules with their source) and the
bytes of the one network file the scenario references, at most :data:`MAX_NET_BYTES`,
put into Ray's object store once per network however many scenarios use it. No other
file is read: not the catalog's folder, not what lies beside the network. The worker
writes the network into a temporary folder, runs there and ships the run directory
back as a gzipped tar archive, which the parent unpacks into a staging directory
(links and paths out of it refused: ``tarfile``'s ``data`` filter) and publishes
atomically. So no shared filesystem is needed.

A network that cannot be shipped (too large, unreadable) or a lost task is that
scenario's ``error``; the others go on. On a stop request the pending and running
tasks are cancelled (their worker processes killed) and Ray is shut down if this
executor started it.
"""

from __future__ import annotations

import dataclasses
import io
import tarfile
import tempfile
import traceback
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from reports.record import RUN_JSON, RunRecord
from reports.record.run import discard_staging, publish_run_dir, remove_path, staging_dir
from suite.exec.jobs import OnDone, RunJob, read_result, write_failure
from suite.exec.local import LocalExecutor
from suite.exec.signals import POLL_S, StopRequest

__all__ = ["MAX_NET_BYTES", "RayExecutor", "ray_payload"]

MAX_NET_BYTES = 256 * 1024 * 1024  # a network larger than this is not shipped to Ray [bytes]


def read_net(path: Path, limit: int = MAX_NET_BYTES) -> bytes:
    """The bytes of a network file; ValueError if it is larger than ``limit`` [bytes] or
    not a regular file, OSError if it cannot be read."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: not a regular file, not shipped to Ray")
    size = path.stat().st_size
    if size > limit:
        raise ValueError(f"{path}: {size} bytes is more than the {limit} bytes the Ray "
                         "executor ships per network")
    data = path.read_bytes()
    if len(data) > limit:  # it grew meanwhile
        raise ValueError(f"{path}: more than the {limit} bytes the Ray executor ships")
    return data


def ray_payload(job: RunJob, limit: int = MAX_NET_BYTES) -> tuple[RunJob, bytes]:
    """Everything a Ray task of ``job`` receives: the job and its network's bytes."""
    return job, read_net(job.scenario.net_path, limit)


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
            # In a child process of this worker, as the local executor runs every
            # scenario: its wall-clock backstop kills a run hung beyond its budget (a
            # step stuck in C holds the GIL: no thread in this process could) and
            # records it as a timeout, and a crash of the child is that run's error.
            LocalExecutor(jobs=1, start_method="fork").run([local])
        except Exception:  # noqa: BLE001
            write_failure(local, "error", traceback.format_exc())
        if not (local.run_dir / RUN_JSON).is_file():
            write_failure(local, "error", "the scenario process left no record")
        buf = io.BytesIO()
        with tarfile.open(fileobj=buf, mode="w:gz") as tar:
            tar.add(local.run_dir, arcname=scenario.name)
        return buf.getvalue()


def unpack_run(archive: bytes, job: RunJob) -> None:
    """Unpack a shipped run directory into a staging directory and publish it as the
    job's run directory (replacing an older one; nothing outside the staging directory
    is ever written)."""
    stage = staging_dir(job.out_dir, job.name)
    try:
        with tarfile.open(fileobj=io.BytesIO(archive), mode="r:gz") as tar:
            tar.extractall(stage, filter="data")
        run = stage / job.name
        if run.is_symlink() or not run.is_dir():
            raise ValueError(f"the shipped archive of {job.name} holds no directory {job.name}/")
        publish_run_dir(run, job.run_dir)
    finally:
        remove_path(stage)


class RayExecutor:
    """Runs each scenario as a Ray task in a fresh worker process (module doc).

    ``address`` is passed to ``ray.init`` (None: start or join a local Ray; "auto": join
    the cluster this machine belongs to).
    """

    def __init__(self, address: str | None = None, num_cpus_per_task: float = 1.0,
                 max_net_bytes: int = MAX_NET_BYTES) -> None:
        try:
            import ray
        except ImportError as exc:
            raise RuntimeError(
                "the Ray executor needs the 'cluster' extra: pip install 'hwyeval[cluster]'"
            ) from exc
        self.ray = ray
        self.max_net_bytes = max_net_bytes
        self.started_ray = not ray.is_initialized()
        if self.started_ray:
            ray.init(address=address, include_dashboard=False, log_to_driver=False)
        self._remote = ray.remote(num_cpus=num_cpus_per_task, max_calls=1)(_ray_task)

    def _submit(self, jobs: Sequence[RunJob], done: OnDone) -> dict[Any, RunJob]:
        """A task per job (its network put into the object store once); a job whose
        network cannot be shipped is recorded as an error at once."""
        nets: dict[Path, Any] = {}
        refs: dict[Any, RunJob] = {}
        for job in jobs:
            net = job.scenario.net_path
            try:
                remove_path(job.run_dir)
                if net not in nets:
                    _, data = ray_payload(job, self.max_net_bytes)
                    nets[net] = self.ray.put(data)
            except (OSError, ValueError) as exc:
                done(write_failure(job, "error", f"cannot ship the network to Ray: {exc}"))
                continue
            refs[self._remote.remote(job, nets[net])] = job
        return refs

    def run(self, jobs: Sequence[RunJob], on_done: OnDone | None = None,
            stop: StopRequest | None = None) -> list[RunRecord]:
        stop = stop if stop is not None else StopRequest()
        results: list[RunRecord] = []

        def done(record: RunRecord) -> None:
            results.append(record)
            if on_done is not None:
                on_done(record)

        if stop.requested:
            return results
        refs = self._submit(jobs, done)
        remaining = list(refs)
        try:
            while remaining and not stop.requested:
                ready, remaining = self.ray.wait(remaining, num_returns=1, timeout=POLL_S)
                for ref in ready:
                    done(self._collect(ref, refs[ref]))
        finally:
            if remaining:
                self._cancel(remaining, refs)
        return results

    def _collect(self, ref: Any, job: RunJob) -> RunRecord:
        try:
            unpack_run(self.ray.get(ref), job)
            return read_result(job)
        except Exception:  # noqa: BLE001 - a lost task is an error, the rest go on
            return write_failure(job, "error", traceback.format_exc())

    def _cancel(self, remaining: list[Any], refs: dict[Any, RunJob]) -> None:
        for ref in remaining:
            try:
                self.ray.cancel(ref, force=True)
            except Exception:  # noqa: BLE001 - already finished or gone
                pass
            discard_staging(refs[ref].out_dir, refs[ref].name)
        if self.started_ray:
            self.ray.shutdown()
