"""A run directory: the one contract between the runner, the metrics, the Rerun log and
the reports. Written once by the runner (:func:`write_run`), read by everyone else
(:func:`load_run`).

``DIR/<scenario>/`` holds:

``run.json``
    ``{"schema": 2, "info": RunInfo, "outcome": RunOutcome, "verdict": Verdict}``
    (:mod:`reports.record.meta`, :mod:`reports.record.verdict`).
``road.json``
    :class:`reports.record.road.RoadRecord`.
``trace.parquet``
    one row per control step: ``step``, ``t_s``, the columns of every group of
    :mod:`reports.record.columns` and the controller's own diagnostics (``Trace.extra``).
``series.parquet``
    :class:`reports.record.columns.SeriesColumns`, one row per trace row: the
    signals the metrics are extremes of (smoothed accelerations, jerk, TTC, ...).
``neighbours.parquet``
    :class:`reports.record.columns.NeighbourColumns`, one row per (step, vehicle
    within the recording radius).
``controller_arrays.npz``
    per-step arrays, NaN-padded, first axis = step: ``plan_xy_m`` (T, N+1, 2),
    ``preview_xy_m`` (T, Np+1, 2), ``ellipses`` (T, K, 6) = [cx_m, cy_m,
    heading_rad, semi_a_m, semi_b_m, active] in the world frame, ``ellipse_ids`` (T, K)
    the vehicle id behind each ellipse ('' padding or unknown; absent in older runs,
    read as all ''), and the scalar ``detection_radius_m``.
``traceback.txt``
    the error text of a run that ended in 'error'.
``run.rrd``
    the Rerun recording.

Reading: :func:`load_run` is the one reader of a run directory (the reports, ``compare``,
``view``, ``history add`` and ``run --resume`` all go through it). Before anything else
it checks the files run.json lists (``files``: size and SHA-256, written by
:func:`write_run_json`): one missing, of another size or another content (a file
overwritten in place, bit rot) makes the directory unreadable (:class:`DamagedRun`,
naming the file), whatever its stored verdict says. A run written before run.json
listed its files is checked by reading its parquet files whole instead
(:func:`check_run_files`). SHA-256 costs ~1-2 ms per MB on a 2-core VM; a 24 s run's
files are 1.2 MB (3.9 MB with its Rerun log): a few ms per run, several times decoding
its run.json, so a whole output directory's read is mostly these checksums.

Headings are radians counter-clockwise from +X; neighbours' positions are box centres,
the ego's is its CG (its box centre is ``cg_to_box_centre_m`` ahead).

Atomic run directories: a run is written into a staging directory beside its final place
(:func:`staging_dir`, ``OUT/.partial-<scenario>-<pid>``) and moved there in one rename
when complete (:func:`publish_run_dir`), replacing whatever was there before (an older
run, a symbolic link: never followed). A run killed half-way leaves only its staging
directory, which no reader lists (:func:`iter_run_dirs` skips names starting with a
dot) and the executor removes (:func:`discard_staging`): ``OUT/<scenario>/`` is always
one complete run, never an older run's files mixed with a newer one's.
"""

from __future__ import annotations

import errno
import hashlib
import math
import os
import shutil
import stat
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # imported by the readers only: the writer goes to pyarrow directly
    import pandas as pd

from reports.record.codec import (
    RecordError,
    decode_dataclass,
    read_json,
    to_plain,
    write_json_atomic,
)
from reports.record.columns import NeighbourColumns, SeriesColumns, Trace
from reports.record.meta import END_OK, FileDigest, RunInfo, RunOutcome
from reports.record.road import RoadRecord
from reports.record.verdict import Verdict

SCHEMA_VERSION = 2
RUN_JSON = "run.json"
ROAD_JSON = "road.json"
TRACE = "trace.parquet"
SERIES = "series.parquet"
NEIGHBOURS = "neighbours.parquet"
CONTROLLER_ARRAYS = "controller_arrays.npz"
TRACEBACK = "traceback.txt"
RRD = "run.rrd"
RUN_FILES = (RUN_JSON, ROAD_JSON, TRACE, SERIES, NEIGHBOURS, CONTROLLER_ARRAYS, TRACEBACK, RRD)
STAGING_PREFIX = ".partial-"  # OUT/.partial-<scenario>-<pid>: a run being written
TRASH_PREFIX = ".replaced-"  # OUT/.replaced-<scenario>-<pid>: an older run being removed


