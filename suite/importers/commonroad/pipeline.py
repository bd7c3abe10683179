"""One CommonRoad file -> ``<stem>.net.xml``, ``<stem>.tracks.parquet`` and its catalog
scenario (``<stem>.scenario.json``, gathered into ``catalog.toml``); several files in
turn. Before anything is written the inputs and the output folder are checked
(:mod:`suite.importers.common.out_guard`: no two inputs of one stem, nothing in the
folder the import did not write, an unedited generated catalog, unless ``overwrite``).
A file's outputs are written into a staging folder and moved into the output folder
only once all of them are (:mod:`suite.importers.common.staging`): a file that
fails leaves nothing of its own, keeps what an earlier import of its stem wrote, and
does not touch what the other files wrote."""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from controllers.plant.vehicle_model import VehicleParams
from suite.catalog.loader import MAX_STEPS
from suite.catalog.tracks import Track, TrackSet, write_tracks
from suite.importers.common import batch, out_guard, staging
from suite.importers.commonroad import catalog_out, recorded_ego
from suite.importers.commonroad.checks import (
    EgoBox,
    LaneShape,
    StepCheck,
    StepParams,
    check_step,
    find_jumps,
    jump_notes,
    refuse_overlap_at_start,
)
from suite.importers.commonroad.errors import ImportFailure
from suite.importers.commonroad.geometry import project
from suite.importers.commonroad.lanelets import RoadRows, build_road
from suite.importers.commonroad.net_build import BuiltNet, NetParams, build_net, plan_net
from suite.importers.commonroad.reader import read_file
from suite.importers.commonroad.records import RecordedFile
from suite.importers.commonroad.speed import lane_speeds
from suite.importers.commonroad.tracks import select_tracks
from suite.road.network import RoadNetwork, RoadNetworkError

__all__ = ["FileResult", "ImportOutcome", "ImportParams", "import_file", "import_files"]


@dataclass(frozen=True)
class ImportParams:
    """Everything the import takes: the net's (extensions, speed limit), the time-step
    check's, and hwyeval's ego (its ``length_m`` turns CommonRoad's centre into the
    catalog's front bumper)."""

    net: NetParams = field(default_factory=NetParams)
    step: StepParams = field(default_factory=StepParams)
    vehicle: VehicleParams = field(default_factory=VehicleParams)
    ego_obstacle: int | None = None  # --ego-obstacle: this recorded vehicle is the ego


@dataclass(frozen=True)
class FileResult:
    """What one file gave: outputs, net size, tracks kept and dropped (by reason), the
    step check, uncertain states, the ego's lane and position [m], the ego centre's
    signed lateral offset from its lane's centre line [m] (left > 0; the catalog's
    ``ego.lateral_offset_m`` / ``heading_rad`` start the run there), notes, wall time
    [s]."""

    source: Path
    name: str
    net_path: Path
    tracks_path: Path
    edges: int
    lanes: int
    recorded_edges: int
    extension_m: float
    route: tuple[str, ...]
    kept: int
    dropped: dict[str, tuple[int, ...]]
    step: StepCheck
    uncertain_states: int
    stalled: int
    ego_lane: int
    ego_pos_m: float
    ego_lateral_m: float
    duration_s: float
    notes: tuple[str, ...]
    wall_s: float
    ego_track: str | None = None  # the recorded ego's track id (recorded_ego), if any
    jumps: int = 0  # recorded vehicles' jumps between samples (checks.find_jumps)


@dataclass(frozen=True)
class ImportOutcome:
    """Every file's result, the failures (in input order) and the catalog written."""

    results: tuple[FileResult, ...]
    failures: tuple[ImportFailure, ...]
    catalog: Path | None


def _lane_shapes(net: BuiltNet) -> list[LaneShape]:
    return [LaneShape(e.edge_id, i, xy, w) for e in net.edges.values()
            for i, (xy, w) in enumerate(zip(e.lanes_xy_m, e.widths_m, strict=True))]


def _goal_edges(rec: RecordedFile, road: RoadRows, net: BuiltNet) -> list[str]:
    """Edges of the goal's lanelets and of the lanes nearest its goal positions."""
    edges = [net.row_edges[r] for lid in rec.ego.goal_lanelets
             for r, _ in road.places_of(lid)]
    lanes = _lane_shapes(net)
    for x, y in rec.ego.goal_points_xy_m:
        edges.append(min(lanes, key=lambda ln: project(ln.xy_m, x, y).distance_m).edge_id)
    return edges


