"""The Ray actor pool follows the cluster's nodes (issue 36), its bookkeeping with a
stand-in for Ray (tests/test_ray_cluster.py does it on a real cluster): a node that joins
gets actors within the room left, one that leaves has its actors dropped and gets none
again, a node that lost an actor gets no new one, free CPUs of a known node are used when
the pool shrank below its cap; with no actor and no node for the wait, the scenarios left
are errors saying why."""

from __future__ import annotations

import itertools
from collections import deque
from pathlib import Path
from typing import Any

import pytest

from reports.record import RunRecord
from suite.catalog import load_catalog
from suite.exec.jobs import RunJob
from suite.exec.ray.executor import (
    NODE_WAIT_S,
    RayExecutor,
    Shipment,
    _Watch,
    node_wait_s,
)
from suite.exec.ray.nodes import NodeBook, NodeCpus, alive_nodes
from suite.exec.ray.pool import ActorPool
from suite.run.options import RunOptions

pytest.importorskip("ray", reason="the 'cluster' extra is not installed")

A, B, C = "a" * 56, "b" * 56, "c" * 56


class _Call:
    """``handle.ready`` / ``handle.run``: ``.remote()`` gives a fresh reference."""

    refs = itertools.count()

    def remote(self, *args: Any) -> str:
        return f"ref{next(self.refs)}"


class _Handle:
    def __init__(self, node_id: str) -> None:
        self.node_id = node_id
        self.ready = _Call()
        self.run = _Call()


class _ActorClass:
    """``actor_class.options(...).remote()``: a handle on the node asked for."""

    def __init__(self) -> None:
        self.node_id = ""

    def options(self, **options: Any) -> _ActorClass:
        self.node_id = options["scheduling_strategy"].node_id
        return self

    def remote(self) -> _Handle:
        return _Handle(self.node_id)


class _Ray:
    def __init__(self) -> None:
        self.killed: list[_Handle] = []

    def kill(self, handle: _Handle, no_restart: bool = True) -> None:
        self.killed.append(handle)


def _pool(nodes: list[NodeCpus], plan: list[str]) -> tuple[ActorPool, _Ray]:
    ray = _Ray()
    pool = ActorPool(ray, _ActorClass())
    pool.book.look(nodes)
    pool.add(plan)
    return pool, ray


def _on(pool: ActorPool) -> list[str]:
    return sorted(a.node_id[0] for a in pool.all)


def test_ray_nodes_are_read_with_their_cpus_and_address() -> None:
    nodes = alive_nodes([{"NodeID": A, "Alive": True, "NodeManagerAddress": "10.0.0.1",
                          "Resources": {"CPU": 2.0}},
                         {"NodeID": B, "Alive": False, "Resources": {"CPU": 4.0}},
                         {"NodeID": C, "Alive": True, "Resources": {}}])
    assert nodes == [NodeCpus(A, 2.0, "10.0.0.1"), NodeCpus(C, 0.0)]
    book = NodeBook()
    book.look(nodes)
    assert book.where(A) == "node aaaaaaaaaaaa at 10.0.0.1"
    assert book.where(C) == "node cccccccccccc"


def test_a_node_that_joins_gets_actors_within_the_room(capsys: pytest.CaptureFixture[str]
                                                       ) -> None:
    pool, _ = _pool([NodeCpus(A, 2.0)], [A, A])
    pool.follow([NodeCpus(A, 2.0), NodeCpus(B, 2.0, "10.0.0.2")], room=1)
    assert _on(pool) == ["a", "a", "b"] and len(pool.starting) == 3
    assert capsys.readouterr().err == "hwyeval: ray: node bbbbbbbbbbbb at 10.0.0.2 joined: " \
                                      "+1 actor\n"
    pool.follow([NodeCpus(A, 2.0), NodeCpus(B, 2.0, "10.0.0.2"), NodeCpus(C, 1.0)], room=0)
    assert _on(pool) == ["a", "a", "b"]  # no room: the scenarios left have their actors
    assert "node cccccccccccc joined: +0 actors" in capsys.readouterr().err
    pool.follow([NodeCpus(A, 2.0), NodeCpus(B, 2.0), NodeCpus(C, 1.0)], room=5)
    assert _on(pool) == ["a", "a", "b", "b", "c"]  # every CPU once, not more
    err = capsys.readouterr().err
    assert "node bbbbbbbbbbbb at 10.0.0.2: +1 actor on its free CPUs" in err
    assert "node cccccccccccc: +1 actor on its free CPUs" in err


