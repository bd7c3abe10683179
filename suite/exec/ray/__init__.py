"""The Ray executor (:mod:`suite.exec.ray.executor`), for a Ray cluster of one machine or
many: where it runs (:mod:`.target`, :mod:`.auth`), the long-lived actors that run
scenarios (:mod:`.actor`, :mod:`.pool`), what travels (:mod:`suite.exec.shipping`,
:mod:`.archive`). docs/cluster.md is the recipe.

Importing this package does not import Ray: that happens when a
:class:`~suite.exec.ray.executor.RayExecutor` is made (Ray is the optional ``cluster``
extra).
"""

from __future__ import annotations

from suite.exec.ray.archive import pack_run, unpack_run
from suite.exec.ray.executor import (
    MAX_ATTEMPTS,
    MAX_NET_BYTES,
    NODE_WAIT_ENV,
    NODE_WAIT_S,
    RETURN_GRACE_S,
    TRACE_ENV,
    RayExecutor,
    ray_payload,
    read_net,
)
from suite.exec.ray.target import (
    CHECK_S,
    CONNECT_S,
    RayAddressError,
    RayTarget,
    check_target,
    ray_target,
)

__all__ = ["CHECK_S", "CONNECT_S", "MAX_ATTEMPTS", "MAX_NET_BYTES", "NODE_WAIT_ENV", "NODE_WAIT_S",
           "RETURN_GRACE_S", "TRACE_ENV", "RayAddressError", "RayExecutor", "RayTarget",
           "check_target", "pack_run", "ray_payload", "ray_target", "read_net", "unpack_run"]
