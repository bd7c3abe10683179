"""From scenarios to jobs on an executor: what ``run`` and ``search`` share.

:class:`RunSettings` is how the runs of a command execute (``--jobs``, ``--executor``,
``--ray-address``, ``--no-log``, ``--timeout``, ``--max-memory-mb``, ``--plugin``).
:func:`build_jobs` makes one :class:`~suite.exec.jobs.RunJob` per scenario (its budget,
:mod:`suite.exec.budget`, and its content and code hashes), :func:`make_executor` the
executor, :func:`start_manifest` the output's manifest with its provenance.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from suite.exec.command import Plugins, UsageError

if TYPE_CHECKING:
    from reports.manifest import Manifest
    from suite.catalog import Catalog, Scenario
    from suite.exec.jobs import Executor, RunJob
    from suite.exec.memory import MemoryCap

__all__ = ["EXECUTORS", "RunSettings", "build_jobs", "load_catalog_for", "make_executor",
           "route_warnings", "start_manifest"]

EXECUTORS = ("local", "ray")


@dataclass(frozen=True)
class RunSettings:
    """How a command's runs execute. ``jobs``: scenarios at once (0: the machine's
    cores); ``timeout_s``: every run's wall-clock budget (None: the catalog's, else the
    default); ``max_memory_mb``: the address-space cap as given (None: the environment's
    or the default, :meth:`memory_cap`); ``plugins``: the ``--plugin`` specs as given."""

    jobs: int = 0
    executor: str = "local"
    ray_address: str | None = None
    no_log: bool = False
    timeout_s: float | None = None
    max_memory_mb: int | None = None
    plugins: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if isinstance(self.jobs, bool) or not isinstance(self.jobs, int) or self.jobs < 0:
            raise ValueError(f"RunSettings.jobs: expected a whole number >= 0, got {self.jobs!r}")
        if self.executor not in EXECUTORS:
            raise ValueError(f"RunSettings.executor: expected one of {EXECUTORS}, got "
                             f"{self.executor!r}")
        if self.timeout_s is not None and not (math.isfinite(self.timeout_s)
                                               and self.timeout_s > 0):
            raise ValueError(f"RunSettings.timeout_s: expected a finite number of seconds > 0 "
                             f"or None, got {self.timeout_s!r}")
        if self.max_memory_mb is not None and self.max_memory_mb < 0:
            raise ValueError(f"RunSettings.max_memory_mb: expected >= 0 or None, got "
                             f"{self.max_memory_mb!r}")
        if not isinstance(self.plugins, tuple):
            raise TypeError(f"RunSettings.plugins: expected a tuple, got {self.plugins!r}")

    def memory_cap(self) -> MemoryCap:
        """The :class:`suite.exec.memory.MemoryCap` of every run: ``max_memory_mb``, else
        ``HWYEVAL_MAX_MEMORY_MB``, else the default; a bad variable is a UsageError."""
        from suite.exec.memory import memory_cap_from

        try:
            return memory_cap_from(self.max_memory_mb, os.environ)
        except ValueError as exc:
            raise UsageError(str(exc)) from exc

    def flags(self) -> list[str]:
        """The flags a resume command repeats for how runs execute: ``--timeout``,
        ``--executor``, ``--ray-address``, ``--max-memory-mb`` and every ``--plugin``."""
        parts: list[str] = []
        if self.timeout_s is not None:
            parts += ["--timeout", f"{self.timeout_s:g}"]
        if self.executor != "local":
            parts += ["--executor", self.executor]
        if self.ray_address:
            parts += ["--ray-address", self.ray_address]
        if self.max_memory_mb is not None:
            parts += ["--max-memory-mb", str(self.max_memory_mb)]
        for plugin in self.plugins:
            parts += ["--plugin", plugin]
        return parts


def build_jobs(scenarios: Sequence[Scenario], out: Path, catalog_name: str, no_log: bool,
               plugins: Plugins, timeout_s: float | None = None,
               memory: MemoryCap | None = None) -> list[RunJob]:
    """One job per scenario: its budget (``timeout_s``, else the catalog's, else the
    default from its duration), its content hash (each network and tracks file read once)
    and the hashes of the code and of a plug-in controller (:mod:`suite.run.code_identity`);
    ``memory``: every scenario process's :class:`~suite.exec.memory.MemoryCap` (None:
    the default)."""
    from suite.exec.budget import run_budget_s
    from suite.exec.jobs import RunJob
    from suite.exec.memory import MemoryCap
    from suite.run.code_identity import controller_sha256, hwyeval_code_sha256
    from suite.run.info import file_sha256, scenario_content_sha256, scenario_tracks_path
    from suite.run.options import RunOptions

    file_hashes: dict[Path, str] = {}

    def digest(path: Path, what: str, scenario: str) -> str:
        if path not in file_hashes:
            try:
                file_hashes[path] = file_sha256(path)
            except OSError as exc:
                raise UsageError(f"{path}: cannot read the {what} of scenario {scenario!r} "
                                 f"({exc})") from exc
        return file_hashes[path]

    code = hwyeval_code_sha256()
    controllers = {name: controller_sha256(name)
                   for name in sorted({sc.controller.name for sc in scenarios})}
    jobs = []
    for sc in scenarios:
        net = digest(sc.net_path, "network", sc.name)
        tracks = scenario_tracks_path(sc)
        content = scenario_content_sha256(
            sc, net, digest(tracks, "tracks file", sc.name) if tracks is not None else None)
        budget = run_budget_s(sc.duration_s, sc.timeout_s, timeout_s)
        options = RunOptions(write_rrd=not no_log, catalog_name=catalog_name, timeout_s=budget,
                             content_sha256=content, code_sha256=code,
                             controller_sha256=controllers[sc.controller.name])
        jobs.append(RunJob(sc, out.resolve(), options, budget, plugins.modules,
                           memory if memory is not None else MemoryCap()))
    return jobs


def make_executor(settings: RunSettings, n_jobs: int) -> tuple[Executor, int]:
    """The executor and how many scenarios it runs at once."""
    from suite.exec.executors import LocalExecutor, RayExecutor

    if settings.executor == "ray":
        try:
            ray_executor = RayExecutor(address=settings.ray_address, jobs=settings.jobs or None)
        except (RuntimeError, ConnectionError, ValueError) as exc:
            raise UsageError(f"--executor ray: {exc}") from exc
        # the actors the cluster holds now, not the scenario count (the pool is planned
        # again when the run starts: a node that joins meanwhile is used)
        return ray_executor, max(1, ray_executor.planned_actors(n_jobs))
    if settings.ray_address:
        raise UsageError(f"--ray-address {settings.ray_address}: only with --executor ray")
    workers = max(1, min(settings.jobs or os.cpu_count() or 1, n_jobs))
    return LocalExecutor(jobs=workers), workers


def start_manifest(catalog_path: str, executor: str, scenarios: Sequence[Scenario],
                   workers: int, plugins: Plugins) -> Manifest:
    """The manifest of an output: the catalog (``catalog_path`` as given) and its
    identity, the scenarios, how they run, the provenance and the controllers' code."""
    from controllers import registry
    from reports.manifest import ControllerCode, Manifest, catalog_identity, now_iso
    from reports.provenance import collect
    from suite.run.code_identity import controller_sha256

    used = sorted({sc.controller.name for sc in scenarios})
    plugin_names = tuple(f"{name} ({registry.origin(name)})" for name in used
                         if registry.origin(name) != "built in")
    catalog = Path(catalog_path).resolve()
    identity = catalog_identity(catalog)  # what the history files the night under
    return Manifest(catalog=str(catalog), catalog_name=Path(catalog_path).stem,
                    scenarios=tuple(sc.name for sc in scenarios), started=now_iso(),
                    jobs=workers, executor=executor, plugins=plugins.labels,
                    provenance=collect(plugin_names), catalog_id=identity.name,
                    catalog_origin=identity.origin,
                    controllers=tuple(ControllerCode(n, controller_sha256(n)) for n in used))


def load_catalog_for(catalog: str, pattern: str | None) -> tuple[Catalog, list[Scenario]]:
    """The catalog and its scenarios (``--filter`` applied; none matching is an error)."""
    from suite.catalog import expand_filter, load_catalog

    cat = load_catalog(Path(catalog))
    scenarios = list(cat.scenarios)
    if pattern:
        scenarios = list(expand_filter(scenarios, pattern))
        if not scenarios:
            raise UsageError(f"{catalog}: --filter {pattern!r} matches no scenario")
    return cat, scenarios


def route_warnings(scenarios: Sequence[Scenario]) -> list[str]:
    """One line per scenario whose route uses link edges (ramps, exits: an OpenStreetMap
    ``*_link`` type): positions along it then mean another place than on the through
    carriageway the default route follows (suite.road.network)."""
    from suite.road.network import RoadNetwork

    lines = []
    for sc in scenarios:
        links = RoadNetwork.load(sc.net_path).link_edges(sc.route)
        if links:
            lines.append(f"warning: scenario {sc.name}: its route uses link edges (ramps, "
                         f"exits) {links}; the default route keeps to the through carriageway")
    return lines
