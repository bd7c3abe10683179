"""What a scenario reads, shipped to a machine that cannot see the driver's files.

A run reads these files and nothing else of the catalog's folder (the catalog itself is
read once, by the driver, and its scenarios travel resolved in the job; an OpenSCENARIO
storyboard travels as its content, ``Scenario.story``):

* ``net``: the SUMO network, ``Scenario.net_path`` (a bundled one, a catalog's own, an
  imported scenario's ``<stem>.net.xml``);
* ``tracks``: the recorded traffic a scenario replays, ``ReplaySpec.tracks_path`` (an
  imported CommonRoad scenario's ``<stem>.tracks.parquet``);
* ``plugin``: each ``--plugin`` file (its module is executed from its source; the copy
  is what its ``__file__`` names on the worker).

An imported scenario's folder is thereby shipped file by file, as far as a run reads it.
:func:`job_files` lists them as :class:`ShippedFile` (the driver's path, the content's
SHA-256, size); the driver puts each distinct content once into the transport (Ray's
object store), whatever the number of scenarios and files sharing it. On the worker
:func:`localise` writes each content once into a store folder (``<sha256>/<name>``,
atomically) and returns the job with every path rewritten to those copies, and the
mapping back; after the run :func:`restore_paths` puts the driver's paths back into the
run's ``run.json`` and ``traceback.txt`` (the record says where the driver had the
network, as a local run does; the files' digests are recomputed).
"""

from __future__ import annotations

import hashlib
import os
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from reports.record import RUN_JSON
from reports.record.codec import read_json, to_plain, write_json_atomic, write_text_atomic
from reports.record.run import TRACEBACK, file_digests
from suite.exec.jobs import RunJob

__all__ = ["MAX_FILE_BYTES", "ROLES", "ShippedFile", "job_files", "localise",
           "plugin_without_source", "read_shipped", "restore_paths"]

MAX_FILE_BYTES = 256 * 1024 * 1024  # a file larger than this is not shipped [bytes]
ROLES = ("net", "tracks", "plugin")
_SHA = re.compile(r"[0-9a-f]{64}")


@dataclass(frozen=True)
class ShippedFile:
    """One file a scenario reads (module doc): ``role`` (:data:`ROLES`), ``path`` where
    the driver has it, ``sha256`` of its bytes (hex), ``size`` [bytes]."""

    role: str
    path: Path
    sha256: str
    size: int

    def __post_init__(self) -> None:
        if self.role not in ROLES:
            raise ValueError(f"ShippedFile.role: expected one of {ROLES}, got {self.role!r}")
        object.__setattr__(self, "path", Path(self.path))
        if not isinstance(self.sha256, str) or not _SHA.fullmatch(self.sha256):
            raise ValueError(f"ShippedFile.sha256: expected 64 hex digits, got {self.sha256!r}")
        if isinstance(self.size, bool) or not isinstance(self.size, int) or self.size < 0:
            raise ValueError(f"ShippedFile.size: expected a whole number of bytes >= 0, "
                             f"got {self.size!r}")

    @property
    def name(self) -> str:
        """The file's name, as the copy on the worker keeps it."""
        return self.path.name


def read_shipped(path: Path, limit: int = MAX_FILE_BYTES) -> bytes:
    """The bytes of a file to ship; ValueError if it is larger than ``limit`` [bytes]
    or not a regular file, OSError if it cannot be read."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: not a regular file, not shipped")
    size = path.stat().st_size
    if size > limit:
        raise ValueError(f"{path}: {size} bytes is more than the {limit} bytes shipped "
                         "per file")
    data = path.read_bytes()
    if len(data) > limit:  # it grew meanwhile
        raise ValueError(f"{path}: more than the {limit} bytes shipped per file")
    return data


def _paths(job: RunJob) -> list[tuple[str, Path]]:
    """(role, driver path) of every file ``job``'s run reads (module doc)."""
    out: list[tuple[str, Path]] = [("net", Path(job.scenario.net_path))]
    replay = job.scenario.replay
    if replay is not None and replay.tracks_path is not None:
        out.append(("tracks", Path(replay.tracks_path)))
    out += [("plugin", Path(p.path)) for p in job.plugins if p.source is not None and p.path]
    return out