def _uncertain_note(rec: RecordedFile) -> list[str]:
    u = rec.uncertain
    if not u.states:
        return []
    return [f"WARNING {u.states} uncertain states of {u.obstacles} obstacles (position "
            "shapes, orientation/velocity intervals): their centres were used"]


def _dropped_notes(dropped: dict[str, tuple[int, ...]]) -> list[str]:
    what = {"opposite": "heading against the road (opposite carriageway)",
            "off_road": "first sample off the ego's road",
            "not_vehicle": "not road vehicles",
            "before_start": "no sample at or after the initial time step"}
    return [f"{len(ids)} obstacles dropped, {what.get(k, k)}: ids "
            f"{', '.join(map(str, ids[:20]))}{' ...' if len(ids) > 20 else ''}"
            for k, ids in sorted(dropped.items()) if ids]


def _duration_s(rec: RecordedFile, ts: TrackSet, dt_s: float) -> float:
    end = max((t.end_s for t in ts.tracks), default=0.0)
    if end <= 0.0 and rec.ego.goal_end_step is not None:
        end = (rec.ego.goal_end_step - rec.ego.time_step) * dt_s
    if not (math.isfinite(end) and end > 0.0):
        raise ImportFailure(rec.path, "dynamicObstacle", "no recorded sample after the "
                            "planning problem's initial time step: the run would be empty")
    return round(end, 6)


def _runnable(path: str, ts: TrackSet, duration_s: float) -> float:
    """``duration_s`` [s], refused (naming the vehicle recorded last) when its run would
    be longer than the catalog allows (:data:`suite.catalog.loader.MAX_STEPS` control
    steps of :data:`~suite.importers.commonroad.catalog_out.STEP_S`): the catalog
    written would not load."""
    steps = round(duration_s / catalog_out.STEP_S)
    if steps <= MAX_STEPS:
        return duration_s
    last = max(ts.tracks, key=lambda t: t.end_s)
    raise ImportFailure(path, f"obstacle {last.track_id.removeprefix('rec_')}",
                        f"recorded until {last.end_s:g} s after the initial time step: a "
                        f"run lasts at most {MAX_STEPS} control steps of "
                        f"{catalog_out.STEP_S:g} s ({MAX_STEPS * catalog_out.STEP_S:g} s, "
                        "suite.catalog.loader.MAX_STEPS)")


def _ego_box(rec: RecordedFile, params: ImportParams, ego_track: Track | None) -> EgoBox:
    """The ego's box at run time 0: hwyeval's car at the planning problem's centre, or
    the recorded ego's own box."""
    length, width = ((params.vehicle.length_m, params.vehicle.width_m) if ego_track is None
                     else (ego_track.length_m, ego_track.width_m))
    return EgoBox(rec.ego.x_m, rec.ego.y_m, rec.ego.heading_rad, length, width)


def import_file(source: Path, out_dir: Path, params: ImportParams) -> FileResult:
    """Import one file into ``out_dir`` (module docstring; the folder is not checked
    here: :func:`import_files` does)."""
    t0 = time.perf_counter()
    rec, recorded = recorded_ego.resolve(read_file(source), params.ego_obstacle)
    stem = out_guard.output_stem(source, catalog_out.OUTPUTS)
    with staging.staged(out_dir) as stage:
        with recorded_ego.blamed(recorded):
            result = _import(source, stage, params, rec, recorded, t0)
        staging.commit(stage, out_dir,
                       out_guard.output_names(stem, catalog_out.OUTPUTS.per_input))
    return replace(result, net_path=out_dir / result.net_path.name,
                   tracks_path=out_dir / result.tracks_path.name)


