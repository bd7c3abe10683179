"""The pool of long-lived scenario actors (:mod:`suite.exec.ray.actor`) across a Ray
cluster's nodes.

Size: one actor per ``cpus_per_actor`` CPUs of every alive node, at most ``want`` (the
number of scenarios, or ``--jobs``), spread round-robin over the nodes so that each node
has one before any has two (:func:`plan_pool`). During the run the pool follows the
cluster (:meth:`ActorPool.follow`, :mod:`suite.exec.ray.nodes`): a node that joins gets
actors (within the cap and the scenarios left), a node that leaves has its actors
dropped, each said on stderr. Each actor is pinned (softly) to its node. An actor is
usable once its ``ready`` call returned (its preload done); one not ready within
``start_s`` [s] is killed. An actor whose call failed with a lost worker or node is
dropped (its idle siblings on that node are asked ``ready`` again before they get work,
so that a dead node costs a scenario one attempt, not one per actor there), and its
node gets no new actor. An actor whose node has another hwyeval version installed is
dropped too; one whose code differs from the driver's
(:func:`suite.run.code_identity.hwyeval_code_sha256`: an uncommitted edit, another
checkout) is kept and said once on stderr.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from suite.exec.ray.nodes import NodeBook, NodeCpus, actors, plan_pool
from suite.exec.ray.say import say

__all__ = ["ACTOR_START_S", "ActorPool", "PooledActor"]

ACTOR_START_S = 300.0  # an actor must be ready (preload done) within this [s]
RECHECK_S = 30.0  # a sibling of a lost actor must answer ready within this [s]


@dataclass
class PooledActor:
    """One actor of the pool: its handle, the node it was placed on, its pending
    ``ready`` call (None once ready) and that call's deadline (``time.monotonic()``)."""

    handle: Any
    node_id: str
    ready_ref: Any = None
    deadline: float = 0.0
    info: dict[str, Any] = field(default_factory=dict)


