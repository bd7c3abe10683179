"""``hwyeval import openscenario``: OpenSCENARIO 1.x files -> a catalog folder.

Per scenario file: safe XML (:mod:`.xml_safe`), parameters and constraints
(:mod:`.params`), catalog references (:mod:`.catalogs`), the road through netconvert and
its lane map (:mod:`.road`), entities (:mod:`.entities`), the Init and the stories
(:mod:`.story`) -> ``<stem>.story.json`` (:mod:`suite.catalog.storyboard`) and a
scenario table (:mod:`.catalog_out`). A variation file (``ParameterValueDistribution``)
imports its template with the declared values, counts its parameter sets (those that
violate the template's constraints are counted apart) and writes them to
``<stem>.sets.json``; ``variants`` > 0 also imports that many of the valid sets (evenly
spread) as scenarios of their own. The variation file's own scenario is a *logical
scenario*: it names its template and the varied parameters' values (``openscenario``)
and carries their space as a ``[scenario.search]`` table (:mod:`.logical`), which
``hwyeval search`` falsifies by importing the template per point. Before anything is
written the inputs and the output folder are checked (:mod:`.plan`,
:mod:`suite.importers.common.out_guard`); a file's outputs are staged and moved into the
folder once all of them are (:mod:`suite.importers.common.staging`), as ``import
commonroad`` does.
"""

from __future__ import annotations

import json
import math
import re
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from suite.catalog import storyboard as sb
from suite.importers.common import batch, out_guard, staging
from suite.importers.openscenario import catalog_out
from suite.importers.openscenario.actions_xml import ActionReader
from suite.importers.openscenario.catalogs import CatalogIndex, resolve_references
from suite.importers.openscenario.conditions_xml import read_trigger
from suite.importers.openscenario.entities import read_entities
from suite.importers.openscenario.errors import OscImportError, fail_at
from suite.importers.openscenario.lane_bands import read_bands
from suite.importers.openscenario.logical import logical_tables, set_table
from suite.importers.openscenario.params import declare, resolve_tree
from suite.importers.openscenario.plan import check_plan, road_file
from suite.importers.openscenario.positions import Placer, nearest_lane
from suite.importers.openscenario.road import LaneMap, build_road
from suite.importers.openscenario.story import read_init, read_stories
from suite.importers.openscenario.variation import (
    distribution_space,
    parameter_sets,
    template_of,
)
from suite.importers.openscenario.vocabulary import check_vocabulary
from suite.importers.openscenario.xml_safe import read_xml
from suite.road.network import RoadNetwork, RoadNetworkError

__all__ = ["FileResult", "ImportOptions", "ImportOutcome", "import_files"]

TOP_LEVEL = ("FileHeader", "ParameterDeclarations", "CatalogLocations", "RoadNetwork",
             "Entities", "Storyboard")
DEFAULT_DURATION_S = 60.0
# UN R157's acceptance criteria that are off by default (docs/metrics.md): the minimum
# following time gap, kept beyond 3 s of each shortfall. No collision caused by the
# system is the default max_at_fault_collisions = 0 already.
R157_CRITERIA = {"max_r157_gap_shortfall_s": 0.0}
R157_SECTION_LABEL = "r157_section"  # the label naming a scenario's Annex 5 section
_R157_SECTION = re.compile(r"(?<![\d.])4[._ ]([1-6])(?![\d])")
MIN_ROAD_AHEAD_M = 50.0  # an ego starting closer than this [m] to its route's end is refused


@dataclass(frozen=True)
class ImportOptions:
    """``ego``: the ego entity's name (None: the one named like an ego);
    ``ignore_constraints``; ``duration_s`` [s]: the run's length when the stop trigger
    is not a plain simulation time (None: :data:`DEFAULT_DURATION_S`); ``variants``: how
    many parameter sets of a variation file become scenarios; ``r157``: each scenario
    is judged by UN R157's acceptance criteria too (:data:`R157_CRITERIA`) and labelled
    with its Annex 5 section (:func:`r157_section`); ``parameters``: (name, value)
    pairs that replace the declared values of the files' top-level parameters (a
    variation's parameter set included: the command line wins), each of them declared
    by every file imported; ``search_ranges``: a variation file's deterministic
    ``DistributionRange`` becomes a range of its logical scenario's search table rather
    than its steps as choices (:mod:`.logical`)."""

    ego: str | None = None
    ignore_constraints: bool = False
    duration_s: float | None = None
    variants: int = 0
    r157: bool = False
    parameters: tuple[tuple[str, str], ...] = ()
    search_ranges: bool = False

    def __post_init__(self) -> None:
        if self.duration_s is not None and not (math.isfinite(self.duration_s)
                                                and self.duration_s > 0):
            raise ValueError(f"duration_s must be > 0, got {self.duration_s!r}")
        if self.variants < 0:
            raise ValueError(f"variants must be >= 0, got {self.variants}")
        names = [n for n, _ in self.parameters]
        if len(set(names)) != len(names):
            twice = sorted(n for n in set(names) if names.count(n) > 1)
            raise ValueError(f"parameters set twice: {twice}")


