"""Executors: where scenarios run. One scenario per process (libsumo: one simulation each).

The catalog is validated once, in the parent; every job carries its resolved
:class:`suite.catalog.Scenario` (no worker re-reads the catalog file).

* :class:`~suite.exec.local.LocalExecutor` runs up to ``jobs`` scenario processes at once
  on this machine (forkserver with the heavy modules preloaded; process groups; a
  budget backstop; an orderly stop on SIGINT/SIGTERM).
* :class:`~suite.exec.ray_executor.RayExecutor` sends each scenario to a Ray cluster with
  only the network file it needs and ships the run directory back.

Both publish every run directory atomically (:mod:`reports.record.run`) and take a
:class:`~suite.exec.signals.StopRequest`. This module gathers their public names.
"""

from __future__ import annotations

from suite.exec.forkserver import PRELOAD, stop_forkserver
from suite.exec.jobs import (
    Executor,
    OnDone,
    RunJob,
    read_result,
    record_in_memory,
    run_job,
    write_failure,
)
from suite.exec.local import KILL_GRACE_S, LocalExecutor
from suite.exec.ray_executor import MAX_NET_BYTES, RayExecutor, ray_payload
from suite.exec.signals import StopRequest, stop_on_signals

__all__ = ["KILL_GRACE_S", "MAX_NET_BYTES", "PRELOAD", "Executor", "LocalExecutor", "OnDone",
           "RayExecutor", "RunJob", "StopRequest", "ray_payload",
           "read_result", "record_in_memory", "run_job", "stop_forkserver",
           "stop_on_signals", "write_failure"]
