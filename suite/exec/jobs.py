"""A scenario to run (:class:`RunJob`), how a worker runs it (:func:`run_job`), and the
record of a run that did not finish (:func:`write_failure`).

The catalog is validated once, in the parent; every job carries its resolved
:class:`suite.catalog.Scenario` (no worker reads the catalog file), the options of the
run (its wall-clock budget and content hash among them) and the ``--plugin`` modules.
"""

from __future__ import annotations

import math
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

from reports.record import (
    ControllerArrays,
    NeighbourColumns,
    RoadRecord,
    RunOutcome,
    RunRecord,
    Trace,
    load_run,
)
from reports.record.run import write_run_atomic
from suite.catalog import Scenario
from suite.exec.memory import MemoryCap
from suite.exec.signals import StopRequest
from suite.run.info import scenario_info
from suite.run.options import RunOptions

if TYPE_CHECKING:
    from controllers import registry

__all__ = ["Executor", "OnDone", "RunJob", "read_result", "record_in_memory", "run_job",
           "write_failure"]

OnDone = Callable[[RunRecord], None]


@dataclass(frozen=True)
class RunJob:
    """One scenario to run into ``out_dir/<scenario.name>``. ``timeout_s`` [s]: the
    executor kills the process ``KILL_GRACE_S`` after it (None: never; the runner's
    own budget is ``options.timeout_s``). ``plugins``: the ``--plugin`` modules (with a
    file's source), imported by the worker before it builds the controller
    (entry-point plug-ins load themselves). ``memory``: the scenario process's
    address-space cap (:mod:`suite.exec.memory`)."""

    scenario: Scenario
    out_dir: Path
    options: RunOptions = field(default_factory=RunOptions)
    timeout_s: float | None = None
    plugins: tuple[registry.PluginModule, ...] = ()
    memory: MemoryCap = field(default_factory=MemoryCap)

    def __post_init__(self) -> None:
        if not isinstance(self.scenario, Scenario):
            raise TypeError(f"RunJob.scenario: expected a Scenario, got {self.scenario!r}")
        if not isinstance(self.options, RunOptions):
            raise TypeError(f"RunJob.options: expected RunOptions, got {self.options!r}")
        object.__setattr__(self, "out_dir", Path(self.out_dir))
        if self.timeout_s is not None and (
                isinstance(self.timeout_s, bool) or not isinstance(self.timeout_s, int | float)
                or not math.isfinite(self.timeout_s) or self.timeout_s <= 0):
            raise ValueError(f"RunJob.timeout_s: expected a finite number of seconds > 0 or "
                             f"None, got {self.timeout_s!r}")
        object.__setattr__(self, "plugins", tuple(self.plugins))
        if not isinstance(self.memory, MemoryCap):
            raise TypeError(f"RunJob.memory: expected a MemoryCap, got {self.memory!r}")

    @property
    def name(self) -> str:
        return self.scenario.name

    @property
    def run_dir(self) -> Path:
        return self.out_dir / self.scenario.name


def run_job(job: RunJob) -> RunRecord:
    """Worker entry point: load the job's plug-ins, run its scenario (``run_scenario``
    never raises; a plug-in that fails to import here raises, and is recorded as the
    run's error by the caller)."""
    from controllers import registry
    from suite.run.runner import run_scenario

    registry.load_plugin_modules(job.plugins)
    return run_scenario(job.scenario, job.out_dir, job.options)


def record_in_memory(job: RunJob, end: str, message: str) -> RunRecord:
    """A fresh, judged record of a run that did not finish (``end`` 'error' or
    'timeout'): the job's identity and controller, no trace, NaN metrics; nothing of an
    older run of it. Not written."""
    from controllers.plant.vehicle_model import VehicleParams
    from suite.run.runner import judge_record

    sc = job.scenario
    info = scenario_info(sc, job.options.catalog_name, VehicleParams(friction_coeff=sc.friction),
                         content_sha256=job.options.content_sha256)
    record = RunRecord(info=info, outcome=RunOutcome(end=end, error=message), road=RoadRecord(),
                       trace=Trace.empty(), neighbours=NeighbourColumns.allocate(0),
                       arrays=ControllerArrays())
    return judge_record(record)


def write_failure(job: RunJob, end: str, message: str) -> RunRecord:
    """:func:`record_in_memory`, written atomically to the job's run directory (replacing
    whatever was there). If even that fails, the record says why and has no
    ``run_dir``; this never raises."""
    record = record_in_memory(job, end, message)
    try:
        write_run_atomic(record, job.run_dir)
        record.run_dir = job.run_dir
    except Exception:  # noqa: BLE001 - the catalog goes on; the summary shows the reason
        record.outcome = replace(record.outcome, error=(
            f"{message}\nand its record could not be written to {job.run_dir}:\n"
            f"{traceback.format_exc()}"))
    return record


def read_result(job: RunJob) -> RunRecord:
    """The job's record as written (run.json and road only)."""
    return load_run(job.run_dir, trace=False, neighbours=False, arrays=False, series=False)


class Executor(Protocol):
    """Runs jobs and calls ``on_done(record)`` as each finishes (any order). When
    ``stop`` is requested it dispatches nothing more, ends the running scenarios
    (their runs are not recorded: they did not finish) and returns what finished."""

    def run(self, jobs: Sequence[RunJob], on_done: OnDone | None = None,
            stop: StopRequest | None = None) -> list[RunRecord]: ...
