"""Write a run as a Rerun recording, ``DIR/<scenario>/run.rrd``.

The runner calls :func:`write_rrd` after the run directory is written; everything is
logged from the typed record (:mod:`reports.record`): the trace and controller arrays
as recorded, and the verdict and series the metrics stored (never recomputed here).

Recording
---------
* application id :func:`application_id_for` (``hwyeval:<catalog>:<scenario>``): the
  viewer groups every recording of one scenario under it, so last night's and
  tonight's run of a scenario sit side by side;
* recording id :func:`new_recording_id`, a fresh UUID4 per written log: two runs of
  the same scenario (two nights, a re-run) are two recordings, never merged into one
  (which would show every event twice); the recording's name says scenario, seed,
  status and catalog, its start time is when the log was written, and its properties
  (``/__properties``) carry catalog, scenario, seed, controller, status and version;
* a per-run ``rr.RecordingStream`` (never the global one) encoded in memory and written
  to ``run.rrd`` (a full disk raises at once, naming the file) with the default
  blueprint of :mod:`suite.rerun.blueprint` embedded;
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

import os
import re
import time
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

__all__ = ["ENTITY_PATHS", "FLUSH_TIMEOUT_S", "application_id_for", "lane_edges",
           "log_record", "new_recording_id", "write_rrd"]

# Encoding a run's log takes well under a second; this bounds a Rerun that never
# finishes encoding (it raises then) [s].
FLUSH_TIMEOUT_S = 60.0


def _catalog_name(catalog: str | None) -> str:
    """A catalog name from a name or a catalog file path ('catalogs/smoke.yaml' -> 'smoke')."""
    if not catalog:
        return ""
    path = Path(catalog)
    if path.suffix.lower() in {".yaml", ".yml", ".toml", ".json"}:
        return path.stem
    return path.name if "/" in catalog else catalog


def application_id_for(catalog: str | None, scenario: str) -> str:
    """``hwyeval:<catalog name>:<scenario>``: what groups a scenario's recordings
    (characters Rerun does not accept in an application id become ``_``)."""
    parts = ["hwyeval", _catalog_name(catalog), scenario]
    return ":".join(re.sub(r"[^A-Za-z0-9_-]", "_", p) for p in parts if p)


def new_recording_id() -> str:
    """A recording id of its own for every log written (UUID4)."""
    return str(uuid.uuid4())


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


def _send_identity(rec: rr.RecordingStream, record: RunRecord, catalog: str) -> None:
    info = record.info
    rec.send_recording_name(f"{info.scenario} · seed {info.seed} · {record.status.upper()} · "
                            f"{_catalog_name(catalog) or 'no catalog'}")
    rec.send_recording_start_time_nanos(time.time_ns())
    rec.send_property("run", rr.AnyValues(
        catalog=_text(_catalog_name(catalog)), scenario=_text(info.scenario),
        seed=_text(str(info.seed)), controller=_text(info.controller),
        status=_text(record.status), hwyeval_version=_text(info.hwyeval_version)))


def _text(value: str) -> np.ndarray:
    """``value`` as a one-element numpy string array, the form Rerun's AnyValues takes
    without pyarrow's ``pa.scalar``: that call imports pandas (0.25 s), which scenario
    processes run without (suite.exec.arrow_without_pandas)."""
    return np.array([value], dtype=np.str_)


def log_record(record: RunRecord, out: Path, *, catalog_name: str | None = None,
               application_id: str | None = None) -> Path:
    """Write the recording of ``record`` (judged or not) to ``out``; returns ``out``.
    ``application_id`` defaults to :func:`application_id_for` the run's scenario.

    All or nothing: on any exception no file is left at ``out`` (nor a partial one
    beside it) and the exception propagates."""
    info = record.info
    catalog = catalog_name if catalog_name is not None else (info.catalog_name or info.catalog)
    app = application_id or application_id_for(catalog, info.scenario)
    # Written beside ``out`` and renamed into place once complete: a log that raised
    # half way leaves no file, so nothing (a viewer, a resume) mistakes a road-only
    # recording for the run's log.
    partial = out.with_name(out.name + ".partial")
    rec = rr.RecordingStream(app, recording_id=new_recording_id())
    # Encoded in memory and written here, not by Rerun's file sink: on a full disk that
    # sink's writer thread dies and every later log call, flush and disconnect waits for
    # it forever (the run then hung until its wall-clock budget). Here the write raises
    # at once, naming the file. The bytes are the file sink's (footer included).
    stream = rr.binary_stream(recording=rec)
    try:
        rec.send_blueprint(default_blueprint(view_geometry(record)), make_active=False,
                           make_default=True)
        _send_identity(rec, record, catalog)
        _write(RunLog(rec, record))
        data = stream.read(flush=True, flush_timeout_sec=FLUSH_TIMEOUT_S) or b""
        rec.disconnect()
        data += stream.read(flush=False) or b""
        _write_bytes(partial, data)
    except BaseException:
        rec.disconnect()
        partial.unlink(missing_ok=True)
        raise
    os.replace(partial, out)
    return out


def _write_bytes(path: Path, data: bytes) -> None:
    """``path.write_bytes(data)``, its OSError naming ``path`` (a failed write names no
    file by itself)."""
    try:
        path.write_bytes(data)
    except OSError as exc:
        if exc.filename is None:
            raise OSError(exc.errno, exc.strerror, str(path)) from exc
        raise


def write_rrd(run_dir: Path, *, catalog_name: str | None = None,
              application_id: str | None = None) -> Path:
    """Write ``run_dir/run.rrd`` from the run directory; returns its path.

    Raises what :func:`reports.record.load_run` raises for an unreadable directory.
    """
    run_dir = Path(run_dir)
    record = load_run(run_dir)
    return log_record(record, run_dir / RRD, catalog_name=catalog_name,
                      application_id=application_id)