def _import(source: Path, out_dir: Path, params: ImportParams, rec: RecordedFile,
            recorded: recorded_ego.RecordedEgo | None, t0: float) -> FileResult:
    """:func:`import_file` of the read file ``rec`` (its ego start and goal already set
    for its recorded ego, if it has one), its outputs written into ``out_dir`` (the
    staging folder)."""
    stem = out_guard.output_stem(source, catalog_out.OUTPUTS)
    road = build_road(rec)
    speeds = lane_speeds(road, rec, params.net.speed_limit_mps)
    plan = plan_net(road, params.net, rec.path, speeds)
    step = check_step(rec.obstacles, rec.dt_s, params.step)
    dt_s = step.dt_s
    selection, ego_track = recorded_ego.split(
        select_tracks(rec.obstacles, _lane_shapes(plan), rec.ego.time_step, dt_s), rec,
        recorded, dt_s)
    # a recording's own glitches: refused (on the ego at t = 0) or warned of (jumps)
    refuse_overlap_at_start(rec.path, selection.tracks, _ego_box(rec, params, ego_track))
    jumps = find_jumps(selection.tracks)
    net_path = out_dir / f"{stem}.net.xml"
    net = build_net(plan, params.net, net_path, rec.path)
    try:
        network = RoadNetwork.load(net_path)
    except RoadNetworkError as exc:
        raise ImportFailure(rec.path, "SUMO net", str(exc)) from exc
    ego_edge = net.row_edges[road.place[road.ego_lanelet][0]]
    route = catalog_out.choose_route(net, network, ego_edge, _goal_edges(rec, road, net))
    ego, centre = catalog_out.ego_table(rec.path, network, route, rec.ego, params.vehicle)
    stalled, stalled_notes = catalog_out.stalled_tables(
        network, route, [o for o in rec.obstacles if o.static])
    early = ([f"{selection.early_samples_dropped} samples before the initial time step "
              "dropped (the last one before it kept where t = 0 falls between samples)"]
             if selection.early_samples_dropped else [])
    notes = [step.note, catalog_out.ego_offset_note(centre), *_uncertain_note(rec),
             *_dropped_notes(selection.dropped), *early, *jump_notes(jumps), *road.notes,
             speeds.note, *rec.notes, *stalled_notes,
             *(f"netconvert: {w}" for w in net.warnings)]
    notes.insert(1, f"{len(selection.tracks)} recorded vehicles kept")
    notes[2:2] = recorded_ego.notes(recorded, ego_track)
    ts = TrackSet((*selection.tracks, *recorded_ego.tracks(ego_track)), dt_s, tuple(notes))
    duration = _runnable(rec.path, ts, _duration_s(rec, ts, dt_s) if ego_track is None
                         else recorded_ego.duration_s(ego_track))
    tracks_path = out_dir / f"{stem}.tracks.parquet"
    write_tracks(tracks_path, ts)
    name = catalog_out.scenario_name(stem)
    table: dict[str, object] = {"name": name, "net": net_path.name, "route": list(route),
                                "ego": ego, "duration_s": duration,
                                "step_s": catalog_out.STEP_S}
    if stalled:
        table["stalled"] = stalled
    table["replay"] = {"tracks": tracks_path.name, "mode": "replay",
                       **recorded_ego.replay_keys(ego_track)}
    table.update(recorded_ego.scenario_keys(ego_track))
    catalog_out.write_fragment(out_dir, stem, name, table, notes, source.name)
    n_lanes = sum(len(e.lanes_xy_m) for e in net.edges.values())
    return FileResult(source, name, net_path, tracks_path, len(net.edges), n_lanes,
                      len(net.row_edges), params.net.downstream_extension_m, route,
                      len(selection.tracks), selection.dropped, step, rec.uncertain.states,
                      len(stalled), int(ego["lane"]), float(ego["pos_m"]),
                      round(centre.lateral_m, 3), duration,
                      tuple(notes), time.perf_counter() - t0,
                      None if ego_track is None else ego_track.track_id, len(jumps))


def import_files(sources: Sequence[Path], out_dir: Path,
                 params: ImportParams | None = None, *,
                 overwrite: bool = False) -> ImportOutcome:
    """Check the inputs and ``out_dir`` (:class:`~suite.importers.common.errors.
    OutputRefused` before anything is written; ``overwrite``: write beside files the
    import did not write and replace an edited ``catalog.toml``), then import every file
    in turn; a failing file is recorded and the next one goes on. When a file imported,
    ``catalog.toml`` is rebuilt at the end from every scenario of ``out_dir`` (when none
    did, nothing in ``out_dir`` changes)."""
    params = ImportParams() if params is None else params
    outputs = catalog_out.OUTPUTS
    sources = out_guard.check_inputs(sources, outputs)
    names = [n for s in sources
             for n in out_guard.output_names(out_guard.output_stem(s, outputs),
                                             outputs.per_input)]
    out_guard.check_out_dir(out_dir, names, outputs, overwrite)
    done = batch.import_each(sources, out_dir, outputs,
                             lambda source: import_file(source, out_dir, params),
                             ImportFailure)
    return ImportOutcome(done.results, done.failures, done.catalog)
