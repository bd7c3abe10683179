"""Entity paths of a run's recording (users, the blueprint and tests rely on them)."""

from __future__ import annotations

ENTITY_PATHS = {
    "lanes": "/world/road/lanes",
    "shoulders": "/world/road/shoulders",
    "centrelines": "/world/road/centrelines",
    "reference_path": "/world/reference_path",
    "driven_path": "/world/ego/driven_path",
    "ego_box": "/world/ego/box",
    "ego_velocity": "/world/ego/velocity",
    "ego_frame": "/world/ego/frame",
    "north_up": "/world/view/north_up",
    "vehicles": "/world/vehicles",
    "stalled": "/world/stalled",
    "ellipses": "/world/ellipses",
    "plan": "/world/plan",
    "preview": "/world/preview",
    "preview_error": "/world/preview_error",
    "detection": "/world/detection",
    "events": "/events",
    "scenario_doc": "/docs/scenario",
    "controller_doc": "/docs/controller",
}

# Every controller-specific diagnostic (``Trace.extra``) is a scalar at CONTROLLER/<name>.
CONTROLLER = "/controller"

# Recorded vehicles (scenario ``replay``), only in the logs of runs that have them:
# following their recording, and handed over to SUMO's driver (reactive replay).
RECORDED_PATHS = {
    "replayed": "/world/replayed",
    "reactive": "/world/reactive",
}
