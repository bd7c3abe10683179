"""Search spaces: the ``[scenario.search]`` tables of a catalog, checked and drawn.

A scenario with a ``search`` table is a *family*; each key is a dotted path into the
merged scenario, exactly as a ``[scenario.sweep]`` key (:mod:`suite.catalog.sweep`:
``"stalled.0.pos_m"``, ``"ego.speed_mps"``, ``"actors.0.events.0.t_s"``,
``"traffic.seed"``, ``"controller.outer.horizon_s"``, ...), and each value one of::

    { min = 60.0, max = 400.0 }             # a float in [min, max]
    { min = 0, max = 999, int = true }      # an integer in [min, max] (both ends in)
    { choices = ["J1", "J3"] }              # one of these values (any TOML values)

A drawn point is a sweep of one value per key: the values are set with
:func:`suite.catalog.sweep.set_path` into the merged scenario, which is then loaded by the
catalog loader itself (:func:`suite.catalog.loader.load_catalog_doc`), so it passes every
check a catalog scenario passes (placement on the route, lanes, actors, traffic, the
controller's options). A point the loader refuses is *refused* (:class:`Refused`): it is
not run, and the search counts it.

Checked when the catalog is read (a :class:`~suite.catalog.CatalogError` naming file,
scenario and key; exit 2): the search table is a non-empty table; the scenario has no
``sweep`` too; every key is a path a sweep could set (:func:`path_target`) and none lies
inside another; every value is one of the three forms with nothing else in it; ``min``
and ``max`` are finite numbers (integers with ``int = true``) with ``min < max``;
``choices`` is a non-empty list of distinct values; the nominal scenario loads; and the
catalog accepts each end of every range (and every choice) with the other keys at their
nominal values. ``hwyeval run`` and ``list`` ignore the search table: they run the
nominal scenario.

A family with keys under ``openscenario`` is a *logical scenario*
(:mod:`suite.search.logical`): each point is made by importing its OpenSCENARIO template
with the point's parameter values (a point the template's constraints refuse is
refused); its range ends are not imported when the catalog is read (the template's
constraints span several parameters: an end is refused in some combinations, not in
others), the template and its declarations are checked instead.
"""

from __future__ import annotations

import copy
import json
import math
import tomllib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from suite.catalog import CatalogError, Scenario, load_catalog
from suite.catalog.errors import MISSING, CatalogIssue
from suite.catalog.frozen import FrozenMap, freeze, thaw
from suite.catalog.loader import load_catalog_doc, merge_scenario
from suite.catalog.rules import MAX_NAME_LEN
from suite.catalog.sweep import overlapping, path_target, set_path
from suite.search.logical import Logical, import_point, is_logical_path, logical_issues

__all__ = ["FLOAT", "INT", "CHOICE", "Family", "Param", "Refused", "SearchCatalog",
           "build_point", "load_search_catalog", "trial_name"]

FLOAT, INT, CHOICE = "float", "int", "choice"
KINDS = (FLOAT, INT, CHOICE)
SPEC_KEYS = ("min", "max", "int", "choices")
TRIAL_SUFFIX_LEN = len("__shrink000")  # the longest suffix a family's run names get


def trial_name(family: str, trial: int) -> str:
    """The run directory (and scenario) name of trial ``trial`` of ``family``."""
    return f"{family}__t{trial:04d}"


def shrink_name(family: str, index: int) -> str:
    """The run name of the ``index``-th line-search run of ``family``."""
    return f"{family}__shrink{index:03d}"