def test_a_node_that_leaves_has_its_actors_dropped_and_gets_none_again(
        capsys: pytest.CaptureFixture[str]) -> None:
    pool, ray = _pool([NodeCpus(A, 2.0), NodeCpus(B, 2.0)], [A, B, A])
    first = pool.all[0]
    pool.drop(first, "RayActorError: lost", lost=True)  # lost before Ray said "a" is dead
    pool.follow([NodeCpus(B, 2.0)], room=3)
    assert _on(pool) == ["b", "b"]  # "a"'s other actor dropped, "b" filled, "a" never again
    assert {h.node_id for h in ray.killed} == {A}
    err = capsys.readouterr().err
    assert "hwyeval: ray: node aaaaaaaaaaaa left: -2 actors\n" in err
    assert "node aaaaaaaaaaaa left the cluster" in pool.lost
    pool.follow([NodeCpus(A, 2.0), NodeCpus(B, 2.0)], room=3)  # a stale view: still not "a"
    assert _on(pool) == ["b", "b"]


def test_a_node_that_lost_an_actor_gets_no_new_one_but_a_known_nodes_free_cpus_do(
        capsys: pytest.CaptureFixture[str]) -> None:
    pool, _ = _pool([NodeCpus(A, 2.0), NodeCpus(B, 2.0)], [A, B])  # --jobs 2
    pool.drop(pool.all[0], "RayActorError: lost", lost=True)
    pool.follow([NodeCpus(A, 2.0), NodeCpus(B, 2.0)], room=1)
    assert _on(pool) == ["b", "b"]
    assert "node bbbbbbbbbbbb: +1 actor on its free CPUs" in capsys.readouterr().err
    pool.drop(pool.all[0], "did not return from a run in time")  # not lost: "b" is fine
    pool.follow([NodeCpus(A, 2.0), NodeCpus(B, 2.0)], room=1)
    assert _on(pool) == ["b"]  # but each CPU of it had its actor once


def test_the_wait_for_a_node_is_60_s_unless_set() -> None:
    assert node_wait_s({}) == NODE_WAIT_S == 60.0
    assert node_wait_s({"HWYEVAL_RAY_NODE_WAIT_S": " 5 "}) == 5.0
    for bad in ("-1", "soon", "inf", "nan"):
        with pytest.raises(ValueError, match="HWYEVAL_RAY_NODE_WAIT_S"):
            node_wait_s({"HWYEVAL_RAY_NODE_WAIT_S": bad})


def test_with_no_actor_and_no_node_the_scenarios_left_are_errors_after_the_wait(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    catalog = tmp_path / "c.toml"
    catalog.write_text('[defaults]\ncontroller = "lane_keep"\nduration_s = 1.0\nstep_s = 0.05\n'
                       + "".join(f'[[scenario]]\nname = "s{i}"\nnet = "straight_2lane"\n'
                                 'ego = { lane = 0, pos_m = 60.0, speed_mps = 20.0 }\n'
                                 for i in range(2)))
    jobs = [RunJob(sc, tmp_path / "out", RunOptions(write_rrd=False))
            for sc in load_catalog(catalog).scenarios]
    executor = RayExecutor.__new__(RayExecutor)
    executor.node_wait_s = 0.0
    pool, _ = _pool([], [])
    pool.lost.append("node aaaaaaaaaaaa left the cluster")
    pending = deque(Shipment(j, j, ()) for j in jobs)
    watch = _Watch(next_look=1e18)
    done: list[RunRecord] = []
    assert not executor._out_of_workers(pool, pending, {}, watch, done.append)
    assert watch.next_look < 1e18  # the nodes are looked at at once
    assert "waiting up to 0 s for a node with a free CPU" in capsys.readouterr().err
    assert executor._out_of_workers(pool, pending, {}, watch, done.append)
    assert not pending and [r.status for r in done] == ["error", "error"]
    assert done[0].outcome.error == ("no Ray worker left to run it: no node with a free CPU "
                                     "for 0 s (node aaaaaaaaaaaa left the cluster)")