@dataclass(frozen=True)
class FileResult:
    """One imported file: source, scenario names written, parameter sets (variation
    files: total and violating the constraints), notes, wall time [s]."""

    source: Path
    names: tuple[str, ...]
    sets: int = 0
    invalid_sets: int = 0
    notes: tuple[str, ...] = ()
    wall_s: float = 0.0


@dataclass(frozen=True)
class ImportOutcome:
    results: tuple[FileResult, ...]
    failures: tuple[OscImportError, ...]
    catalog: Path | None


@dataclass
class _Built:
    table: dict[str, Any]
    story: sb.Storyboard
    notes: list[str] = field(default_factory=list)


def _route(lane_map: LaneMap, network: RoadNetwork, start: str) -> tuple[str, ...]:
    """From ``start`` downstream: the successor with the most lanes, no edge twice."""
    route = [start]
    while True:
        nxt = sorted({ln.to_edge_id for ln in network.lane_links(route[-1])
                      if ln.direction != "t" and ln.to_edge_id not in route},
                     key=lambda e: (-network.lane_count(e), e))
        if not nxt:
            return tuple(route)
        route.append(nxt[0])


def _ego_start_edge(root: Any, ego: str, lane_map: LaneMap, network: RoadNetwork) -> str:
    """The edge the ego's Init teleport puts it on."""
    for priv in root.iterfind("Storyboard/Init/Actions/Private"):
        if priv.get("entityRef") != ego:
            continue
        pos = priv.find("PrivateAction/TeleportAction/Position")
        kid = None if pos is None else next((k for k in pos if isinstance(k.tag, str)), None)
        if kid is None:
            continue
        if kid.tag in ("LanePosition", "RoadPosition"):
            road = str(kid.get("roadId"))
            lane = float(kid.get("laneId", kid.get("t", "-1")))
            side = -1 if lane < 0 else 1
            edges = lane_map.edges.get((road, side))
            if not edges:
                raise fail_at(kid, f"road {road} has no SUMO edge on that side")
            return edges[0]
        if kid.tag == "WorldPosition":
            x, y = float(kid.get("x", "0")), float(kid.get("y", "0"))
            cands = [e for es in lane_map.edges.values() for e in es]
            return min(cands, key=lambda e: nearest_lane(network, (e,), x, y)[0])
        raise fail_at(kid, "the ego's Init position must be a lane, road or world position")
    raise fail_at(root.find("Storyboard") if root.find("Storyboard") is not None else root,
                  f"the ego {ego} has no TeleportAction in Init")


def _duration(stop: sb.Trigger, options: ImportOptions, notes: list[str]) -> float:
    if len(stop.groups) == 1 and len(stop.groups[0].conditions) == 1:
        c = stop.groups[0].conditions[0]
        if isinstance(c.check, sb.SimulationTimeCondition) and c.check.rule in (
                "greaterThan", "greaterOrEqual"):
            return round(c.check.value_s + c.delay_s, 3)
    d = options.duration_s or DEFAULT_DURATION_S
    notes.append(f"the stop trigger is no plain simulation time: the run lasts until it "
                 f"fires, at most {d:g} s (--duration-s)")
    return d


def _road(root: Any, source: Path, out_dir: Path) -> tuple[Path, LaneMap, Any]:
    xodr = road_file(root, source)
    net_path = out_dir / f"{catalog_out.net_stem(xodr)}.net.xml"
    lane_map = build_road(xodr, net_path)
    catalog_out.write_atomic(net_path.with_suffix("").with_suffix(".lanes.json"),
                             json.dumps(lane_map.as_json(), indent=1) + "\n")
    return net_path, lane_map, read_xml(xodr)


def _check_top(root: Any) -> None:
    if root.tag != "OpenSCENARIO":
        raise fail_at(root, "not an OpenSCENARIO file")
    for kid in root:
        if isinstance(kid.tag, str) and kid.tag not in TOP_LEVEL:
            raise fail_at(kid, f"{kid.tag} is not supported")
    header = root.find("FileHeader")
    if header is not None and (header.get("revMajor") != "1"
                               or int(header.get("revMinor", "0")) > 3):
        raise fail_at(header, "only OpenSCENARIO 1.0 to 1.3 is supported")


