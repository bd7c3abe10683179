"""The recorded ego: the recorded vehicle whose drive the ego's is (docs/recorded.md).

A CommonRoad planning problem's initial state is the ego's. In files converted from
highD / exiD with the ego kept, one recorded obstacle *is* that ego; in others (the
NGSIM and A 9 development files) the ego is no recorded vehicle. Either way one recorded
vehicle can be made the ego:

* **detected** (:func:`detect`): a dynamic road vehicle with a sample at the planning
  problem's initial time step k0 whose centre lies within :data:`DETECT_TOL_M` of the
  initial state's position (the nearest such, with a sample after k0 too). The catalog's
  ``ego`` stays the planning problem's; the ego's recorded track is that vehicle's.
* **chosen** (``hwyeval import commonroad FILE --ego-obstacle ID``, :func:`choose`): the
  obstacle's first sample (time step k_e) replaces the planning problem's initial state:
  the ego's road, lane, position, heading and speed are its, run time 0 is k_e (the
  other tracks are cut there as they are at k0).

In both cases the route's goal becomes the recorded ego's last sample (its position and
time step), so that the route follows where the recorded driver went; its track
(``rec_<id>``, from run time 0) is written into the tracks file but not counted among
(nor replayed as) the recorded traffic: the catalog names it ``replay.ego_track``
(:func:`suite.catalog.tracks.ego_track_problem` checks it at load) and the controller
``recorded`` drives it.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, replace

import numpy as np

from suite.catalog.tracks import TRACK_ID_PREFIX, Track
from suite.importers.commonroad.catalog_out import DEFAULT_CONTROLLER
from suite.importers.commonroad.errors import ImportFailure
from suite.importers.commonroad.records import EgoStart, ObstacleRecord, RecordedFile
from suite.importers.commonroad.tracks import NOT_VEHICLES, TrackSelection, to_track

__all__ = ["DETECT_TOL_M", "SWEPT_CONTROLLERS", "RecordedEgo", "blamed", "choose", "detect",
           "duration_s", "ego_track", "notes", "replay_keys", "resolve", "scenario_keys",
           "split", "tracks", "without_ego"]

DETECT_TOL_M = 0.5
"""A recorded vehicle this close [m] to the planning problem's initial position, at its
initial time step, is the recorded ego."""

HOW = ("detected", "chosen")


@dataclass(frozen=True)
class RecordedEgo:
    """The recorded ego of a file: its ``obstacle_id``, ``how`` it was found
    (``"detected"`` or ``"chosen"``, module docstring) and, when detected, its centre's
    distance from the planning problem's initial position [m] (NaN when chosen)."""

    obstacle_id: int
    how: str
    distance_m: float = math.nan

    def __post_init__(self) -> None:
        if self.how not in HOW:
            raise ValueError(f"how: expected one of {list(HOW)}, got {self.how!r}")
        if self.how == "detected" and not (self.distance_m >= 0.0):
            raise ValueError(f"distance_m: expected >= 0 m for a detected ego, got "
                             f"{self.distance_m!r}")

    @property
    def track_id(self) -> str:
        """Its id in the tracks file (``replay.ego_track``)."""
        return f"{TRACK_ID_PREFIX}{self.obstacle_id}"

    @property
    def chosen(self) -> bool:
        return self.how == "chosen"

    def note(self, track: Track) -> str:
        """The line of the catalog's notes that names it."""
        how = ("chosen with --ego-obstacle: its first sample is the ego's start" if self.chosen
               else f"detected: {self.distance_m:.2f} m from the planning problem's "
               "initial state at its time step")
        return (f"recorded ego: obstacle {self.obstacle_id} ({how}), replay.ego_track = "
                f"{self.track_id!r}, {track.time_s.shape[0]} samples over {track.end_s:g} s, "
                f"{track.length_m:g} x {track.width_m:g} m; controller 'recorded' drives it")


