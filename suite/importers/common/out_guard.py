"""What an import may write: the checks that run before anything is written
(:class:`~suite.importers.commonroad.errors.OutputRefused`, exit 2; docs/recorded.md).

* **Inputs.** Each input ``<stem>.xml`` writes ``<stem>.net.xml``,
  ``<stem>.tracks.parquet`` and ``<stem>.scenario.json``. Two inputs whose stems are
  equal (ignoring case: a case-insensitive file system has one file for both) would
  write the same files, the second silently replacing the first: refused, naming both.
  The same file given twice (one real path) is imported once.
* **The output folder** may hold only what imports write: those files (of any stem),
  ``catalog.toml``, and what a killed import leaves (``*.partial`` of those, a staging
  folder ``.hwyeval-import-*``, :mod:`~suite.importers.commonroad.staging`; removed by
  :func:`discard_leftovers`). Anything else (another file, a folder, a symbolic link) is
  refused, naming the folder and the first such entry, unless ``overwrite``: then the
  import writes beside it and never changes it.
* **catalog.toml** is rebuilt by every import. One that the import did not generate
  (no marker line) or that was edited since (its hash differs,
  :mod:`~suite.importers.commonroad.catalog_mark`) is refused unless ``overwrite``
  (which replaces it: the edits are lost).
* Always refused: ``--out`` that is a file or a dangling link, and a directory where
  the import would write one of its files.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Sequence
from pathlib import Path

from suite.importers.commonroad.catalog_mark import MARKER, is_unedited
from suite.importers.commonroad.catalog_out import CATALOG_NAME, FRAGMENT_SUFFIX
from suite.importers.commonroad.errors import OutputRefused
from suite.importers.commonroad.staging import PARTIAL_SUFFIX, STAGING_PREFIX

__all__ = ["OWN_SUFFIXES", "check_inputs", "check_out_dir", "discard_leftovers",
           "output_names", "output_stem"]

OWN_SUFFIXES = (".net.xml", ".tracks.parquet", FRAGMENT_SUFFIX)
"""The files one input writes: ``<stem>`` + each."""


def output_stem(source: Path) -> str:
    """The stem of an input's outputs: its name without ``.xml``."""
    return source.name[:-4] if source.name.lower().endswith(".xml") else source.stem


def output_names(stem: str) -> tuple[str, ...]:
    """The files an input of stem ``stem`` writes, in the order they are moved into
    the folder (the scenario file last: the catalog lists the scenario files)."""
    return tuple(f"{stem}{suffix}" for suffix in OWN_SUFFIXES)


def check_inputs(sources: Sequence[Path]) -> tuple[Path, ...]:
    """``sources`` without repeats of one real path; OutputRefused for two inputs of one
    stem (module docstring)."""
    first: dict[str, Path] = {}
    kept: list[Path] = []
    for src in sources:
        key = output_stem(src).lower()
        other = first.get(key)
        if other is None:
            first[key] = src
            kept.append(src)
        elif os.path.realpath(other) != os.path.realpath(src):
            raise OutputRefused(
                f"{other} and {src}: both would write {output_stem(src)}.net.xml, "
                f"{output_stem(src)}.tracks.parquet and {output_stem(src)}"
                f"{FRAGMENT_SUFFIX} (inputs of one file name, ignoring case), the second "
                "replacing the first: rename one, or import them into separate --out "
                "folders; nothing was written")
    return tuple(kept)


def _is_leftover(entry: Path) -> bool:
    """A staging folder or an output's ``.partial`` (what a killed import leaves)."""
    if entry.name.startswith(STAGING_PREFIX):
        return entry.is_dir() and not entry.is_symlink()
    name = entry.name
    return (name.endswith(PARTIAL_SUFFIX) and _own_name(name[:-len(PARTIAL_SUFFIX)])
            and entry.is_file() and not entry.is_symlink())


def _own_name(name: str) -> bool:
    return name == CATALOG_NAME or (name.endswith(OWN_SUFFIXES)
                                    and name not in OWN_SUFFIXES)


def _is_own(entry: Path) -> bool:
    """Whether an import may have written ``entry`` (module docstring)."""
    if _is_leftover(entry):
        return True
    return _own_name(entry.name) and entry.is_file() and not entry.is_symlink()


def _check_path(out: Path, stems: Sequence[str]) -> None:
    if out.is_symlink() and not out.exists():
        raise OutputRefused(f"--out {out}: a symbolic link to nothing; nothing was written")
    if out.exists() and not out.is_dir():
        raise OutputRefused(f"--out {out}: exists and is not a directory; nothing was "
                            "written")
    for name in sorted({CATALOG_NAME, *(n for s in stems for n in output_names(s))}):
        target = out / name
        if target.is_dir():
            raise OutputRefused(f"--out {out}: {name} is a directory, where the import "
                                "writes a file: move it away or choose another --out; "
                                "nothing was written")


def _check_catalog(out: Path) -> None:
    path = out / CATALOG_NAME
    if not (path.exists() or path.is_symlink()):
        return
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise OutputRefused(f"--out {out}: {CATALOG_NAME} cannot be read ({exc}); nothing "
                            "was written") from exc
    if is_unedited(data):
        return
    why = ("was edited since the import generated it" if data.startswith(MARKER.encode())
           else "was not generated by hwyeval import commonroad (no generated-by line)")
    raise OutputRefused(f"--out {out}: {path} {why}; every import rebuilds it, which would "
                        "lose that: keep your own scenarios in a catalog outside the folder "
                        "(docs/recorded.md), or pass --overwrite to replace it; nothing was "
                        "written")


def check_out_dir(out: Path, stems: Sequence[str], overwrite: bool) -> None:
    """Check the output folder ``out`` for an import of the inputs of stems ``stems``
    (module docstring); nothing is written. Raises OutputRefused."""
    _check_path(out, stems)
    if not out.exists() or overwrite:
        return
    foreign = [e.name for e in sorted(out.iterdir()) if not _is_own(e)]
    if foreign:
        more = f" (and {len(foreign) - 1} more)" if len(foreign) > 1 else ""
        raise OutputRefused(
            f"--out {out}: holds {out / foreign[0]}{more}, which hwyeval import commonroad "
            "did not write (it writes <stem>.net.xml, <stem>.tracks.parquet, "
            f"<stem>{FRAGMENT_SUFFIX} and {CATALOG_NAME}): pass --overwrite to import "
            "beside it (what the import did not write is never changed), or choose another "
            "--out; nothing was written")
    _check_catalog(out)


def discard_leftovers(out: Path) -> None:
    """Remove what a killed import left in ``out`` (module docstring)."""
    for entry in sorted(out.iterdir()):
        if not _is_leftover(entry):
            continue
        if entry.is_dir():
            shutil.rmtree(entry, ignore_errors=True)
        else:
            entry.unlink(missing_ok=True)
