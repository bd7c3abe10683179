"""Logical scenarios: search families whose points are imported from an OpenSCENARIO
template (docs/search.md "Logical scenarios").

A family is *logical* when its search table has keys under ``openscenario``
(``openscenario.parameters.<Name>``, ``openscenario.value_sets.<i>``): the scenario's
``openscenario`` table names the template it was imported from (relative to the
catalog) and the parameter values (``hwyeval import openscenario`` writes both for a
variation file, :mod:`suite.importers.openscenario.logical`). A parameter changes derived
values everywhere (the ego's start, positions, speeds, the storyboard), so a point is not
a set of catalog values: each point's scenario is made by importing the template with the
point's parameter values (:func:`suite.importers.openscenario.pipeline.build_scenario`)
into a folder of its own, ``<search output>/openscenario/<run name>/`` (the net, its
lane map, the storyboard and ``point.json``: the parameters, the import's notes and the
scenario table); the import's ``net``, ``route``, ``ego``, ``duration_s`` and
``storyboard`` replace the entry's, every other key (controller, criteria, labels,
step_s, ...) is the catalog's. A point the template refuses (a violated constraint, an
ego at its road's end, ...) is *refused* with the importer's message, which names the
parameter and the constraint.

Checked when the catalog is read (:func:`logical_issues`): the template exists and is an
OpenSCENARIO file, every searched parameter (and every key of a value set's choices) is
one it declares, and no other searched key is one the import replaces.
"""

from __future__ import annotations

import json
import math
import os
import shutil
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from suite.catalog import storyboard as sb
from suite.catalog.errors import CatalogIssue
from suite.importers.openscenario.errors import OscImportError
from suite.importers.openscenario.logical import (
    OSC_KEY,
    PARAMETERS,
    VALUE_SETS,
    declared_types,
    point_overrides,
)
from suite.importers.openscenario.pipeline import ImportOptions, build_scenario
from suite.importers.openscenario.xml_safe import read_xml

__all__ = ["IMPORTED_KEYS", "POINT_JSON", "TRIALS_DIR", "Logical", "import_point",
           "is_logical_path", "logical_issues", "point_file"]

TRIALS_DIR = "openscenario"  # under the search's output: one folder per point
POINT_JSON = "point.json"
STORY_JSON = "point.story.json"
# the keys of a point's scenario that its import writes (they replace the catalog's)
IMPORTED_KEYS = ("net", "route", "ego", "duration_s", "storyboard")


@dataclass(frozen=True)
class Logical:
    """A logical family's template (resolved), the import's ego and constraint
    settings (the ``openscenario`` table's), and the folder its points are imported into
    (None until the search sets it: :meth:`suite.search.space.Family.at`)."""

    template: Path
    ego: str | None = None
    ignore_constraints: bool = False
    work_dir: Path | None = None


def is_logical_path(path: str) -> bool:
    return path == OSC_KEY or path.startswith(f"{OSC_KEY}.")


def _searched_names(path: str, spec: Any) -> list[str] | None:
    """The template parameters a searched key sets (None: a key under openscenario that
    is no parameter or value set)."""
    parts = path.split(".")
    if len(parts) == 3 and parts[1] == PARAMETERS:
        return [parts[2]]
    if len(parts) == 3 and parts[1] == VALUE_SETS and parts[2].isdigit():
        choices = spec.get("choices") if isinstance(spec, Mapping) else None
        if not isinstance(choices, list):
            return []
        return sorted({str(k) for c in choices if isinstance(c, Mapping) for k in c})
    return None


def _key_problem(key: str, spec: Any, declared: Mapping[str, str], template: str) -> str:
    """What a searched key of a logical family should be ('' when it is)."""
    if key.split(".")[0] in IMPORTED_KEYS:
        return ("a key the template's import does not write (a logical scenario's "
                f"{', '.join(IMPORTED_KEYS)} come from importing its template)")
    if not is_logical_path(key):
        return ""
    names = _searched_names(key, spec)
    if names is None:
        return f"openscenario.{PARAMETERS}.<Name> or openscenario.{VALUE_SETS}.<index>"
    missing = [n for n in names if n not in declared]
    if missing:
        return f"parameters the template {template} declares ({missing[0]!r} is not one of them)"
    return ""


