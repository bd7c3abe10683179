"""Where one file's outputs are written before they are its: a fresh hidden folder
``.hwyeval-import-*`` inside the output folder (the same file system, so moving a file
out of it is one atomic rename). A file that fails leaves nothing (the folder is
removed); one that imports has its outputs moved into the output folder, the scenario
files last (``catalog.toml`` lists the scenario files), replacing those of an earlier
import of the same stem only then. A killed import may leave a staging folder or a
``*.partial`` file behind: the next import removes them
(:func:`suite.importers.common.out_guard.discard_leftovers`)."""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

__all__ = ["PARTIAL_SUFFIX", "STAGING_PREFIX", "commit", "staged"]

STAGING_PREFIX = ".hwyeval-import-"
PARTIAL_SUFFIX = ".partial"  # a file being written (then renamed into place)


@contextmanager
def staged(out_dir: Path) -> Iterator[Path]:
    """A fresh staging folder in ``out_dir`` (created), removed when the block ends."""
    out_dir.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, dir=out_dir))
    try:
        yield stage
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def _every_file(stage: Path, last: str) -> list[str]:
    """The files of ``stage`` by name, those ending with ``last`` at the end."""
    names = sorted(p.name for p in stage.iterdir() if p.is_file())
    return sorted(names, key=lambda n: n.endswith(last))


def commit(stage: Path, out_dir: Path, names: Sequence[str] | None = None,
           last: str = ".scenario.json") -> None:
    """Move the files ``names`` from ``stage`` into ``out_dir``, in that order, each in
    one atomic rename (``names`` None: every file of ``stage``, those ending with
    ``last``, the scenario files, at the end)."""
    for name in _every_file(stage, last) if names is None else names:
        os.replace(stage / name, out_dir / name)