def _is_vehicle(ob: ObstacleRecord) -> bool:
    return not ob.static and ob.kind not in NOT_VEHICLES


def detect(rec: RecordedFile, tol_m: float = DETECT_TOL_M) -> RecordedEgo | None:
    """The recorded vehicle at the planning problem's initial state (module docstring),
    None if there is none."""
    k0 = rec.ego.time_step
    best: RecordedEgo | None = None
    for ob in rec.obstacles:
        hit = np.flatnonzero(ob.steps == k0)
        if not _is_vehicle(ob) or hit.size == 0 or int(np.sum(ob.steps > k0)) == 0:
            continue
        i = int(hit[0])
        d = math.hypot(float(ob.x_m[i]) - rec.ego.x_m, float(ob.y_m[i]) - rec.ego.y_m)
        if d <= tol_m and (best is None or d < best.distance_m):
            best = RecordedEgo(ob.obstacle_id, "detected", d)
    return best


def _obstacle(rec: RecordedFile, obstacle_id: int) -> ObstacleRecord:
    """The obstacle ``obstacle_id`` of ``rec``; ImportFailure naming it when it is none
    or cannot be the ego."""
    found = [ob for ob in rec.obstacles if ob.obstacle_id == obstacle_id]
    if not found:
        ids = sorted(ob.obstacle_id for ob in rec.obstacles if _is_vehicle(ob))
        shown = ", ".join(map(str, ids[:20])) + (" ..." if len(ids) > 20 else "")
        raise ImportFailure(rec.path, f"obstacle {obstacle_id} (--ego-obstacle)",
                            f"no obstacle of that id in the file (its recorded vehicles: "
                            f"{shown or 'none'})")
    ob = found[0]
    if not _is_vehicle(ob):
        what = "a static obstacle" if ob.static else f"of type {ob.kind!r}"
        raise ImportFailure(rec.path, f"obstacle {obstacle_id} (--ego-obstacle)",
                            f"expected a dynamic road vehicle to be the ego, it is {what}")
    if ob.steps.shape[0] < 2:
        raise ImportFailure(rec.path, f"obstacle {obstacle_id} (--ego-obstacle)",
                            "expected a recorded vehicle of two samples or more (the ego "
                            "drives between them), it has one")
    return ob


def _first_speed(ob: ObstacleRecord, dt_s: float) -> float:
    """The speed of the first sample [m/s]: the file's, else from the first two positions
    (``dt_s`` the header's step)."""
    v = float(ob.speed_mps[0])
    if math.isfinite(v):
        return v
    k = max(int(ob.steps[1] - ob.steps[0]), 1)
    return math.hypot(float(ob.x_m[1] - ob.x_m[0]), float(ob.y_m[1] - ob.y_m[0])) / (k * dt_s)


def _goal_at_end(ego: EgoStart, ob: ObstacleRecord) -> EgoStart:
    """``ego`` whose goal is ``ob``'s last sample (position and time step)."""
    return replace(ego, goal_lanelets=(),
                   goal_points_xy_m=((float(ob.x_m[-1]), float(ob.y_m[-1])),),
                   goal_end_step=int(ob.steps[-1]))


def choose(rec: RecordedFile, obstacle_id: int) -> tuple[RecordedFile, RecordedEgo]:
    """``rec`` with obstacle ``obstacle_id``'s first sample as the ego's initial state
    (module docstring), and that recorded ego."""
    ob = _obstacle(rec, obstacle_id)
    start = EgoStart(rec.ego.problem_id, int(ob.steps[0]), float(ob.x_m[0]),
                     float(ob.y_m[0]), float(ob.heading_rad[0]), _first_speed(ob, rec.dt_s),
                     (), (), None)
    return replace(rec, ego=_goal_at_end(start, ob)), RecordedEgo(obstacle_id, "chosen")