def build_scenario(source: Path, out_dir: Path, options: ImportOptions,
                   overrides: Mapping[str, str] | None = None) -> _Built:
    """Read, resolve and convert one scenario file (module docstring)."""
    root = read_xml(source).getroot()
    _check_top(root)
    params = declare(root, {**(overrides or {}), **dict(options.parameters)},
                     options.ignore_constraints)
    resolve_tree(root, params)
    resolve_references(root, CatalogIndex.of(root, source))
    check_vocabulary(root)
    net_path, lane_map, odr = _road(root, source, out_dir)
    try:
        network = RoadNetwork.load(net_path)
    except RoadNetworkError as exc:
        raise OscImportError(str(source), "RoadNetwork", f"the SUMO net: {exc}") from None
    entities = read_entities(root, str(source), options.ego)
    ego = next(e for e in entities if e.ego)
    route = _route(lane_map, network, _ego_start_edge(root, ego.name, lane_map, network))
    bands = {str(r.get("id")): read_bands(r) for r in odr.getroot().iter("road")}
    placer = Placer(lane_map, bands, network, route)
    names = {e.name for e in entities}
    reader = ActionReader(placer, names, ego.name)
    board = root.find("Storyboard")
    if board is None:
        raise fail_at(root, "a Storyboard is required")
    by_name = {e.name: e for e in entities}
    init = read_init(board, reader, by_name, ego.name)
    stories = read_stories(board, reader, ego.name, init)
    stop = read_trigger(board.find("StopTrigger"), placer, names)
    inits = tuple(sb.EntityInit(n, _front(init.places[n], by_name[n]), init.speeds.get(n, 0.0))
                  for n in by_name if n != ego.name)
    story = sb.Storyboard(entities, inits, stories, stop, source.name)
    notes = list(init.notes)
    start = _front(init.places[ego.name], ego)
    speed = round(init.speeds.get(ego.name, 0.0), 6)
    ego_t: dict[str, Any] = {"lane": start.lane, "pos_m": round(start.pos_m, 3),
                             "speed_mps": speed, "target_speed_mps": speed}
    if abs(start.lateral_m) > 1e-6 or abs(start.heading_rad) > 1e-6:
        ego_t.update(lateral_offset_m=round(start.lateral_m, 4),
                     heading_rad=round(start.heading_rad, 5))
    left = network.route_length_m(route) - start.pos_m
    if left < MIN_ROAD_AHEAD_M:
        raise OscImportError(str(source), "Init", f"the ego {ego.name} starts {left:.1f} m "
                             "before its route ends (a lane driving against the road's "
                             "reference line on a right-hand-traffic road?)")
    table: dict[str, Any] = {"net": net_path.name, "route": list(route), "ego": ego_t,
                             "duration_s": _duration(stop, options, notes)}
    if options.r157:
        table["criteria"] = dict(R157_CRITERIA)
        section = r157_section(root, source)
        if section is None:
            notes.append("no R157 section (4.1 to 4.6) in the file header's description "
                         "or the file's name: not labelled with one")
        else:
            table["labels"] = {R157_SECTION_LABEL: section}
    return _Built(table, story, notes)


def r157_section(root: Any, source: Path) -> str | None:
    """UN R157 Annex 5's test section ("4.1" to "4.6") a scenario file names: the first
    "4.N" or "4_N" (N = 1..6, not followed by a digit) in its FileHeader's description,
    else in its file name; None when neither names one."""
    header = root.find("FileHeader")
    texts = ("" if header is None else str(header.get("description", "")), source.stem)
    for text in texts:
        m = _R157_SECTION.search(text)
        if m is not None:
            return f"4.{m.group(1)}"
    return None


def _front(p: sb.RoutePosition, e: sb.Entity) -> sb.RoutePosition:
    """The front bumper's place of an entity whose reference point is at ``p``."""
    return sb.RoutePosition(p.pos_m + e.front_m, p.lane, p.lateral_m, p.heading_rad)


def _write(built: _Built, out_dir: Path, stem: str, source: Path,
           extra_notes: Sequence[str] = (), extra: Mapping[str, Any] | None = None) -> str:
    name = catalog_out.scenario_name(stem)
    story_file = f"{stem}.story.json"
    catalog_out.write_atomic(out_dir / story_file, sb.story_to_json(built.story))
    table = {"name": name, **built.table, "storyboard": story_file, **(extra or {})}
    catalog_out.write_fragment(out_dir, stem, name, table, [*built.notes, *extra_notes],
                               source.name)
    return name


