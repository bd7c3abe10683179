"""Which Ray the Ray executor runs on, checked before any work.

Without an address (``--ray-address`` or the ``RAY_ADDRESS`` variable) a **private
local Ray**, ``ray.init(address="local")``, never a cluster found on this machine: Ray's
own ``ray.init()`` joins the cluster its ``ray_current_cluster`` file in its temporary
folder names, which may be another virtual environment's or one long dead (it then
retries for minutes), or any Ray process it finds running. A given address
(``host:port``, ``ray://host:port``, or ``auto``: the cluster Ray would find, resolved
first) is checked before any work: a TCP connection within :data:`CHECK_S`, then the
cluster's authentication (:mod:`suite.exec.ray.auth`: a refused token is named as such,
at once, instead of Ray's minute of retries ending in "Failed to connect"), then
``ray.init`` within :data:`CONNECT_S`; any of them failing is a
:class:`RayAddressError` (the command exits 2, nothing written).
"""

from __future__ import annotations

import os
import socket
import threading
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from suite.exec.ray.auth import refused_message, use_token_auth

__all__ = ["CHECK_S", "CONNECT_S", "RayAddressError", "RayTarget", "check_target", "init_within",
           "ray_target"]

CHECK_S = 5.0  # a given Ray address must accept a TCP connection within this [s]
CONNECT_S = 60.0  # and ray.init must have joined its cluster within this [s]


class RayAddressError(ValueError):
    """The Ray cluster asked for cannot be used (the message names the address and where
    it came from)."""


@dataclass(frozen=True)
class RayTarget:
    """Where the Ray executor runs. ``address`` None: a private local Ray; else the
    address to pass to ``ray.init``, ``given`` as written and ``source`` where it came
    from (``--ray-address`` or ``RAY_ADDRESS``), ``host`` and ``port`` what is checked."""

    address: str | None
    given: str = ""
    source: str = ""
    host: str = ""
    port: int = 0

    def __post_init__(self) -> None:
        if self.address is not None and not (self.host and 0 < self.port < 65536):
            raise ValueError(f"RayTarget: a host and a port in 1..65535 are needed for "
                             f"{self.address!r}, got {self.host!r}:{self.port}")

    @property
    def shown(self) -> str:
        """``--ray-address auto (192.0.2.2:6379)`` or ``a private local Ray``."""
        if self.address is None:
            return "a private local Ray"
        resolved = f" ({self.host}:{self.port})" if self.given != self.address else ""
        return f"{self.source} {self.given}{resolved}"

    @property
    def is_client(self) -> bool:
        """Whether the address is a Ray Client one (``ray://``): no GCS to probe."""
        return bool(self.address) and str(self.address).startswith("ray://")


def _host_port(address: str, what: str) -> tuple[str, int]:
    """``(host, port)`` of ``host:port``, ``[v6]:port`` or ``scheme://host:port``."""
    hostport = address.split("://", 1)[-1].rstrip("/")
    host, sep, port = hostport.rpartition(":")
    host = host.strip("[]")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise RayAddressError(f"{what} {address}: expected host:port, ray://host:port, "
                              "auto or local")
    return host, int(port)


def _found_address(what: str) -> str:
    """The cluster ``ray.init(address="auto")`` would join, as host:port (Ray's own
    lookup: RAY_ADDRESS, its ray_current_cluster file, Ray processes running here)."""
    from ray._private.services import canonicalize_bootstrap_address

    try:
        found = canonicalize_bootstrap_address("auto")
    except (ConnectionError, ValueError) as exc:
        raise RayAddressError(f"{what} auto: {exc}") from exc
    if not found:
        raise RayAddressError(f"{what} auto: Ray found no cluster to join")
    return str(found)


def ray_target(address: str | None, environ: Mapping[str, str]) -> RayTarget:
    """The Ray to run on (module doc): ``address`` (``--ray-address``), else
    ``RAY_ADDRESS`` from ``environ``, else a private local Ray. RayAddressError for an
    address that is not host:port, ray://host:port, auto or local."""
    given, source = (address, "--ray-address") if address else \
        (environ.get("RAY_ADDRESS", "").strip(), "RAY_ADDRESS")
    if not given or given == "local":
        return RayTarget(None)
    resolved = _found_address(source) if given == "auto" else given
    host, port = _host_port(resolved, source)
    return RayTarget(resolved, given, source, host, port)


def check_target(target: RayTarget, timeout_s: float = CHECK_S) -> None:
    """RayAddressError unless ``target``'s host accepts a TCP connection on its port
    within ``timeout_s`` [s] (a private local Ray is not checked: it is started)."""
    if target.address is None:
        return
    try:
        with socket.create_connection((target.host, target.port), timeout=timeout_s):
            pass
    except OSError as exc:
        why = "no answer" if isinstance(exc, TimeoutError) else (exc.strerror or str(exc))
        raise RayAddressError(
            f"{target.shown}: nothing answers at {target.host}:{target.port} ({why} within "
            f"{timeout_s:g} s); start the cluster, give its address, or leave "
            "--ray-address out (and RAY_ADDRESS unset) for a private local Ray") from exc


def _probe_auth(target: RayTarget) -> None:
    """Ask the cluster's GCS for its id as Ray's client does: a refused token raises
    Ray's AuthenticationError at once (anything else is left to ``ray.init``)."""
    if target.is_client:
        return
    import importlib

    raylet: Any = importlib.import_module("ray._raylet")  # compiled, no stubs
    raylet.GcsClient(address=f"{target.host}:{target.port}")


def init_within(ray: Any, target: RayTarget, timeout_s: float) -> None:
    """Join ``target``: its authentication probed, then ``ray.init``, in a thread: a
    cluster that takes the connection but never answers as Ray makes ray.init retry for
    minutes, so it gets ``timeout_s`` [s] and is then left behind (the command ends;
    Ray's exit handler does not wait). A refused token is a RayAddressError saying what
    to set (:func:`suite.exec.ray.auth.refused_message`)."""
    from ray.exceptions import AuthenticationError

    use_token_auth()
    outcome: list[BaseException | None] = []

    def join() -> None:
        try:
            _probe_auth(target)
            ray.init(address=target.address, include_dashboard=False, log_to_driver=False)
            outcome.append(None)
        except BaseException as exc:  # noqa: BLE001 - handed to the caller's thread
            outcome.append(exc)

    thread = threading.Thread(target=join, name="hwyeval-ray-init", daemon=True)
    thread.start()
    thread.join(timeout_s)
    if not outcome:
        raise RayAddressError(f"{target.shown}: Ray did not join the cluster within "
                              f"{timeout_s:g} s (is it a Ray head of this Ray version?)")
    exc = outcome[0]
    if isinstance(exc, AuthenticationError) or (
            exc is not None and "InvalidAuthToken" in str(exc)):
        raise RayAddressError(refused_message(target.shown, os.environ,
                                              "InvalidAuthToken")) from exc
    if exc is not None:
        raise RayAddressError(f"{target.shown}: {type(exc).__name__}: {exc}") from exc