def resolve(rec: RecordedFile, ego_obstacle: int | None) -> tuple[RecordedFile,
                                                                    RecordedEgo | None]:
    """The file's recorded ego, chosen (``ego_obstacle``) or detected, with ``rec``'s
    ego start and goal set for it (module docstring); ``rec`` itself and None when it
    has none."""
    if ego_obstacle is not None:
        return choose(rec, ego_obstacle)
    found = detect(rec)
    if found is None:
        return rec, None
    ob = _obstacle(rec, found.obstacle_id)
    return replace(rec, ego=_goal_at_end(rec.ego, ob)), found


def ego_track(rec: RecordedFile, ego: RecordedEgo, dt_s: float) -> Track:
    """The recorded ego's track in run time (k0 = ``rec.ego.time_step``, ``dt_s`` the
    checked step [s]): from its sample at k0, at least two samples."""
    ob = _obstacle(rec, ego.obstacle_id)
    track = to_track(ob, rec.ego.time_step, dt_s)
    if track.start_s != 0.0 or track.time_s.shape[0] < 2:
        raise ImportFailure(rec.path, f"obstacle {ego.obstacle_id}",
                            f"the recorded ego's track must start at the initial time step "
                            f"{rec.ego.time_step} and go on after it (it has "
                            f"{track.time_s.shape[0]} samples from {track.start_s:g} s)")
    return track


def without_ego(selection: TrackSelection, ego: Track | None) -> TrackSelection:
    """The recorded traffic: ``selection`` without the ego's track (the ego is not
    traffic; it is written to the tracks file beside it, as ``replay.ego_track``)."""
    if ego is None:
        return selection
    return replace(selection, tracks=tuple(t for t in selection.tracks
                                           if t.track_id != ego.track_id))


@contextmanager
def blamed(ego: RecordedEgo | None) -> Iterator[None]:
    """Failures about the ego's initial state name the chosen obstacle, not the planning
    problem, when the ego was chosen with --ego-obstacle (its state replaced the
    problem's)."""
    try:
        yield
    except ImportFailure as exc:
        if ego is None or not ego.chosen or not exc.element.startswith("planningProblem"):
            raise
        raise ImportFailure(exc.path, f"obstacle {ego.obstacle_id} (--ego-obstacle) "
                            "initialState", exc.reason) from exc


def split(selection: TrackSelection, rec: RecordedFile, ego: RecordedEgo | None,
          dt_s: float) -> tuple[TrackSelection, Track | None]:
    """The recorded traffic (``selection`` without the ego) and the ego's track (None
    when the file has no recorded ego)."""
    if ego is None:
        return selection, None
    track = ego_track(rec, ego, dt_s)
    return without_ego(selection, track), track


def notes(ego: RecordedEgo | None, track: Track | None) -> list[str]:
    """The notes line naming the recorded ego (none without one)."""
    return [] if ego is None or track is None else [ego.note(track)]


def tracks(track: Track | None) -> tuple[Track, ...]:
    """The ego's track as the tracks file gets it beside the traffic (none without)."""
    return () if track is None else (track,)


def duration_s(track: Track) -> float:
    """A scenario with a recorded ego lasts as long as the ego's track [s] (the
    recorded run ends with it, and the controllers' runs cover the same time)."""
    return round(track.end_s, 6)


SWEPT_CONTROLLERS = (DEFAULT_CONTROLLER, "recorded")
"""An imported scenario with a recorded ego runs the default controller and the human
(``[scenario.sweep] controller``): the human's verdict beside the controller's."""


def scenario_keys(track: Track | None) -> dict[str, object]:
    """The scenario's keys for its recorded ego: the sweep over the controllers (none
    without a recorded ego)."""
    return {} if track is None else {"sweep": {"controller": list(SWEPT_CONTROLLERS)}}


def replay_keys(track: Track | None) -> dict[str, object]:
    """The ``replay`` table's key naming the ego's track (none without one)."""
    return {} if track is None else {"ego_track": track.track_id}
