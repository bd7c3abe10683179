"""A Ray cluster of several nodes on this machine, for tests/test_ray_cluster.py.

Every node is a ``ray start --block`` in a session of its own, on loopback, with its own
``--temp-dir`` and ports, its private ``RAY_TMPDIR`` (no ``ray_current_cluster`` file
where another ``ray.init()`` would find it), token authentication on, and a fixed token.
A worker node may be started in a mount namespace of its own (``unshare -m``) with a
tmpfs over folders of the driver's: it cannot see them, as a machine of a real cluster
cannot. Nodes are stopped by the process ids of their session (never ``ray stop``,
which would stop every cluster of this machine). The head checks its nodes every second
(:data:`HEALTH_CHECK`): a killed node is known dead within seconds.
"""

from __future__ import annotations

import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RAY = Path(sys.executable).with_name("ray")
OBJECT_STORE_BYTES = 150 * 1024 * 1024  # each node's object store [bytes]
START_S = 90.0  # a node must be up within this [s]
# the head's check of its nodes: a dead node is dead for Ray after ~5 s (Ray's default:
# 5 failed checks 3 s apart), so that a test sees it said within its run
HEALTH_CHECK = {"RAY_health_check_period_ms": "1000", "RAY_health_check_failure_threshold": "5"}


def free_port() -> int:
    """A loopback port nothing listens on now."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def session_pids(sid: int) -> list[int]:
    """The processes of session ``sid`` (a node's ``ray start`` and all it started, even
    those reparented to init)."""
    pids = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        fields = stat.rsplit(")", 1)[-1].split()
        if len(fields) > 3 and int(fields[3]) == sid:
            pids.append(int(entry.name))
    return pids


def pids_mentioning(text: str) -> list[int]:
    """The processes whose command line holds ``text`` (a node's temporary folder: its
    Ray workers, which leave the node's session)."""
    needle = text.encode()
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            if needle in (entry / "cmdline").read_bytes():
                found.append(int(entry.name))
        except OSError:
            continue
    return found


def child_named(pid: int, name: str) -> int | None:
    """The pid of a process of ``pid``'s session called ``name`` (e.g. ``raylet``)."""
    for p in session_pids(pid):
        try:
            if Path(f"/proc/{p}/comm").read_text().strip() == name:
                return p
        except OSError:
            continue
    return None


class RayNode:
    """One ``ray start --block`` (module doc); ``hide``: folders covered by a tmpfs in
    its own mount namespace."""

    def __init__(self, root: Path, name: str, env: dict[str, str], args: Sequence[str],
                 hide: Sequence[Path] = ()) -> None:
        self.name = name
        self.log = root / f"{name}.log"
        temp = root / name
        self.temp = temp
        self.node_manager_port = free_port()
        self.node_id = ""  # Ray's id of the node, once the cluster has it (wait_cpus)
        ports = ["--dashboard-agent-listen-port", str(free_port()),
                 "--dashboard-agent-grpc-port", str(free_port()),
                 "--metrics-export-port", str(free_port()),
                 "--runtime-env-agent-port", str(free_port()),
                 "--node-manager-port", str(self.node_manager_port),
                 "--object-manager-port", str(free_port())]
        cmd = [str(RAY), "start", "--block", "--node-ip-address", "127.0.0.1", "--temp-dir",
               str(temp), "--object-store-memory", str(OBJECT_STORE_BYTES),
               "--disable-usage-stats", *ports, *args]
        if hide:
            mounts = " && ".join(f'mount -t tmpfs hwyeval-hidden "${i + 1}"'
                                 for i in range(len(hide)))
            cmd = ["unshare", "-m", "sh", "-c", f'{mounts} && shift {len(hide)} && exec "$@"',
                   "sh", *map(str, hide), *cmd]
        with self.log.open("w") as log:
            self.proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env,
                                         start_new_session=True, cwd=root)

    def wait_started(self, timeout_s: float = START_S) -> None:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if "Ray runtime started" in self.log.read_text(errors="replace"):
                return
            if self.proc.poll() is not None:
                break
            time.sleep(0.5)
        raise RuntimeError(f"ray node {self.name} did not start:\n"
                           + self.log.read_text(errors="replace")[-3000:])

    def raylet(self) -> int | None:
        return child_named(self.proc.pid, "raylet")

    def kill(self) -> None:
        """SIGKILL every process of the node's session and every Ray worker of its
        temporary folder, by pid."""
        for _ in range(3):
            pids = session_pids(self.proc.pid) + pids_mentioning(f"{self.temp}/")
            if not pids:
                break
            for pid in pids:
                try:
                    os.kill(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
            time.sleep(0.2)
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            pass


class LocalCluster:
    """A head (``head_args``, e.g. ``--num-cpus 0``) and worker nodes added by
    :meth:`add_worker`; :meth:`stop` kills them all (module doc)."""

    def __init__(self, head_args: Sequence[str] = ("--num-cpus", "0")) -> None:
        self.root = Path(tempfile.mkdtemp(prefix="hwc", dir="/tmp"))  # short: socket paths
        self.token = secrets.token_hex(16)
        (self.root / "rt").mkdir()
        (self.root / "home").mkdir()
        self.port = free_port()
        self.address = f"127.0.0.1:{self.port}"
        self.nodes: list[RayNode] = []
        base = {k: v for k, v in os.environ.items()
                if not k.startswith("RAY_") or k == "RAY_USAGE_STATS_ENABLED"}
        self.node_env = {**base, "RAY_TMPDIR": str(self.root / "rt"), "HOME": str(self.root /
                                                                               "home"),
                         "RAY_USAGE_STATS_ENABLED": "0", "RAY_AUTH_MODE": "token",
                         "RAY_AUTH_TOKEN": self.token, **HEALTH_CHECK}
        # the driver: the token only (RAY_AUTH_MODE unset: hwyeval turns token mode on)
        self.driver_env = {k: v for k, v in self.node_env.items()
                           if k != "RAY_AUTH_MODE" and k not in HEALTH_CHECK}
        try:
            head = RayNode(self.root, "head", self.node_env,
                           ["--head", "--port", str(self.port), "--include-dashboard", "false",
                            "--ray-client-server-port", str(free_port()), *head_args])
            self.nodes.append(head)
            head.wait_started()
        except BaseException:
            self.stop()
            raise

    def add_worker(self, name: str, cpus: int, hide: Sequence[Path] = ()) -> RayNode:
        node = RayNode(self.root, name, self.node_env,
                       ["--address", self.address, "--num-cpus", str(cpus)], hide)
        self.nodes.append(node)
        node.wait_started()
        self.wait_cpus()
        return node

    def wait_cpus(self, timeout_s: float = START_S) -> float:
        """Wait until the cluster's alive nodes have as many CPUs as the alive nodes
        started here asked for; returns them. Each node's ``node_id`` is set (its node
        manager's port names it)."""
        script = ("import json, sys, time, ray; ray.init(address=sys.argv[1], "
                  "log_to_driver=False); want = float(sys.argv[2]); t = time.time()\n"
                  "while time.time() - t < float(sys.argv[3]):\n"
                  "    alive = [n for n in ray.nodes() if n['Alive']]\n"
                  "    got = sum(n['Resources'].get('CPU', 0) for n in alive)\n"
                  "    if got >= want:\n"
                  "        print(json.dumps({n['NodeManagerPort']: n['NodeID'] "
                  "for n in alive}))\n"
                  "        print(got); break\n"
                  "    time.sleep(0.5)\n")
        want = sum(float(n.proc.args[n.proc.args.index("--num-cpus") + 1])
                   for n in self.nodes if n.proc.poll() is None and "--num-cpus" in n.proc.args)
        env = {**self.driver_env, "RAY_AUTH_MODE": "token"}
        done = subprocess.run([sys.executable, "-c", script, self.address, str(want),
                               str(timeout_s)], env=env, capture_output=True, text=True,
                              timeout=timeout_s + 60)
        lines = done.stdout.strip().splitlines()
        if len(lines) < 2:
            raise RuntimeError(f"the cluster never had {want} CPUs:\n{done.stderr[-2000:]}")
        ids = {int(port): node_id for port, node_id in json.loads(lines[-2]).items()}
        for node in self.nodes:
            node.node_id = ids.get(node.node_manager_port, node.node_id)
        return float(lines[-1])

    def node(self, name: str) -> RayNode | None:
        """The node started as ``name``, if its session is still running."""
        for node in self.nodes:
            if node.name == name and node.proc.poll() is None:
                return node
        return None

    def stop(self) -> None:
        for node in reversed(self.nodes):
            node.kill()
        shutil.rmtree(self.root, ignore_errors=True)
