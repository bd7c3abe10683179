"""The Ray executor on a real cluster of several nodes (issue 36): a head with no CPU
and a worker node that cannot see the driver's catalog folder (its own mount namespace,
a tmpfs over the folder), token authentication on, all on loopback
(tests/ray_cluster_support.py). Every file a run reads travels through Ray's object
store; the results equal the local executor's; a refused token is exit 2 saying what to
set; the pool follows the cluster: a node that joins mid-run gets actors and scenarios, a
worker node killed mid-run loses no scenario (its running ones run again on the other
node, which the executor's trace lines, ``HWYEVAL_RAY_TRACE=1``, show), and with no node
left the rest are errors after the wait and the command ends."""

from __future__ import annotations

import json
import os
import re
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import pandas as pd
import pytest

from tests.plain_nets import build_plain_net
from tests.ray_cluster_support import LocalCluster, RayNode
from tests.reliability_support import Background, hwyeval

pytestmark = [pytest.mark.sumo]
ray = pytest.importorskip("ray", reason="the 'cluster' extra is not installed")

COMMONROAD = Path("/work/shared/commonroad/USA_US101-3_3_T-1.xml")
ROOT = Path(__file__).resolve().parents[1]
PLUGIN = ROOT / "tests" / "crash_plugin.py"
# the columns of a run's wall-clock timing (the machine's, not the simulation's)
TIMING = re.compile(r"^(wall_s|realtime_factor|deadline_misses|deadline_miss_frac)$"
                    r"|_ms_(p\d+|max|mean)$|step_var_s2$")

NODES = '<nodes>\n  <node id="a" x="0" y="0"/>\n  <node id="b" x="600" y="0"/>\n</nodes>\n'
EDGES = '<edges>\n  <edge id="e0" from="a" to="b" numLanes="2" speed="30"/>\n</edges>\n'


def _catalog(folder: Path) -> Path:
    """folder/cat.toml: a bundled net, a netconvert net of its own, a replayed
    CommonRoad import (folder/imported/), a --plugin controller (folder/plugin_cr.py)."""
    build_plain_net(folder / "nets", "own", NODES, EDGES)
    (folder / "plugin_cr.py").write_text(PLUGIN.read_text())
    proc = hwyeval("import", "commonroad", "--out", str(folder / "imported"), str(COMMONROAD))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    generated = (folder / "imported" / "catalog.toml").read_text()
    block = generated[generated.index("[[scenario]]"):]
    block = re.sub(r'(net|tracks) = "', r'\1 = "imported/', block)
    block = block.replace("\nnet = ", '\ncontroller = "two_loop"\nnet = ', 1)  # as imported
    text = ('[defaults]\ncontroller = "lane_keep"\nduration_s = 4.0\nstep_s = 0.05\n'
            '[[scenario]]\nname = "bundled"\nnet = "straight_2lane"\n'
            'ego = { lane = 0, pos_m = 60.0, speed_mps = 20.0 }\n'
            '[[scenario]]\nname = "own_net"\nnet = "nets/own.net.xml"\n'
            'ego = { lane = 1, pos_m = 50.0, speed_mps = 20.0 }\n'
            '[[scenario]]\nname = "plugin_crash"\nnet = "nets/own.net.xml"\n'
            'controller = "crash_at_step_50"\n'
            'ego = { lane = 0, pos_m = 50.0, speed_mps = 20.0 }\n' + block)
    catalog = folder / "cat.toml"
    catalog.write_text(text)
    return catalog


@pytest.fixture(scope="module")
def cluster() -> Iterator[tuple[LocalCluster, Path]]:
    """The cluster (head: no CPU; node "a": 2 CPUs, the catalog folder hidden) and the
    catalog."""
    if not COMMONROAD.is_file():
        pytest.skip(f"{COMMONROAD} is not here")
    c = LocalCluster(("--num-cpus", "0"))
    try:
        folder = c.root / "catalog"
        folder.mkdir()
        catalog = _catalog(folder)
        c.add_worker("a", 2, hide=[folder])
        yield c, catalog
    finally:
        c.stop()


