"""The time series of a recording (``Scalars`` with static ``SeriesLines`` names/colours).

``/safety/...``      SUMO SSM TTC (``/safety/ttc_s``) and ours, the verdict's, ahead and
                     behind (``/safety/ttc_s/{ahead,behind}``; "no conflict", +∞, is
                     drawn at :data:`TTC_CAP_S` so the panel is never empty), the
                     verdict's minimum (``/safety/ttc_s/verdict_min``), gap, collision
                     flag, off-road excess, ellipse margin and DRAC ahead
                     (``/safety/drac_mps2``; the verdict's series)
verdict series       every catalogue entry whose ``Drawing`` names a Rerun path
                     (:mod:`reports.metrics.catalogue`), at that path with its label and
                     colour: :func:`log_metric_series`
limits               every criterion in force is a constant series next to its signal
                     (``.../limit``, ``.../limit_min``, ``.../limit_max``; a bound on an
                     absolute value as ``limit_pos`` and ``limit_neg``), from the
                     verdict's ``criteria``: :data:`LIMITS`, the catalogue's criteria
                     with a ``line``
``/comfort/...``     body accelerations as recorded and as the verdict smoothed them,
                     jerks, yaw rate and yaw acceleration (the verdict's series)
``/controller/...``  speed and set-point, lateral deviation, heading error, steering and
                     torque (total; outer and correction when the controller records
                     them), residual, preview error, pass side, fallback, obstacles;
                     and every controller diagnostic of ``Trace.extra`` at
                     ``/controller/<name>`` in its own unit
``/timing/...``      time per loop [ms]
"""

from __future__ import annotations

import numpy as np
import rerun as rr

from reports.metrics.catalogue import CATALOGUE, CRITERIA
from reports.metrics.catalogue import TTC_CAP_S as CAP_S
from reports.metrics.values import signal
from suite.rerun.paths import CONTROLLER
from suite.rerun.stream import Colour, RunLog, time_columns

BLUE = (80, 170, 255, 255)
ORANGE = (255, 150, 60, 255)
PURPLE = (160, 120, 255, 255)
WHITE = (255, 255, 255, 255)
GREY = (200, 200, 200, 255)
MAGENTA = (230, 80, 230, 255)
RED = (255, 60, 60, 255)
GREEN = (60, 230, 120, 255)
PALETTE = (BLUE, ORANGE, GREEN, PURPLE, MAGENTA, GREY)
LIMIT = (255, 80, 80, 160)
TTC_CAP_S = CAP_S  # +inf TTC ("no conflict") is drawn here

# criterion -> (entity path of its limit line(s), label, symmetric: ±limit): the
# catalogue's criteria that have a line (reports.metrics.catalogue)
LIMITS: dict[str, tuple[str, str, bool]] = {
    name: (s.criterion.line, s.criterion.line_label, s.criterion.symmetric)
    for name, s in CRITERIA.items() if s.criterion is not None and s.criterion.line}


def _constant(log: RunLog, path: str, value: float, name: str, color: Colour) -> None:
    """A horizontal line over the whole run (first and last trace row)."""
    if log.n == 0 or not np.isfinite(value):
        return
    rows = np.array([0, log.n - 1]) if log.n > 1 else np.array([0])
    log.static(path, rr.SeriesLines(names=[name], colors=[color], widths=[1.0]))
    log.send(path, rr.Scalars.columns(scalars=np.full(rows.size, float(value))),
             idx=time_columns(log.steps[rows], log.t[rows]))


def log_limits(log: RunLog) -> None:
    """Every criterion in force of :data:`LIMITS` as a constant series by its signal."""
    verdict = log.record.verdict
    if verdict is None:
        return
    for criterion, (path, label, symmetric) in LIMITS.items():
        limit = verdict.criteria.get(criterion)
        if limit is None:
            continue
        if symmetric:
            _constant(log, f"{path}_pos", float(limit), f"{label} = {limit:g}", LIMIT)
            _constant(log, f"{path}_neg", -float(limit), f"{label} = -{limit:g}", LIMIT)
        else:
            _constant(log, path, float(limit), f"{label} = {limit:g}", LIMIT)


def _capped_ttc(values: np.ndarray) -> np.ndarray:
    out: np.ndarray = np.where(np.isposinf(values), TTC_CAP_S,
                               np.minimum(values, TTC_CAP_S))
    return out


def log_safety(log: RunLog) -> None:
    trace, series = log.record.trace, log.record.series
    s = log.scalar
    s("/safety/ttc_s", trace.safety.ssm_ttc_s, "TTC [s] (SUMO SSM)", (255, 90, 90, 255))
    s("/safety/min_gap_m", trace.safety.min_gap_m, "min gap [m]", (255, 200, 60, 255))
    # the verdict's contact is the boxes'; SUMO's lane-based report is its own series
    s("/safety/collision", trace.safety.geom_collision.astype(float), "collision (boxes)",
      (255, 0, 0, 255))
    s("/safety/collision/sumo", trace.safety.sumo_collision.astype(float),
      "SUMO's collision report (lane-based)", (255, 120, 120, 255))
    if series is None:
        return
    verdict = log.record.verdict
    if verdict is not None:
        value = verdict.value("min_ttc_s")
        shown = "∞ (no conflict)" if np.isposinf(value) else f"{value:.3g} s"
        _constant(log, "/safety/ttc_s/verdict_min", float(_capped_ttc(np.array([value]))[0]),
                  f"min TTC (verdict) = {shown}", (255, 200, 120, 255))


