"""Which Ray the Ray executor uses (issue 35): without an address a private local Ray,
never the cluster Ray's ``ray_current_cluster`` file names (another virtual
environment's, or a dead one that ``ray.init()`` retried for minutes); a given address
is checked first and one that does not answer is exit 2 at once. Every test uses a
private RAY_TMPDIR and loopback addresses only; none touches a real cluster."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path

import pandas as pd
import pytest

from suite.exec.ray_executor import RayAddressError, RayTarget, check_target, ray_target
from tests.reliability_support import ROOT, scenario_toml, write_catalog

ray = pytest.importorskip("ray", reason="the 'cluster' extra is not installed")


def _dead_port() -> int:
    """A loopback port nothing listens on (bound, then closed)."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


@pytest.fixture
def ray_env() -> Iterator[dict[str, str]]:
    """This environment without RAY_ADDRESS, with a private, short RAY_TMPDIR (Ray's
    socket paths must stay under 108 characters)."""
    tmp = tempfile.mkdtemp(prefix="hwr", dir="/tmp")
    env = {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}
    env["RAY_TMPDIR"] = tmp
    try:
        yield env
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def test_the_target_is_the_option_else_ray_address_else_a_private_local_ray() -> None:
    assert ray_target(None, {}) == RayTarget(None)
    assert ray_target("local", {"RAY_ADDRESS": "10.0.0.1:6379"}) == RayTarget(None)
    from_env = ray_target(None, {"RAY_ADDRESS": "10.0.0.1:6379"})
    assert (from_env.address, from_env.source, from_env.host, from_env.port) == \
        ("10.0.0.1:6379", "RAY_ADDRESS", "10.0.0.1", 6379)
    given = ray_target("ray://head.example:10001", {"RAY_ADDRESS": "10.0.0.1:6379"})
    assert (given.address, given.source, given.host, given.port) == \
        ("ray://head.example:10001", "--ray-address", "head.example", 10001)
    assert ray_target("[::1]:6379", {}).host == "::1"
    for bad in ("nohost", "h:0", "h:x", ":6379", "h:70000"):
        with pytest.raises(RayAddressError):
            ray_target(bad, {})
    with pytest.raises(ValueError):
        RayTarget("h:1", host="", port=1)


def test_an_address_nobody_answers_at_is_refused_at_once() -> None:
    target = ray_target(f"127.0.0.1:{_dead_port()}", {})
    with pytest.raises(RayAddressError, match=str(target.port)):
        check_target(target, timeout_s=5.0)
    check_target(RayTarget(None))  # a private local Ray is started, not checked


@pytest.mark.slow
def test_a_dead_ray_address_exits_2_before_anything_is_written(
        tmp_path: Path, ray_env: dict[str, str]) -> None:
    """ray.init retried a dead address for minutes (the run hung); now exit 2 at once."""
    catalog = write_catalog(tmp_path / "c.toml", [scenario_toml("one")])
    out = tmp_path / "out"
    for address in (f"127.0.0.1:{_dead_port()}", f"ray://127.0.0.1:{_dead_port()}"):
        proc = subprocess.run([sys.executable, "-m", "suite", "run", str(catalog), "--out",
                               str(out), "--executor", "ray", "--ray-address", address],
                              cwd=ROOT, capture_output=True, text=True, timeout=120,
                              env=ray_env)
        assert proc.returncode == 2, proc.stdout + proc.stderr
        assert address in proc.stderr and "Traceback" not in proc.stderr
        assert not out.exists()
    local = subprocess.run([sys.executable, "-m", "suite", "run", str(catalog), "--out",
                            str(out), "--ray-address", "127.0.0.1:6379"], cwd=ROOT,
                           capture_output=True, text=True, timeout=120, env=ray_env)
    assert local.returncode == 2 and not out.exists()  # --ray-address without ray


JOIN_SILENT = """
import sys
from suite.exec.ray_executor import RayAddressError, RayExecutor
try:
    RayExecutor(address=sys.argv[1], connect_s=3.0)
    print("joined")
except RayAddressError:
    print("refused")
"""


@pytest.mark.slow
def test_an_address_that_takes_the_connection_but_never_answers_is_refused_in_time(
        ray_env: dict[str, str]) -> None:
    """A listener on loopback (127.0.0.2: Ray does not rewrite it to this host's address)
    that accepts and says nothing: ray.init would retry for minutes; the executor gives
    up after its connect bound."""
    server = socket.socket()
    server.bind(("127.0.0.2", 0))
    server.listen(16)
    accepted: list[socket.socket] = []

    def accept() -> None:
        while True:
            try:
                accepted.append(server.accept()[0])
            except OSError:
                return

    threading.Thread(target=accept, daemon=True).start()
    try:
        address = f"127.0.0.2:{server.getsockname()[1]}"
        done = subprocess.run([sys.executable, "-c", JOIN_SILENT, address], cwd=ROOT,
                              capture_output=True, text=True, timeout=120, env=ray_env)
        assert done.stdout.split()[-1:] == ["refused"], done.stdout + done.stderr
    finally:
        server.close()
        for conn in accepted:
            conn.close()


@pytest.mark.slow
@pytest.mark.sumo
def test_a_stale_cluster_file_is_ignored_without_an_address(
        tmp_path: Path, ray_env: dict[str, str]) -> None:
    """Ray's ray_current_cluster names a dead cluster (a crashed `ray start`, another
    venv's): ray.init() joined it and hung; without --ray-address the run now starts a
    private local Ray and runs."""
    marker = Path(ray_env["RAY_TMPDIR"]) / "ray" / "ray_current_cluster"
    marker.parent.mkdir(parents=True)
    marker.write_text(f"127.0.0.1:{_dead_port()}")
    catalog = write_catalog(tmp_path / "c.toml", [scenario_toml("one")], duration_s=1.0)
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "suite", "run", str(catalog), "--out",
                           str(out), "--executor", "ray", "--no-log"], cwd=ROOT,
                          capture_output=True, text=True, timeout=300, env=ray_env)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert pd.read_csv(out / "results.csv")["status"].tolist() == ["pass"]