@dataclass(frozen=True)
class Param:
    """One searched key: ``path`` (dotted), ``kind`` float | int | choice, the range
    ``low``..``high`` (float and int; both ends in) or the ``choices``."""

    path: str
    kind: str
    low: float = math.nan
    high: float = math.nan
    choices: tuple[Any, ...] = ()

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"Param.kind must be one of {KINDS}, got {self.kind!r}")
        if self.kind == CHOICE:
            if not self.choices:
                raise ValueError(f"Param {self.path!r}: choices must not be empty")
        elif not (math.isfinite(self.low) and math.isfinite(self.high)
                  and self.low < self.high):
            raise ValueError(f"Param {self.path!r}: expected finite low < high, got "
                             f"{self.low!r}, {self.high!r}")

    def value(self, raw: Any) -> Any:
        """The catalog value of a drawn number (an index for a choice)."""
        if self.kind == CHOICE:
            return thaw(self.choices[int(raw)])
        if self.kind == INT:
            return int(raw)
        return float(raw)

    def unit(self, value: Any) -> float:
        """``value`` as a coordinate in [0, 1] of the range (a choice: its index over
        the count - 1; NaN for a value outside the choices)."""
        if self.kind == CHOICE:
            for i, c in enumerate(self.choices):
                if thaw(c) == value:
                    return i / max(len(self.choices) - 1, 1)
            return math.nan
        return (float(value) - self.low) / (self.high - self.low)

    def toward(self, nominal: Any, value: Any, t: float) -> Any:
        """The value a fraction ``t`` of the way from ``nominal`` (t = 0) to ``value``
        (t = 1): a float linearly, an integer rounded toward ``value``, a choice
        ``nominal`` for t < 1."""
        if self.kind == CHOICE or nominal is None:
            return value if t >= 1.0 or nominal is None else nominal
        x = float(nominal) + t * (float(value) - float(nominal))
        if self.kind == INT:
            return int(math.floor(x + 0.5)) if value >= nominal else int(math.ceil(x - 0.5))
        return x


@dataclass(frozen=True)
class Family:
    """A scenario with a search table. ``base``: the merged scenario (defaults in,
    no sweep or search), frozen; ``nominal``: its value at each param's path (None where
    unset); ``where``: ``scenario[i]`` in the catalog; ``logical``: set for a logical
    scenario (its points imported from its template, :mod:`suite.search.logical`)."""

    name: str
    where: str
    catalog_path: Path
    base: Mapping[str, Any]
    params: tuple[Param, ...]
    nominal: tuple[Any, ...]
    logical: Logical | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        if not self.params or len(self.params) != len(self.nominal):
            raise ValueError(f"Family {self.name!r}: expected one nominal value per param")

    @property
    def paths(self) -> tuple[str, ...]:
        return tuple(p.path for p in self.params)

    def at(self, work_dir: Path) -> Family:
        """This family with its points imported under ``work_dir`` (a logical scenario;
        any other family is returned as it is)."""
        if self.logical is None:
            return self
        return replace(self, logical=replace(self.logical, work_dir=work_dir))

    def distance(self, values: Sequence[Any]) -> float:
        """Euclidean distance [-] of ``values`` to the nominal point in range units
        (each key's range scaled to 1; a choice differs by 0 or 1; a key without a
        nominal value counts 0)."""
        total = 0.0
        for p, nom, v in zip(self.params, self.nominal, values, strict=True):
            if nom is None:
                continue
            d = (0.0 if thaw(nom) == v else 1.0) if p.kind == CHOICE \
                else p.unit(v) - p.unit(nom)
            total += d * d
        return math.sqrt(total)


@dataclass(frozen=True)
class Refused:
    """A point the catalog refuses: ``reason`` is its first issue's line."""

    reason: str


@dataclass(frozen=True)
class SearchCatalog:
    path: Path
    families: tuple[Family, ...]
    skipped: tuple[str, ...] = ()  # scenarios without a search table


def point_entry(family: Family, values: Sequence[Any], name: str) -> dict[str, Any]:
    """The concrete ``[[scenario]]`` table of a point (the merged scenario with each
    value set), named ``name``; None values are left as the base has them."""
    entry: dict[str, Any] = thaw(family.base)
    entry["name"] = name
    for p, v in zip(family.params, values, strict=True):
        if v is not None:
            set_path(entry, p.path, v)
    return entry


def build_point(family: Family, values: Sequence[Any], name: str) -> Scenario | Refused:
    """The scenario of a point, checked and built by the catalog loader, named ``name``
    (its family the family's name, its ``sweep_values`` the point), or why the catalog
    refuses it. A logical scenario's point is imported from its template first, into
    ``<work_dir>/<name>`` (:func:`suite.search.logical.import_point`): a point the
    template refuses is refused with the importer's reason."""
    return _build(family, values, name, imported=family.logical is not None)


def _build(family: Family, values: Sequence[Any], name: str, *, imported: bool
           ) -> Scenario | Refused:
    entry = point_entry(family, values, family.name)
    if imported and family.logical is not None:
        made = import_point(family.logical, entry, name, family.catalog_path)
        if isinstance(made, str):
            return Refused(made)
        entry = made
    try:
        catalog = load_catalog_doc(family.catalog_path, {"scenario": [entry]})
    except CatalogError as exc:
        first = exc.issues[0] if exc.issues else None
        return Refused(first.line(family.catalog_path) if first is not None else str(exc))
    sc = catalog.scenarios[0]
    swept = {p.path: v for p, v in zip(family.params, values, strict=True)}
    return replace(sc, name=name, family=family.name, sweep_values=FrozenMap(freeze(swept)))


