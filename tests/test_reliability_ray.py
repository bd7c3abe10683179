"""What the Ray executor ships (W15): the job and the bytes of the one network its
scenario references, size-capped; never the catalog's folder (a ``.ssh/id_rsa`` beside
a catalog stayed on the cluster), and a network outside that folder is shipped too."""

from __future__ import annotations

import pickle
import shutil
from pathlib import Path
from typing import Any

import pandas as pd
import pytest

import sumo_nets
from reports.record import RunRecord
from suite.catalog import load_catalog
from suite.exec.executors import RayExecutor, RunJob, ray_payload
from suite.exec.ray_executor import read_net
from suite.run.runner import RunOptions
from tests.reliability_support import hwyeval

SECRET = b"-----BEGIN OPENSSH PRIVATE KEY----- do not ship me"


def _layout(tmp_path: Path) -> Path:
    """catalogs/cat.toml with a key and a big file beside it; its net in ../nets/."""
    cat_dir = tmp_path / "catalogs"
    (cat_dir / ".ssh").mkdir(parents=True)
    (cat_dir / ".ssh" / "id_rsa").write_bytes(SECRET)
    (cat_dir / "data.bin").write_bytes(SECRET * 1000)
    nets = tmp_path / "nets"
    nets.mkdir()
    shutil.copy(sumo_nets.net_path("straight_2lane"), nets / "road.net.xml")
    catalog = cat_dir / "cat.toml"
    catalog.write_text('[defaults]\ncontroller = "lane_keep"\nduration_s = 1.0\nstep_s = 0.05\n'
                       '[[scenario]]\nname = "outside_net"\nnet = "../nets/road.net.xml"\n'
                       'ego = { lane = 0, pos_m = 60.0, speed_mps = 20.0 }\n'
                       '[[scenario]]\nname = "bundled_net"\nnet = "straight_3lane"\n'
                       'ego = { lane = 1, pos_m = 60.0, speed_mps = 20.0 }\n')
    return catalog


def _jobs(catalog: Path, out: Path) -> list[RunJob]:
    return [RunJob(sc, out, RunOptions(write_rrd=False))
            for sc in load_catalog(catalog).scenarios]


def test_the_payload_is_the_job_and_its_net_only(tmp_path: Path) -> None:
    jobs = _jobs(_layout(tmp_path), tmp_path / "out")
    for job in jobs:
        shipped, net = ray_payload(job)
        assert shipped is job
        assert net == job.scenario.net_path.read_bytes()
        assert SECRET not in pickle.dumps((shipped, net))
    assert jobs[0].scenario.net_path == (tmp_path / "nets" / "road.net.xml").resolve()


def test_a_net_over_the_cap_or_not_a_file_is_refused(tmp_path: Path) -> None:
    big = tmp_path / "big.net.xml"
    big.write_bytes(b"x" * 2048)
    with pytest.raises(ValueError, match="more than the 1024 bytes"):
        read_net(big, limit=1024)
    with pytest.raises(ValueError, match="not a regular file"):
        read_net(tmp_path, limit=1024)


class _FakeRay:
    """Records everything the executor would hand to Ray."""

    def __init__(self) -> None:
        self.shipped: list[Any] = []

    def put(self, value: Any) -> str:
        self.shipped.append(value)
        return f"ref{len(self.shipped)}"


class _FakeRemote:
    def __init__(self, ray: _FakeRay) -> None:
        self.ray = ray

    def remote(self, *args: Any) -> str:
        self.ray.shipped.append(args)
        return f"task{len(self.ray.shipped)}"


def _executor(max_net_bytes: int) -> tuple[RayExecutor, _FakeRay]:
    executor = RayExecutor.__new__(RayExecutor)
    fake = _FakeRay()
    executor.ray = fake
    executor.max_net_bytes = max_net_bytes
    executor.started_ray = False
    executor._remote = _FakeRemote(fake)
    return executor, fake


def test_each_net_is_put_once_and_nothing_else_is_shipped(tmp_path: Path) -> None:
    catalog = _layout(tmp_path)
    jobs = _jobs(catalog, tmp_path / "out") * 2
    executor, fake = _executor(256 * 1024 * 1024)
    errors: list[RunRecord] = []
    refs = executor._submit(jobs, errors.append)
    assert not errors and len(refs) == 4
    nets = [item for item in fake.shipped if isinstance(item, bytes)]
    assert len(nets) == 2  # one put per network, whatever the number of scenarios
    assert SECRET not in pickle.dumps(fake.shipped)


def test_a_net_that_cannot_be_shipped_is_that_scenarios_error_only(tmp_path: Path) -> None:
    catalog = _layout(tmp_path)
    jobs = _jobs(catalog, tmp_path / "out")
    small = min(j.scenario.net_path.stat().st_size for j in jobs)
    executor, fake = _executor(small)  # the larger of the two nets is over the cap
    errors: list[RunRecord] = []
    refs = executor._submit(jobs, errors.append)
    assert len(refs) == 1 and len(errors) == 1
    assert errors[0].status == "error"
    assert "cannot ship the network to Ray" in (errors[0].outcome.error or "")
    assert errors[0].run_dir is not None and errors[0].run_dir.is_dir()


@pytest.mark.sumo
@pytest.mark.slow
def test_ray_runs_a_scenario_whose_net_lies_outside_the_catalogs_folder(tmp_path: Path) -> None:
    pytest.importorskip("ray", reason="the 'cluster' extra is not installed")
    out = tmp_path / "out"
    proc = hwyeval("run", str(_layout(tmp_path)), "--out", str(out), "--executor", "ray",
                   "--no-log")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    res = pd.read_csv(out / "results.csv").set_index("scenario")
    assert set(res["status"]) == {"pass"} and len(res) == 2
    assert not [p for p in out.iterdir() if p.name.startswith(".")]


@pytest.mark.sumo
@pytest.mark.slow
def test_ray_kills_a_hung_run_at_its_budget(tmp_path: Path) -> None:
    """A step hung in C (the GIL held) on a Ray worker: the run is a timeout within its
    budget plus the kill grace, as with the local executor, not left running."""
    import time

    catalog = tmp_path / "hang.toml"
    catalog.write_text('[defaults]\nduration_s = 10.0\nstep_s = 0.05\n'
                       '[[scenario]]\nname = "hangs"\nnet = "straight_2lane"\n'
                       'controller = "hang_at_step_20"\n'
                       'ego = { lane = 0, pos_m = 60.0, speed_mps = 20.0 }\n')
    plugin = Path(__file__).with_name("hang_plugin.py")
    t0 = time.monotonic()
    proc = hwyeval("run", str(catalog), "--out", str(tmp_path / "out"), "--no-log",
                   "--executor", "ray", "--timeout", "5", "--plugin", str(plugin))
    took = time.monotonic() - t0
    assert proc.returncode == 1, proc.stdout + proc.stderr
    status = pd.read_csv(tmp_path / "out" / "results.csv").set_index("scenario")["status"]
    assert status["hangs"] == "timeout"
    assert took < 90.0  # Ray's start, 5 s of budget, the grace: not an hour
