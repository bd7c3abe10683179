"""What the Ray executor ships (W15, issue 36): the job and the bytes of the files its
run reads (network, tracks, ``--plugin`` files), size-capped, each content put once;
never the catalog's folder (a ``.ssh/id_rsa`` beside a catalog stayed on the cluster),
and a network outside that folder is shipped too. On the worker the paths are rewritten
to local copies, and put back in the record."""

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
from suite.exec.ray.nodes import NodeCpus, plan_pool
from suite.exec.ray_executor import read_net
from suite.exec.shipping import localise, restore_paths
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
        sent, contents, files = ray_payload(job)
        assert sent == job
        assert list(contents.values()) == [job.scenario.net_path.read_bytes()]
        assert [(f.role, f.path) for f in files] == [("net", job.scenario.net_path)]
        assert SECRET not in pickle.dumps((sent, contents, files))
    assert jobs[0].scenario.net_path == (tmp_path / "nets" / "road.net.xml").resolve()


def test_a_net_over_the_cap_or_not_a_file_is_refused(tmp_path: Path) -> None:
    big = tmp_path / "big.net.xml"
    big.write_bytes(b"x" * 2048)
    with pytest.raises(ValueError, match="more than the 1024 bytes"):
        read_net(big, limit=1024)
    with pytest.raises(ValueError, match="not a regular file"):
        read_net(tmp_path, limit=1024)


class _FakeRay:
    """Records everything the executor would put into Ray's object store."""

    def __init__(self) -> None:
        self.shipped: list[Any] = []

    def put(self, value: Any) -> str:
        self.shipped.append(value)
        return f"ref{len(self.shipped)}"


def _executor(max_net_bytes: int) -> tuple[RayExecutor, _FakeRay]:
    executor = RayExecutor.__new__(RayExecutor)
    fake = _FakeRay()
    executor.ray = fake
    executor.max_net_bytes = max_net_bytes
    executor.started_ray = False
    executor.refs = {}
    executor._known = {}
    return executor, fake


def test_each_net_is_put_once_and_nothing_else_is_shipped(tmp_path: Path) -> None:
    catalog = _layout(tmp_path)
    jobs = _jobs(catalog, tmp_path / "out") * 2
    executor, fake = _executor(256 * 1024 * 1024)
    errors: list[RunRecord] = []
    shipments = executor._ship(jobs, errors.append)
    assert not errors and len(shipments) == 4
    assert len(fake.shipped) == 2  # one put per network, whatever the number of scenarios
    assert SECRET not in pickle.dumps(fake.shipped)
    assert SECRET not in pickle.dumps([(s.sent, s.files) for s in shipments])


def test_the_same_content_at_two_paths_is_put_once(tmp_path: Path) -> None:
    catalog = _layout(tmp_path)
    shutil.copy(sumo_nets.net_path("straight_3lane"), tmp_path / "nets" / "copy.net.xml")
    catalog.write_text(catalog.read_text() + '[[scenario]]\nname = "copied_net"\n'
                       'net = "../nets/copy.net.xml"\n'
                       'ego = { lane = 1, pos_m = 60.0, speed_mps = 20.0 }\n')
    jobs = _jobs(catalog, tmp_path / "out")
    assert len({j.scenario.net_path for j in jobs}) == 3
    executor, fake = _executor(256 * 1024 * 1024)
    assert len(executor._ship(jobs, [].append)) == len(jobs)
    assert len(fake.shipped) == 2  # straight_3lane and its copy: one content


def test_a_net_that_cannot_be_shipped_is_that_scenarios_error_only(tmp_path: Path) -> None:
    catalog = _layout(tmp_path)
    jobs = _jobs(catalog, tmp_path / "out")
    small = min(j.scenario.net_path.stat().st_size for j in jobs)
    executor, fake = _executor(small)  # the larger of the two nets is over the cap
    errors: list[RunRecord] = []
    shipments = executor._ship(jobs, errors.append)
    assert len(shipments) == 1 and len(errors) == 1
    assert errors[0].status == "error"
    assert "cannot ship a file of it to Ray" in (errors[0].outcome.error or "")
    assert errors[0].run_dir is not None and errors[0].run_dir.is_dir()


