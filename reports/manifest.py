"""``manifest.json`` of a catalog output: what was run, by whom and where.

Written by ``hwyeval run`` when the catalog starts (``finished`` empty) and again
when it ends; read by the report (header) and by ``hwyeval compare`` (provenance
differences, load). A directory without a manifest (made by hand, or by an older
hwyeval) is reported with an unknown provenance, never refused.
"""

from __future__ import annotations

import datetime as _dt
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from reports.provenance import Provenance
from reports.record.codec import (
    RecordError,
    decode_dataclass,
    read_json,
    to_plain,
    write_json_atomic,
)

MANIFEST = "manifest.json"


@dataclass(frozen=True)
class Manifest:
    """catalog: the catalog file (absolute); scenarios: the names run, in order;
    started / finished: local ISO times ('' while running); jobs: parallel scenario
    processes; executor: local | ray; plugins: the ``--plugin`` modules given."""

    catalog: str
    catalog_name: str
    scenarios: tuple[str, ...]
    started: str
    jobs: int
    executor: str
    finished: str = ""
    plugins: tuple[str, ...] = ()
    provenance: Provenance = field(default_factory=Provenance)

    def finish(self) -> Manifest:
        """This manifest with ``finished`` and the provenance's end load set now."""
        return replace(self, finished=now_iso(), provenance=self.provenance.finished())


def not_run(manifest: Manifest | None, present: Sequence[str]) -> tuple[str, ...]:
    """The scenarios the manifest lists that have no run directory (an interrupted run,
    or one whose directories were removed), in the manifest's order."""
    if manifest is None:
        return ()
    have = set(present)
    return tuple(name for name in manifest.scenarios if name not in have)


def now_iso() -> str:
    return _dt.datetime.now().astimezone().isoformat(timespec="seconds")


def write_manifest(out_dir: Path, manifest: Manifest) -> Path:
    """Write ``out_dir/manifest.json`` atomically; returns its path."""
    path = Path(out_dir) / MANIFEST
    write_json_atomic(path, to_plain(manifest))
    return path


def read_manifest(out_dir: Path) -> Manifest | None:
    """The manifest of a catalog output (None when it has none or it cannot be read:
    a report must not fail on it)."""
    path = Path(out_dir) / MANIFEST
    if not path.is_file():
        return None
    try:
        return decode_dataclass(Manifest, read_json(path), path)
    except (RecordError, TypeError, ValueError):
        return None
