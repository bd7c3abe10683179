"""What a search hands over: ``found.toml`` and ``search.csv``.

``found.toml`` is a runnable catalog (``hwyeval run DIR/found.toml --out ...``): one
concrete ``[[scenario]]`` per failure mode of each family, its shrunk point
(:mod:`suite.search.shrink`), named ``<family>__t<trial>`` after the trial it was shrunk
from, with the family's ``[defaults]`` merged in (self-contained: copy it into a
regression catalog as it is) and no search table; a comment above each names its mode,
robustness and the run it reproduces. A ``net`` (and a ``storyboard``) given as a path is
rewritten relative to the directory of found.toml. A logical scenario's case is the
scenario its point's import made (``openscenario/<run>/point.json``: its net and
storyboard there, its ``openscenario`` table with the point's parameter values).
``search.csv``'s rows: :mod:`reports.record.search`.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from reports.record.codec import write_text_atomic
from reports.record.search import SEARCH_CSV, SearchRow, write_search_csv
from suite.catalog.nets import bundled_nets
from suite.catalog.toml_write import toml_key, toml_value
from suite.search.logical import point_file
from suite.search.loop import FamilyResult, TrialResult
from suite.search.shrink import Shrunk
from suite.search.space import Family, point_entry, trial_name

__all__ = ["FOUND_TOML", "found_name", "search_rows", "write_found", "write_search"]

FOUND_TOML = "found.toml"


def found_name(case: Shrunk) -> str:
    return trial_name(case.origin.family, case.origin.trial)


def _relative_paths(entry: dict[str, Any], family: Family, dest_dir: Path) -> None:
    """The entry's ``net`` (a path, not a bundled net's name) and ``storyboard``,
    relative to the catalog, rewritten relative to ``dest_dir``."""
    for key in ("net", "storyboard"):
        value = entry.get(key)
        if not isinstance(value, str) or not value or (key == "net"
                                                      and value in bundled_nets()):
            continue
        target = (family.catalog_path.parent / value).resolve()
        entry[key] = os.path.relpath(target, dest_dir.resolve())


def _case_entry(family: Family, case: Shrunk) -> dict[str, Any]:
    """The case's concrete scenario table: the point's (a logical scenario's: as its
    import wrote it, when its point.json is there)."""
    name = found_name(case)
    if family.logical is not None:
        path = point_file(family.logical, case.result.run)
        if path is not None and path.is_file():
            entry: dict[str, Any] = dict(json.loads(path.read_text(encoding="utf-8"))["scenario"])
            entry["name"] = name
            return entry
    return point_entry(family, case.result.values, name)


def found_text(cases: Sequence[tuple[Family, Shrunk]], dest_dir: Path) -> str:
    lines = ["# hwyeval search: the failures found, one scenario per failure mode, each",
             "# shrunk toward its family's nominal point (hwyeval run this file to replay).",
             ""]
    for family, case in cases:
        entry = _case_entry(family, case)
        _relative_paths(entry, family, dest_dir)
        res = case.result
        lines.append(f"# {family.name}: mode {case.mode}, robustness {res.robustness!r} "
                     f"({res.criterion}); run {res.run}; from trial {case.origin.trial} "
                     f"(run {case.origin.run}, robustness {case.origin.robustness!r})")
        lines.append("[[scenario]]")
        for key, value in entry.items():
            lines.append(f"{toml_key(key)} = {toml_value(value)}")
        lines.append("")
    return "\n".join(lines)


def write_found(cases: Sequence[tuple[Family, Shrunk]], out: Path) -> Path:
    """Write ``out/found.toml`` (module doc); with no case, a catalog-less comment."""
    path = out / FOUND_TOML
    write_text_atomic(path, found_text(cases, out))
    return path


def _row(t: TrialResult, family: Family, kind: str, found: str) -> SearchRow:
    params = tuple((p.path, json.dumps(v, allow_nan=True))
                   for p, v in zip(family.params, t.values, strict=False))
    return SearchRow(family=t.family, kind=kind, trial=t.trial, run=t.run, status=t.status,
                     robustness=t.robustness, robustness_criterion=t.criterion,
                     failure_mode=t.mode, found=found, reason=t.reason, params=params)


def search_rows(results: Sequence[FamilyResult],
                shrinks: Mapping[str, tuple[list[Shrunk], list[TrialResult]]]) -> list[SearchRow]:
    """search.csv's rows: every trial, then every line-search run, per family."""
    rows: list[SearchRow] = []
    for res in results:
        cases, tried = shrinks.get(res.family.name, ([], []))
        found_of = {c.result.run: found_name(c) for c in cases}
        rows.extend(_row(t, res.family, "trial", found_of.get(t.run, "")) for t in res.trials)
        rows.extend(_row(t, res.family, "shrink", found_of.get(t.run, "")) for t in tried)
    return rows


def write_search(results: Sequence[FamilyResult],
                 shrinks: Mapping[str, tuple[list[Shrunk], list[TrialResult]]],
                 out: Path) -> Path:
    """Write ``out/search.csv``."""
    return write_search_csv(search_rows(results, shrinks), out / SEARCH_CSV)
