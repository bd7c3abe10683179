"""Typed records passed between the import stages (no commonroad-io objects past the
reader). Units: metres, radians (counter-clockwise from +x), m/s, seconds; positions in
CommonRoad's (= the built net's) x/y."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import numpy.typing as npt

from suite.importers.commonroad.geometry import FloatArray, bound_width_m

IntArray = npt.NDArray[np.int64]

__all__ = ["EgoStart", "FloatArray", "IntArray", "LaneletRecord", "ObstacleRecord",
           "RecordedFile", "UncertainCount"]


@dataclass(frozen=True, eq=False)
class LaneletRecord:
    """One lanelet: its bounds (n, 2) [m] with opposite vertices (the i-th left and right
    ones face each other), same-direction neighbours (``None``: none or opposite
    direction), successors/predecessors, CommonRoad lanelet types and the
    lowest ``MAX_SPEED`` sign it references [m/s] (``None``: none).

    A piece of a lanelet cut by :mod:`~suite.importers.commonroad.split` has its own
    (internal) ``lanelet_id``, the file's id as ``source_id`` and ``piece`` 1, 2, ...
    (piece 0 is the original lanelet, or its first piece, and keeps its id); ``label``
    is what the net and the notes call it: ``<id>`` or ``<source id>_<piece>``.

    ``start_anchor_xy_m`` / ``end_anchor_xy_m``: where the lanelet is taken to start /
    end when its neighbours are cut to align rows (``None``: its centre line's own end).
    A lanelet reached only through a connector (a wedge that became a junction link,
    :mod:`~suite.importers.commonroad.connectors`) starts, for its row, where the
    connector starts; one that leaves only through a connector ends where it ends."""

    lanelet_id: int
    left_xy_m: FloatArray
    right_xy_m: FloatArray
    adj_left: int | None
    adj_right: int | None
    opposite_left: bool
    successors: tuple[int, ...]
    predecessors: tuple[int, ...]
    types: tuple[str, ...]
    speed_limit_mps: float | None = None
    source_id: int | None = None
    piece: int = 0
    start_anchor_xy_m: tuple[float, float] | None = None
    end_anchor_xy_m: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        for name in ("left_xy_m", "right_xy_m"):
            xy = getattr(self, name)
            if xy.ndim != 2 or xy.shape[1] != 2 or xy.shape[0] < 2 or not np.all(
                    np.isfinite(xy)):
                raise ValueError(f"lanelet {self.lanelet_id}: {name}: expected at least 2 "
                                 f"finite (x, y) points, got shape {xy.shape}")
        if self.left_xy_m.shape != self.right_xy_m.shape:  # the centre pairs them
            raise ValueError(f"lanelet {self.lanelet_id}: bounds of {len(self.left_xy_m)} "
                             f"and {len(self.right_xy_m)} points: expected them paired "
                             "(geometry.pair_bounds)")
        if self.speed_limit_mps is not None and not (
                math.isfinite(self.speed_limit_mps) and self.speed_limit_mps > 0.0):
            raise ValueError(f"speed_limit_mps: expected > 0 or None, got "
                             f"{self.speed_limit_mps!r}")
        if self.piece < 0 or (self.piece > 0) != (self.source_id is not None):
            raise ValueError(f"lanelet {self.lanelet_id}: piece {self.piece} with source "
                             f"{self.source_id!r} (a piece > 0 needs its source id)")

    @property
    def label(self) -> str:
        """The lanelet's name in the net and the notes: ``<id>`` or ``<source>_<piece>``."""
        return (str(self.lanelet_id) if self.piece == 0
                else f"{self.source_id}_{self.piece}")

    @property
    def file_id(self) -> int:
        """The id of the lanelet of the file this is (a piece of)."""
        return self.lanelet_id if self.source_id is None else self.source_id

    @property
    def centre_xy_m(self) -> FloatArray:
        """Centre line: the mean of the left and right vertices [m] (the reader pairs
        the bounds' vertices opposite each other first:
        :func:`~suite.importers.commonroad.geometry.pair_bounds`)."""
        return np.asarray(0.5 * (self.left_xy_m + self.right_xy_m), dtype=np.float64)

    @cached_property
    def width_m(self) -> float:
        """The median perpendicular distance between the bounds [m]
        (:func:`~suite.importers.commonroad.geometry.bound_width_m`; computed once)."""
        return bound_width_m(self.left_xy_m, self.right_xy_m)

    @property
    def start_xy_m(self) -> tuple[float, float]:
        """Where the lanelet starts for aligning rows: its anchor, else its centre
        line's first point [m]."""
        if self.start_anchor_xy_m is not None:
            return self.start_anchor_xy_m
        c = self.centre_xy_m
        return float(c[0, 0]), float(c[0, 1])

    @property
    def end_xy_m(self) -> tuple[float, float]:
        """Where the lanelet ends for aligning rows: its anchor, else its centre line's
        last point [m]."""
        if self.end_anchor_xy_m is not None:
            return self.end_anchor_xy_m
        c = self.centre_xy_m
        return float(c[-1, 0]), float(c[-1, 1])


@dataclass(frozen=True, eq=False)
class ObstacleRecord:
    """One obstacle: samples (n,) at CommonRoad time steps ``steps`` (increasing), box
    centre ``x_m``/``y_m``, heading ``heading_rad`` (as recorded, not unwrapped),
    ``speed_mps`` (NaN where the file gives none), box ``length_m`` x ``width_m``."""

    obstacle_id: int
    kind: str
    static: bool
    length_m: float
    width_m: float
    steps: IntArray
    x_m: FloatArray
    y_m: FloatArray
    heading_rad: FloatArray
    speed_mps: FloatArray


@dataclass(frozen=True)
class UncertainCount:
    """How many states gave a set instead of a value (2018b): a position shape, an
    orientation or a velocity interval; their centres were taken."""

    states: int = 0
    obstacles: int = 0


@dataclass(frozen=True)
class EgoStart:
    """The planning problem: the ego's initial state (vehicle centre [m], heading [rad],
    speed [m/s], time step) and its goal (lanelet ids, goal position centres [m], last
    goal time step or ``None``)."""

    problem_id: int
    time_step: int
    x_m: float
    y_m: float
    heading_rad: float
    speed_mps: float
    goal_lanelets: tuple[int, ...]
    goal_points_xy_m: tuple[tuple[float, float], ...]
    goal_end_step: int | None


@dataclass(frozen=True)
class RecordedFile:
    """A read CommonRoad file: header ``dt_s``, its lanelets, obstacles and ego, the
    country of its scenario id (``DEU``, ``USA``, ...; ``ZAM`` when none); ``notes``
    say what the reader changed or ignored."""

    path: str
    dt_s: float
    lanelets: tuple[LaneletRecord, ...]
    obstacles: tuple[ObstacleRecord, ...]
    ego: EgoStart
    uncertain: UncertainCount
    notes: tuple[str, ...] = ()
    country: str = "ZAM"
