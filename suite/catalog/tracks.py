"""Recorded vehicle tracks: the file a scenario's ``replay`` table points at.

A tracks file is Parquet, one row per recorded vehicle and sample, in **net
coordinates** (the SUMO net's x/y, metres) and **run time** (0 = the recording's
sample the run starts at, e.g. a CommonRoad planning problem's initial time step):

=============  =======  ===============================================================
column         type     meaning
=============  =======  ===============================================================
``track_id``   string   the vehicle's id in hwyeval: ``rec_<id in the recording>``
``time_s``     float64  run time of the sample [s]; strictly increasing per track
``x_m``        float64  centre of the vehicle's box, net x [m]
``y_m``        float64  centre of the vehicle's box, net y [m]
``heading_rad`` float64 heading, counter-clockwise from +x [rad], unwrapped per track
``speed_mps``  float64  speed along the heading [m/s], >= 0
``length_m``   float64  box length [m] (constant per track)
``width_m``    float64  box width [m] (constant per track)
``kind``       string   vehicle class from the recording (``car``, ``truck``, ``bus``, ...)
=============  =======  ===============================================================

The file's key-value metadata keeps ``hwyeval.tracks.version`` (``"1"``),
``hwyeval.tracks.dt_s`` (the sample period after any correction) and
``hwyeval.tracks.notes`` (what the import corrected or dropped, one line each).

:class:`Track` interpolates a pose at any run time inside its samples (linear in
position, heading and speed: the heading is stored unwrapped, so no interpolation
crosses the ±π seam); outside them the vehicle is not on the road.

**The recorded ego.** One track of a file may be the ego's own recording (a scenario's
``replay.ego_track``): the ``recorded`` controller drives the ego along it, and it is
never replayed as traffic (:meth:`TrackSet.without`). :func:`ego_track_problem` says
whether a track can be that: it exists, has at least two samples, and its first sample
is at run time 0 (within :data:`EGO_TRACK_START_TOL_S`), where the run starts.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pyarrow as pa
import pyarrow.parquet as pq

__all__ = ["EGO_TRACK_START_TOL_S", "TRACK_ID_PREFIX", "TRACKS_VERSION", "Track", "TrackPose",
           "TrackSet", "TrackSpan", "TracksError", "ego_track_problem", "read_tracks",
           "track_spans", "write_tracks"]

TRACKS_VERSION = "1"
TRACK_ID_PREFIX = "rec_"
EGO_TRACK_START_TOL_S = 1e-6
"""The ego's track starts at run time 0 within this [s] (run times are (k - k0) dt)."""
_META_VERSION = b"hwyeval.tracks.version"
_META_DT = b"hwyeval.tracks.dt_s"
_META_NOTES = b"hwyeval.tracks.notes"

_FLOAT_COLUMNS = ("time_s", "x_m", "y_m", "heading_rad", "speed_mps", "length_m", "width_m")
_SCHEMA = pa.schema([("track_id", pa.string()), *[(c, pa.float64()) for c in _FLOAT_COLUMNS],
                     ("kind", pa.string())])

FloatArray = npt.NDArray[np.float64]


class TracksError(ValueError):
    """A tracks file is unusable: ``path`` names it, ``key`` the column or track, and
    ``expected`` what would fit."""

    def __init__(self, path: Path | str, key: str, expected: str) -> None:
        self.path = str(path)
        self.key = key
        self.expected = expected
        super().__init__(f"{path}: {key}: expected {expected}")


@dataclass(frozen=True)
class TrackPose:
    """One vehicle's interpolated state: box centre ``x_m``/``y_m`` [m, net], heading
    ``heading_rad`` [rad, CCW from +x], ``speed_mps`` [m/s]."""

    x_m: float
    y_m: float
    heading_rad: float
    speed_mps: float


