"""The Ray executor's public names, where they always were: the executor itself is the
package :mod:`suite.exec.ray` (long-lived actors, every file a run reads shipped through
Ray's object store, token authentication; docs/cluster.md)."""

from __future__ import annotations

from suite.exec.ray import (
    CHECK_S,
    CONNECT_S,
    MAX_NET_BYTES,
    RayAddressError,
    RayExecutor,
    RayTarget,
    check_target,
    ray_payload,
    ray_target,
    read_net,
    unpack_run,
)

__all__ = ["CHECK_S", "CONNECT_S", "MAX_NET_BYTES", "RayAddressError", "RayExecutor",
           "RayTarget", "check_target", "ray_payload", "ray_target", "read_net", "unpack_run"]