@dataclass
class ControllerArrays:
    """Per-step arrays for logs (see the module docstring); empty arrays when absent."""

    plan_xy_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 2)))
    preview_xy_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 2)))
    ellipses: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 6)))
    detection_radius_m: float = 0.0
    ellipse_ids: np.ndarray | None = None

    def __post_init__(self) -> None:
        shape = self.ellipses.shape[:2]
        if self.ellipse_ids is None:  # not recorded (older runs): no ids
            self.ellipse_ids = np.full(shape, "", dtype=str)
        elif self.ellipse_ids.shape != shape:
            raise ValueError(f"ControllerArrays.ellipse_ids must have shape {shape} (the "
                             f"ellipses'), got {self.ellipse_ids.shape}")

    def ellipse_id(self, step: int, slot: int) -> str:
        """The vehicle behind ellipse ``slot`` of ``step`` ('' none or unknown)."""
        ids = self.ellipse_ids
        if ids is None or not (0 <= step < ids.shape[0] and 0 <= slot < ids.shape[1]):
            return ""
        return str(ids[step, slot])


@dataclass
class RunRecord:
    """One run, in memory. ``verdict``/``series`` are None until judged."""

    info: RunInfo
    outcome: RunOutcome
    road: RoadRecord
    trace: Trace
    neighbours: NeighbourColumns
    arrays: ControllerArrays
    verdict: Verdict | None = None
    series: SeriesColumns | None = None
    run_dir: Path | None = None
    # the files run.json lists with their size and SHA-256 (read back: () in memory)
    files: tuple[FileDigest, ...] = ()

    @property
    def name(self) -> str:
        return self.info.scenario

    @property
    def status(self) -> str:
        """pass | fail | error | timeout (error/timeout from the outcome win)."""
        if self.outcome.end != "ok":
            return self.outcome.end
        return self.verdict.status if self.verdict is not None else "error"


def write_run(record: RunRecord, run_dir: Path, *, run_json: bool = True) -> None:
    """Write every file of ``record`` into ``run_dir`` (run.json last, atomically; not at
    all with ``run_json=False``, for a writer that adds files first)."""
    run_dir.mkdir(parents=True, exist_ok=True)
    # one line: 93 KB of lane polylines, read by the reports, not by eye
    write_json_atomic(run_dir / ROAD_JSON, record.road.as_plain(), indent=None)
    write_parquet(record.trace.table_columns(), run_dir / TRACE)
    write_parquet(dict(record.neighbours.columns()), run_dir / NEIGHBOURS)
    if record.series is not None:
        write_parquet(dict(record.series.columns()), run_dir / SERIES)
    arr = record.arrays
    # Stored, not deflated: the plans' float64 coordinates deflate by only ~20 % (1.0 MB
    # -> 0.82 MB for a 40 s run), for 33 ms of every run's 1.1 s.
    np.savez(run_dir / CONTROLLER_ARRAYS, plan_xy_m=arr.plan_xy_m,
             preview_xy_m=arr.preview_xy_m, ellipses=arr.ellipses,
             ellipse_ids=np.asarray(arr.ellipse_ids, dtype=str),
             detection_radius_m=np.array(arr.detection_radius_m))
    if record.outcome.error:
        (run_dir / TRACEBACK).write_text(record.outcome.error)
    if run_json:
        write_run_json(record, run_dir)