def _run(catalog: Path, out: Path, env: dict[str, str], *extra: str) -> tuple[float, str]:
    t0 = time.monotonic()
    proc = hwyeval("run", str(catalog), "--out", str(out), "--no-log", "--plugin",
                   str(catalog.parent / "plugin_cr.py"), *extra, env=env, timeout_s=900)
    took = time.monotonic() - t0
    assert proc.returncode in (0, 1), proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr, proc.stderr
    return took, proc.stdout + proc.stderr


def _same_cells(local: pd.DataFrame, remote: pd.DataFrame) -> None:
    """results.csv cell for cell, timing columns aside."""
    assert list(local.columns) == list(remote.columns)
    timing = [c for c in local.columns if TIMING.search(c)]
    keep = [c for c in local.columns if c not in timing]
    a = local[keep].sort_values("scenario").reset_index(drop=True)
    b = remote[keep].sort_values("scenario").reset_index(drop=True)
    pd.testing.assert_frame_equal(a, b, check_exact=True)


@pytest.mark.slow
def test_a_catalog_on_a_node_without_the_catalog_equals_the_local_run(
        cluster: tuple[LocalCluster, Path], tmp_path: Path) -> None:
    c, catalog = cluster
    node = c.node("a")
    assert node is not None
    raylet = node.raylet()
    assert raylet is not None
    # the worker node's own view of the catalog folder: the empty tmpfs
    assert os.listdir(f"/proc/{raylet}/root{catalog.parent}") == []
    env = {k: v for k, v in c.driver_env.items() if k != "RAY_TMPDIR"}
    _run(catalog, tmp_path / "local", env, "--jobs", "2")
    _, said = _run(catalog, tmp_path / "ray", c.driver_env, "--executor", "ray",
                   "--ray-address", c.address)
    local = pd.read_csv(tmp_path / "local" / "results.csv")
    remote = pd.read_csv(tmp_path / "ray" / "results.csv")
    status = remote.set_index("scenario")["status"]
    assert status["plugin_crash"] == "error", said
    assert (status[["bundled", "own_net"]] == "pass").all(), said
    assert status["usa_us101_3_3_t_1"] in ("pass", "fail"), said  # it ran its recording
    _same_cells(local, remote)
    tb = (tmp_path / "ray" / "plugin_crash" / "traceback.txt").read_text()
    assert "deliberate crash at step 50" in tb and str(catalog.parent / "plugin_cr.py") in tb
    assert "hwyeval-ray-" not in (tmp_path / "ray" / "own_net" / "run.json").read_text()


@pytest.mark.slow
def test_a_refused_token_is_exit_2_naming_the_address_and_what_to_set(
        cluster: tuple[LocalCluster, Path], tmp_path: Path) -> None:
    c, catalog = cluster
    for env in ({**c.driver_env, "RAY_AUTH_TOKEN": "0" * 32},
                {k: v for k, v in c.driver_env.items() if k != "RAY_AUTH_TOKEN"}):
        t0 = time.monotonic()
        proc = hwyeval("run", str(catalog), "--out", str(tmp_path / "out"), "--no-log",
                       "--plugin", str(catalog.parent / "plugin_cr.py"), "--executor", "ray",
                       "--ray-address", c.address, env=env, timeout_s=300)
        assert proc.returncode == 2, proc.stdout + proc.stderr
        assert c.address in proc.stderr and "RAY_AUTH_TOKEN" in proc.stderr, proc.stderr
        assert "refused" in proc.stderr and "Traceback" not in proc.stderr, proc.stderr
        assert not (tmp_path / "out").exists()
        assert time.monotonic() - t0 < 60.0  # not Ray's minute of retries


def _overhead_catalog(path: Path, n: int) -> Path:
    runs = "".join(f'[[scenario]]\nname = "r{i}"\nnet = "straight_2lane"\n'
                   'ego = { lane = 0, pos_m = 60.0, speed_mps = 20.0 }\n' for i in range(n))
    path.write_text('[defaults]\ncontroller = "lane_keep"\nduration_s = 4.0\nstep_s = 0.05\n'
                    + runs)
    return path


