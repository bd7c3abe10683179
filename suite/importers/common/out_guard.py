"""What an import may write: the checks that run before anything is written
(:class:`~suite.importers.common.errors.OutputRefused`, exit 2; docs/recorded.md,
"The output folder"), parametrised by what the importer writes
(:class:`~suite.importers.common.outputs.Outputs`).

* **Inputs.** Each input ``<stem><input_suffix>`` writes ``<stem>`` + each of
  ``per_input``. Two inputs whose stems are equal (ignoring case: a case-insensitive
  file system has one file for both) would write the same files, the second silently
  replacing the first: refused, naming both. The same file given twice (one real path)
  is imported once (:func:`check_inputs`).
* **Shared outputs** (an OpenSCENARIO road, ``<road>`` + each of ``shared``): several
  inputs made from one file (one real path) share its outputs; two files whose outputs
  would have one name are refused, naming both (:func:`check_shared`).
* **The output folder** may hold only what imports write: files ending with one of
  ``own_suffixes`` (of any stem), ``catalog.toml``, and what a killed import leaves
  (``*.partial`` of those, a staging folder ``.hwyeval-import-*``,
  :mod:`~suite.importers.common.staging`; removed by :func:`discard_leftovers`).
  Anything else (another file, a folder, a symbolic link) is refused, naming the folder
  and the first such entry, unless ``overwrite``: then the import writes beside it and
  never changes it.
* **catalog.toml** is rebuilt by every import. One that an import did not generate
  (no marker line) or that was edited since (its hash differs,
  :mod:`~suite.importers.common.catalog_mark`) is refused unless ``overwrite``
  (which replaces it: the edits are lost).
* Always refused: ``--out`` that is a file or a dangling link, and a directory where
  the import would write one of its files.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterable, Sequence
from pathlib import Path

from suite.importers.common.catalog import CATALOG_NAME
from suite.importers.common.catalog_mark import MARKER, is_unedited
from suite.importers.common.errors import OutputRefused
from suite.importers.common.outputs import Outputs
from suite.importers.common.staging import PARTIAL_SUFFIX, STAGING_PREFIX

__all__ = ["check_inputs", "check_out_dir", "check_shared", "discard_leftovers",
           "output_names", "output_stem"]


def output_stem(source: Path, outputs: Outputs) -> str:
    """The stem of an input's outputs: its name without the input suffix (any case)."""
    suffix = outputs.input_suffix
    name = source.name
    return name[:-len(suffix)] if name.lower().endswith(suffix) else source.stem


def output_names(stem: str, suffixes: Sequence[str]) -> tuple[str, ...]:
    """``stem`` + each of ``suffixes``: the files of one input (``per_input``, in the
    order they are moved into the folder) or of one shared output (``shared``)."""
    return tuple(f"{stem}{suffix}" for suffix in suffixes)


def _first_of_each(claims: Iterable[tuple[str, Path]], refuse: str) -> list[Path]:
    """The paths of ``claims`` (an output stem, the file it is made from) without
    repeats of one real path; OutputRefused when two files claim one stem (ignoring
    case): ``refuse`` formatted with ``a``, ``b`` (the files) and ``stem``."""
    first: dict[str, Path] = {}
    kept: list[Path] = []
    for stem, src in claims:
        other = first.get(stem.lower())
        if other is None:
            first[stem.lower()] = src
            kept.append(src)
        elif os.path.realpath(other) != os.path.realpath(src):
            raise OutputRefused(refuse.format(a=other, b=src, stem=stem))
    return kept


def _would_write(suffixes: Sequence[str]) -> str:
    names = [f"{{stem}}{s}" for s in suffixes]
    return ", ".join(names[:-1]) + f" and {names[-1]}" if len(names) > 1 else names[0]


def check_inputs(sources: Sequence[Path], outputs: Outputs) -> tuple[Path, ...]:
    """``sources`` without repeats of one real path; OutputRefused for two inputs of one
    stem (module docstring)."""
    refuse = (f"{{a}} and {{b}}: both would write {_would_write(outputs.per_input)} "
              "(inputs of one file name, ignoring case), the second replacing the first: "
              "rename one, or import them into separate --out folders; nothing was written")
    return tuple(_first_of_each(((output_stem(s, outputs), s) for s in sources), refuse))


