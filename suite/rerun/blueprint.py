"""Default Rerun blueprint for a hwyeval run (embedded in ``run.rrd`` by ``suite.rerun.log``).

Layout (left two thirds / right third)::

    +-------------------------------------+----------------------+
    | [Follow ego] [Whole road]  (tabs)   | [Safety] [Comfort]   |
    |  bird's-eye 2D view of /world       | [Controller] [Timing]|
    |                                     | [Diagnostics]        |
    |                                     |  time-series panels  |
    +------------------+------------------+                      |
    | events (TextLog) | scenario / ctrl  |                      |
    +------------------+------------------+----------------------+
    time panel on ``sim_time``

Following the ego
-----------------
Rerun 0.41's 2D view has no "track entity" camera (only the 3D view's
``EyeControls3D.tracking_entity`` does, and 2D primitives do not show in a 3D
view). Instead the log carries ``/world/ego/frame``, a per-step ``Transform3D``
whose translation is the ego box centre and whose scale is (1, -1, 1). The
"Follow ego" view renders everything in that frame
(``SpatialInformation(target_frame="tf#/world/ego/frame")``) with fixed
``VisualBounds2D`` around the origin, so the ego stays put while the road moves
past, exactly like a chase camera. The -1 Y scale turns SUMO's Y-up world into
the 2D view's Y-down screen, so "left" (positive y, the pass-left side) is up
on screen. The "Whole road" tab shows all of ``/world`` in a static Y-flipped
frame (``/world/view/north_up``) with bounds fitted to the road.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import rerun as rr
import rerun.blueprint as rrb

FOLLOW_FRAME_ENTITY = "/world/ego/frame"
NORTH_UP_FRAME_ENTITY = "/world/view/north_up"
FOLLOW_AHEAD_M = 80.0
FOLLOW_BEHIND_M = 25.0
FOLLOW_HALF_WIDTH_M = 15.0

# Scale of both view frames: mirror Y so world +Y (left of an eastbound road) is screen up.
VIEW_FRAME_SCALE = (1.0, -1.0, 1.0)


def north_up_transform() -> rr.Transform3D:
    """Static transform logged at NORTH_UP_FRAME_ENTITY (Y mirrored for the 2D screen)."""
    return rr.Transform3D(scale=VIEW_FRAME_SCALE)


def _ts(origin: str, name: str, **kwargs: Any) -> rrb.TimeSeriesView:
    return rrb.TimeSeriesView(origin=origin, name=name, **kwargs)


@dataclass(frozen=True)
class ViewGeometry:
    """What the layout depends on. ego_start_xy [m] / ego_heading_rad only choose which
    way "ahead" is (the follow view shows more road ahead than behind); road_bounds =
    (xmin, xmax, ymin, ymax) [m] fits the whole-road tab; diagnostics are the
    controller's ``Trace.extra`` names, one panel each in the "Diagnostics" tab."""

    ego_start_xy: tuple[float, float] | None = None
    ego_heading_rad: float = 0.0
    road_bounds: tuple[float, float, float, float] | None = None
    diagnostics: tuple[str, ...] = ()


def _diagnostics(names: tuple[str, ...]) -> rrb.Container | None:
    if not names:
        return None
    return rrb.Vertical(*(_ts(f"/controller/{name}", name) for name in names),
                        name="Diagnostics")