@pytest.mark.slow
def test_the_overhead_of_ray_over_the_local_executor_per_warm_run(
        cluster: tuple[LocalCluster, Path], tmp_path: Path) -> None:
    """Per run, once the node's actor is warm: the marginal time of a run, (T(N) -
    T(1)) / (N - 1) of whole commands, Ray's minus the local executor's, one worker
    each (--jobs 1), best of two rounds, in one sitting."""
    c, catalog = cluster
    n = 9
    one = _overhead_catalog(tmp_path / "one.toml", 1)
    many = _overhead_catalog(tmp_path / "many.toml", n)
    (tmp_path / "plugin_cr.py").write_text(PLUGIN.read_text())
    local_env = {k: v for k, v in c.driver_env.items() if k != "RAY_TMPDIR"}
    ray_args = ("--executor", "ray", "--ray-address", c.address, "--jobs", "1")
    best: dict[str, float] = {}
    for _ in range(2):
        for label, env, extra in (("local", local_env, ("--jobs", "1")),
                                  ("ray", c.driver_env, ray_args)):
            t1, _ = _run(one, tmp_path / f"{label}1", env, "--overwrite", *extra)
            tn, _ = _run(many, tmp_path / f"{label}n", env, "--overwrite", *extra)
            per_run = (tn - t1) / (n - 1)
            best[label] = min(best.get(label, float("inf")), per_run)
    overhead = best["ray"] - best["local"]
    load = os.getloadavg()
    print(f"\nper warm run: local {best['local']:.3f} s, ray {best['ray']:.3f} s, "
          f"overhead {overhead:+.3f} s; load {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    assert overhead <= 1.0  # the target is 0.3 s on a quiet machine (docs/cluster.md)


SLOW_PLUGIN = """
import time

from controllers import registry


class Slow:
    name = "slow_lane_keep"

    def __init__(self):
        self.inner = registry.make("lane_keep")

    def reset(self, context):
        self.inner.reset(context)

    def step(self, observation):
        time.sleep(0.05)  # a run lasts at least its steps x 50 ms: the kill finds runs going
        return self.inner.step(observation)

    def parameters(self):
        return {"name": self.name}

    def __getattr__(self, attr):
        return getattr(self.inner, attr)


registry.register("slow_lane_keep", lambda options: Slow())
"""
STEP_S = 0.05  # the slow catalogs' step: a run of D s sleeps at least D s (SLOW_PLUGIN)
FRESH_S = 1.5  # a run started on a node this recently is still going when it is killed
# the executor's trace lines (HWYEVAL_RAY_TRACE=1) and its lost-worker lines
EVENT = re.compile(r"^hwyeval: ray: (\S+): (?:(started|finished) on|its Ray worker on) "
                   r"node ([0-9a-f]{12})\b(.*)$")


def _slow_catalog(folder: Path, name: str, prefix: str, n: int, duration_s: float) -> Path:
    """folder/NAME.toml: ``n`` slow runs of ``duration_s`` [s] (SLOW_PLUGIN's controller,
    folder/slow_plugin.py)."""
    (folder / "slow_plugin.py").write_text(SLOW_PLUGIN)
    runs = "".join(f'[[scenario]]\nname = "{prefix}{i}"\nnet = "straight_2lane"\n'
                   'ego = { lane = 0, pos_m = 60.0, speed_mps = 20.0 }\n' for i in range(n))
    catalog = folder / f"{name}.toml"
    catalog.write_text(f'[defaults]\ncontroller = "slow_lane_keep"\nduration_s = {duration_s}'
                       f'\nstep_s = {STEP_S}\n' + runs)
    return catalog


def _background(c: LocalCluster, catalog: Path, out: Path, **env: str) -> Background:
    """``hwyeval run CATALOG --executor ray`` on the cluster, its trace lines on."""
    return Background("run", str(catalog), "--out", str(out), "--no-log", "--executor", "ray",
                      "--ray-address", c.address, "--plugin",
                      str(catalog.parent / "slow_plugin.py"),
                      env={**c.driver_env, "HWYEVAL_RAY_TRACE": "1", **env})


def _events(lines: Sequence[str]) -> list[tuple[int, str, str, str]]:
    """(line index, started | finished | lost, scenario, node id's first 12 characters)
    of the executor's stderr lines."""
    out = []
    for i, line in enumerate(lines):
        m = EVENT.match(line.strip())
        if m is None:
            continue
        scenario, verb, node, rest = m.groups()
        kind = verb or ("lost" if " was lost " in rest else "")
        if kind:
            out.append((i, kind, scenario, node))
    return out


def _worker(c: LocalCluster, name: str, cpus: int) -> RayNode:
    """The worker node ``name``, started now if it is not running."""
    return c.node(name) or c.add_worker(name, cpus, hide=[c.root / "catalog"])


def _wait_until(job: Background, what: str, ok: Callable[[], object],
                timeout_s: float = 300.0) -> None:
    """Poll ``ok()`` every 50 ms while the command runs; fail after ``timeout_s`` [s]."""
    deadline = time.monotonic() + timeout_s
    while not ok():
        assert job.proc.poll() is None, f"ended before {what}:\n{job.out}{job.err}"
        assert time.monotonic() < deadline, f"timed out waiting for {what}:\n{job.err}"
        time.sleep(0.05)


@pytest.mark.slow
def test_a_node_joining_mid_run_gets_actors_and_scenarios(
        cluster: tuple[LocalCluster, Path], tmp_path: Path) -> None:
    """The run starts on node "a" (2 actors, the manifest's count); node "b" joins once
    the first scenarios run: the pool grows by its actor (said on stderr) and "b" runs
    scenarios of the same command."""
    c, _ = cluster
    a = c.node("a")
    assert a is not None
    if c.node("b") is not None:
        pytest.skip("node b is up already: this test runs before the kill test")
    catalog = _slow_catalog(c.root / "catalog", "join", "j", 16, 6.0)
    out = tmp_path / "out"
    job = _background(c, catalog, out)
    try:
        _wait_until(job, "a first scenario started",
                    lambda: any(k == "started" for _, k, _, _ in _events(job.stderr)))
        b = c.add_worker("b", 1, hide=[c.root / "catalog"])
        code = job.wait(600)
    finally:
        job.kill()
    stderr = job.err
    assert code == 0, job.out + stderr
    res = pd.read_csv(out / "results.csv").set_index("scenario")
    assert sorted(res.index) == sorted(f"j{i}" for i in range(16)), stderr
    assert set(res["status"]) == {"pass"}, stderr
    assert json.loads((out / "manifest.json").read_text())["jobs"] == 2  # at the start
    assert b.node_id, "the cluster never named node b"
    a12, b12 = a.node_id[:12], b.node_id[:12]
    assert re.search(rf"^hwyeval: ray: node {b12} at \S+ joined: \+1 actor$", stderr,
                     re.MULTILINE), stderr
    finished = {s: n for _, k, s, n in _events(job.stderr) if k == "finished"}
    assert set(finished) == set(res.index), stderr
    assert set(finished.values()) == {a12, b12}, stderr  # both nodes ran scenarios
    print(f"\nnode b joined: it ran {sorted(s for s, n in finished.items() if n == b12)}")


def _fresh_on(job: Background, node12: str, seen: list[float]) -> set[str]:
    """The scenarios whose last event is a start on ``node12`` that the test saw less
    than FRESH_S ago (``seen``: when the test saw each stderr line)."""
    lines = list(job.stderr)
    now = time.monotonic()
    seen.extend([now] * (len(lines) - len(seen)))
    last: dict[str, tuple[int, str, str]] = {}
    for i, kind, scenario, node in _events(lines):
        last[scenario] = (i, kind, node)
    return {s for s, (i, kind, node) in last.items()
            if kind == "started" and node == node12 and now - seen[i] < FRESH_S}


@pytest.mark.slow
def test_a_worker_node_killed_mid_run_loses_no_scenario(
        cluster: tuple[LocalCluster, Path], tmp_path: Path) -> None:
    """Nodes "a" (2 CPUs) and "b" (1); node "a" is killed (its raylet, then the rest of
    its processes, as when its machine dies) once a run was published and a scenario
    started on "a" less than FRESH_S ago (it runs at least 4 s: it is going). Every
    scenario going on "a" at the kill is said lost there and runs again on "b" (or is an
    error); every run started on "a" finished there or was lost there; "a"'s leaving is
    said and it gets nothing afterwards; no scenario is lost; the command ends."""
    c, _ = cluster
    a, b = c.node("a"), _worker(c, "b", 1)
    assert a is not None and a.node_id and b.node_id
    a12, b12 = a.node_id[:12], b.node_id[:12]
    catalog = _slow_catalog(c.root / "catalog", "kill", "k", 8, 4.0)
    out = tmp_path / "out"
    job = _background(c, catalog, out)
    seen: list[float] = []
    try:
        _wait_until(job, "a run published and a run just started on node a",  # in order:
                    lambda: _fresh_on(job, a12, seen) and any(out.glob("k*/run.json")))
        going, at_kill = _fresh_on(job, a12, seen), len(seen)
        raylet = a.raylet()
        assert going and raylet is not None
        os.kill(raylet, 9)
        a.kill()  # and the rest of the node, as when its machine dies
        code = job.wait(600)
    finally:
        job.kill()
    stderr = job.err
    assert code in (0, 1), job.out + stderr
    res = pd.read_csv(out / "results.csv").set_index("scenario")
    assert sorted(res.index) == [f"k{i}" for i in range(8)], stderr
    assert set(res["status"]) <= {"pass", "error"}, res["status"]
    events = _events(job.stderr)
    for name in going:  # lost on "a", then finished on "b" or recorded as an error
        after = [(kind, node) for i, kind, s, node in events if s == name and i >= at_kill]
        assert after[:1] == [("lost", a12)], (name, stderr)
        if res.loc[name, "status"] == "pass":
            assert after[-2:] == [("started", b12), ("finished", b12)], (name, stderr)
        else:
            assert "Ray worker" in (out / name / "run.json").read_text(), name
    for i, kind, name, node in events:  # a run started on "a" ended there
        if kind == "started" and node == a12:
            following = [(k, n) for j, k, s, n in events if s == name and j > i]
            assert following[:1] in ([("finished", a12)], [("lost", a12)]), (name, stderr)
    left = [i for i, line in enumerate(job.stderr)
            if re.match(rf"hwyeval: ray: node {a12} at \S+ left: -2 actors$", line)]
    assert left, stderr  # the pool shrank, said once
    assert not [e for e in events if e[0] > left[0] and e[1] == "started" and e[3] == a12]
    lost = [li.strip() for li in job.stderr[at_kill:] if "hwyeval: ray:" in li]
    print(f"\ngoing on a at the kill: {sorted(going)}; after: "
          f"{res['status'].value_counts().to_dict()}; {lost}")


@pytest.mark.slow
def test_with_no_node_left_the_rest_are_errors_after_the_wait(
        cluster: tuple[LocalCluster, Path], tmp_path: Path) -> None:
    """Every worker node is killed once a run was published: the pool has no actor and
    no node to start one on; after HWYEVAL_RAY_NODE_WAIT_S the scenarios left are
    recorded as errors saying why, and the command ends (exit 1). Runs last: it leaves
    the cluster with its head only."""
    c, _ = cluster
    workers = [n for n in (c.node("a"), c.node("b")) if n is not None] or [_worker(c, "b", 1)]
    catalog = _slow_catalog(c.root / "catalog", "none", "n", 6, 4.0)
    out = tmp_path / "out"
    wait_s = 20
    job = _background(c, catalog, out, HWYEVAL_RAY_NODE_WAIT_S=str(wait_s))
    try:
        _wait_until(job, "a run published", lambda: any(out.glob("n*/run.json")))
        for node in workers:
            node.kill()
        t_kill = time.monotonic()
        code = job.wait(300)
        took = time.monotonic() - t_kill
    finally:
        job.kill()
    stderr = job.err
    assert code == 1, job.out + stderr
    res = pd.read_csv(out / "results.csv").set_index("scenario")
    assert sorted(res.index) == [f"n{i}" for i in range(6)], stderr
    errors = [s for s in res.index if res.loc[s, "status"] == "error"]
    why = f"no Ray worker left to run it: no node with a free CPU for {wait_s} s"
    waited = [s for s in errors if why in (out / s / "run.json").read_text()]
    assert waited, stderr
    assert f"waiting up to {wait_s} s for a node with a free CPU" in stderr, stderr
    for node in workers:  # each node's leaving said (Ray says it within the wait)
        assert re.search(rf"^hwyeval: ray: node {node.node_id[:12]} at \S+ left: -\d",
                         stderr, re.MULTILINE), stderr
    assert wait_s <= took < wait_s + 60, took
    print(f"\nno node left: {res['status'].value_counts().to_dict()} in {took:.1f} s after "
          f"the kill")
