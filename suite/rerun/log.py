"""Write a run as a Rerun recording, ``DIR/<scenario>/run.rrd``.

The runner calls :func:`write_rrd` after the run directory is written; everything is
logged from the typed record (:mod:`reports.record`): the trace and controller arrays
as recorded, and the verdict and series the metrics stored (never recomputed here).

Recording
---------
* application id ``hwyeval`` (default), recording id :func:`recording_id_for`
  (catalog, scenario, seed): a UUID5 string, the same for the same run, so a re-run
  replaces the old recording in the viewer instead of piling up beside it;
* a per-run ``rr.RecordingStream`` (never the global one) saved to ``run.rrd`` with
  the default blueprint of :mod:`suite.rerun.blueprint` embedded;
* timelines ``sim_time`` (duration, from ``t_s``) and ``step`` (sequence).

Entity paths (:data:`ENTITY_PATHS`; users and tests rely on them)
-----------------------------------------------------------------
World (:mod:`suite.rerun.world`), metres in SUMO's network frame:

``/world/road/{lanes,shoulders,centrelines}``, ``/world/reference_path``  static lines
``/world/ego/driven_path``   static, the whole path of the ego CG
``/world/ego/box``           per step, the ego box (label "ego")
``/world/ego/velocity``      per step, arrow of 1 s of travel, labelled with the pass side
``/world/ego/frame``         per step, Transform3D at the ego box centre, scale (1, -1, 1):
                             the "Follow ego" view renders in this frame
``/world/view/north_up``     static Transform3D scale (1, -1, 1) of the "Whole road" view
``/world/vehicles``          per step, moving traffic with SUMO ids as labels
``/world/stalled``           stalled vehicles, static from the outcome, else per step
``/world/ellipses``          per step, obstacle ellipses (colour = pass side)
``/world/plan``, ``/world/preview``  per step, planned trajectory and CG preview
``/world/preview_error``     per step, arrow from the preview end to the plan, from the
                             trace's ``preview_err_t_m``/``preview_err_n_m``
``/world/detection``         per step, detection circle around the CG

Scalars (:mod:`suite.rerun.scalars`): ``/safety/...``, ``/comfort/...``,
``/controller/...`` (every ``Trace.extra`` column at ``/controller/<name>``),
``/timing/step_ms/...``.

Text (:mod:`suite.rerun.events`): ``/events`` (failed criteria at the step their
verdict located them), ``/docs/scenario``, ``/docs/controller``.
"""

from __future__ import annotations

import uuid
from pathlib import Path

import numpy as np
import rerun as rr

from reports.record import RRD, RunRecord, load_run
from suite.rerun.blueprint import ViewGeometry, default_blueprint
from suite.rerun.events import collect_events, log_docs, log_events
from suite.rerun.paths import ENTITY_PATHS
from suite.rerun.scalars import log_scalars
from suite.rerun.stream import RunLog
from suite.rerun.world import (
    lane_edges,
    log_detection,
    log_ego,
    log_ellipses,
    log_plan_preview,
    log_road,
    log_vehicles,
)

__all__ = ["ENTITY_PATHS", "lane_edges", "log_record", "recording_id_for", "write_rrd"]

# Stable namespace for recording ids (uuid5 of "hwyeval|catalog|scenario|seed").
_RECORDING_NAMESPACE = uuid.UUID("6f1d3c2a-9b7e-5d41-8c3a-2e6f0b9a7d15")


def _catalog_name(catalog: str | None) -> str:
    """A catalog name from a name or a catalog file path ('catalogs/smoke.yaml' -> 'smoke')."""
    if not catalog:
        return ""
    path = Path(catalog)
    if path.suffix.lower() in {".yaml", ".yml", ".toml", ".json"}:
        return path.stem
    return path.name if "/" in catalog else catalog


def recording_id_for(catalog: str | None, scenario: str, seed: int | str | None) -> str:
    """Stable recording id of a run: UUID5 of (catalog name, scenario, seed)."""
    key = f"hwyeval|{_catalog_name(catalog)}|{scenario}|{'' if seed is None else seed}"
    return str(uuid.uuid5(_RECORDING_NAMESPACE, key))


def view_geometry(record: RunRecord) -> ViewGeometry:
    """Where the bird's-eye views should look: ego start, heading, road bounds."""
    ego = record.trace.ego
    start = None
    heading = 0.0
    if len(record.trace):
        if np.isfinite(ego.x_m[0]) and np.isfinite(ego.y_m[0]):
            start = (float(ego.x_m[0]), float(ego.y_m[0]))
        if np.isfinite(ego.psi_rad[0]):
            heading = float(ego.psi_rad[0])
    pts = [np.asarray(lane.shape_xy_m, dtype=np.float64).reshape(-1, 2)
           for lane in record.road.lanes]
    pts = [p for p in pts if len(p)]
    bounds = None
    if pts:
        allp = np.concatenate(pts)
        bounds = (float(allp[:, 0].min()), float(allp[:, 0].max()),
                  float(allp[:, 1].min()), float(allp[:, 1].max()))
    return ViewGeometry(ego_start_xy=start, ego_heading_rad=heading, road_bounds=bounds,
                        diagnostics=tuple(record.trace.extra))


def _write(log: RunLog) -> None:
    log_road(log)
    log_docs(log)
    if log.n:
        log_ego(log)
        log_vehicles(log)
        log_ellipses(log)
        log_plan_preview(log)
        log_detection(log)
        log_scalars(log)
    elif log.record.outcome.stalled:
        log_vehicles(log)
    log_events(log, collect_events(log))


def log_record(record: RunRecord, out: Path, *, catalog_name: str | None = None,
               application_id: str = "hwyeval") -> Path:
    """Write the recording of ``record`` (judged or not) to ``out``; returns ``out``."""
    info = record.info
    catalog = catalog_name if catalog_name is not None else (info.catalog_name or info.catalog)
    rid = recording_id_for(catalog, info.scenario, info.seed)
    rec = rr.RecordingStream(application_id, recording_id=rid)
    try:
        rec.save(out, default_blueprint=default_blueprint(view_geometry(record)))
        rec.send_recording_name(f"{info.scenario} · seed {info.seed} · "
                                f"{record.status.upper()}")
        _write(RunLog(rec, record))
        rec.flush()
    finally:
        rec.disconnect()
    return out


def write_rrd(run_dir: Path, *, catalog_name: str | None = None,
              application_id: str = "hwyeval") -> Path:
    """Write ``run_dir/run.rrd`` from the run directory; returns its path.

    Raises what :func:`reports.record.load_run` raises for an unreadable directory.
    """
    run_dir = Path(run_dir)
    record = load_run(run_dir)
    return log_record(record, run_dir / RRD, catalog_name=catalog_name,
                      application_id=application_id)