@dataclass(frozen=True, eq=False)
class Track:
    """One recorded vehicle: samples (n,) at run times ``time_s`` [s] (strictly
    increasing, n >= 1), box ``length_m`` x ``width_m`` [m]."""

    track_id: str
    kind: str
    length_m: float
    width_m: float
    time_s: FloatArray
    x_m: FloatArray
    y_m: FloatArray
    heading_rad: FloatArray
    speed_mps: FloatArray

    def __post_init__(self) -> None:
        if not self.track_id.startswith(TRACK_ID_PREFIX):
            raise ValueError(f"track_id: expected a name starting {TRACK_ID_PREFIX!r}, "
                             f"got {self.track_id!r}")
        if not (self.length_m > 0.0 and self.width_m > 0.0):
            raise ValueError(f"{self.track_id}: length_m/width_m: expected > 0, got "
                             f"{self.length_m}/{self.width_m}")
        n = self.time_s.shape[0]
        if n < 1:
            raise ValueError(f"{self.track_id}: expected at least one sample")
        for name in ("x_m", "y_m", "heading_rad", "speed_mps"):
            arr = getattr(self, name)
            if arr.shape != (n,):
                raise ValueError(f"{self.track_id}: {name}: expected shape ({n},), got "
                                 f"{arr.shape}")
        if n > 1 and not bool(np.all(np.diff(self.time_s) > 0.0)):
            raise ValueError(f"{self.track_id}: time_s: expected strictly increasing")

    @property
    def start_s(self) -> float:
        """Run time of the first sample [s]: the vehicle appears then."""
        return float(self.time_s[0])

    @property
    def end_s(self) -> float:
        """Run time of the last sample [s]: the vehicle leaves after it."""
        return float(self.time_s[-1])

    def present(self, t_s: float, tol_s: float = 1e-9) -> bool:
        """Whether run time ``t_s`` lies within the recorded samples."""
        return self.start_s - tol_s <= t_s <= self.end_s + tol_s

    def pose_at(self, t_s: float) -> TrackPose | None:
        """The pose at run time ``t_s`` [s], linearly interpolated between the two
        samples around it; ``None`` outside ``[start_s, end_s]``."""
        if not self.present(t_s):
            return None
        t = float(np.clip(t_s, self.start_s, self.end_s))
        return TrackPose(float(np.interp(t, self.time_s, self.x_m)),
                         float(np.interp(t, self.time_s, self.y_m)),
                         float(np.interp(t, self.time_s, self.heading_rad)),
                         float(np.interp(t, self.time_s, self.speed_mps)))


@dataclass(frozen=True)
class TrackSet:
    """Every track of one file, with the sample period ``dt_s`` [s] and the import's
    ``notes`` (one line per correction or dropped element)."""

    tracks: tuple[Track, ...]
    dt_s: float
    notes: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        if not self.dt_s > 0.0:
            raise ValueError(f"dt_s: expected > 0, got {self.dt_s}")
        ids = [t.track_id for t in self.tracks]
        if len(set(ids)) != len(ids):
            raise ValueError("track_id: expected unique ids, got duplicates")

    def by_id(self) -> dict[str, Track]:
        return {t.track_id: t for t in self.tracks}

    def without(self, track_id: str | None) -> TrackSet:
        """The set without track ``track_id`` (the recorded ego's, which the ego drives
        and the replay must not put into traffic on top of it); itself for None."""
        if track_id is None:
            return self
        return TrackSet(tuple(t for t in self.tracks if t.track_id != track_id), self.dt_s,
                        self.notes)


@dataclass(frozen=True)
class TrackSpan:
    """What the catalog checks of one track without keeping its samples: how many
    samples, and the run times [s] of the first and last."""

    samples: int
    start_s: float
    end_s: float


def track_spans(track_set: TrackSet) -> dict[str, TrackSpan]:
    """Every track's :class:`TrackSpan` by id."""
    return {t.track_id: TrackSpan(int(t.time_s.shape[0]), t.start_s, t.end_s)
            for t in track_set.tracks}


def ego_track_problem(spans: Mapping[str, TrackSpan], track_id: str) -> str | None:
    """Why track ``track_id`` (of a file whose :func:`track_spans` are ``spans``) cannot
    be the recorded ego's (None: it can): it must exist, have at least two samples and
    start at run time 0."""
    span = spans.get(track_id)
    if span is None:
        ids = sorted(spans)
        shown = ", ".join(ids[:12]) + (" ..." if len(ids) > 12 else "")
        return f"the id of a track of the file ({shown or 'it has none'})"
    if span.samples < 2:
        return "a track of at least two samples (the ego drives between them)"
    if abs(span.start_s) > EGO_TRACK_START_TOL_S:
        return (f"a track whose first sample is at run time 0, where the run starts "
                f"({track_id} starts at {span.start_s:g} s)")
    return None


