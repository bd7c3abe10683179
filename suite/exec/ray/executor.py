"""The Ray executor: scenarios on a pool of long-lived actors across a Ray cluster.

Where: :func:`suite.exec.ray.target.ray_target` (a private local Ray without an
address; a given one checked, its token authentication handled). How: a pool of actors,
one per CPU of every node, at most ``--jobs`` (:mod:`suite.exec.ray.pool`), each
keeping the suite imported and its kernels loaded and running each scenario in a forked
child with the local executor's wall-clock backstop (:mod:`suite.exec.ray.actor`).

What is shipped: the job, and every file its run reads (:mod:`suite.exec.shipping`:
network, tracks, ``--plugin`` files), each distinct content put into Ray's object store
once, at most :data:`MAX_NET_BYTES` a file. Nothing else is read on a worker: not the
catalog's folder, not what lies beside a network. A file that cannot be shipped (too
large, unreadable) is that scenario's ``error``; the others go on.

As each scenario ends its run directory comes back as an archive and is published at
once (atomically), so a driver lost mid-catalog keeps what finished for ``--resume``. A
worker lost mid-run (its node died, its process was killed) does not lose the
scenario: it runs again on another actor, up to :data:`MAX_ATTEMPTS` times in all, and
is then recorded as an ``error`` saying so. The pool follows the cluster (its nodes
looked at every :data:`~suite.exec.ray.nodes.NODE_POLL_S`): a node that joins gets
actors, one that leaves has its actors dropped. With no actor left and no node to start
one on for :data:`NODE_WAIT_S` (``HWYEVAL_RAY_NODE_WAIT_S``), the scenarios not run are
recorded as errors, and the command ends. ``HWYEVAL_RAY_TRACE=1`` says on stderr the node
each scenario starts and finishes on. An actor that does not return within a run's
budget plus :data:`RETURN_GRACE_S` (beyond the child's own backstop) is killed and the
run recorded as a ``timeout``. On a stop request every actor is killed (their scenario
children die with them), nothing more is recorded, and Ray is shut down if this executor
started it.
"""

from __future__ import annotations

import os
import time
import traceback
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from reports.record import RunRecord
from reports.record.run import discard_staging, remove_path
from suite.exec.jobs import OnDone, RunJob, read_result, write_failure
from suite.exec.local import KILL_GRACE_S
from suite.exec.ray.actor import ScenarioActor
from suite.exec.ray.archive import unpack_run
from suite.exec.ray.nodes import NODE_POLL_S, alive_nodes, plan_pool
from suite.exec.ray.pool import ActorPool, PooledActor
from suite.exec.ray.say import say
from suite.exec.ray.target import CHECK_S, CONNECT_S, check_target, init_within, ray_target
from suite.exec.shipping import (
    MAX_FILE_BYTES,
    ShippedFile,
    job_files,
    plugin_without_source,
    read_shipped,
)
from suite.exec.signals import POLL_S, StopRequest

__all__ = ["MAX_ATTEMPTS", "MAX_NET_BYTES", "NODE_WAIT_ENV", "NODE_WAIT_S", "RETURN_GRACE_S",
           "TRACE_ENV", "RayExecutor", "Shipment", "ray_payload", "read_net"]

MAX_NET_BYTES = MAX_FILE_BYTES  # a file larger than this is not shipped to Ray [bytes]
MAX_ATTEMPTS = 3  # a scenario whose worker is lost runs at most this many times in all
RETURN_GRACE_S = 30.0  # an actor still busy this long after a run's kill deadline [s]
NODE_WAIT_S = 60.0  # no actor and no node to start one on this long: the rest are errors [s]
NODE_WAIT_ENV = "HWYEVAL_RAY_NODE_WAIT_S"  # overrides NODE_WAIT_S [s]
TRACE_ENV = "HWYEVAL_RAY_TRACE"  # 1: say the node each scenario starts and finishes on


def read_net(path: Path, limit: int = MAX_NET_BYTES) -> bytes:
    """The bytes of a network file (:func:`suite.exec.shipping.read_shipped`)."""
    return read_shipped(path, limit)


@dataclass
class Shipment:
    """A job as sent to an actor: the job (plug-in sources left out: they travel as
    files), the files its run reads, how many times it was sent [1]."""

    job: RunJob
    sent: RunJob
    files: tuple[ShippedFile, ...]
    attempts: int = 0
    started: float = field(default=0.0)  # time.monotonic() when last sent [s]