# ------------------------------------------------------------------ reading
def load_search_catalog(path: str | Path, *, known_controllers: Iterable[str] | None = None
                        ) -> SearchCatalog:
    """The families of a catalog (module doc); raises CatalogError listing every problem
    (the nominal catalog's own problems first)."""
    cat_path = Path(path).expanduser().resolve()
    load_catalog(cat_path, known_controllers=known_controllers)  # the nominal catalog
    with cat_path.open("rb") as fh:
        doc = tomllib.load(fh)
    defaults = doc.get("defaults", {})
    issues: list[CatalogIssue] = []
    families: list[Family] = []
    skipped: list[str] = []
    for index, entry in enumerate(doc.get("scenario", [])):
        where = f"scenario[{index}]"
        name = str(entry.get("name", where))
        if "search" not in entry:
            skipped.append(name)
            continue
        fam = _family(cat_path, where, name, merge_scenario(defaults, entry), entry, issues)
        if fam is not None:
            issues.extend(_endpoint_issues(fam))
            families.append(fam)
    if not families and not issues:
        issues.append(CatalogIssue("scenario", "at least one scenario with a "
                                   "[scenario.search] table (hwyeval search)"))
    if issues:
        raise CatalogError(cat_path, issues)
    return SearchCatalog(cat_path, tuple(families), tuple(skipped))


def _flatten(table: Mapping[str, Any], prefix: str = "") -> list[tuple[str, Any]]:
    """(dotted path, spec) of a search table: a nested table is a spec when its keys are
    spec keys, else its keys extend the path (unquoted dotted TOML keys)."""
    out: list[tuple[str, Any]] = []
    for k, v in table.items():
        key = f"{prefix}.{k}" if prefix else str(k)
        if isinstance(v, Mapping) and v and not set(v) & set(SPEC_KEYS):
            out.extend(_flatten(v, key))
        else:
            out.append((key, v))
    return out


def _family(path: Path, where: str, name: str, merged: dict[str, Any], entry: dict[str, Any],
            issues: list[CatalogIssue]) -> Family | None:
    table = entry["search"]
    n_before = len(issues)

    def bad(key: str, expected: str, got: Any = MISSING) -> None:
        issues.append(CatalogIssue(key, expected, got, name))

    if not isinstance(table, Mapping) or not table:
        bad(f"{where}.search", "a non-empty table of dotted path -> { min, max } | "
            "{ min, max, int = true } | { choices = [...] }", table)
        return None
    if "sweep" in entry:
        bad(f"{where}.sweep", "no [scenario.sweep] in a scenario with a [scenario.search] "
            "(search one family per scenario)", "sweep")
    if len(name) + TRIAL_SUFFIX_LEN > MAX_NAME_LEN:
        bad(f"{where}.name", f"a name of at most {MAX_NAME_LEN - TRIAL_SUFFIX_LEN} "
            "characters (trial runs append '__t0000')", name)
    items = _flatten(table)
    for key, outer in overlapping([k for k, _ in items]).items():
        bad(f"{where}.search.{json.dumps(key)}", f"a searched path not inside another "
            f"searched path ({outer!r} is searched too)", key)
    params: list[Param] = []
    for key, spec in items:
        loc = f"{where}.search.{json.dumps(key)}"
        ok, problem = path_target(merged, key)
        if not ok:
            bad(loc, problem, key)
            continue
        param = _param(key, spec, loc, bad)
        if param is not None:
            params.append(param)
    logical, problems = logical_issues(path, where, name, merged, items)
    issues.extend(problems)
    if len(issues) > n_before:
        return None
    nominal = tuple(_value_at(merged, p.path) for p in params)
    return Family(name, where, path, freeze(merged), tuple(params), nominal, logical)


def _number(v: Any) -> bool:
    return not isinstance(v, bool) and isinstance(v, int | float) and math.isfinite(v)


_FORM = "{ min = A, max = B }, { min = A, max = B, int = true } or { choices = [...] }"


