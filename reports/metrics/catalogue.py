"""The metric catalogue: one :class:`~reports.metrics.spec.MetricSpec` per metric.

Every table about metrics is a view of :data:`CATALOGUE`: the unit, kind, direction
and series a metric module stores with each value (:func:`reports.metrics.values.measured`),
results.csv's leading columns (:data:`REQUIRED_METRICS`), the criteria and their
defaults (:data:`CRITERIA`, :class:`reports.metrics.criteria.Criteria`), the robustness
scales, compare's tolerances, timing ratios and overlays, summary.csv's aggregations,
the JUnit key metrics, the Rerun log's verdict series and limit lines, the run page's
failure marks and the history's default sparkline. Adding a metric is an entry here
plus its computation in a metric module; a metric module that stores a name without
an entry raises (:func:`spec`).

Units: ``-`` dimensionless, ``s``, ``m``, ``m/s``, ``m/s^2``, ``m/s^3``, ``rad``,
``rad/s``, ``rad/s^2``, ``ms``, ``s^2``. The definitions (the maths) are in each
metric module's doc and in ``docs/metrics.md``.
"""

from __future__ import annotations

from collections.abc import Iterable

from reports.metrics.spec import Criterion, Drawing, MetricSpec, Summary, Tolerance

__all__ = ["CATALOGUE", "CRITERIA", "CRITERIA_METRICS", "DEFAULT_SPARKLINE", "DRAWN",
           "JUNIT_METRICS", "REQUIRED_METRICS", "SUMMARY_METRICS", "TTC_CAP_S", "spec"]

TTC_CAP_S = 10.0  # "no conflict" (+inf TTC) is drawn at this value [s]
_ORANGE, _PURPLE, _BLUE = (255, 150, 60, 255), (160, 120, 255, 255), (80, 170, 255, 255)
_MAGENTA = (230, 80, 230, 255)
_ACC = "longitudinal acceleration"


def _tol(abs_: float, rel: float) -> Tolerance:
    return Tolerance(abs_, rel)


def _crit(name: str, bound: str, default: float | None, scale: float, rank: int,
          line: str = "", label: str = "", symmetric: bool = False) -> Criterion:
    return Criterion(name, bound, default, scale, rank, line, label, symmetric)


_SAFETY: tuple[MetricSpec, ...] = (
    MetricSpec("collision", "-", "safety", "lower", column=0, mark="#dc2626",
               criterion=_crit("max_collision", "max", None, 1.0, 1),
               tolerance=_tol(0.5, 0.0), summary=Summary(("sum",), 0), junit=0),
    MetricSpec("at_fault_collisions", "-", "safety", "lower", column=1,
               criterion=_crit("max_at_fault_collisions", "max", 0.0, 1.0, 0)),
    MetricSpec("min_gap_m", "m", "safety", "higher", "safety.min_gap_m", column=2,
               criterion=_crit("min_gap_m", "min", None, 1.0, 12, "/safety/min_gap_m/limit",
                               "min gap limit [m]"),
               tolerance=_tol(0.25, 0.1), summary=Summary(("min", "mean"), 1), junit=2,
               drawing=Drawing("gap to the nearest vehicle (box to box)", "m")),
    MetricSpec("min_ttc_s", "s", "safety", "higher", "series.ttc_s", column=4,
               mark="#db2777", sparkline=True,
               criterion=_crit("min_ttc_s", "min", 0.95, 1.0, 3, "/safety/ttc_s/limit",
                               "min TTC limit [s]"),
               tolerance=_tol(0.2, 0.1), summary=Summary(("min", "mean"), 2), junit=3,
               drawing=Drawing(f"TTC ahead (none = {TTC_CAP_S:g})", "s", cap=TTC_CAP_S,
                               rerun="/safety/ttc_s/ahead",
                               rerun_label=f"TTC ahead [s] (verdict; none = {TTC_CAP_S:g})",
                               colour=_ORANGE)),
    MetricSpec("min_ttc_rear_s", "s", "safety", "higher", "series.ttc_rear_s",
               tolerance=_tol(0.2, 0.1),
               drawing=Drawing(f"TTC behind (none = {TTC_CAP_S:g})", "s", cap=TTC_CAP_S,
                               rerun="/safety/ttc_s/behind",
                               rerun_label=f"TTC behind [s] (verdict; none = {TTC_CAP_S:g})",
                               colour=_PURPLE)),
    MetricSpec("max_drac_mps2", "m/s^2", "safety", "lower", "series.drac_mps2",
               tolerance=_tol(0.3, 0.1),
               drawing=Drawing("DRAC: deceleration to avoid a crash with the car ahead",
                               "m/s²", rerun="/safety/drac_mps2",
                               rerun_label="DRAC ahead [m/s²] (verdict)",
                               colour=(255, 60, 60, 255))),
    MetricSpec("r157_gap_shortfall_s", "s", "safety", "lower",
               criterion=_crit("max_r157_gap_shortfall_s", "max", None, 1.0, 20),
               tolerance=_tol(0.2, 0.1)),
    MetricSpec("min_ellipse_margin", "-", "safety", "higher", "series.ellipse_margin",
               column=5,
               criterion=_crit("min_ellipse_margin", "min", None, 1.0, 13,
                               "/safety/ellipse_margin/limit", "ellipse margin limit"),
               tolerance=_tol(0.1, 0.1),
               drawing=Drawing("ellipse margin", "-", rerun="/safety/ellipse_margin",
                               rerun_label="ellipse margin (< 0 inside)", colour=_MAGENTA)),
    MetricSpec("geom_collision_steps", "-", "safety", "lower", tolerance=_tol(0.5, 0.0)),
    MetricSpec("sumo_collision_steps", "-", "safety", "none", tolerance=_tol(0.5, 0.0)),
    MetricSpec("sumo_collisions_reported", "-", "safety", "none", tolerance=_tol(0.5, 0.0)),
    MetricSpec("ssm_ttc_min_s", "s", "safety", "higher", "safety.ssm_ttc_s",
               tolerance=_tol(0.2, 0.1)),
    MetricSpec("sumo_ssm_conflicts", "-", "safety", "lower", tolerance=_tol(0.5, 0.0)),
    MetricSpec("sumo_ssm_min_ttc_s", "s", "safety", "higher", tolerance=_tol(0.2, 0.1)),
    MetricSpec("sumo_ssm_max_drac_mps2", "m/s^2", "safety", "lower", tolerance=_tol(0.3, 0.1)),
)