def ray_payload(job: RunJob, limit: int = MAX_NET_BYTES
                ) -> tuple[RunJob, dict[str, bytes], tuple[ShippedFile, ...]]:
    """Everything an actor receives for ``job``: the job as sent, the bytes of every file
    its run reads by SHA-256, and those files."""
    files = job_files(job, lambda p: read_shipped(p, limit))
    return (plugin_without_source(job), {f.sha256: data for f, data in files
                                         if data is not None}, tuple(f for f, _ in files))


def node_wait_s(environ: Mapping[str, str]) -> float:
    """How long a run with no actor waits for a node with a free CPU [s]:
    ``HWYEVAL_RAY_NODE_WAIT_S``, else :data:`NODE_WAIT_S`; ValueError if not a number
    >= 0."""
    text = environ.get(NODE_WAIT_ENV, "").strip()
    if not text:
        return NODE_WAIT_S
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not 0 <= value < float("inf"):
        raise ValueError(f"{NODE_WAIT_ENV}={text!r}: expected a number of seconds >= 0")
    return value


@dataclass
class _Watch:
    """When the driver looks at the cluster's nodes next, and since when (both
    ``time.monotonic()``) the pool has had no actor with scenarios left to run."""

    next_look: float
    empty_since: float | None = None


class RayExecutor:
    """Runs scenarios on a pool of Ray actors (module doc).

    ``address``: the cluster (host:port, ray://host:port, auto; :func:`ray_target`),
    else ``RAY_ADDRESS`` from ``environ`` (default: this process's), else a private
    local Ray. A given one is checked first (``check_s`` [s]) and joined within
    ``connect_s`` [s]; RayAddressError otherwise (a refused token says what to set).
    ``jobs``: at most this many actors (None: one per CPU of the cluster);
    ``num_cpus_per_task``: Ray CPUs each actor holds; ``max_net_bytes``: the largest
    file shipped [bytes]; ``max_attempts``: runs of a scenario whose worker is lost.
    """

    def __init__(self, address: str | None = None, num_cpus_per_task: float = 1.0,
                 max_net_bytes: int = MAX_NET_BYTES, *, jobs: int | None = None,
                 environ: Mapping[str, str] | None = None, check_s: float = CHECK_S,
                 connect_s: float = CONNECT_S, max_attempts: int = MAX_ATTEMPTS) -> None:
        if not num_cpus_per_task > 0:
            raise ValueError(f"num_cpus_per_task: expected > 0, got {num_cpus_per_task!r}")
        if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, int)
                                 or jobs < 1):
            raise ValueError(f"jobs: expected a whole number >= 1 or None, got {jobs!r}")
        if isinstance(max_attempts, bool) or not isinstance(max_attempts, int) \
                or max_attempts < 1:
            raise ValueError(f"max_attempts: expected a whole number >= 1, got {max_attempts!r}")
        try:
            import ray
        except ImportError as exc:
            raise RuntimeError(
                "the Ray executor needs the 'cluster' extra: pip install 'hwyeval[cluster]'"
            ) from exc
        self.ray: Any = ray
        self.max_net_bytes = max_net_bytes
        self.cpus = float(num_cpus_per_task)
        self.jobs = jobs
        self.max_attempts = max_attempts
        env = os.environ if environ is None else environ
        self.target = ray_target(address, env)
        self.node_wait_s = node_wait_s(env)
        self.trace = env.get(TRACE_ENV, "").strip() not in ("", "0")
        self.started_ray = not ray.is_initialized()
        if self.started_ray:
            if self.target.address is None:
                ray.init(address="local", include_dashboard=False, log_to_driver=False)
            else:
                check_target(self.target, check_s)
                init_within(ray, self.target, connect_s)
        self.refs: dict[str, Any] = {}  # SHA-256 -> object ref, one put per content
        self._known: dict[Path, tuple[ShippedFile, bytes | None]] = {}
        self.latency_s: dict[str, float] = {}  # scenario -> sent to published [s]

    # ------------------------------------------------------------------ shipping
    def _ship(self, jobs: Sequence[RunJob], done: OnDone) -> list[Shipment]:
        """A shipment per job, each distinct file content put into the object store
        once; a job with a file that cannot be shipped is recorded as an error at once."""
        out: list[Shipment] = []
        for job in jobs:
            try:
                remove_path(job.run_dir)
                files = job_files(job, lambda p: read_shipped(p, self.max_net_bytes),
                                  self._known)
            except (OSError, ValueError) as exc:
                done(write_failure(job, "error", f"cannot ship a file of it to Ray: {exc}"))
                continue
            for shipped, data in files:
                if data is not None and shipped.sha256 not in self.refs:
                    self.refs[shipped.sha256] = self.ray.put(data)
            out.append(Shipment(job, plugin_without_source(job),
                                tuple(f for f, _ in files)))
        return out

    # ------------------------------------------------------------------ the loop
    def run(self, jobs: Sequence[RunJob], on_done: OnDone | None = None,
            stop: StopRequest | None = None) -> list[RunRecord]:
        stop = stop if stop is not None else StopRequest()
        results: list[RunRecord] = []

        def done(record: RunRecord) -> None:
            results.append(record)
            if on_done is not None:
                on_done(record)

        if stop.requested or not jobs:
            return results
        pending = deque(self._ship(jobs, done))
        if not pending:
            return results
        pool = self._pool(len(pending))
        busy: dict[Any, tuple[PooledActor, Shipment]] = {}
        try:
            self._loop(pool, pending, busy, done, stop)
        finally:
            for _, item in busy.values():
                discard_staging(item.job.out_dir, item.job.name)
            pool.close(graceful=not stop.requested)
            if stop.requested and self.started_ray:
                self.ray.shutdown()
        return results

    def _plan(self, n_jobs: int) -> list[str]:
        """The node of each actor a run of ``n_jobs`` scenarios starts, on the cluster as
        it is now (:func:`plan_pool`: at most ``jobs``, at most one per
        ``num_cpus_per_task`` CPUs of each alive node)."""
        return plan_pool(alive_nodes(self.ray.nodes()), self._want(n_jobs), self.cpus)

    def _want(self, n_jobs: int) -> int:
        return min(n_jobs, self.jobs) if self.jobs else n_jobs

    def planned_actors(self, n_jobs: int) -> int:
        """How many actors (scenarios at once) a run of ``n_jobs`` scenarios starts on
        the cluster as it is now (the pool then follows the cluster's nodes)."""
        return len(self._plan(n_jobs))

    def _pool(self, n: int) -> ActorPool:
        from suite import __version__
        from suite.run.code_identity import hwyeval_code_sha256

        pool = ActorPool(self.ray, self.ray.remote(ScenarioActor), self.cpus,
                         version=__version__, code=hwyeval_code_sha256())
        nodes = alive_nodes(self.ray.nodes())
        pool.book.look(nodes)
        pool.add(plan_pool(nodes, self._want(n), self.cpus))
        return pool

    def _say_trace(self, line: str) -> None:
        if self.trace:
            say(line)

    def _loop(self, pool: ActorPool, pending: deque[Shipment],
              busy: dict[Any, tuple[PooledActor, Shipment]], done: OnDone,
              stop: StopRequest) -> None:
        watch = _Watch(next_look=time.monotonic() + NODE_POLL_S)
        while (pending or busy) and not stop.requested:
            pool.expire()
            if time.monotonic() >= watch.next_look:
                watch.next_look = time.monotonic() + NODE_POLL_S
                self._follow(pool, pending, busy)
            self._dispatch(pool, pending, busy)
            if self._out_of_workers(pool, pending, busy, watch, done):
                return
            waiting = list(busy) + list(pool.starting)
            if not waiting:
                time.sleep(POLL_S)
                continue
            ready, _ = self.ray.wait(waiting, num_returns=1, timeout=POLL_S)
            for ref in ready:
                if ref in pool.starting:
                    pool.started(ref)
                elif ref in busy:
                    self._returned(ref, busy.pop(ref), pool, pending, done)
            self._expire_busy(pool, busy, done)

    def _dispatch(self, pool: ActorPool, pending: deque[Shipment],
                  busy: dict[Any, tuple[PooledActor, Shipment]]) -> None:
        """Send a pending scenario to each idle actor."""
        while pending and pool.idle:
            actor, item = pool.idle.pop(0), pending.popleft()
            item.attempts += 1
            item.started = time.monotonic()
            refs = {f.sha256: self.refs[f.sha256] for f in item.files}
            busy[actor.handle.run.remote(item.sent, item.files, refs)] = (actor, item)
            self._say_trace(f"{item.job.name}: started on {pool.book.where(actor.node_id)} "
                            f"(attempt {item.attempts} of {self.max_attempts})")

    def _follow(self, pool: ActorPool, pending: deque[Shipment],
                busy: dict[Any, tuple[PooledActor, Shipment]]) -> None:
        """Look at the cluster's nodes; the pool follows them, within ``jobs`` actors and
        one actor per scenario left (:meth:`ActorPool.follow`)."""
        try:
            nodes = alive_nodes(self.ray.nodes())
        except (self.ray.exceptions.RayError, OSError, RuntimeError):
            return  # the head briefly unreachable: the next look
        room = len(pending) - len(pool.idle) - len(pool.starting)
        if self.jobs:
            room = min(room, self.jobs - pool.alive)
        pool.follow(nodes, room)

    def _out_of_workers(self, pool: ActorPool, pending: deque[Shipment],
                        busy: dict[Any, tuple[PooledActor, Shipment]], watch: _Watch,
                        done: OnDone) -> bool:
        """With scenarios to run and no actor (starting, idle or busy): wait for a node
        to start one on, ``node_wait_s`` at most; then record them as errors (True)."""
        if not pending or busy or pool.all:
            watch.empty_since = None
            return False
        now = time.monotonic()
        if watch.empty_since is None:
            watch.empty_since = watch.next_look = now
            say(f"no Ray worker to run the {len(pending)} scenario(s) left: waiting up to "
                f"{self.node_wait_s:g} s for a node with a free CPU")
            return False
        if now - watch.empty_since < self.node_wait_s:
            return False
        why = "; ".join(pool.lost[-3:]) or "the cluster has no node with a free CPU"
        while pending:
            item = pending.popleft()
            done(write_failure(item.job, "error", f"no Ray worker left to run it: no node "
                                                  f"with a free CPU for {self.node_wait_s:g} "
                                                  f"s ({why})"))
        return True

    def _returned(self, ref: Any, entry: tuple[PooledActor, Shipment], pool: ActorPool,
                  pending: deque[Shipment], done: OnDone) -> None:
        """A run's call returned: its archive published, or its worker lost (the run
        sent again, or recorded once out of attempts), or the call's error recorded."""
        from ray.exceptions import (
            NodeDiedError,
            ObjectLostError,
            RayActorError,
            WorkerCrashedError,
        )

        actor, item = entry
        job = item.job
        where = pool.book.where(actor.node_id)
        try:
            archive = self.ray.get(ref)
        except (RayActorError, WorkerCrashedError, NodeDiedError, ObjectLostError) as exc:
            why = f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
            pool.drop(actor, why, lost=True)
            again = item.attempts < self.max_attempts
            say(f"{job.name}: its Ray worker on {where} was lost ({why}); "
                + (f"runs again (attempt {item.attempts + 1} of {self.max_attempts})"
                   if again else "recorded as an error"))
            if again:
                pending.appendleft(item)
            else:
                done(write_failure(job, "error", f"its Ray worker was lost {item.attempts} "
                                                 f"times (last: {where}: {why})"))
            return
        except Exception:  # noqa: BLE001 - the call failed on the worker: this run's error
            pool.idle.append(actor)
            record = write_failure(job, "error", traceback.format_exc())
        else:
            pool.idle.append(actor)
            record = self._publish(archive, job)
            self.latency_s[job.name] = time.monotonic() - item.started
        self._say_trace(f"{job.name}: finished on {where} ({record.status})")
        done(record)

    @staticmethod
    def _publish(archive: bytes, job: RunJob) -> RunRecord:
        try:
            unpack_run(archive, job)
            return read_result(job)
        except Exception:  # noqa: BLE001 - a broken archive is an error, the rest go on
            return write_failure(job, "error", traceback.format_exc())

    def _expire_busy(self, pool: ActorPool, busy: dict[Any, tuple[PooledActor, Shipment]],
                     done: OnDone) -> None:
        """Kill an actor still running a scenario well past its kill deadline."""
        now = time.monotonic()
        for ref, (actor, item) in list(busy.items()):
            budget = item.job.timeout_s
            if budget is None or now - item.started <= budget + KILL_GRACE_S + RETURN_GRACE_S:
                continue
            del busy[ref]
            pool.drop(actor, "did not return from a run in time")
            self._say_trace(f"{item.job.name}: finished on {pool.book.where(actor.node_id)} "
                            "(timeout)")
            done(write_failure(item.job, "timeout", f"its Ray worker did not return within "
                                                    f"{now - item.started:.1f} s (budget "
                                                    f"{budget:g} s); killed"))