def logical_issues(catalog_path: Path, where: str, name: str, merged: Mapping[str, Any],
                   items: Sequence[tuple[str, Any]]) -> tuple[Logical | None, list[CatalogIssue]]:
    """The family's :class:`Logical` (None when no searched key is under openscenario)
    and the problems of its logical keys (module doc)."""
    if not any(is_logical_path(k) for k, _ in items):
        return None, []
    issues: list[CatalogIssue] = []

    def bad(key: str, expected: str, got: Any) -> None:
        issues.append(CatalogIssue(key, expected, got, name))

    osc = merged.get(OSC_KEY)
    if not isinstance(osc, Mapping) or not isinstance(osc.get("template"), str):
        bad(f"{where}.{OSC_KEY}", "an openscenario table naming its template (searched "
            "keys under openscenario)", osc)
        return None, issues
    raw = Path(str(osc["template"])).expanduser()
    template = (raw if raw.is_absolute() else catalog_path.parent / raw).resolve()
    try:
        root = read_xml(template).getroot()
        if root.tag != "OpenSCENARIO" or root.find("Storyboard") is None:
            raise OscImportError(str(template), str(root.tag), "not an OpenSCENARIO scenario")
    except (OSError, OscImportError) as exc:
        bad(f"{where}.{OSC_KEY}.template", f"a readable OpenSCENARIO scenario file, relative "
            f"to the catalog ({exc})", osc["template"])
        return None, issues
    declared = declared_types(root)
    for key, spec in items:
        problem = _key_problem(key, spec, declared, template.name)
        if problem:
            bad(f"{where}.search.{json.dumps(key)}", problem, key)
    ego = osc.get("ego")
    return Logical(template, ego if isinstance(ego, str) else None,
                   osc.get("ignore_constraints") is True), issues


def point_file(logical: Logical, run: str) -> Path | None:
    """The ``point.json`` of a point imported under the run name ``run`` (None when the
    family has no work folder)."""
    return None if logical.work_dir is None else logical.work_dir / run / POINT_JSON


def _refusal(exc: OscImportError) -> str:
    where = Path(exc.path).name + (f":{exc.line}" if exc.line else "")
    element = exc.element if exc.element.startswith("parameter") else f"<{exc.element}>"
    reason = exc.reason.replace("--ignore-constraints to run it anyway",
                                "openscenario.ignore_constraints = true to run it anyway")
    return f"the template refuses the point: {where}: {element}: {reason}"


def _duration(entry: Mapping[str, Any]) -> float | None:
    d = entry.get("duration_s")
    if isinstance(d, int | float) and not isinstance(d, bool) and math.isfinite(d) and d > 0:
        return float(d)
    return None


def import_point(logical: Logical, entry: Mapping[str, Any], run: str,
                 catalog_path: Path) -> dict[str, Any] | str:
    """The concrete scenario table of a point (``entry``: the family's merged scenario
    with the point's values set), its template imported into ``work_dir/<run>/``; or why
    the template refuses the point."""
    if logical.work_dir is None:
        raise ValueError("a logical family's points are imported into a folder: "
                         "Family.at(work_dir) first")
    folder = logical.work_dir / run
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    osc = entry.get(OSC_KEY, {})
    overrides = point_overrides(osc if isinstance(osc, Mapping) else {})
    options = ImportOptions(ego=logical.ego, ignore_constraints=logical.ignore_constraints,
                            duration_s=_duration(entry))
    try:
        built = build_scenario(logical.template, folder, options, overrides)
    except OscImportError as exc:
        shutil.rmtree(folder, ignore_errors=True)
        return _refusal(exc)
    (folder / STORY_JSON).write_text(sb.story_to_json(built.story), encoding="utf-8")
    base = catalog_path.parent.resolve()
    net, story = (folder / str(built.table["net"])).resolve(), (folder / STORY_JSON).resolve()
    out = {**entry, **built.table,
           "net": Path(os.path.relpath(net, base)).as_posix(),
           "storyboard": Path(os.path.relpath(story, base)).as_posix()}
    point = {"run": run, "template": str(logical.template), "parameters": overrides,
             "notes": list(built.notes),
             "scenario": {**out, "net": str(net), "storyboard": str(story)}}
    (folder / POINT_JSON).write_text(json.dumps(point, indent=1) + "\n", encoding="utf-8")
    return out
