"""The Ray executor on a real cluster of several nodes (issue 36): a head with no CPU
and a worker node that cannot see the driver's catalog folder (its own mount namespace,
a tmpfs over the folder), token authentication on, all on loopback
(tests/ray_cluster_support.py). Every file a run reads travels through Ray's object
store; the results equal the local executor's; a refused token is exit 2 saying what to
set; a worker node killed mid-run loses no scenario and the command ends."""

from __future__ import annotations

import os
import re
import time
from collections.abc import Iterator
from pathlib import Path

import pandas as pd
import pytest

from tests.plain_nets import build_plain_net
from tests.ray_cluster_support import LocalCluster
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
    node = c.nodes[1]
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
        time.sleep(0.02)  # 80 steps: a run of ~2 s, so that the kill finds runs going
        return self.inner.step(observation)

    def parameters(self):
        return {"name": self.name}

    def __getattr__(self, attr):
        return getattr(self.inner, attr)


registry.register("slow_lane_keep", lambda options: Slow())
"""


@pytest.mark.slow
def test_a_worker_node_killed_mid_run_loses_no_scenario(
        cluster: tuple[LocalCluster, Path], tmp_path: Path) -> None:
    """Node "b" joins; node "a"'s raylet is killed once the first run is published, then
    the rest of its processes: its running scenarios run again on "b" (or are recorded
    as errors), none is lost, and the command ends."""
    c, _ = cluster
    folder = c.root / "catalog"
    c.add_worker("b", 1, hide=[folder])
    (folder / "slow_plugin.py").write_text(SLOW_PLUGIN)
    runs = "".join(f'[[scenario]]\nname = "k{i}"\nnet = "straight_2lane"\n'
                   'ego = { lane = 0, pos_m = 60.0, speed_mps = 20.0 }\n' for i in range(8))
    catalog = folder / "kill.toml"
    catalog.write_text('[defaults]\ncontroller = "slow_lane_keep"\nduration_s = 4.0\n'
                       'step_s = 0.05\n' + runs)
    out = tmp_path / "out"
    job = Background("run", str(catalog), "--out", str(out), "--no-log", "--executor", "ray",
                     "--ray-address", c.address, "--plugin", str(folder / "slow_plugin.py"),
                     env=c.driver_env)
    try:
        deadline = time.monotonic() + 300
        while not any(out.glob("k*/run.json")) and time.monotonic() < deadline:
            assert job.proc.poll() is None, job.out + job.err
            time.sleep(0.1)
        raylet = c.nodes[1].raylet()
        assert raylet is not None
        os.kill(raylet, 9)
        c.nodes[1].kill()  # and the rest of the node, as when its machine dies
        code = job.wait(600)
    finally:
        job.kill()
    stdout, stderr = job.out, job.err
    assert code in (0, 1), stdout + stderr
    res = pd.read_csv(out / "results.csv").set_index("scenario")
    assert sorted(res.index) == [f"k{i}" for i in range(8)], stdout + stderr
    assert set(res["status"]) <= {"pass", "error"}, res["status"]
    lost = [li for li in stderr.splitlines() if "hwyeval: ray:" in li]
    print(f"\nafter the kill: {res['status'].value_counts().to_dict()}; {lost}")