def test_tracks_and_plugin_files_travel_and_the_worker_reads_only_its_copies(
        tmp_path: Path) -> None:
    """A replayed scenario's tracks and a --plugin file are shipped with the net; on the
    worker every path is its copy's (nothing of the driver's), and the record gets the
    driver's paths back."""
    import json

    import numpy as np

    from controllers import registry
    from suite.catalog.tracks import Track, TrackSet, write_tracks

    cat_dir = tmp_path / "cat"
    cat_dir.mkdir()
    tracks = cat_dir / "rec.tracks.parquet"
    t = np.array([0.0, 0.1, 0.2])
    write_tracks(tracks, TrackSet((Track("rec_1", "car", 4.5, 1.8, t, 100 + 2 * t,
                                         np.full(3, -1.6), np.zeros(3), np.full(3, 20.0)),),
                                  dt_s=0.1))
    shutil.copy(sumo_nets.net_path("straight_2lane"), cat_dir / "road.net.xml")
    plugin = cat_dir / "my_plugin.py"
    plugin.write_text(Path(__file__).with_name("crash_plugin.py").read_text())
    (cat_dir / "c.toml").write_text(
        '[defaults]\ncontroller = "lane_keep"\nduration_s = 1.0\nstep_s = 0.05\n'
        '[[scenario]]\nname = "rec"\nnet = "road.net.xml"\n'
        'ego = { lane = 0, pos_m = 60.0, speed_mps = 20.0 }\n'
        'replay = { tracks = "rec.tracks.parquet" }\n')
    job = RunJob(load_catalog(cat_dir / "c.toml").scenarios[0], tmp_path / "out",
                 RunOptions(write_rrd=False), plugins=(registry.plugin_module(str(plugin)),))
    sent, contents, files = ray_payload(job)
    assert sorted(f.role for f in files) == ["net", "plugin", "tracks"]
    assert all(p.source == "" for p in sent.plugins)  # the source travels as a file
    fetched: list[str] = []

    def fetch(sha: str) -> bytes:
        fetched.append(sha)
        return contents[sha]

    store, out = tmp_path / "worker" / "files", tmp_path / "worker" / "out"
    local, back = localise(sent, files, fetch, store, out)
    again, _ = localise(sent, files, fetch, store, out)
    assert len(fetched) == 3 and again == local  # each content written once
    paths = [local.scenario.net_path, local.scenario.replay.tracks_path,
             Path(local.plugins[0].path)]
    assert all(p.is_relative_to(store) and p.is_file() for p in paths)
    assert local.plugins[0].source == plugin.read_text()
    assert str(cat_dir) not in pickle.dumps(local.scenario.replay).decode("latin-1")
    run = out / "rec"
    run.mkdir(parents=True)
    (run / "traceback.txt").write_text(f'File "{paths[2]}", line 26\n')
    (run / "run.json").write_text(json.dumps({"info": {"net": str(paths[0])}, "files": []}))
    restore_paths(run, back)
    assert json.loads((run / "run.json").read_text())["info"]["net"] == str(
        cat_dir / "road.net.xml")
    assert str(plugin) in (run / "traceback.txt").read_text()
    assert [f["name"] for f in json.loads((run / "run.json").read_text())["files"]] == \
        ["traceback.txt"]


def test_the_pool_spreads_actors_over_the_nodes_by_their_cpus() -> None:
    nodes = [NodeCpus("head", 0.0), NodeCpus("a", 2.0), NodeCpus("b", 1.0)]
    assert plan_pool(nodes, 10) == ["a", "b", "a"]
    assert plan_pool(nodes, 2) == ["a", "b"]
    assert plan_pool(nodes, 10, cpus_per_actor=2.0) == ["a"]
    assert plan_pool([NodeCpus("head", 0.0)], 4) == []
    with pytest.raises(ValueError):
        NodeCpus("", 1.0)


def test_the_token_is_found_where_ray_reads_it(tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    from suite.exec.ray.auth import refused_message, token_source, use_token_auth

    monkeypatch.setenv("HOME", str(tmp_path))
    assert token_source({}) == ""
    (tmp_path / ".ray").mkdir()
    (tmp_path / ".ray" / "auth_token").write_text("abc")
    assert token_source({}).startswith("~/.ray/auth_token")
    named = tmp_path / "tok"
    named.write_text("def")
    assert token_source({"RAY_AUTH_TOKEN_PATH": str(named)}).startswith("RAY_AUTH_TOKEN_PATH")
    assert token_source({"RAY_AUTH_TOKEN": "x", "RAY_AUTH_TOKEN_PATH": str(named)}) == \
        "RAY_AUTH_TOKEN"
    env = {"RAY_AUTH_TOKEN": "x"}
    assert use_token_auth(env) == "RAY_AUTH_TOKEN" and env["RAY_AUTH_MODE"] == "token"
    off = {"RAY_AUTH_TOKEN": "x", "RAY_AUTH_MODE": "disabled"}
    use_token_auth(off)
    assert off["RAY_AUTH_MODE"] == "disabled"  # an explicit mode is respected
    message = refused_message("--ray-address h:1", {})
    assert "--ray-address h:1" in message and "RAY_AUTH_TOKEN" in message


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
