"""The World role: a traffic simulation the ego lives in (SUMO, or a fake in tests).

``start`` inserts the scenario's vehicles (and places the ego at ``ego_pose`` when the
ego is driven from outside), ``step`` advances one simulation step after pushing the
ego's pose, ``close`` ends it and returns what was learnt over the run. Every output is
a typed record of arrays; nothing SUMO-specific leaves an implementation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import numpy.typing as npt

from controllers.behaviour.types import Traffic
from reports.record import ReplaySummary, SsmSummary, StalledVehicle, SumoCollision


@dataclass(frozen=True)
class EgoPose:
    """The ego's pose to push into the world: front bumper centre [m], heading CCW from
    +X [rad] (the SUMO adapter converts to navigation degrees)."""

    front_x_m: float
    front_y_m: float
    heading_rad: float


@dataclass(frozen=True)
class WorldEgo:
    """The ego as the world has it after a step (front bumper, heading, speed [m/s],
    acceleration [m/s²], lane index on its road, road id) and the heading of the lane
    polyline segment it is on [rad] (NaN if unknown): heading minus lane heading is the
    ego's yaw relative to its lane, free of the polyline's kinks."""

    front_x_m: float
    front_y_m: float
    heading_rad: float
    speed_mps: float
    accel_mps2: float
    lane_index: int
    road_id: str
    lane_heading_rad: float = float("nan")


@dataclass(frozen=True)
class Scene:
    """The world after a step: time since the run's origin [s], the other vehicles,
    the ego as the world has it (None once it left), collisions of the ego this step.

    ``fresh``: the world's own state is new at this step (a SUMO step, or every step of
    a world without multi-rate); False when ``traffic`` is the last such state
    extrapolated (:mod:`suite.world.multirate`). The behaviour decides on fresh scenes
    only (:func:`suite.run.loop.run_loop`)."""

    t_s: float
    traffic: Traffic
    ego: WorldEgo | None
    collisions: tuple[SumoCollision, ...] = ()
    fresh: bool = True


@dataclass(frozen=True)
class WorldSummary:
    """What the world reports at the end: stalled cars as placed, every collision of
    the ego, SUMO's SSM summary and per-time TTC (times on the world clock [s], ttc [s]),
    the world time [s] that the run's t = 0 corresponds to, and the recorded traffic
    (None: the scenario had none)."""

    stalled: tuple[StalledVehicle, ...] = ()
    collisions: tuple[SumoCollision, ...] = ()
    ssm: SsmSummary = field(default_factory=SsmSummary)
    ssm_times_s: npt.NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    ssm_ttc_s: npt.NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    t_origin_s: float = 0.0
    replay: ReplaySummary | None = None

    def ssm_ttc_at(self, t_s: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """SSM TTC [s] at run times ``t_s`` (NaN where SUMO tracked no conflict)."""
        out = np.full(np.shape(t_s), math.nan)
        if self.ssm_times_s.size == 0:
            return out
        lookup = dict(zip(np.round(self.ssm_times_s, 6).tolist(), self.ssm_ttc_s.tolist(),
                          strict=True))
        for i, t in enumerate(np.asarray(t_s, dtype=np.float64).tolist()):
            value = lookup.get(round(t + self.t_origin_s, 6))
            if value is not None:
                out[i] = value
        return out


class World(Protocol):
    """One simulation per run; see the module docstring."""

    def start(self, ego_pose: EgoPose | None) -> Scene: ...

    def step(self, ego_pose: EgoPose | None) -> Scene: ...

    def close(self) -> WorldSummary: ...