_COLLISION_CLASSES = ("active_front", "active_lateral", "active_rear", "replayed_into_ego",
                      "stopped_ego", "stopped_track", "unclassified")
_COLLISIONS: tuple[MetricSpec, ...] = (
    MetricSpec("collisions", "-", "safety", "lower"),
    *(MetricSpec(f"collisions_{k}", "-", "safety", "lower") for k in _COLLISION_CLASSES),
    MetricSpec("swept_only_collisions", "-", "safety", "lower"),
    MetricSpec("first_collision_t_s", "s", "safety", "none"),
    MetricSpec("first_at_fault_collision_t_s", "s", "safety", "none"),
    MetricSpec("max_at_fault_delta_v_mps", "m/s", "safety", "lower"),
    MetricSpec("collision_disagreements", "-", "safety", "none", junit=1),
    *(MetricSpec(name, "-", "safety", "none") for name in (
        "sumo_collisions_as_collider", "sumo_collisions_as_victim", "sumo_only_collisions",
        "geometry_only_collisions")),
)

_EXCESS = Drawing("corner beyond the drivable area", "m", series="series.offroad_excess_m")
_DRIVABLE: tuple[MetricSpec, ...] = (
    MetricSpec("offroad_s", "s", "safety", "lower", column=6, mark="#ea580c",
               criterion=_crit("max_offroad_s", "max", 0.0, 0.1, 2),
               tolerance=_tol(0.1, 0.0), summary=Summary(("max", "sum"), 5), junit=5,
               drawing=_EXCESS),
    MetricSpec("offroad_m", "m", "safety", "lower", tolerance=_tol(1.0, 0.1)),
    MetricSpec("max_offroad_m", "m", "safety", "lower", "series.offroad_excess_m",
               tolerance=_tol(0.1, 0.1),
               drawing=Drawing(_EXCESS.label, "m", rerun="/safety/offroad_excess_m",
                               rerun_label="corner beyond the lanes [m]", colour=_ORANGE)),
    MetricSpec("shoulder_s", "s", "safety", "lower",
               criterion=_crit("max_shoulder_s", "max", None, 1.0, 14),
               tolerance=_tol(0.5, 0.1)),
)