def check_shared(claims: Sequence[tuple[str, Path]], outputs: Outputs) -> None:
    """OutputRefused when two files (different real paths) would write the shared
    outputs of one stem (module docstring); ``claims``: (stem, the file it is made
    from), one per input that has one."""
    refuse = (f"{{a}} and {{b}}: both would write {_would_write(outputs.shared)} (files "
              "of one name once made a catalog name), the second replacing the first for "
              "every scenario on it: rename one, or import their scenarios into separate "
              "--out folders; nothing was written")
    _first_of_each(claims, refuse)


def _is_leftover(entry: Path, outputs: Outputs) -> bool:
    """A staging folder or an output's ``.partial`` (what a killed import leaves)."""
    if entry.name.startswith(STAGING_PREFIX):
        return entry.is_dir() and not entry.is_symlink()
    name = entry.name
    return (name.endswith(PARTIAL_SUFFIX)
            and _own_name(name[:-len(PARTIAL_SUFFIX)], outputs)
            and entry.is_file() and not entry.is_symlink())


def _own_name(name: str, outputs: Outputs) -> bool:
    own = outputs.own_suffixes
    return name == CATALOG_NAME or (name.endswith(own) and name not in own)


def _is_own(entry: Path, outputs: Outputs) -> bool:
    """Whether an import may have written ``entry`` (module docstring)."""
    if _is_leftover(entry, outputs):
        return True
    return _own_name(entry.name, outputs) and entry.is_file() and not entry.is_symlink()


def _check_path(out: Path, names: Iterable[str]) -> None:
    if out.is_symlink() and not out.exists():
        raise OutputRefused(f"--out {out}: a symbolic link to nothing; nothing was written")
    if out.exists() and not out.is_dir():
        raise OutputRefused(f"--out {out}: exists and is not a directory; nothing was "
                            "written")
    for name in sorted({CATALOG_NAME, *names}):
        if (out / name).is_dir():
            raise OutputRefused(f"--out {out}: {name} is a directory, where the import "
                                "writes a file: move it away or choose another --out; "
                                "nothing was written")


def _check_catalog(out: Path, outputs: Outputs) -> None:
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
           else f"was not generated by hwyeval import {outputs.command} (no generated-by "
           "line)")
    raise OutputRefused(f"--out {out}: {path} {why}; every import rebuilds it, which would "
                        "lose that: keep your own scenarios in a catalog outside the folder "
                        f"({outputs.doc}), or pass --overwrite to replace it; nothing was "
                        "written")


def check_out_dir(out: Path, names: Iterable[str], outputs: Outputs,
                  overwrite: bool) -> None:
    """Check the output folder ``out`` for an import that writes the files ``names``
    (module docstring); nothing is written. Raises OutputRefused."""
    _check_path(out, names)
    if not out.exists() or overwrite:
        return
    foreign = [e.name for e in sorted(out.iterdir()) if not _is_own(e, outputs)]
    if foreign:
        more = f" (and {len(foreign) - 1} more)" if len(foreign) > 1 else ""
        writes = ", ".join(f"<stem>{s}" for s in outputs.own_suffixes)
        raise OutputRefused(
            f"--out {out}: holds {out / foreign[0]}{more}, which hwyeval import "
            f"{outputs.command} did not write (it writes {writes} and {CATALOG_NAME}): "
            "pass --overwrite to import beside it (what the import did not write is never "
            "changed), or choose another --out; nothing was written")
    _check_catalog(out, outputs)


def discard_leftovers(out: Path, outputs: Outputs) -> None:
    """Remove what a killed import left in ``out`` (module docstring)."""
    for entry in sorted(out.iterdir()):
        if not _is_leftover(entry, outputs):
            continue
        if entry.is_dir():
            shutil.rmtree(entry, ignore_errors=True)
        else:
            entry.unlink(missing_ok=True)
