"""Logical scenarios: a variation file's template and its space as catalog keys.

A variation file's own scenario (its template with the declared values) carries

* ``openscenario = { template = "<path relative to the catalog>", parameters = {...},
  value_sets = [...] }``: the template it came from and the values of the parameters the
  file varies (the template's declared values; ``--param`` values too, fixed), typed by
  the template's declarations (``double`` a float, ``int`` an integer, ``boolean`` a
  bool, else a string); ``value_sets`` one table per multi-parameter distribution;
  ``ego`` and ``ignore_constraints`` when the import was given them;
* ``search``: one ``[scenario.search]`` key per distribution:
  ``openscenario.parameters.<Name>`` (a ``DistributionSet`` or probability set: its
  values as choices; a ``DistributionRange``: its steps as choices, or its range with
  ``search_ranges``; a stochastic distribution: its range, :func:`~.variation.
  distribution_space`) and ``openscenario.value_sets.<i>`` (a ``ValueSetDistribution``:
  its sets as choices).

``hwyeval search`` makes each point's scenario by importing the template with the
point's values (:func:`point_overrides`; ``suite.search.logical``). A parameter set
imported as a scenario of its own carries ``openscenario`` with its values (data only).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from suite.importers.openscenario.params import declare
from suite.importers.openscenario.variation import GRID, RANGE, SETS, Axis

__all__ = ["OSC_KEY", "PARAMETERS", "VALUE_SETS", "catalog_value", "declared_types",
           "logical_tables", "override_text", "point_overrides", "set_table"]

OSC_KEY = "openscenario"
PARAMETERS = "parameters"
VALUE_SETS = "value_sets"
INT_TYPES = ("int", "unsignedInt", "unsignedShort")
NUMBER_TYPES = ("double", *INT_TYPES)
Typed = str | int | float | bool


def declared_types(root: Any) -> dict[str, str]:
    """Each top-level parameter's declared ``parameterType`` by name."""
    decls = root.find("ParameterDeclarations")
    return {str(d.get("name", "")): str(d.get("parameterType", "string"))
            for d in ([] if decls is None else decls.findall("ParameterDeclaration"))}


def catalog_value(value: Any, kind: str | None) -> Typed:
    """A parameter's value (an XML string or a resolved value) as the catalog holds it,
    typed by the declaration's ``kind``; a value that is not of its type stays a string
    (the import refuses it, naming the parameter)."""
    if kind in NUMBER_TYPES:
        return _number_value(value, kind)
    if kind == "boolean":
        return _boolean_value(value)
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return value if isinstance(value, str) else str(value)


def _number_value(value: Any, kind: str | None) -> Typed:
    """:func:`catalog_value` of an integer kind (an int when integral) or a double (a
    finite float); otherwise the value as a string."""
    try:
        f = float(value)
    except (TypeError, ValueError):
        return str(value)
    if kind in INT_TYPES:
        return int(f) if f.is_integer() else str(value)
    return f if math.isfinite(f) else str(value)


def _boolean_value(value: Any) -> Typed:
    """:func:`catalog_value` of a boolean: a bool, or "true"/"false" in any case and
    spacing; otherwise the value as a string."""
    if isinstance(value, bool):
        return value
    text = str(value).strip().lower()
    return text == "true" if text in ("true", "false") else str(value)


