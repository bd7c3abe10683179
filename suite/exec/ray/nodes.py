"""The Ray cluster's nodes as the actor pool (:mod:`suite.exec.ray.pool`) sees them during
a run.

The pool is planned from the alive nodes at the start (:func:`plan_pool`: one actor per
``cpus_per_actor`` CPUs of every node, at most ``want``, round-robin) and then follows
the cluster: the driver looks at ``ray.nodes()`` every :data:`NODE_POLL_S` and the
:class:`NodeBook` says which nodes joined (they get actors, within the ``--jobs`` cap
and the scenarios left), which left (their actors are dropped and never recreated
there), and which alive nodes still have CPUs no actor of this run ever held (used
when the pool shrank below its cap). A node gets no more actors once one of its actors
was lost (its node dying is the usual cause, and Ray says a node is dead only some
seconds after its processes are gone) or once it left.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

__all__ = ["NODE_POLL_S", "NodeBook", "NodeCpus", "alive_nodes", "plan_pool"]

NODE_POLL_S = 2.0  # the driver looks at the cluster's nodes this often during a run [s]


@dataclass(frozen=True)
class NodeCpus:
    """An alive Ray node, its CPUs (Ray's ``CPU`` resource) and its address."""

    node_id: str
    cpus: float
    address: str = ""

    def __post_init__(self) -> None:
        if not self.node_id:
            raise ValueError("NodeCpus.node_id: expected a node id")
        if not math.isfinite(self.cpus) or self.cpus < 0:
            raise ValueError(f"NodeCpus.cpus: expected a finite number >= 0, got {self.cpus!r}")


def alive_nodes(nodes: Iterable[Mapping[str, Any]]) -> list[NodeCpus]:
    """The alive nodes of ``ray.nodes()`` with their CPUs and addresses."""
    return [NodeCpus(str(n["NodeID"]), float(n.get("Resources", {}).get("CPU", 0.0)),
                     str(n.get("NodeManagerAddress", "")))
            for n in nodes if n.get("Alive")]


def plan_pool(nodes: Sequence[NodeCpus], want: int, cpus_per_actor: float = 1.0) -> list[str]:
    """The node id of each actor to start (module doc): at most ``want``, at most
    ``floor(cpus / cpus_per_actor)`` on a node, round-robin over the nodes."""
    if want < 0 or cpus_per_actor <= 0:
        raise ValueError(f"plan_pool: want >= 0 and cpus_per_actor > 0, got {want}, "
                         f"{cpus_per_actor}")
    slots = {n.node_id: slots_of(n.cpus, cpus_per_actor) for n in nodes}
    plan: list[str] = []
    while len(plan) < want and any(slots.values()):
        for node in list(slots):
            if slots[node] > 0 and len(plan) < want:
                plan.append(node)
                slots[node] -= 1
    return plan


def slots_of(cpus: float, cpus_per_actor: float) -> int:
    """How many actors of ``cpus_per_actor`` CPUs ``cpus`` CPUs hold."""
    return max(0, int(cpus // cpus_per_actor + 1e-9))


@dataclass
class NodeBook:
    """What a run's pool knows of the nodes (module doc): the alive ones at the last look
    (CPUs, address), how many actors each ever received, how many it lost not yet said
    with its leaving, and the nodes that get no more actors."""

    cpus_per_actor: float = 1.0
    alive: dict[str, NodeCpus] = field(default_factory=dict)
    addresses: dict[str, str] = field(default_factory=dict)
    started: Counter[str] = field(default_factory=Counter)
    lost: Counter[str] = field(default_factory=Counter)
    barred: set[str] = field(default_factory=set)

    def look(self, nodes: Sequence[NodeCpus]) -> tuple[list[NodeCpus], list[str]]:
        """Take the alive ``nodes`` as the cluster now; returns the nodes that joined
        since the last look and the ids of those that left (barred from now on)."""
        now = {n.node_id: n for n in nodes}
        joined = [n for n in nodes if n.node_id not in self.alive]
        left = [node_id for node_id in self.alive if node_id not in now]
        self.alive = now
        for node in nodes:
            if node.address:
                self.addresses[node.node_id] = node.address
        self.barred.update(left)
        return joined, left

    def spare(self) -> list[NodeCpus]:
        """The alive nodes that may take more actors, with the CPUs no actor of this run
        ever held there."""
        out = []
        for node in self.alive.values():
            free = slots_of(node.cpus, self.cpus_per_actor) - self.started[node.node_id]
            if node.node_id not in self.barred and free > 0:
                out.append(NodeCpus(node.node_id, free * self.cpus_per_actor, node.address))
        return out

    def where(self, node_id: str) -> str:
        """``node <first 12 characters of its id>[ at <address>]``."""
        address = self.addresses.get(node_id, "")
        return f"node {node_id[:12]}" + (f" at {address}" if address else "")


def actors(n: int) -> str:
    """``1 actor``, ``2 actors``."""
    return f"{n} actor" + ("" if n == 1 else "s")