def default_blueprint(view: ViewGeometry | None = None) -> rrb.Blueprint:
    """The blueprint the viewer opens a run with (see the module doc)."""
    view = view if view is not None else ViewGeometry()
    ego_heading_rad, road_bounds = view.ego_heading_rad, view.road_bounds
    ahead_sign = -1.0 if math.cos(ego_heading_rad) < 0 else 1.0
    if ahead_sign > 0:
        x_range = (-FOLLOW_BEHIND_M, FOLLOW_AHEAD_M)
    else:
        x_range = (-FOLLOW_AHEAD_M, FOLLOW_BEHIND_M)
    follow = rrb.Spatial2DView(
        origin="/world",
        contents=["/world/**"],
        name="Follow ego",
        spatial_information=rrb.SpatialInformation(target_frame=f"tf#{FOLLOW_FRAME_ENTITY}"),
        visual_bounds=rrb.VisualBounds2D(x_range=x_range,
                                         y_range=(-FOLLOW_HALF_WIDTH_M, FOLLOW_HALF_WIDTH_M)),
        background=(14, 16, 22, 255),
    )
    overview_kwargs: dict[str, Any] = {}
    if road_bounds is not None:
        xmin, xmax, ymin, ymax = road_bounds
        pad = 10.0
        # Bounds are in the north-up frame, i.e. y mirrored.
        overview_kwargs["visual_bounds"] = rrb.VisualBounds2D(
            x_range=(xmin - pad, xmax + pad), y_range=(-ymax - pad, -ymin + pad))
    overview = rrb.Spatial2DView(
        origin="/world",
        contents=["/world/**", f"- {FOLLOW_FRAME_ENTITY}"],
        name="Whole road",
        spatial_information=rrb.SpatialInformation(target_frame=f"tf#{NORTH_UP_FRAME_ENTITY}"),
        background=(14, 16, 22, 255),
        **overview_kwargs,
    )
    world = rrb.Tabs(follow, overview, active_tab=0, name="Bird's eye")

    safety = rrb.Vertical(
        _ts("/safety/ttc_s", "TTC [s] (SUMO SSM; verdict ahead / behind)"),
        _ts("/safety/min_gap_m", "Min gap [m]"),
        _ts("/safety/collision", "Collision"),
        _ts("/safety/offroad_excess_m", "Corner beyond the drivable lanes [m]"),
        _ts("/safety/ellipse_margin", "Obstacle-ellipse margin [-]"),
        _ts("/controller/speed_mps", "Speed vs target [m/s]"),
        row_shares=[3, 3, 1, 2, 2, 2],
        name="Safety",
    )
    comfort = rrb.Vertical(
        _ts("/comfort/accel_mps2", "Acceleration [m/s²] (recorded; smoothed = verdict)"),
        _ts("/comfort/jerk_mps3", "Jerk [m/s³]"),
        _ts("/comfort/yaw_rate_radps", "Yaw rate [rad/s]"),
        _ts("/comfort/yaw_acc_radps2", "Yaw acceleration [rad/s²]"),
        name="Comfort",
    )
    controller = rrb.Vertical(
        _ts("/controller/speed_mps", "Speed vs target [m/s]"),
        _ts("/controller/lat_dev_m", "Lateral deviation [m]"),
        _ts("/controller/steer_deg", "Steering [deg]"),
        _ts("/controller/torque_nm", "Torque [N m]"),
        _ts("/controller/residual", "Residual E"),
        _ts("/controller/preview_err_m", "Preview error [m]"),
        _ts("/controller", "Side / fallback / obstacles",
            contents=["/controller/side", "/controller/fallback", "/controller/n_obstacles"]),
        name="Controller",
    )
    timing = rrb.Vertical(
        _ts("/timing/step_ms", "Step time per loop [ms]"),
        name="Timing",
    )
    diagnostics = _diagnostics(view.diagnostics)
    tabs = [safety, comfort, controller, timing] + ([diagnostics] if diagnostics else [])
    plots = rrb.Tabs(*tabs, active_tab=0, name="Plots")

    text = rrb.Horizontal(
        rrb.TextLogView(origin="/events", name="Events"),
        rrb.Tabs(rrb.TextDocumentView(origin="/docs/scenario", name="Scenario"),
                 rrb.TextDocumentView(origin="/docs/controller", name="Controller"),
                 active_tab=0),
        column_shares=[3, 2],
    )
    root = rrb.Horizontal(
        rrb.Vertical(world, text, row_shares=[2.2, 1.4]),
        plots,
        column_shares=[3, 2],
    )
    return rrb.Blueprint(
        root,
        rrb.TimePanel(timeline="sim_time", state="collapsed"),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        auto_layout=False,
        auto_views=False,
    )