def override_text(value: Any) -> str:
    """A catalog value as the text of a parameter's value (what a declaration reads)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    return str(value)


def point_overrides(osc: Mapping[str, Any]) -> dict[str, str]:
    """The parameter values an ``openscenario`` table sets: ``parameters``, then each of
    ``value_sets`` (a later one wins), as texts."""
    out = {str(k): override_text(v) for k, v in dict(osc.get(PARAMETERS, {})).items()}
    for group in osc.get(VALUE_SETS, []) or []:
        out.update({str(k): override_text(v) for k, v in dict(group).items()})
    return out


def _template_path(template: Path, catalog_dir: Path) -> str:
    try:
        return Path(os.path.relpath(template.resolve(), catalog_dir.resolve())).as_posix()
    except ValueError:  # another drive
        return template.resolve().as_posix()


def _head(template: Path, catalog_dir: Path, ego: str | None,
          ignore_constraints: bool) -> dict[str, Any]:
    head: dict[str, Any] = {"template": _template_path(template, catalog_dir)}
    if ego is not None:
        head["ego"] = ego
    if ignore_constraints:
        head["ignore_constraints"] = True
    return head


def _unique(values: Sequence[Any]) -> list[Any]:
    out: list[Any] = []
    for v in values:
        if not any(type(v) is type(u) and v == u for u in out):
            out.append(v)
    return out


def _range_spec(low: float, high: float, integer: bool) -> dict[str, Any]:
    lo, hi = min(low, high), max(low, high)
    if integer:
        a, b = math.ceil(lo), math.floor(hi)
        return {"min": a, "max": b, "int": True} if a < b else {"choices": [a]}
    return {"min": float(lo), "max": float(hi)} if lo < hi else {"choices": [float(lo)]}


def _spec(axis: Axis, kind: str | None, ranges: bool) -> dict[str, Any]:
    if axis.kind == RANGE or (axis.kind == GRID and ranges and kind in NUMBER_TYPES):
        return _range_spec(axis.low, axis.high, axis.integer or kind in INT_TYPES)
    return {"choices": _unique([catalog_value(v, kind) for v in axis.values])}


def _unsearchable(name: str, types: Mapping[str, str], fixed: set[str]) -> str:
    """Why a varied parameter is not searched ('' when it is, or is fixed)."""
    if name in fixed:
        return ""
    if name not in types:
        return "is not declared by the template"
    return "has a '.' in its name" if "." in name else ""


def logical_tables(template: Path, troot: Any, axes: Sequence[Axis], catalog_dir: Path, *,
                   fixed: Sequence[tuple[str, str]] = (), ego: str | None = None,
                   ignore_constraints: bool = False, search_ranges: bool = False
                   ) -> tuple[dict[str, Any], list[str]]:
    """The ``openscenario`` and ``search`` keys of a variation file's own scenario (module
    doc) and notes on what is not searched. ``troot``: the template's root (its
    declarations, unresolved); ``fixed``: the command line's ``--param`` values (set,
    never searched); ``catalog_dir``: where the catalog is written."""
    types = declared_types(troot)
    nominal = declare(troot, dict(fixed), ignore_constraints=True)
    fixed_names = {n for n, _ in fixed}
    notes: list[str] = []

    def usable(name: str) -> bool:
        why = _unsearchable(name, types, fixed_names)
        if why:
            notes.append(f"parameter {name} {why}: not searched")
        return not why and name not in fixed_names

    params: dict[str, Typed] = {}
    value_sets: list[dict[str, Typed]] = []
    search: dict[str, Any] = {}
    for axis in axes:
        names = [n for n in axis.names if usable(n)]
        if not names:
            continue
        if axis.kind == SETS:
            choices = _unique([{n: catalog_value(s[n], types[n]) for n in names}
                               for s in axis.sets])
            search[f"{OSC_KEY}.{VALUE_SETS}.{len(value_sets)}"] = {"choices": choices}
            value_sets.append({n: catalog_value(nominal[n], types[n]) for n in names})
            continue
        name = names[0]
        params[name] = catalog_value(nominal[name], types[name])
        search[f"{OSC_KEY}.{PARAMETERS}.{name}"] = _spec(axis, types[name], search_ranges)
    for name, value in fixed:
        params[name] = catalog_value(value, types.get(name))
    osc = _head(template, catalog_dir, ego, ignore_constraints)
    osc[PARAMETERS] = params
    if value_sets:
        osc[VALUE_SETS] = value_sets
    out: dict[str, Any] = {OSC_KEY: osc}
    if search:
        out["search"] = search
    return out, notes


def set_table(template: Path, troot: Any, values: Mapping[str, str], catalog_dir: Path, *,
              fixed: Sequence[tuple[str, str]] = (), ego: str | None = None,
              ignore_constraints: bool = False) -> dict[str, Any]:
    """The ``openscenario`` key of one parameter set imported as a scenario (data only:
    the template and the set's values, the command line's winning)."""
    types = declared_types(troot)
    merged = {**dict(values), **dict(fixed)}
    osc = _head(template, catalog_dir, ego, ignore_constraints)
    osc[PARAMETERS] = {n: catalog_value(v, types.get(n)) for n, v in merged.items()}
    return {OSC_KEY: osc}