def write_parquet(columns: Mapping[str, np.ndarray], path: Path) -> None:
    """One parquet file of equal-length 1-D columns (text columns as strings), written
    with pyarrow directly: what ``DataFrame.to_parquet(index=False)`` wrote, read back
    alike, in half the time (12 against 27 ms for a 40 s run's three files)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    arrays = [pa.array(values, type=pa.string()) if values.dtype == np.object_
              else pa.array(values) for values in columns.values()]
    pq.write_table(pa.Table.from_arrays(arrays, names=list(columns)), path)


def write_run_atomic(record: RunRecord, final: Path) -> None:
    """:func:`write_run` into a staging directory beside ``final``, then
    :func:`publish_run_dir` it there (replacing an older run; nothing of it is kept)."""
    stage = staging_dir(final.parent, final.name)
    try:
        write_run(record, stage)
        publish_run_dir(stage, final)
    finally:
        remove_path(stage)  # gone already once published


def write_run_json(record: RunRecord, run_dir: Path) -> None:
    """(Re)write run.json from ``record.info``/``outcome``/``verdict`` (atomic), with the
    digest of every other file of the run directory (``files``: :class:`FileDigest`)."""
    doc: dict[str, Any] = {"schema": SCHEMA_VERSION, "info": to_plain(record.info),
                           "outcome": to_plain(record.outcome),
                           "verdict": to_plain(record.verdict) if record.verdict else None,
                           "files": to_plain(file_digests(run_dir))}
    write_json_atomic(run_dir / RUN_JSON, doc)


def file_digests(run_dir: Path) -> tuple[FileDigest, ...]:
    """Size and SHA-256 of every regular file directly in ``run_dir`` but run.json (and
    hidden temporaries), by name."""
    out = []
    for path in sorted(run_dir.iterdir()):
        if path.name == RUN_JSON or path.name.startswith(".") or not path.is_file() \
                or path.is_symlink():
            continue
        out.append(FileDigest(path.name, path.stat().st_size, _sha256_of(path)))
    return tuple(out)


def _file_digests(doc: dict[str, Any], path: Path) -> tuple[FileDigest, ...]:
    """The ``files`` of a parsed run.json (() for one written without them)."""
    raw = doc.get("files")
    if raw is None:
        return ()
    if not isinstance(raw, list):
        raise RecordError(path, "files", "a list of {name, size_bytes, sha256}", raw)
    return tuple(decode_dataclass(FileDigest, item, path, f"files[{i}]")
                 for i, item in enumerate(raw))


def incomplete_files(run_dir: Path, digests: tuple[FileDigest, ...] | None = None, *,
                     contents: bool = False) -> list[str]:
    """What is wrong with the files run.json lists ([] when complete, or when it lists
    none): a file missing or of another size, and with ``contents`` another SHA-256.
    Each entry is ``<name>: <what>``. ``digests``: the list as already read
    (``RunRecord.files``), else run.json is read for it."""
    if digests is None:
        digests = _read_run_doc(run_dir)[1]
    problems = []
    for d in digests:
        path = run_dir / d.name
        if not path.is_file():
            problems.append(f"{d.name}: missing")
        elif path.stat().st_size != d.size_bytes:
            problems.append(f"{d.name}: {path.stat().st_size} bytes, run.json says "
                            f"{d.size_bytes}")
        elif contents and _sha256_of(path) != d.sha256:
            problems.append(f"{d.name}: content differs from run.json's checksum (changed "
                            "after the run wrote it)")
    return problems


def _sha256_of(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


class DamagedRun(RecordError):
    """A run directory whose files are not those its run.json lists (missing, another
    size or content), or, for a run written without that list, whose parquet files
    cannot be read. ``problems``: one ``<file>: <what>`` each; ``info``: what run.json
    says was run (its run.json itself was readable), None when not known."""

    def __init__(self, run_dir: Path, problems: Sequence[str],
                 info: RunInfo | None = None) -> None:
        self.problems = tuple(problems)
        self.info = info
        super().__init__(run_dir, "", "the files run.json lists, unchanged", "; ".join(problems))
        self.args = (f"{run_dir}: damaged run directory: {'; '.join(self.problems)}",)


LEGACY_PARQUETS = (TRACE, SERIES, NEIGHBOURS)  # read whole when run.json lists no files


def check_run_files(run_dir: Path, digests: tuple[FileDigest, ...], *,
                    judged_steps: bool, info: RunInfo | None = None) -> None:
    """Raise :class:`DamagedRun` (carrying ``info``) unless the files of ``run_dir`` are
    those run.json lists (``digests``: each there, of its size and SHA-256). A run
    written before run.json listed them (``digests`` empty) is checked by reading its
    parquet files whole (a corrupt page fails to decode), and, when it was judged over
    steps (``judged_steps``), by the presence of its trace and series."""
    if digests:
        problems = incomplete_files(run_dir, digests, contents=True)
    else:
        problems = _legacy_problems(run_dir, judged_steps)
    if problems:
        raise DamagedRun(run_dir, problems, info)


def _legacy_problems(run_dir: Path, judged_steps: bool) -> list[str]:
    """What is wrong with the parquet files of a run whose run.json lists no files."""
    problems = []
    for name in LEGACY_PARQUETS:
        if not _is_file(os.path.join(run_dir, name)):
            if judged_steps and name != NEIGHBOURS:
                problems.append(f"{name}: missing")
            continue
        import pyarrow.parquet as pq

        try:
            pq.read_table(run_dir / name)
        except Exception as exc:  # noqa: BLE001 - pyarrow raises many kinds for a broken file
            problems.append(f"{name}: not a readable parquet file ({type(exc).__name__}: "
                            f"{exc})")
    return problems


def read_run_json(run_dir: Path) -> tuple[RunInfo, RunOutcome, Verdict | None]:
    """run.json of ``run_dir``, checked field by field (RecordError names the key)."""
    return _decode_run_doc(*_read_run_doc(run_dir)[::2])


def _read_run_doc(run_dir: Path) -> tuple[dict[str, Any], tuple[FileDigest, ...], Path]:
    """(run.json parsed and its schema checked, the files it lists, its path)."""
    path = run_dir / RUN_JSON
    doc = read_json(path)
    if not isinstance(doc, dict):
        raise RecordError(path, "", "a JSON object with info, outcome, verdict", doc)
    if doc.get("schema") != SCHEMA_VERSION:
        raise RecordError(path, "schema", f"{SCHEMA_VERSION} (this hwyeval's record format)",
                          doc.get("schema"))
    return doc, _file_digests(doc, path), path


def _decode_run_doc(doc: dict[str, Any], path: Path
                    ) -> tuple[RunInfo, RunOutcome, Verdict | None]:
    info = decode_dataclass(RunInfo, doc.get("info"), path, "info")
    outcome = decode_dataclass(RunOutcome, doc.get("outcome"), path, "outcome")
    raw_verdict = doc.get("verdict")
    verdict = None if raw_verdict is None else decode_dataclass(Verdict, raw_verdict, path,
                                                                "verdict")
    return info, outcome, verdict


def _read_parquet(path: Path) -> pd.DataFrame | None:
    import pandas as pd

    if not path.is_file():
        return None
    try:
        return pd.read_parquet(path)
    except Exception as exc:  # pyarrow raises many kinds for a broken file
        raise RecordError(path, "", "a readable parquet file", f"{type(exc).__name__}: {exc}") \
            from exc


def load_run(run_dir: str | Path, *, trace: bool = True, neighbours: bool = True,
             arrays: bool = True, series: bool = True, road: bool = True,
             verify: bool = True) -> RunRecord:
    """Read a run directory. Parts not asked for (or absent) come back empty.

    ``verify`` (default): first :func:`check_run_files` (module doc), so a damaged
    directory is refused whichever parts are asked for. Raises FileNotFoundError
    without run.json, :class:`DamagedRun` for a damaged directory and RecordError for
    a malformed file (each names the file).
    """
    run_dir = Path(run_dir)
    if not (run_dir / RUN_JSON).is_file():
        raise FileNotFoundError(f"{run_dir / RUN_JSON}: no run.json, not a run directory")
    doc, digests, path = _read_run_doc(run_dir)
    info, outcome, verdict = _decode_run_doc(doc, path)
    if verify:
        check_run_files(run_dir, digests, info=info, judged_steps=verdict is not None
                        and outcome.end == END_OK and outcome.steps > 0)
    road_path = run_dir / ROAD_JSON
    road_record = RoadRecord.from_plain(read_json(road_path), road_path) \
        if road and road_path.is_file() else RoadRecord()
    frame = _read_parquet(run_dir / TRACE) if trace else None
    tr = Trace.from_frame(frame) if frame is not None else Trace.empty()
    nb_frame = _read_parquet(run_dir / NEIGHBOURS) if neighbours else None
    nb = NeighbourColumns.from_frame(nb_frame) if nb_frame is not None \
        else NeighbourColumns.no_rows()
    se_frame = _read_parquet(run_dir / SERIES) if series else None
    se = SeriesColumns.from_frame(se_frame) if se_frame is not None else None
    ca = ControllerArrays()
    arr_path = run_dir / CONTROLLER_ARRAYS
    if arrays and arr_path.is_file():
        try:
            with np.load(arr_path) as npz:
                files = set(npz.files)
                radius = float(npz["detection_radius_m"]) if "detection_radius_m" in files \
                    else 0.0
                ca = ControllerArrays(
                    plan_xy_m=npz["plan_xy_m"] if "plan_xy_m" in files else ca.plan_xy_m,
                    preview_xy_m=(npz["preview_xy_m"] if "preview_xy_m" in files
                                  else ca.preview_xy_m),
                    ellipses=npz["ellipses"] if "ellipses" in files else ca.ellipses,
                    ellipse_ids=npz["ellipse_ids"] if "ellipse_ids" in files else None,
                    detection_radius_m=radius if math.isfinite(radius) else 0.0)
        except (OSError, ValueError, KeyError) as exc:
            raise RecordError(arr_path, "", "a readable .npz file", str(exc)) from exc
    return RunRecord(info=info, outcome=outcome, road=road_record, trace=tr, neighbours=nb,
                     arrays=ca, verdict=verdict, series=se, run_dir=run_dir, files=digests)


def staging_dir(out_dir: Path, name: str) -> Path:
    """A fresh, empty staging directory for the run ``name`` under ``out_dir`` (created;
    a leftover of this process from an earlier attempt is removed first)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    stage = out_dir / f"{STAGING_PREFIX}{name}-{os.getpid()}"
    remove_path(stage)
    stage.mkdir()
    return stage