def _param(key: str, spec: Any, loc: str, bad: Any) -> Param | None:
    """The parameter searched at ``key`` from its ``spec`` table (one of the three
    forms); None after telling ``bad`` (at ``loc``) what is wrong with it."""
    if not isinstance(spec, Mapping) or not spec:
        bad(loc, _FORM, spec)
        return None
    unknown = [k for k in spec if k not in SPEC_KEYS]
    if unknown:
        bad(loc, f"only the keys {list(SPEC_KEYS)} ({_FORM})", unknown[0])
        return None
    if "choices" in spec:
        return _choice_param(key, spec, loc, bad)
    return _range_param(key, spec, loc, bad)


def _choice_param(key: str, spec: Mapping[str, Any], loc: str, bad: Any) -> Param | None:
    """A ``{ choices = [...] }`` parameter: a non-empty list of distinct values and no
    other key; None after telling ``bad`` what is wrong."""
    choices = spec["choices"]
    if set(spec) != {"choices"}:
        bad(loc, "choices alone, without min, max or int", dict(spec))
    elif not isinstance(choices, list) or not choices:
        bad(loc, "a non-empty list of choices", choices)
    elif len({json.dumps(c, sort_keys=True, default=str) for c in choices}) < len(choices):
        bad(loc, "distinct choices", choices)
    else:
        return Param(key, CHOICE, choices=tuple(freeze(c) for c in choices))
    return None


def _range_param(key: str, spec: Mapping[str, Any], loc: str, bad: Any) -> Param | None:
    """A ``{ min, max }`` or ``{ min, max, int = true }`` parameter; None after telling
    ``bad`` what is wrong."""
    is_int = spec.get("int", False)
    if not isinstance(is_int, bool):
        bad(loc, "int = true or false", is_int)
        return None
    lo: Any = spec.get("min")
    hi: Any = spec.get("max")
    problem = _range_problem(lo, hi, is_int, spec)
    if problem is not None:
        bad(loc, *problem)
        return None
    return Param(key, INT if is_int else FLOAT, float(lo), float(hi))


def _range_problem(lo: Any, hi: Any, is_int: bool, spec: Mapping[str, Any]
                   ) -> tuple[str, Any] | None:
    """(what was expected, what was found) for the first problem of the range ends
    ``lo`` (min), ``hi`` (max): missing, not a finite number (integer when ``is_int``),
    out of order or equal; None when they make a range."""
    for end, v in (("min", lo), ("max", hi)):
        if v is None:
            return f"a '{end}' (with '{'max' if end == 'min' else 'min'}'), or choices", MISSING
        if not _number(v) or (is_int and not (isinstance(v, int) or float(v).is_integer())):
            return f"{end}: a finite {'integer' if is_int else 'number'}", v
    if lo > hi:
        return f"min <= max (min {lo!r} > max {hi!r})", dict(spec)
    if lo == hi:
        return f"a non-empty range, min < max (both {lo!r}: set the key itself)", dict(spec)
    return None


def _value_at(root: Any, path: str) -> Any:
    node = root
    for comp in path.split("."):
        if isinstance(node, list) and comp.isdigit() and int(comp) < len(node):
            node = node[int(comp)]
        elif isinstance(node, Mapping) and comp in node:
            node = node[comp]
        else:
            return None
    return copy.deepcopy(thaw(node))


def _ends(p: Param) -> list[Any]:
    if p.kind == CHOICE:
        return [thaw(c) for c in p.choices]
    if p.kind == INT:
        return [int(p.low), int(p.high)]
    return [p.low, p.high]


def _endpoint_issues(fam: Family) -> list[CatalogIssue]:
    """A problem for every range end (or choice) the catalog refuses with the other
    keys at their nominal values. A logical scenario's parameters are not imported here
    (module doc); its other keys are checked on the catalog's own (nominal) import."""
    out: list[CatalogIssue] = []
    for i, p in enumerate(fam.params):
        if fam.logical is not None and is_logical_path(p.path):
            continue
        for end in _ends(p):
            values = list(fam.nominal)
            values[i] = end
            built = _build(fam, values, fam.name, imported=False)
            if isinstance(built, Refused):
                out.append(CatalogIssue(
                    f"{fam.where}.search.{json.dumps(p.path)}",
                    f"a range whose ends the catalog accepts (at {end!r}, the other keys "
                    f"nominal: {built.reason})", end, fam.name))
                break
    return out
