"""``manifest.json`` of a catalog output: what was run, by whom and where.

Written by ``hwyeval run`` when the catalog starts (``finished`` empty) and again
when it ends; read by the report (header) and by ``hwyeval compare`` (provenance
differences, load). A directory without a manifest (made by hand, or by an older
hwyeval) is reported with an unknown provenance, never refused.

**The catalog's identity** (:func:`catalog_identity`, what the history files nights
under, docs/history.md) must survive a new checkout: it is the catalog's declared
``[catalog] name`` when the file sets one, else its path relative to the root of the
git repository that holds it (``catalogs/nightly.toml``), else its file name. Beside
it, its **origin** tells two different catalogs of the same name apart: the root
commit(s) of that git repository (the same in every clone of it; '' outside git for a
declared name), or ``file:<absolute path>`` for a file name outside git.
"""

from __future__ import annotations

import datetime as _dt
import subprocess
import tomllib
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
_GIT_TIMEOUT_S = 10.0


@dataclass(frozen=True)
class CatalogIdentity:
    """A catalog as the history knows it (module doc): its ``name`` and ``origin``."""

    name: str
    origin: str

    def __post_init__(self) -> None:
        if not self.name:
            raise ValueError("CatalogIdentity.name must not be empty")


def declared_catalog_name(path: Path) -> str:
    """The ``[catalog] name`` a catalog file sets ('' when none, or it cannot be read)."""
    try:
        with Path(path).open("rb") as fh:
            table = tomllib.load(fh).get("catalog")
    except (OSError, ValueError):
        return ""
    name = table.get("name") if isinstance(table, dict) else None
    return name if isinstance(name, str) else ""


def git_root(path: Path) -> Path | None:
    """The root of the git work tree holding ``path`` (a ``.git`` directory or file in
    it or a parent), None outside one."""
    for folder in Path(path).absolute().parents:
        if (folder / ".git").exists():
            return folder
    return None


def git_root_commits(root: Path) -> str:
    """The repository's root commit(s), sorted and comma-joined ('' when git cannot
    say: no commit yet, git missing)."""
    try:
        proc = subprocess.run(["git", "-C", str(root), "rev-list", "--max-parents=0", "HEAD"],
                              capture_output=True, text=True, timeout=_GIT_TIMEOUT_S,
                              check=False)
    except (OSError, subprocess.SubprocessError):
        return ""
    return ",".join(sorted(proc.stdout.split())) if proc.returncode == 0 else ""


def catalog_identity(path: Path, declared: str | None = None) -> CatalogIdentity:
    """The catalog file's identity (module doc); ``declared``: its ``[catalog] name``
    when already read (None: read it from the file)."""
    path = Path(path).absolute()
    name = declared if declared is not None else declared_catalog_name(path)
    root = git_root(path)
    origin = git_root_commits(root) if root is not None else ""
    if name:
        return CatalogIdentity(name, origin)
    if root is not None:
        return CatalogIdentity(path.relative_to(root).as_posix(), origin)
    return CatalogIdentity(path.name, f"file:{path}")


@dataclass(frozen=True)
class ControllerCode:
    """A controller the night ran and the hash of its code
    (:func:`suite.run.code_identity.controller_sha256`: a plug-in's source, or the
    built-in controllers' package)."""

    name: str
    sha256: str


@dataclass(frozen=True)
class Manifest:
    """catalog: the catalog file (absolute); catalog_name: its stem; catalog_id /
    catalog_origin: its identity (:func:`catalog_identity`; '' in manifests of older
    hwyeval versions: :meth:`identity` works it out from the path); scenarios: the names
    run, in order; started / finished: local ISO times ('' while running); jobs:
    parallel scenario processes; executor: local | ray; plugins: the ``--plugin``
    modules given; controllers: the controllers run and their code hashes (the system
    under test's code, docs/nightly.md)."""

    catalog: str
    catalog_name: str
    scenarios: tuple[str, ...]
    started: str
    jobs: int
    executor: str
    finished: str = ""
    plugins: tuple[str, ...] = ()
    provenance: Provenance = field(default_factory=Provenance)
    catalog_id: str = ""
    catalog_origin: str = ""
    controllers: tuple[ControllerCode, ...] = ()

    def finish(self) -> Manifest:
        """This manifest with ``finished`` and the provenance's end load set now."""
        return replace(self, finished=now_iso(), provenance=self.provenance.finished())

    def identity(self) -> CatalogIdentity:
        """The catalog's identity as recorded, or worked out from its path (an older
        manifest: the file's declared name and git root as they are now)."""
        if self.catalog_id:
            return CatalogIdentity(self.catalog_id, self.catalog_origin)
        return catalog_identity(Path(self.catalog))


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
