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

Which Ray (:func:`ray_target`): without an address (``--ray-address`` or the
``RAY_ADDRESS`` variable) a **private local Ray**, ``ray.init(address="local")``, never
a cluster found on this machine: Ray's own ``ray.init()`` joins the cluster its
``ray_current_cluster`` file in its temporary folder names, which may be another
virtual environment's or one long dead (it then retries for minutes), or any Ray
process it finds running. A given address (``host:port``, ``ray://host:port``, or
``auto``: the cluster Ray would find, resolved first) is checked before any work: a TCP
connection within :data:`CHECK_S`, then ``ray.init`` within :data:`CONNECT_S`;
either failing is a :class:`RayAddressError` (the command exits 2, nothing written).
"""

from __future__ import annotations

import dataclasses
import io
import os
import socket
import tarfile
import tempfile
import threading
import traceback
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from reports.record import RUN_JSON, RunRecord
from reports.record.run import discard_staging, publish_run_dir, remove_path, staging_dir
from suite.exec.jobs import OnDone, RunJob, read_result, write_failure
from suite.exec.local import LocalExecutor
from suite.exec.signals import POLL_S, StopRequest

__all__ = ["CHECK_S", "CONNECT_S", "MAX_NET_BYTES", "RayAddressError", "RayExecutor",
           "RayTarget", "check_target", "ray_payload", "ray_target"]

MAX_NET_BYTES = 256 * 1024 * 1024  # a network larger than this is not shipped to Ray [bytes]
CHECK_S = 5.0  # a given Ray address must accept a TCP connection within this [s]
CONNECT_S = 60.0  # and ray.init must have joined its cluster within this [s]


class RayAddressError(ValueError):
    """The Ray cluster asked for cannot be used (the message names the address and where
    it came from)."""


@dataclass(frozen=True)
class RayTarget:
    """Where the Ray executor runs. ``address`` None: a private local Ray; else the
    address to pass to ``ray.init``, ``given`` as written and ``source`` where it came
    from (``--ray-address`` or ``RAY_ADDRESS``), ``host`` and ``port`` what is checked."""

    address: str | None
    given: str = ""
    source: str = ""
    host: str = ""
    port: int = 0

    def __post_init__(self) -> None:
        if self.address is not None and not (self.host and 0 < self.port < 65536):
            raise ValueError(f"RayTarget: a host and a port in 1..65535 are needed for "
                             f"{self.address!r}, got {self.host!r}:{self.port}")

    @property
    def shown(self) -> str:
        """``--ray-address auto (192.0.2.2:6379)`` or ``a private local Ray``."""
        if self.address is None:
            return "a private local Ray"
        resolved = f" ({self.host}:{self.port})" if self.given != self.address else ""
        return f"{self.source} {self.given}{resolved}"


def _host_port(address: str, what: str) -> tuple[str, int]:
    """``(host, port)`` of ``host:port``, ``[v6]:port`` or ``scheme://host:port``."""
    hostport = address.split("://", 1)[-1].rstrip("/")
    host, sep, port = hostport.rpartition(":")
    host = host.strip("[]")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise RayAddressError(f"{what} {address}: expected host:port, ray://host:port, "
                              "auto or local")
    return host, int(port)


def _found_address(what: str) -> str:
    """The cluster ``ray.init(address="auto")`` would join, as host:port (Ray's own
    lookup: RAY_ADDRESS, its ray_current_cluster file, Ray processes running here)."""
    from ray._private.services import canonicalize_bootstrap_address

    try:
        found = canonicalize_bootstrap_address("auto")
    except (ConnectionError, ValueError) as exc:
        raise RayAddressError(f"{what} auto: {exc}") from exc
    if not found:
        raise RayAddressError(f"{what} auto: Ray found no cluster to join")
    return str(found)


def ray_target(address: str | None, environ: Mapping[str, str]) -> RayTarget:
    """The Ray to run on (module doc): ``address`` (``--ray-address``), else
    ``RAY_ADDRESS`` from ``environ``, else a private local Ray. RayAddressError for an
    address that is not host:port, ray://host:port, auto or local."""
    given, source = (address, "--ray-address") if address else \
        (environ.get("RAY_ADDRESS", "").strip(), "RAY_ADDRESS")
    if not given or given == "local":
        return RayTarget(None)
    resolved = _found_address(source) if given == "auto" else given
    host, port = _host_port(resolved, source)
    return RayTarget(resolved, given, source, host, port)


def check_target(target: RayTarget, timeout_s: float = CHECK_S) -> None:
    """RayAddressError unless ``target``'s host accepts a TCP connection on its port
    within ``timeout_s`` [s] (a private local Ray is not checked: it is started)."""
    if target.address is None:
        return
    try:
        with socket.create_connection((target.host, target.port), timeout=timeout_s):
            pass
    except OSError as exc:
        why = "no answer" if isinstance(exc, TimeoutError) else (exc.strerror or str(exc))
        raise RayAddressError(
            f"{target.shown}: nothing answers at {target.host}:{target.port} ({why} within "
            f"{timeout_s:g} s); start the cluster, give its address, or leave "
            "--ray-address out (and RAY_ADDRESS unset) for a private local Ray") from exc


def _init_within(ray: Any, target: RayTarget, timeout_s: float) -> None:
    """``ray.init`` joining ``target``, in a thread: a cluster that takes the connection
    but never answers as Ray makes ray.init retry for minutes, so it gets ``timeout_s``
    [s] and is then left behind (the command ends; Ray's exit handler does not wait)."""
    outcome: list[BaseException | None] = []

    def join() -> None:
        try:
            ray.init(address=target.address, include_dashboard=False, log_to_driver=False)
            outcome.append(None)
        except BaseException as exc:  # noqa: BLE001 - handed to the caller's thread
            outcome.append(exc)

    thread = threading.Thread(target=join, name="hwyeval-ray-init", daemon=True)
    thread.start()
    thread.join(timeout_s)
    if not outcome:
        raise RayAddressError(f"{target.shown}: Ray did not join the cluster within "
                              f"{timeout_s:g} s (is it a Ray head of this Ray version?)")
    if outcome[0] is not None:
        raise RayAddressError(f"{target.shown}: {type(outcome[0]).__name__}: "
                              f"{outcome[0]}") from outcome[0]


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
        local = dataclasses.replace(job, scenario=scenario, out_dir=tmp_path / "out")
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

    ``address``: the cluster (host:port, ray://host:port, auto; :func:`ray_target`),
    else ``RAY_ADDRESS`` from ``environ`` (default: this process's), else a private
    local Ray. A given one is checked first (:func:`check_target`, ``check_s`` [s]) and
    joined within ``connect_s`` [s]; RayAddressError otherwise.
    """

    def __init__(self, address: str | None = None, num_cpus_per_task: float = 1.0,
                 max_net_bytes: int = MAX_NET_BYTES, *,
                 environ: Mapping[str, str] | None = None, check_s: float = CHECK_S,
                 connect_s: float = CONNECT_S) -> None:
        try:
            import ray
        except ImportError as exc:
            raise RuntimeError(
                "the Ray executor needs the 'cluster' extra: pip install 'hwyeval[cluster]'"
            ) from exc
        self.ray = ray
        self.max_net_bytes = max_net_bytes
        self.target = ray_target(address, os.environ if environ is None else environ)
        self.started_ray = not ray.is_initialized()
        if self.started_ray:
            if self.target.address is None:
                ray.init(address="local", include_dashboard=False, log_to_driver=False)
            else:
                check_target(self.target, check_s)
                _init_within(ray, self.target, connect_s)
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