def write_tracks(path: Path, track_set: TrackSet) -> None:
    """Write ``track_set`` to ``path`` (Parquet, the schema above), atomically."""
    cols: dict[str, list[object]] = {name: [] for name in _SCHEMA.names}
    for t in track_set.tracks:
        n = t.time_s.shape[0]
        cols["track_id"].extend([t.track_id] * n)
        cols["kind"].extend([t.kind] * n)
        cols["length_m"].extend([t.length_m] * n)
        cols["width_m"].extend([t.width_m] * n)
        for name in ("time_s", "x_m", "y_m", "heading_rad", "speed_mps"):
            cols[name].extend(getattr(t, name).tolist())
    table = pa.table(cols, schema=_SCHEMA).replace_schema_metadata({
        _META_VERSION: TRACKS_VERSION.encode(),
        _META_DT: repr(float(track_set.dt_s)).encode(),
        _META_NOTES: "\n".join(track_set.notes).encode(),
    })
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(path.name + ".partial")
    pq.write_table(table, partial)
    partial.replace(path)


def _column(path: Path, table: pa.Table, name: str) -> FloatArray:
    if name not in table.column_names:
        raise TracksError(path, name, "a column of that name (see suite.catalog.tracks)")
    arr = np.asarray(table.column(name).to_numpy(zero_copy_only=False), dtype=np.float64)
    if not bool(np.all(np.isfinite(arr))):
        raise TracksError(path, name, "finite numbers in every row")
    return arr


def _strings(path: Path, table: pa.Table, name: str) -> list[str]:
    if name not in table.column_names:
        raise TracksError(path, name, "a column of that name (see suite.catalog.tracks)")
    values = table.column(name).to_pylist()
    if any(not isinstance(v, str) or not v for v in values):
        raise TracksError(path, name, "a non-empty string in every row")
    return [str(v) for v in values]


def read_tracks(path: Path) -> TrackSet:
    """Read and validate a tracks file; :class:`TracksError` names the file and the
    column or track that is wrong."""
    try:
        table = pq.read_table(path)
    except (OSError, pa.ArrowInvalid) as exc:
        raise TracksError(path, "file", f"a readable Parquet tracks file ({exc})") from exc
    meta = table.schema.metadata or {}
    version = meta.get(_META_VERSION, b"").decode()
    if version != TRACKS_VERSION:
        raise TracksError(path, "hwyeval.tracks.version",
                          f"{TRACKS_VERSION!r} in the file's metadata, got {version!r}")
    try:
        dt_s = float(meta.get(_META_DT, b"nan").decode())
    except ValueError:
        dt_s = float("nan")
    if not dt_s > 0.0:
        raise TracksError(path, "hwyeval.tracks.dt_s", "a positive sample period [s]")
    notes = tuple(line for line in meta.get(_META_NOTES, b"").decode().splitlines() if line)
    ids = _strings(path, table, "track_id")
    kinds = _strings(path, table, "kind")
    data = {name: _column(path, table, name) for name in _FLOAT_COLUMNS}
    return TrackSet(_group(path, ids, kinds, data), dt_s, notes)


def _group(path: Path, ids: Sequence[str], kinds: Sequence[str],
           data: dict[str, FloatArray]) -> tuple[Track, ...]:
    order: dict[str, list[int]] = {}
    for row, tid in enumerate(ids):
        order.setdefault(tid, []).append(row)
    tracks = []
    for tid, rows in order.items():
        idx = np.asarray(rows, dtype=np.int64)
        idx = idx[np.argsort(data["time_s"][idx], kind="stable")]
        length = data["length_m"][idx]
        width = data["width_m"][idx]
        if np.ptp(length) > 1e-9 or np.ptp(width) > 1e-9:
            raise TracksError(path, f"{tid}.length_m/width_m", "one box size per track")
        try:
            tracks.append(Track(tid, kinds[rows[0]], float(length[0]), float(width[0]),
                                data["time_s"][idx], data["x_m"][idx], data["y_m"][idx],
                                data["heading_rad"][idx], data["speed_mps"][idx]))
        except ValueError as exc:
            raise TracksError(path, tid, str(exc)) from exc
    return tuple(tracks)