def log_metric_series(log: RunLog) -> None:
    """The verdict's series of every catalogue entry whose drawing has a Rerun path,
    at that path with its label and colour (+inf and values above a cap drawn at it)."""
    record = log.record
    if record.series is None:
        return
    for entry in CATALOGUE:
        d = entry.drawing
        if d is None or not d.rerun:
            continue
        values = signal(entry.drawn_series, record.trace, record.series)
        if values is None:
            continue
        if d.cap is not None:
            values = np.minimum(values, d.cap)
        log.scalar(d.rerun, values, d.rerun_label, d.colour)


def log_comfort(log: RunLog) -> None:
    ego = log.record.trace.ego
    s = log.scalar
    s("/comfort/accel_mps2/long", ego.long_acc_mps2, "long acc [m/s²]", BLUE)
    s("/comfort/accel_mps2/lat", ego.lat_acc_mps2, "lat acc [m/s²]", ORANGE)


def _optional(log: RunLog, name: str) -> np.ndarray | None:
    return log.record.trace.extra.get(name)


def log_controller(log: RunLog) -> None:
    trace = log.record.trace
    s = log.scalar
    s("/controller/speed_mps/actual", trace.ego.speed_mps, "speed [m/s]", GREEN)
    s("/controller/speed_mps/target", trace.decision.target_speed_mps, "target [m/s]", GREY)
    s("/controller/lat_dev_m", trace.ego.lat_dev_m, "lateral deviation [m]", BLUE)
    s("/controller/heading_err_deg", np.degrees(trace.ego.heading_err_rad),
      "heading error [deg]", PURPLE)
    s("/controller/steer_deg/total", np.degrees(trace.ego.steer_rad), "steer total [deg]", WHITE)
    s("/controller/torque_nm/total", trace.ego.torque_nm, "torque total [N m]", WHITE)
    # the two-loop controller's split of its command, when it records it
    for path, name, label, scale, colour in (
            ("steer_deg/outer", "steer_outer_rad", "steer outer [deg]", 180 / np.pi, BLUE),
            ("steer_deg/correction", "steer_corr_rad", "steer correction [deg]", 180 / np.pi,
             ORANGE),
            ("torque_nm/outer", "torque_outer_nm", "torque outer [N m]", 1.0, BLUE),
            ("torque_nm/correction", "torque_corr_nm", "torque correction [N m]", 1.0, ORANGE),
            ("preview_err_m/t", "preview_err_t_m", "preview err t [m]", 1.0, BLUE),
            ("preview_err_m/n", "preview_err_n_m", "preview err n [m]", 1.0, ORANGE)):
        values = _optional(log, name)
        if values is not None:
            s(f"{CONTROLLER}/{path}", scale * values, label, colour)
    s("/controller/residual", trace.controller.residual, "residual E", MAGENTA)
    s("/controller/side", trace.decision.side.astype(float), "pass side (+1 L, -1 R, 2 follow)",
      MAGENTA)
    s("/controller/fallback", trace.controller.fallback.astype(float), "fallback", RED)
    s("/controller/n_obstacles", np.maximum(trace.decision.n_obstacles, 0).astype(float),
      "obstacles", GREY)
    log_diagnostics(log)


def diagnostic_path(name: str) -> str:
    """Entity path of a controller diagnostic (a ``Trace.extra`` column)."""
    return f"{CONTROLLER}/{name}"


def log_diagnostics(log: RunLog) -> None:
    """Every ``Trace.extra`` column as a scalar at ``/controller/<name>``."""
    for i, (name, values) in enumerate(log.record.trace.extra.items()):
        log.scalar(diagnostic_path(name), values, name, PALETTE[i % len(PALETTE)])


def log_timing(log: RunLog) -> None:
    trace = log.record.trace
    loops: tuple[tuple[str, np.ndarray, Colour], ...] = (
        ("outer", trace.controller.outer_s, BLUE), ("inner", trace.controller.inner_s, ORANGE),
        ("obstacles", trace.timing.obstacles_s, PURPLE),
        ("controller", trace.timing.controller_s, WHITE), ("sumo", trace.timing.sumo_s, GREEN))
    for name, seconds, colour in loops:
        log.scalar(f"/timing/step_ms/{name}", 1e3 * seconds, f"{name} [ms]", colour)


def log_scalars(log: RunLog) -> None:
    """Every time series of the recording (see the module doc)."""
    if not log.n:
        return
    log_safety(log)
    log_comfort(log)
    log_metric_series(log)
    log_controller(log)
    log_timing(log)
    log_limits(log)

