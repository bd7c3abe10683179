"""Which runs of an output directory are which of the paper's experiments.

A run belongs to an experiment by its scenario family (the scenario's name before the
sweep suffix, ``info.family``; catalogs/paper.toml names them) and is told apart from
its siblings by the controller it ran with (``info.controller``, and the options it
ran with, ``info.controller_params``), never by parsing its name. The parameters are
read once into a typed :class:`Variant`; a run whose parameters lack what an
experiment needs is reported, not guessed.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from reports.record import RecordError, RunRecord, iter_run_dirs, load_run
from reports.record.codec import decode_dataclass, read_json

FAMILY_COSTS = "paper_costs"  # (a) J1 / J2 / J3, straight road, stalled car 110 m ahead
FAMILY_PREVIEW = "paper_preview"  # (b) J3, preview on / off (and feed-forward), curve
FAMILY_SOLVERS = "paper_solvers"  # (c) two_loop / ipopt_nmpc on (a)'s road
FAMILY_OBSTACLES = "paper_obstacles"  # (d) several stalled cars along a curve
FAMILIES = (FAMILY_COSTS, FAMILY_PREVIEW, FAMILY_SOLVERS, FAMILY_OBSTACLES)
SOLVERS = {"two_loop": "C/GMRES", "ipopt_nmpc": "Ipopt"}


class PaperError(ValueError):
    """The output directory does not hold what the paper's page needs."""


@dataclass(frozen=True)
class Variant:
    """What tells a paper run from its siblings: ``controller`` (registry name),
    ``solver`` (C/GMRES or Ipopt), ``cost`` (J1/J2/J3), ``preview`` (the preview's
    corrections applied), ``feedforward`` (our cornering feed-forward in the
    conversion), ``preview_horizon_s`` = Np dt_p [s] (where the preview compares the
    car with the plan), ``obstacle_fade_s`` [s] (C/GMRES's fade of an obstacle's
    barrier weight; NaN for a planner without one)."""

    controller: str
    solver: str
    cost: str
    preview: bool
    feedforward: bool
    preview_horizon_s: float
    obstacle_fade_s: float
    k_psc_radpm: float

    @property
    def label(self) -> str:
        """Short text naming the variant ("J1", "preview on, feed-forward off", ...)."""
        return f"{self.solver} {self.cost}, preview {'on' if self.preview else 'off'}, " \
               f"feed-forward {'on' if self.feedforward else 'off'}"


def _section(params: dict[str, Any], name: str, where: str) -> dict[str, Any]:
    section = params.get(name)
    if not isinstance(section, dict):
        raise PaperError(f"{where}: controller_params.{name}: expected a table, got "
                         f"{section!r}")
    return section


def _value(section: dict[str, Any], key: str, kind: type, where: str) -> Any:
    value = section.get(key)
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if not isinstance(value, kind) or (kind is not bool and isinstance(value, bool)):
        raise PaperError(f"{where}: {key}: expected {kind.__name__}, got {value!r}")
    return value


def variant_of(record: RunRecord) -> Variant:
    """The :class:`Variant` of a two-loop-family run (two_loop or ipopt_nmpc) from the
    parameters it ran with; PaperError for another controller or missing parameters."""
    where = str(record.run_dir or record.name)
    info = record.info
    if info.controller not in SOLVERS:
        raise PaperError(f"{where}: controller {info.controller!r} is none of the paper's "
                         f"({', '.join(SOLVERS)})")
    outer = _section(info.controller_params, "outer", where)
    inner = _section(info.controller_params, "inner", where)
    fade = outer.get("obstacle_fade_s")
    return Variant(
        controller=info.controller, solver=SOLVERS[info.controller],
        cost=_value(outer, "cost", str, where + ": controller_params.outer"),
        preview=_value(inner, "preview", bool, where + ": controller_params.inner"),
        feedforward=_value(inner, "feedforward", bool, where + ": controller_params.inner"),
        preview_horizon_s=(_value(inner, "n_preview", int, where + ": controller_params.inner")
                           * _value(inner, "preview_dt_s", float,
                                    where + ": controller_params.inner")),
        obstacle_fade_s=float(fade) if isinstance(fade, int | float)
        and not isinstance(fade, bool) else math.nan,
        k_psc_radpm=_value(inner, "k_psc", float, where + ": controller_params.inner"))


@dataclass(frozen=True)
class PaperRun:
    """A run of one of the paper's experiments: its record (trace, series and controller
    arrays loaded) and its variant."""

    record: RunRecord
    variant: Variant

    @property
    def name(self) -> str:
        return self.record.name


@dataclass(frozen=True)
class Machine:
    """Where the runs were timed (``manifest.json`` → provenance): host, CPU model and
    logical cores, the 1-minute load average per core at the catalog's start and end
    (NaN: unknown), the git revision and whether it had uncommitted changes."""

    host: str = ""
    cpu_model: str = ""
    cpu_count: int = 0
    load_start: float = math.nan
    load_end: float = math.nan
    git_sha: str = ""
    git_dirty: bool | None = None


def read_machine(out_dir: Path) -> Machine:
    """The :class:`Machine` of an output directory (an empty one when the directory has
    no readable manifest: the numbers are still the runs', only their context is
    unknown)."""
    path = Path(out_dir) / "manifest.json"
    if not path.is_file():
        return Machine()
    try:
        doc = read_json(path)
        prov = doc.get("provenance") if isinstance(doc, dict) else None
        return decode_dataclass(Machine, prov, path, "provenance")
    except RecordError:
        return Machine()


@dataclass(frozen=True)
class PaperRuns:
    """The paper runs of an output directory, per experiment, in directory order, and
    the runs that could not be read (name, reason)."""

    costs: tuple[PaperRun, ...]
    preview: tuple[PaperRun, ...]
    solvers: tuple[PaperRun, ...]
    obstacles: tuple[PaperRun, ...]
    unreadable: tuple[tuple[str, str], ...]
    machine: Machine


def _load(run_dir: Path) -> PaperRun:
    record = load_run(run_dir, neighbours=False)
    if record.status == "error" or len(record.trace) == 0:
        why = (record.outcome.error or "no trace rows").strip().splitlines()
        raise PaperError(f"{run_dir.name}: status {record.status}: {why[-1] if why else ''}")
    return PaperRun(record, variant_of(record))


def find_paper_runs(out_dir: Path, families: Iterable[str] = FAMILIES) -> PaperRuns:
    """Every run of ``out_dir`` whose family is one of the paper's, loaded (one run at a
    time is small: a minute of 50 Hz trace). PaperError when there is none."""
    wanted = set(families)
    found: dict[str, list[PaperRun]] = {f: [] for f in FAMILIES}
    bad: list[tuple[str, str]] = []
    for run_dir in iter_run_dirs(out_dir):
        try:
            doc = read_json(run_dir / "run.json")
            family = doc.get("info", {}).get("family") if isinstance(doc, dict) else None
            if family not in wanted:
                continue
            found[str(family)].append(_load(run_dir))
        except (RecordError, PaperError, FileNotFoundError) as exc:
            bad.append((run_dir.name, str(exc)))
    if not any(found.values()):
        raise PaperError(f"{out_dir}: no run of the paper's experiments (families "
                         f"{', '.join(FAMILIES)}; run catalogs/paper.toml into it)")
    return PaperRuns(costs=tuple(found[FAMILY_COSTS]), preview=tuple(found[FAMILY_PREVIEW]),
                     solvers=tuple(found[FAMILY_SOLVERS]),
                     obstacles=tuple(found[FAMILY_OBSTACLES]), unreadable=tuple(bad),
                     machine=read_machine(out_dir))