def remove_path(path: Path) -> None:
    """Remove ``path`` whatever it is (a symbolic link is unlinked, never followed; a
    directory removed with its content); nothing if it does not exist."""
    if path.is_symlink() or (path.exists() and not path.is_dir()):
        path.unlink(missing_ok=True)
    elif path.is_dir():
        shutil.rmtree(path, ignore_errors=True)


def publish_run_dir(stage: Path, final: Path) -> None:
    """Move the complete run directory ``stage`` to ``final`` (same parent), replacing
    what ``final`` was: the old entry is first renamed out of the way (a directory
    cannot be renamed onto a non-empty one), then removed. A reader sees the old run,
    then briefly no run, then the new run; never a mixture."""
    old: Path | None = None
    if final.is_symlink() or final.exists():
        old = final.with_name(f"{TRASH_PREFIX}{final.name}-{os.getpid()}")
        remove_path(old)
        os.replace(final, old)
    os.replace(stage, final)
    if old is not None:
        remove_path(old)


def discard_staging(out_dir: Path, name: str | None = None) -> list[Path]:
    """Remove the staging and replaced-run leftovers under ``out_dir`` (of the run
    ``name`` only, when given) that killed writers left behind; returns them."""
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        return []
    found = []
    for child in out_dir.iterdir():
        for prefix in (STAGING_PREFIX, TRASH_PREFIX):
            rest = child.name[len(prefix):] if child.name.startswith(prefix) else None
            if rest is None:
                continue
            owner, _, pid = rest.rpartition("-")
            if pid.isdigit() and (name is None or owner == name):
                remove_path(child)
                found.append(child)
    return found


def iter_run_dirs(out_dir: str | Path) -> list[Path]:
    """Run directories (with a run.json) directly under ``out_dir``, sorted by name.

    Symbolic links are not followed: a run directory is always inside ``out_dir``.
    Hidden entries (a run being written, :func:`staging_dir`) are not runs.
    """
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        return []
    with os.scandir(out_dir) as entries:  # types as listed: 1 system call a run, not 4
        names = sorted(e.name for e in entries
                       if not e.name.startswith(".") and e.is_dir(follow_symlinks=False))
    return [out_dir / name for name in names
            if _is_file(os.path.join(out_dir, name, RUN_JSON), follow_symlinks=False)]


def _is_file(path: str, *, follow_symlinks: bool = True) -> bool:
    """``Path(path).is_file()`` (``and not is_symlink()`` if not following) in one stat."""
    try:
        return stat.S_ISREG(os.stat(path, follow_symlinks=follow_symlinks).st_mode)
    except OSError as exc:  # what is_file() reads as "no such file", not an error
        if exc.errno in (errno.ENOENT, errno.ENOTDIR, errno.EBADF, errno.ELOOP):
            return False
        raise
    except ValueError:  # a path holding a NUL byte
        return False