def job_files(job: RunJob, read: Callable[[Path], bytes],
              known: dict[Path, tuple[ShippedFile, bytes | None]] | None = None
              ) -> list[tuple[ShippedFile, bytes | None]]:
    """The files of ``job`` with their bytes (``read``: :func:`read_shipped` with a cap;
    its ValueError and OSError propagate). ``known`` caches them per driver path across
    jobs; a file seen before comes back with its bytes None (already shipped)."""
    known = {} if known is None else known
    out: list[tuple[ShippedFile, bytes | None]] = []
    for role, path in _paths(job):
        if path in known:
            out.append((known[path][0], None))
            continue
        data = read(path)
        shipped = ShippedFile(role, path, hashlib.sha256(data).hexdigest(), len(data))
        known[path] = (shipped, None)
        out.append((shipped, data))
    return out


def _write_once(store: Path, shipped: ShippedFile, fetch: Callable[[str], bytes]) -> Path:
    """The worker's copy of ``shipped`` in ``store`` (written atomically if missing;
    its bytes checked against the hash)."""
    local = store / shipped.sha256 / shipped.name
    if local.is_file():
        return local
    data = fetch(shipped.sha256)
    if hashlib.sha256(data).hexdigest() != shipped.sha256:
        raise ValueError(f"{shipped.path}: the shipped bytes do not match their SHA-256")
    local.parent.mkdir(parents=True, exist_ok=True)
    tmp = local.parent / f".{shipped.name}.{os.getpid()}.tmp"
    tmp.write_bytes(data)
    os.replace(tmp, local)
    return local


def localise(job: RunJob, files: Sequence[ShippedFile], fetch: Callable[[str], bytes],
             store: Path, out_dir: Path) -> tuple[RunJob, dict[str, str]]:
    """On the worker: ``job`` with every file it reads copied into ``store`` (``fetch``:
    a content's bytes by its SHA-256, called once per missing content) and its paths
    rewritten to the copies, its output into ``out_dir``; and the mapping from each
    worker path back to the driver's (for :func:`restore_paths`)."""
    local = {f.path: _write_once(store, f, fetch) for f in files}
    missing = [str(p) for _, p in _paths(job) if p not in local]
    if missing:
        raise ValueError(f"{job.name}: not shipped: {', '.join(missing)}")
    sc = job.scenario
    replay = sc.replay
    if replay is not None and replay.tracks_path is not None:
        replay = replace(replay, tracks_path=local[Path(replay.tracks_path)])
    scenario = replace(sc, net_path=local[Path(sc.net_path)], replay=replay)
    plugins = tuple(
        replace(p, path=str(local[Path(p.path)]),
                source=local[Path(p.path)].read_text(encoding="utf-8"))
        if p.source is not None and p.path else p for p in job.plugins)
    back = {str(copy): str(path) for path, copy in local.items()}
    back[str(out_dir)] = str(job.out_dir)
    return replace(job, scenario=scenario, out_dir=out_dir, plugins=plugins), back


def _rewrite(value: Any, mapping: Mapping[str, str]) -> Any:
    """``value`` (plain JSON) with every occurrence of a key of ``mapping`` in its
    strings replaced by its value (longest first)."""
    if isinstance(value, str):
        for old in sorted(mapping, key=len, reverse=True):
            if old in value:
                value = value.replace(old, mapping[old])
        return value
    if isinstance(value, list):
        return [_rewrite(v, mapping) for v in value]
    if isinstance(value, dict):
        return {k: _rewrite(v, mapping) for k, v in value.items()}
    return value


def restore_paths(run_dir: Path, mapping: Mapping[str, str]) -> None:
    """Put the driver's paths back into a run directory written on a worker
    (:func:`localise`'s mapping): ``traceback.txt`` and ``run.json`` (its ``files``
    digests recomputed), each replaced atomically. No run.json: nothing to do."""
    run_json = run_dir / RUN_JSON
    if not run_json.is_file():
        return
    tb = run_dir / TRACEBACK
    if tb.is_file():
        text = tb.read_text(encoding="utf-8", errors="replace")
        new = _rewrite(text, mapping)
        if new != text:
            write_text_atomic(tb, new)
    doc = _rewrite(read_json(run_json), mapping)
    if isinstance(doc, dict) and "files" in doc:
        doc["files"] = to_plain(file_digests(run_dir))
    write_json_atomic(run_json, doc)


def plugin_without_source(job: RunJob) -> RunJob:
    """``job`` with its plug-in files' sources left out (they travel as shipped files and
    are read back from the worker's copies by :func:`localise`): '' stands for them."""
    return replace(job, plugins=tuple(replace(p, source="") if p.source is not None and p.path
                                      else p for p in job.plugins))