class ActorPool:
    """Starts actors on nodes and tracks them: starting, idle, lost; follows the
    cluster's nodes (module doc)."""

    def __init__(self, ray: Any, actor_class: Any, cpus_per_actor: float = 1.0,
                 start_s: float = ACTOR_START_S, version: str = "", code: str = "") -> None:
        self.ray = ray
        self.actor_class = actor_class
        self.cpus = cpus_per_actor
        self.start_s = start_s
        self.version = version  # the driver's hwyeval version ('': not checked)
        self.code = code  # the driver's hwyeval code hash ('': not compared)
        self.warned: set[str] = set()  # code hashes warned about
        self.starting: dict[Any, PooledActor] = {}  # ready ref -> actor
        self.idle: list[PooledActor] = []
        self.all: list[PooledActor] = []
        self.lost: list[str] = []  # why each lost actor was dropped
        self.book = NodeBook(cpus_per_actor)

    @property
    def alive(self) -> int:
        """Actors that are starting, idle or running a scenario."""
        return len(self.all)

    def add(self, plan: Sequence[str]) -> None:
        """Start an actor on each node of ``plan`` (node ids)."""
        from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

        deadline = time.monotonic() + self.start_s
        for node_id in plan:
            handle = self.actor_class.options(
                num_cpus=self.cpus, max_restarts=0, max_task_retries=0,
                scheduling_strategy=NodeAffinitySchedulingStrategy(node_id, soft=True),
            ).remote()
            actor = PooledActor(handle, node_id, handle.ready.remote(), deadline)
            self.starting[actor.ready_ref] = actor
            self.all.append(actor)
            self.book.started[node_id] += 1

    def follow(self, nodes: Sequence[NodeCpus], room: int) -> None:
        """Take ``nodes`` (the alive ones, :func:`~suite.exec.ray.nodes.alive_nodes`) as
        the cluster now: drop the actors of the nodes that left, start at most ``room``
        actors on the nodes that joined or have CPUs no actor of this run held; each said
        on stderr."""
        joined, left = self.book.look(nodes)
        for node_id in left:
            gone = self.forget_node(node_id)
            if gone or self.book.started[node_id]:
                say(f"{self.book.where(node_id)} left: -{actors(gone)}")
        plan = plan_pool(self.book.spare(), max(room, 0), self.cpus)
        counts = Counter(plan)
        for node in joined:
            if node.cpus > 0:
                say(f"{self.book.where(node.node_id)} joined: +{actors(counts[node.node_id])}")
        new = {n.node_id for n in joined}
        for node_id, n in counts.items():
            if node_id not in new:
                say(f"{self.book.where(node_id)}: +{actors(n)} on its free CPUs")
        self.add(plan)

    def forget_node(self, node_id: str) -> int:
        """Kill and forget every actor on ``node_id`` (it left the cluster: a call still
        running there fails as a lost worker); returns how many actors the pool lost
        with it (those lost there before it was seen gone included)."""
        gone = [a for a in self.all if a.node_id == node_id]
        for actor in gone:
            self.kill(actor)
            self.all.remove(actor)
            if actor in self.idle:
                self.idle.remove(actor)
            self.starting.pop(actor.ready_ref, None)
        if gone:
            self.lost.append(f"{self.book.where(node_id)} left the cluster")
        return len(gone) + self.book.lost.pop(node_id, 0)

    def started(self, ref: Any) -> None:
        """A ``ready`` call returned: that actor is idle, or dropped if it failed."""
        actor = self.starting.pop(ref)
        actor.ready_ref = None
        try:
            actor.info = dict(self.ray.get(ref))
        except Exception as exc:  # noqa: BLE001 - an actor that could not start
            self.drop(actor, f"did not start: {type(exc).__name__}: {exc}", lost=True)
            return
        placed = str(actor.info.get("node_id") or actor.node_id)
        if placed != actor.node_id:  # a soft affinity placed it elsewhere
            self.book.started[actor.node_id] -= 1
            self.book.started[placed] += 1
            actor.node_id = placed
        version = str(actor.info.get("version", ""))
        if self.version and version != self.version:
            self.drop(actor, f"runs hwyeval {version or '?'}, the driver {self.version}: "
                             "install the same version on every node")
            return
        code = str(actor.info.get("code", ""))
        if self.code and code != self.code and code not in self.warned:
            self.warned.add(code)
            say(f"the hwyeval on {self.book.where(actor.node_id)} is not the driver's code "
                f"({code[:10]}, the driver's {self.code[:10]}: an edit, another checkout); "
                "its runs are recorded with the driver's")
        self.idle.append(actor)

    def expire(self) -> None:
        """Kill the actors whose ``ready`` is overdue."""
        now = time.monotonic()
        for ref, actor in list(self.starting.items()):
            if now > actor.deadline:
                del self.starting[ref]
                self.drop(actor, "not ready in time (no free CPU on its node, or a "
                                 "preload that hangs)")

    def drop(self, actor: PooledActor, why: str, lost: bool = False) -> None:
        """Kill ``actor`` and forget it; its idle siblings on the same node are asked
        ``ready`` again before they get more work. ``lost``: its worker or node was
        lost: the node gets no new actor."""
        self.kill(actor)
        if actor in self.all:
            self.all.remove(actor)
            if lost:
                self.book.lost[actor.node_id] += 1
                self.book.barred.add(actor.node_id)
        if actor in self.idle:
            self.idle.remove(actor)
        self.lost.append(f"actor on {self.book.where(actor.node_id)}: {why}")
        for sibling in [a for a in self.idle if a.node_id == actor.node_id]:
            self.idle.remove(sibling)
            sibling.ready_ref = sibling.handle.ready.remote()
            sibling.deadline = time.monotonic() + RECHECK_S
            self.starting[sibling.ready_ref] = sibling

    def kill(self, actor: PooledActor) -> None:
        try:
            self.ray.kill(actor.handle, no_restart=True)
        except Exception:  # noqa: BLE001 - already dead, its node gone
            pass

    def close(self, graceful: bool, wait_s: float = 5.0) -> None:
        """Kill every actor; ``graceful``: let the idle ones remove their folders first
        (within ``wait_s`` [s])."""
        if graceful and self.idle:
            refs = [a.handle.close.remote() for a in self.idle]
            try:
                self.ray.wait(refs, num_returns=len(refs), timeout=wait_s)
            except Exception:  # noqa: BLE001 - a lost node: its folder is gone with it
                pass
        for actor in self.all:
            self.kill(actor)
        self.all.clear()
        self.idle.clear()
        self.starting.clear()
