"""Roads and vehicles for the controller tests on production's loop without SUMO
(:func:`suite.run.scripted.run_plant` on a :class:`suite.world.scripted.ScriptedWorld`)."""

from __future__ import annotations

import numpy as np

from suite.world.scripted import ScriptedRoad, ScriptedVehicle

DT = 0.02
LANE = 3.5
STRAIGHT = np.array([[0.0, 0.0], [1500.0, 0.0]])
_th = np.linspace(0.0, 1.5, 300)
CURVE = np.column_stack([400.0 * np.sin(_th), 400.0 * (1.0 - np.cos(_th))])  # left, R = 400


def road(reference: np.ndarray = STRAIGHT, lanes: int = 2, ego_lane: int = 0) -> ScriptedRoad:
    """``lanes`` lanes of 3.5 m, the reference (and the ego's start) on ``ego_lane``."""
    return ScriptedRoad(reference, lane_count=lanes, reference_lane=ego_lane, lane_width_m=LANE)


def stalled(s_m: float, lane: int = 0, name: str = "stalled", **kw: float) -> ScriptedVehicle:
    return ScriptedVehicle(name, s_m, lane, **kw)