_COMFORT: tuple[MetricSpec, ...] = (
    MetricSpec("min_long_acc_mps2", "m/s^2", "comfort", "higher", "series.long_acc_mps2",
               column=7,
               criterion=_crit("min_long_acc_mps2", "min", -4.05, 0.4, 5,
                               "/comfort/accel_mps2/limit_min", "long acc limit [m/s²]"),
               tolerance=_tol(0.2, 0.1),
               drawing=Drawing(_ACC, "m/s²", rerun="/comfort/accel_mps2/long_smoothed",
                               rerun_label="long acc, smoothed (verdict) [m/s²]",
                               colour=(40, 90, 200, 255))),
    MetricSpec("max_long_acc_mps2", "m/s^2", "comfort", "lower", "series.long_acc_mps2",
               column=8,
               criterion=_crit("max_long_acc_mps2", "max", 2.40, 0.25, 6,
                               "/comfort/accel_mps2/limit_max", "long acc limit [m/s²]"),
               tolerance=_tol(0.2, 0.1), drawing=Drawing(_ACC, "m/s²")),
    MetricSpec("max_abs_lat_acc_mps2", "m/s^2", "comfort", "lower", "series.lat_acc_mps2",
               column=9,
               criterion=_crit("max_abs_lat_acc_mps2", "max", 4.89, 0.5, 7,
                               "/comfort/accel_mps2/lat_limit", "|lat acc| limit [m/s²]",
                               True),
               tolerance=_tol(0.2, 0.1), summary=Summary(("mean", "max"), 8), junit=6,
               drawing=Drawing("lateral acceleration", "m/s²",
                               rerun="/comfort/accel_mps2/lat_smoothed",
                               rerun_label="lat acc, smoothed (verdict) [m/s²]",
                               colour=(200, 100, 30, 255))),
    MetricSpec("max_abs_yaw_rate_radps", "rad/s", "comfort", "lower", "series.yaw_rate_radps",
               column=10,
               criterion=_crit("max_abs_yaw_rate_radps", "max", 0.95, 0.1, 8,
                               "/comfort/yaw_rate_radps/limit", "|yaw rate| limit [rad/s]",
                               True),
               tolerance=_tol(0.02, 0.1), summary=Summary(("max",), 11),
               drawing=Drawing("yaw rate", "rad/s", rerun="/comfort/yaw_rate_radps",
                               rerun_label="yaw rate [rad/s]", colour=_PURPLE)),
    MetricSpec("max_abs_yaw_acc_radps2", "rad/s^2", "comfort", "lower",
               "series.yaw_acc_radps2", column=11,
               criterion=_crit("max_abs_yaw_acc_radps2", "max", 1.93, 0.2, 9,
                               "/comfort/yaw_acc_radps2/limit", "|yaw acc| limit [rad/s²]",
                               True),
               tolerance=_tol(0.1, 0.1),
               drawing=Drawing("yaw acceleration", "rad/s²", rerun="/comfort/yaw_acc_radps2",
                               rerun_label="yaw acc [rad/s²]", colour=_MAGENTA)),
    MetricSpec("max_abs_long_jerk_mps3", "m/s^3", "comfort", "lower", "series.long_jerk_mps3",
               column=12,
               criterion=_crit("max_abs_long_jerk_mps3", "max", 4.13, 0.4, 10,
                               "/comfort/jerk_mps3/long_limit", "|long jerk| limit [m/s³]",
                               True),
               tolerance=_tol(0.3, 0.15), summary=Summary(("mean", "max"), 9),
               drawing=Drawing("longitudinal jerk", "m/s³", rerun="/comfort/jerk_mps3/long",
                               rerun_label="long jerk [m/s³]", colour=_BLUE)),
    MetricSpec("max_abs_jerk_mps3", "m/s^3", "comfort", "lower", "series.jerk_mps3",
               column=13,
               criterion=_crit("max_abs_jerk_mps3", "max", 8.37, 0.8, 11,
                               "/comfort/jerk_mps3/total_limit", "|jerk| limit [m/s³]"),
               tolerance=_tol(0.3, 0.15), summary=Summary(("mean", "max"), 10), junit=7,
               drawing=Drawing("jerk", "m/s³", rerun="/comfort/jerk_mps3/total",
                               rerun_label="|jerk| [m/s³]", colour=_ORANGE)),
    MetricSpec("rms_lat_acc_mps2", "m/s^2", "comfort", "lower", tolerance=_tol(0.1, 0.1)),
    MetricSpec("fallback_max_abs_lat_jerk_mps3", "m/s^3", "comfort", "lower"),
)

