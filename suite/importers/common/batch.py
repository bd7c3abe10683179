"""The import of several files into one folder, once its checks have passed
(:mod:`~suite.importers.common.out_guard`): what a killed import left removed, every
file in turn (a failing one recorded, the next goes on), and ``catalog.toml`` rebuilt
when one imported (when none did, nothing in the folder changes)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Generic, TypeVar

from suite.importers.common.catalog import write_catalog
from suite.importers.common.out_guard import discard_leftovers
from suite.importers.common.outputs import Outputs

__all__ = ["Batch", "import_each"]

R = TypeVar("R")
E = TypeVar("E", bound=Exception)


@dataclass(frozen=True)
class Batch(Generic[R, E]):
    """Every file's result, the failures (in input order) and the catalog written."""

    results: tuple[R, ...]
    failures: tuple[E, ...]
    catalog: Path | None


def import_each(sources: Sequence[Path], out_dir: Path, outputs: Outputs,
                import_one: Callable[[Path], R], failure: type[E]) -> Batch[R, E]:
    """``import_one`` of each of ``sources`` into ``out_dir`` (created); a ``failure``
    (an error with the failed file's ``path``) is recorded and the next file goes on
    (module docstring)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    discard_leftovers(out_dir, outputs)
    results: list[R] = []
    failures: list[E] = []
    for source in sources:
        try:
            results.append(import_one(source))
        except failure as exc:
            failures.append(exc)
    failed = [Path(str(getattr(f, "path", f))).name for f in failures]
    catalog = write_catalog(out_dir, outputs, failed) if results else None
    return Batch(tuple(results), tuple(failures), catalog)