def _import_variation(source: Path, root: Any, out_dir: Path, options: ImportOptions,
                      catalog_dir: Path) -> FileResult:
    t0 = time.perf_counter()
    template = template_of(root, source)
    sets = parameter_sets(root)
    axes = distribution_space(root)
    troot = read_xml(template).getroot()
    valid, invalid = [], 0
    for s in sets:
        try:
            declare(troot, s, options.ignore_constraints)
            valid.append(s)
        except OscImportError:
            invalid += 1
    stem = out_guard.output_stem(source, catalog_out.OUTPUTS)
    note = (f"{len(sets)} parameter sets, {invalid} violate the template's constraints "
            f"({stem}.sets.json)")
    built = build_scenario(template, out_dir, options)
    logical, unsearched = logical_tables(
        template, troot, axes, catalog_dir, fixed=options.parameters, ego=options.ego,
        ignore_constraints=options.ignore_constraints, search_ranges=options.search_ranges)
    names = [_write(built, out_dir, stem, template, [note, *unsearched], logical)]
    n = min(options.variants, len(valid))
    notes = [note, *unsearched]
    imported: list[dict[str, Any]] = []
    for k in range(n):
        idx = (k * len(valid)) // n
        try:
            built = build_scenario(template, out_dir, options, valid[idx])
        except OscImportError as exc:  # this set only: the others go on
            notes.append(f"parameter set {idx} not imported: {exc}")
            continue
        names.append(_write(built, out_dir, f"{stem}__set{idx}", template,
                            [f"parameter set {idx}: {valid[idx]}"],
                            set_table(template, troot, valid[idx], catalog_dir,
                                      fixed=options.parameters, ego=options.ego,
                                      ignore_constraints=options.ignore_constraints)))
        imported.append({"set": idx, "scenario": names[-1], "values": valid[idx]})
    # the counts and the sets imported, not every valid set: the ALKS files expand to
    # up to 40 000 of them (12 MB); the variation file itself lists them all
    catalog_out.write_atomic(out_dir / f"{stem}.sets.json", json.dumps(
        {"template": template.name, "sets": len(sets), "violating_constraints": invalid,
         "valid": len(valid), "imported": imported}, indent=0) + "\n")
    return FileResult(source, tuple(names), len(sets), invalid, tuple(notes),
                      time.perf_counter() - t0)


def import_file(source: Path, out_dir: Path, options: ImportOptions) -> FileResult:
    """Import one file (a scenario or a variation file) into ``out_dir``: its outputs
    are written into a staging folder and moved into ``out_dir`` once all of them are
    (:mod:`suite.importers.common.staging`; the folder is not checked here:
    :func:`import_files` does)."""
    with staging.staged(out_dir) as stage:
        result = _import_file(source, stage, options, out_dir)
        staging.commit(stage, out_dir)
    return result


def _import_file(source: Path, out_dir: Path, options: ImportOptions,
                 catalog_dir: Path) -> FileResult:
    """``out_dir``: where the outputs are written (the staging folder); ``catalog_dir``:
    where they end up (a logical scenario's template path is relative to it)."""
    t0 = time.perf_counter()
    root = read_xml(source).getroot()
    if root.find("ParameterValueDistribution") is not None:
        return _import_variation(source, root, out_dir, options, catalog_dir)
    stem = out_guard.output_stem(source, catalog_out.OUTPUTS)
    built = build_scenario(source, out_dir, options)
    return FileResult(source, (_write(built, out_dir, stem, source),),
                      notes=tuple(built.notes), wall_s=time.perf_counter() - t0)


def import_files(sources: Sequence[Path], out_dir: Path,
                 options: ImportOptions | None = None, *,
                 overwrite: bool = False) -> ImportOutcome:
    """Check the inputs and ``out_dir`` (:func:`~suite.importers.openscenario.plan.
    check_plan`: :class:`~suite.importers.common.errors.OutputRefused` before anything
    is written; ``overwrite``: write beside files the import did not write and replace
    an edited ``catalog.toml``), then import every file in turn (a failing one is
    recorded, the next goes on). When a file imported, ``catalog.toml`` is rebuilt at
    the end from every scenario of ``out_dir`` (when none did, nothing in ``out_dir``
    changes)."""
    opts = options or ImportOptions()
    sources = check_plan([Path(s) for s in sources], out_dir, overwrite)
    done = batch.import_each(sources, out_dir, catalog_out.OUTPUTS,
                             lambda source: import_file(source, out_dir, opts),
                             OscImportError)
    return ImportOutcome(done.results, done.failures, done.catalog)