_LAT_DEV = Drawing("lateral deviation", "m", series="ego.lat_dev_m")
_TRACKING: tuple[MetricSpec, ...] = (
    MetricSpec("progress_m", "m", "tracking", "higher", column=3, tolerance=_tol(5.0, 0.05),
               summary=Summary(("mean",), 3), junit=4),
    MetricSpec("rms_lat_dev_m", "m", "tracking", "lower", column=14,
               criterion=_crit("max_rms_lat_dev_m", "max", None, 0.1, 15),
               tolerance=_tol(0.05, 0.1), summary=Summary(("mean", "max"), 6), junit=8,
               drawing=_LAT_DEV),
    MetricSpec("mean_speed_mps", "m/s", "tracking", "higher", column=15,
               tolerance=_tol(0.5, 0.05), summary=Summary(("mean",), 7)),
    MetricSpec("max_abs_lat_dev_m", "m", "tracking", "lower", "ego.lat_dev_m",
               tolerance=_tol(0.1, 0.1), drawing=_LAT_DEV),
    MetricSpec("final_abs_lat_dev_m", "m", "tracking", "lower", "ego.lat_dev_m",
               criterion=_crit("max_final_abs_lat_dev_m", "max", None, 0.1, 16),
               tolerance=_tol(0.1, 0.1), drawing=_LAT_DEV),
    MetricSpec("max_abs_heading_err_rad", "rad", "tracking", "lower", "ego.heading_err_rad",
               tolerance=_tol(0.01, 0.1)),
    MetricSpec("mean_target_speed_mps", "m/s", "tracking", "none"),
    MetricSpec("mean_speed_error_mps", "m/s", "tracking", "none"),
    MetricSpec("expected_progress_m", "m", "tracking", "none"),
    MetricSpec("progress_ratio", "-", "tracking", "higher",
               criterion=_crit("min_progress_fraction", "min", 0.5, 0.05, 4),
               tolerance=_tol(0.05, 0.0), summary=Summary(("min", "mean"), 4)),
    MetricSpec("route_fraction", "-", "tracking", "higher", tolerance=_tol(0.02, 0.0)),
)

LOOPS: tuple[str, ...] = ("step", "outer", "inner", "obstacles", "sumo")
STATS: tuple[str, ...] = ("p50", "p95", "p99", "mean", "max")
# the leading results.csv columns among the loop statistics, and the timing ratios
_LOOP_COLUMNS = {"step_ms_p50": 16, "step_ms_p99": 17, "step_ms_max": 18}
_LOOP_RATIOS = {"step_ms_p50": 1.5, "step_ms_p99": 1.5, "outer_ms_p99": 1.5,
                "inner_ms_p99": 1.5, "sumo_ms_p50": 1.5}


def var_name(loop: str) -> str:
    """The variance metric of a loop's per-step time [s²]."""
    return "step_var_s2" if loop == "step" else f"{loop}_step_var_s2"


def _loop_specs() -> Iterable[MetricSpec]:
    for loop in LOOPS:
        for stat in STATS:
            name = f"{loop}_ms_{stat}"
            yield MetricSpec(name, "ms", "timing", "lower", column=_LOOP_COLUMNS.get(name),
                             timing_ratio=_LOOP_RATIOS.get(name),
                             junit=9 if name == "step_ms_p99" else None)
        yield MetricSpec(var_name(loop), "s^2", "timing", "lower",
                         column=19 if loop == "step" else None)


_TIMING: tuple[MetricSpec, ...] = (
    *_loop_specs(),
    MetricSpec("deadline_misses", "-", "timing", "lower", column=20,
               criterion=_crit("max_deadline_misses", "max", None, 1.0, 17),
               tolerance=_tol(2.0, 0.5), summary=Summary(("sum",), 14), junit=10),
    MetricSpec("deadline_miss_frac", "-", "timing", "lower"),
    MetricSpec("wall_s", "s", "timing", "lower"),
    MetricSpec("realtime_factor", "-", "timing", "higher", column=23, timing_ratio=1.5,
               summary=Summary(("mean", "min"), 15)),
)

