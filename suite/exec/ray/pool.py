"""The pool of long-lived scenario actors (:mod:`suite.exec.ray.actor`) across a Ray
cluster's nodes.

Size: one actor per ``cpus_per_actor`` CPUs of every alive node, at most ``want`` (the
number of scenarios, or ``--jobs``), spread round-robin over the nodes so that each node
has one before any has two (:func:`plan_pool`). Each actor is pinned (softly) to its
node. An actor is usable once its ``ready`` call returned (its preload done); one not
ready within ``start_s`` [s] is killed. An actor whose call failed with a lost worker or
node is dropped (its idle siblings on that node are asked ``ready`` again before they
get work, so that a dead node costs a scenario one attempt, not one per actor there).
An actor whose node has another hwyeval version installed is dropped too; one whose
code differs from the driver's (:func:`suite.run.code_identity.hwyeval_code_sha256`: an
uncommitted edit, another checkout) is kept and said once on stderr.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from suite.exec.ray.say import say

__all__ = ["ACTOR_START_S", "ActorPool", "NodeCpus", "PooledActor", "plan_pool"]

ACTOR_START_S = 300.0  # an actor must be ready (preload done) within this [s]
RECHECK_S = 30.0  # a sibling of a lost actor must answer ready within this [s]


@dataclass(frozen=True)
class NodeCpus:
    """An alive Ray node and its CPUs (Ray's ``CPU`` resource)."""

    node_id: str
    cpus: float

    def __post_init__(self) -> None:
        if not self.node_id:
            raise ValueError("NodeCpus.node_id: expected a node id")
        if not math.isfinite(self.cpus) or self.cpus < 0:
            raise ValueError(f"NodeCpus.cpus: expected a finite number >= 0, got {self.cpus!r}")


def alive_nodes(nodes: Iterable[Mapping[str, Any]]) -> list[NodeCpus]:
    """The alive nodes of ``ray.nodes()`` with their CPUs."""
    return [NodeCpus(str(n["NodeID"]), float(n.get("Resources", {}).get("CPU", 0.0)))
            for n in nodes if n.get("Alive")]


def plan_pool(nodes: Sequence[NodeCpus], want: int, cpus_per_actor: float = 1.0) -> list[str]:
    """The node id of each actor to start (module doc): at most ``want``, at most
    ``floor(cpus / cpus_per_actor)`` on a node, round-robin over the nodes."""
    if want < 0 or cpus_per_actor <= 0:
        raise ValueError(f"plan_pool: want >= 0 and cpus_per_actor > 0, got {want}, "
                         f"{cpus_per_actor}")
    slots = {n.node_id: int(n.cpus // cpus_per_actor + 1e-9) for n in nodes}
    plan: list[str] = []
    while len(plan) < want and any(slots.values()):
        for node in list(slots):
            if slots[node] > 0 and len(plan) < want:
                plan.append(node)
                slots[node] -= 1
    return plan


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
    """Starts the actors of a plan and tracks them: starting, idle, lost (module doc)."""

    def __init__(self, ray: Any, actor_class: Any, plan: Sequence[str],
                 cpus_per_actor: float = 1.0, start_s: float = ACTOR_START_S,
                 version: str = "", code: str = "") -> None:
        from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

        self.ray = ray
        self.version = version  # the driver's hwyeval version ('': not checked)
        self.code = code  # the driver's hwyeval code hash ('': not compared)
        self.warned: set[str] = set()  # code hashes warned about
        self.starting: dict[Any, PooledActor] = {}  # ready ref -> actor
        self.idle: list[PooledActor] = []
        self.all: list[PooledActor] = []
        self.lost: list[str] = []  # why each lost actor was dropped
        deadline = time.monotonic() + start_s
        for node_id in plan:
            handle = actor_class.options(
                num_cpus=cpus_per_actor, max_restarts=0, max_task_retries=0,
                scheduling_strategy=NodeAffinitySchedulingStrategy(node_id, soft=True),
            ).remote()
            actor = PooledActor(handle, node_id, handle.ready.remote(), deadline)
            self.starting[actor.ready_ref] = actor
            self.all.append(actor)

    @property
    def alive(self) -> int:
        """Actors that are starting, idle or running a scenario."""
        return len(self.all)

    def started(self, ref: Any) -> None:
        """A ``ready`` call returned: that actor is idle, or dropped if it failed."""
        actor = self.starting.pop(ref)
        actor.ready_ref = None
        try:
            actor.info = dict(self.ray.get(ref))
        except Exception as exc:  # noqa: BLE001 - an actor that could not start
            self.drop(actor, f"did not start: {type(exc).__name__}: {exc}")
            return
        version = str(actor.info.get("version", ""))
        if self.version and version != self.version:
            self.drop(actor, f"runs hwyeval {version or '?'}, the driver {self.version}: "
                             "install the same version on every node")
            return
        code = str(actor.info.get("code", ""))
        if self.code and code != self.code and code not in self.warned:
            self.warned.add(code)
            say(f"the hwyeval on node {actor.node_id[:12]} is not the driver's code "
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

    def drop(self, actor: PooledActor, why: str) -> None:
        """Kill ``actor`` and forget it; its idle siblings on the same node are asked
        ``ready`` again before they get more work."""
        self.kill(actor)
        if actor in self.all:
            self.all.remove(actor)
        if actor in self.idle:
            self.idle.remove(actor)
        self.lost.append(f"actor on node {actor.node_id[:12]}: {why}")
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