_HEALTH: tuple[MetricSpec, ...] = (
    MetricSpec("residual_max", "-", "health", "lower", "controller.residual", column=21,
               criterion=_crit("max_residual", "max", None, 10.0, 19,
                               "/controller/residual/limit", "residual limit"),
               tolerance=_tol(1e-3, 1.0), summary=Summary(("max",), 12)),
    MetricSpec("residual_final", "-", "health", "lower", tolerance=_tol(1e-3, 1.0)),
    MetricSpec("fallbacks", "-", "health", "lower", column=22,
               criterion=_crit("max_fallbacks", "max", None, 1.0, 18),
               tolerance=_tol(0.5, 0.0), summary=Summary(("sum",), 13)),
    MetricSpec("guards", "-", "health", "lower", tolerance=_tol(2.0, 0.25)),
    MetricSpec("steps", "-", "health", "none"),
    MetricSpec("control_period_ms", "ms", "health", "none"),
    MetricSpec("sim_time_s", "s", "health", "none"),
)

CATALOGUE: tuple[MetricSpec, ...] = (*_SAFETY, *_COLLISIONS, *_DRIVABLE, *_COMFORT,
                                     *_TRACKING, *_TIMING, *_HEALTH)
_BY_NAME: dict[str, MetricSpec] = {s.name: s for s in CATALOGUE}


def spec(name: str) -> MetricSpec:
    """The entry of metric ``name``; KeyError naming the catalogue when it has none."""
    found = _BY_NAME.get(name)
    if found is None:
        raise KeyError(f"metric {name!r} has no entry in reports.metrics.catalogue")
    return found


def find(name: str) -> MetricSpec | None:
    """The entry of metric ``name``, None for a name the catalogue does not know (a
    metric of an older run)."""
    return _BY_NAME.get(name)


def _ranked(rank_of: dict[str, int], role: str) -> tuple[str, ...]:
    if len(set(rank_of.values())) != len(rank_of):
        raise ValueError(f"metric catalogue: two entries share a {role} rank")
    return tuple(sorted(rank_of, key=rank_of.__getitem__))


def _check() -> None:
    if len(_BY_NAME) != len(CATALOGUE):
        raise ValueError("metric catalogue: two entries share a name")
    names = [s.criterion.name for s in CATALOGUE if s.criterion is not None]
    if len(set(names)) != len(names):
        raise ValueError("metric catalogue: two entries share a criterion name")
    columns = sorted(s.column for s in CATALOGUE if s.column is not None)
    if columns != list(range(len(columns))):
        raise ValueError(f"metric catalogue: results columns must be 0..n-1, got {columns}")
    if sum(s.sparkline for s in CATALOGUE) != 1:
        raise ValueError("metric catalogue: exactly one entry is the default sparkline")


_check()

# results.csv's leading metric columns, in order (the others follow, sorted by name)
REQUIRED_METRICS: tuple[str, ...] = _ranked(
    {s.name: s.column for s in CATALOGUE if s.column is not None}, "column")
# criteria in check order: criterion name -> its metric's entry
_CRITERION_RANKS: dict[str, int] = {
    s.criterion.name: s.criterion.rank for s in CATALOGUE if s.criterion is not None}
_CRITERION_METRIC: dict[str, str] = {
    s.criterion.name: s.name for s in CATALOGUE if s.criterion is not None}
CRITERIA: dict[str, MetricSpec] = {
    c: _BY_NAME[_CRITERION_METRIC[c]] for c in _ranked(_CRITERION_RANKS, "criterion")}
# criterion -> (metric, bound)
CRITERIA_METRICS: dict[str, tuple[str, str]] = {
    c: (s.name, s.criterion.bound) for c, s in CRITERIA.items() if s.criterion is not None}
# summary.csv: metric -> aggregations, in column order
_SUMMARIES: dict[str, Summary] = {s.name: s.summary for s in CATALOGUE if s.summary is not None}
SUMMARY_METRICS: dict[str, tuple[str, ...]] = {
    name: _SUMMARIES[name].hows
    for name in _ranked({n: v.rank for n, v in _SUMMARIES.items()}, "summary")}
# junit.xml: the key metrics of a case's <system-out>, in order
JUNIT_METRICS: tuple[str, ...] = _ranked(
    {s.name: s.junit for s in CATALOGUE if s.junit is not None}, "junit")
# metrics drawn from a series (compare's overlays)
DRAWN: dict[str, MetricSpec] = {s.name: s for s in CATALOGUE if s.drawing is not None}
DEFAULT_SPARKLINE: str = next(s.name for s in CATALOGUE if s.sparkline)
