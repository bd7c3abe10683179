"""Loading a catalog: read the TOML file, check its top level and ``[defaults]``, merge the
defaults into each ``[[scenario]]``, check the required keys and the name, expand the
sweep, build every variant (:mod:`suite.catalog.build`) and reject duplicate names.
All problems are collected and raised together as one :class:`CatalogError`."""

from __future__ import annotations

import copy
import itertools
import json
import tomllib
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from suite.catalog import rules
from suite.catalog.build import build_variant
from suite.catalog.controller_check import ControllerChecker
from suite.catalog.errors import (
    MISSING,
    CatalogError,
    CatalogIssue,
    IssueCollector,
    dedupe,
    type_name,
)
from suite.catalog.keys import DEFAULT_KEYS, REQUIRED_KEYS, SCENARIO_KEYS
from suite.catalog.nets import bundled_nets
from suite.catalog.report import Report
from suite.catalog.specs import Catalog, Scenario
from suite.catalog.sweep import (
    flatten_sweep,
    overlapping,
    path_target,
    set_path,
    sweep_name,
    sweep_shorts,
)

__all__ = ["MAX_STEPS", "load_catalog", "load_catalog_doc", "merge_scenario"]

# At most this many control steps per run: the trace is allocated for the whole run
# (~0.5 kB a step), so 1e6 steps (5.6 h at 20 ms) is ~0.5 GB; more is a typo.
MAX_STEPS = 1_000_000

# (merged scenario dict, its name, swept path -> value) of one scenario to build
_Variant = tuple[dict[str, Any], str, dict[str, Any]]


def load_catalog(path: str | Path, *, known_controllers: Iterable[str] | None = None
                 ) -> Catalog:
    """Read, validate and expand a TOML catalog; raise :class:`CatalogError` listing
    every problem. ``known_controllers`` replaces ``controllers.registry.names()``."""
    cat_path = Path(path).expanduser()
    try:
        cat_path = cat_path.resolve()
    except OSError:
        pass
    if not cat_path.is_file():
        raise CatalogError(cat_path, [CatalogIssue(
            "catalog", "an existing TOML catalog file", str(path))])
    try:
        with cat_path.open("rb") as fh:
            doc = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise CatalogError(cat_path, [CatalogIssue(
            "catalog", f"valid TOML ({exc})", MISSING)]) from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise CatalogError(cat_path, [CatalogIssue(
            "catalog", f"a readable UTF-8 TOML file ({exc})", MISSING)]) from exc
    return _Loader(cat_path, doc, known_controllers).run()


def load_catalog_doc(path: str | Path, doc: dict[str, Any], *,
                     known_controllers: Iterable[str] | None = None) -> Catalog:
    """:func:`load_catalog` of an already parsed TOML document ``doc``, as if read from
    ``path`` (relative net paths resolve against it). Used by ``hwyeval search`` to check
    and build each drawn point exactly as a catalog scenario."""
    return _Loader(Path(path), doc, known_controllers).run()


def merge_scenario(defaults: dict[str, Any], entry: dict[str, Any]) -> dict[str, Any]:
    """A ``[[scenario]]`` table with ``[defaults]`` merged in (as the loader merges it;
    without ``sweep`` and ``search``)."""
    return _merge(defaults, entry)


class _Loader:
    def __init__(self, path: Path, doc: dict[str, Any], known: Iterable[str] | None) -> None:
        self.path = path
        self.doc = doc
        self.err = IssueCollector()
        self.controllers = ControllerChecker(known)
        self.bundled = bundled_nets()

    # ------------------------------------------------------------------ top level
    def run(self) -> Catalog:
        self._check_top_level()
        defaults = self._defaults()
        scenarios: list[Scenario] = []
        origin: dict[str, str] = {}  # scenario name -> the scenario[i] that produced it
        for index, entry in enumerate(self._scenario_tables()):
            for name, where, sc in self._scenario(index, entry, defaults):
                if name in origin:
                    self.err.add(f"{where}.name", f"a unique scenario name ({name!r} is "
                                 f"also produced by {origin[name]})", name, name)
                    continue
                origin[name] = where
                if sc is not None:
                    scenarios.append(sc)
        if self.err.issues:
            raise CatalogError(self.path, dedupe(self.err.issues))
        return Catalog(self.path, tuple(scenarios))

    def _check_top_level(self) -> None:
        for key in self.doc:
            if key not in ("catalog", "defaults", "scenario"):
                self.err.add(key, "only the top-level keys 'catalog', 'defaults' and "
                             "'scenario'",
                             self.doc[key] if not isinstance(self.doc[key], dict) else key)
        self._check_catalog_table()
        if self.controllers.registry_error and not self.controllers.explicit:
            self.err.add("controller", "an importable controller registry "
                         f"({self.controllers.registry_error})")

    def _check_catalog_table(self) -> None:
        """``[catalog]``: the catalog's own keys, ``name`` only (its identity in the
        history, docs/history.md; read by :func:`reports.manifest.catalog_identity`)."""
        table = self.doc.get("catalog", {})
        if not isinstance(table, dict):
            self.err.add("catalog", "a table [catalog] (with a name)", table)
            return
        for key, value in table.items():
            if key != "name":
                self.err.add(f"catalog.{key}", "only the key 'name' in [catalog]", key)
            elif not isinstance(value, str) or not value.strip() \
                    or len(value) > rules.MAX_NAME_LEN or value != value.strip():
                self.err.add("catalog.name", f"a non-empty name of at most "
                             f"{rules.MAX_NAME_LEN} characters, without surrounding spaces",
                             value)

    def _defaults(self) -> dict[str, Any]:
        """The valid keys of ``[defaults]`` (the others reported)."""
        defaults = self.doc.get("defaults", {})
        if not isinstance(defaults, dict):
            self.err.add("defaults", "a table [defaults]", defaults)
            defaults = {}
        for key in defaults:
            if key not in DEFAULT_KEYS:
                expected = (f"a key allowed in [defaults], one of {list(DEFAULT_KEYS)}"
                            if key not in ("name", "sweep")
                            else "no 'name' or 'sweep' in [defaults] (they are per scenario)")
                self.err.add(f"defaults.{key}", expected, key)
        return {k: v for k, v in defaults.items() if k in DEFAULT_KEYS}

    def _scenario_tables(self) -> list[Any]:
        """The raw ``[[scenario]]`` entries; an empty or malformed array is reported."""
        raw = self.doc.get("scenario", [])
        if not isinstance(raw, list):
            self.err.add("scenario", "an array of tables [[scenario]]", type_name(raw))
            raw = []
        if not raw and isinstance(self.doc.get("scenario", []), list):
            self.err.add("scenario", "at least one [[scenario]] table")
        return raw

    # ------------------------------------------------------------------ one [[scenario]]
    def _scenario(self, index: int, entry: Any, defaults: dict[str, Any]
                  ) -> list[tuple[str, str, Scenario | None]]:
        """(name, where, scenario or None if invalid) for each (expanded) scenario."""
        where = f"scenario[{index}]"
        if not isinstance(entry, dict):
            self.err.add(where, "a table", entry)
            return []
        name = entry.get("name")
        label = name if isinstance(name, str) else None
        self._check_keys(where, entry, label)
        merged = _merge(defaults, entry)
        self._check_required(where, merged, label)
        name_ok = "name" in merged and rules.name_rule(merged["name"]) is None
        if "name" in merged and not name_ok:
            self.err.add(f"{where}.name", rules.name_rule(merged["name"]) or "",
                         merged["name"], label)
        # An invalid or missing name is reported; the rest is still checked under a label.
        base = merged["name"] if name_ok else (label or where)

        out: list[tuple[str, str, Scenario | None]] = []
        variants = self._variants(where, entry.get("sweep"), merged, base)
        if name_ok and not self._variant_names_fit(where, variants, base):
            return []
        for variant, vname, swept in variants:
            report = Report(self.err, index, vname, base, swept, set(entry),
                            name_reported=not name_ok)
            variant = _nameable_net(variant, report)
            sc = build_variant(variant, report, catalog_path=self.path,
                               controllers=self.controllers, bundled=self.bundled)
            if sc is not None and sc.steps > MAX_STEPS:
                report.add("duration_s", f"a run of at most {MAX_STEPS} control steps "
                           f"(duration_s / step_s; its trace is allocated for the whole run), "
                           f"not {sc.steps}", sc.duration_s)
                sc = None
            out.append((vname, where, sc if name_ok else None))
        return out

    def _variant_names_fit(self, where: str, variants: list[_Variant], base: str) -> bool:
        """Whether every sweep variant's name is short enough to name a directory (the
        base name is checked by the name rule; the suffixes make it longer)."""
        too_long = [vname for _, vname, _ in variants if len(vname) > rules.MAX_NAME_LEN]
        if not too_long:
            return True
        self.err.add(f"{where}.name", f"a name whose sweep variants have at most "
                     f"{rules.MAX_NAME_LEN} characters ({len(too_long)} variant(s) longer, "
                     f"e.g. one of {len(too_long[0])}: shorten the name or the swept keys)",
                     too_long[0], base)
        return False

    def _check_keys(self, where: str, entry: dict[str, Any], label: str | None) -> None:
        for key in entry:
            if key not in SCENARIO_KEYS:
                self.err.add(f"{where}.{key}", f"a known scenario key, one of "
                             f"{list(SCENARIO_KEYS)}", key, label)

    def _check_required(self, where: str, merged: dict[str, Any], label: str | None) -> None:
        for key in REQUIRED_KEYS:
            if key not in merged:
                self.err.add(f"{where}.{key}", "this required key (in the scenario or "
                             "[defaults])" if key not in ("name",) else "a scenario name",
                             scenario=label)

    # ------------------------------------------------------------------ sweep expansion
    def _variants(self, where: str, sweep_raw: Any, merged: dict[str, Any], base: str
                  ) -> list[_Variant]:
        """The scenarios to build: one per sweep combination, or the unswept scenario
        (also when the sweep is unusable, so that the rest is still checked)."""
        if sweep_raw is None:
            return [(merged, base, {})]
        if not isinstance(sweep_raw, dict) or not sweep_raw:
            self.err.add(f"{where}.sweep", "a non-empty table of dotted path -> list of "
                         "values", sweep_raw, base)
            return [(merged, base, {})]
        items = flatten_sweep(sweep_raw)
        if not self._check_sweep(where, items, merged, base):
            return [(merged, base, {})]
        variants, problems = _combinations(items, merged, base)
        for key, problem, vname in problems:
            self.err.add(f"{where}.sweep.{json.dumps(key)}", problem, key, vname)
        return variants if not problems else [(merged, base, {})]

    def _check_sweep(self, where: str, items: list[tuple[str, Any]], merged: dict[str, Any],
                     base: str) -> bool:
        """Whether every swept path has a target and a non-empty list of values, and no
        swept path lies inside another."""
        ok = True
        for key, outer in overlapping([k for k, _ in items]).items():
            self.err.add(f"{where}.sweep.{json.dumps(key)}", "a swept path that is not inside "
                         f"another swept path ({outer!r} is swept too)", key, base)
            ok = False
        for key, values in items:
            target_ok, problem = path_target(merged, key)
            if not target_ok:
                self.err.add(f"{where}.sweep.{json.dumps(key)}", problem, key, base)
                ok = False
            if not isinstance(values, list) or not values:
                self.err.add(f"{where}.sweep.{json.dumps(key)}",
                             "a non-empty list of values", values, base)
                ok = False
        return ok


def _nameable_net(variant: dict[str, Any], report: Report) -> dict[str, Any]:
    """The variant, its ``net`` reported and left out when no file system could name it
    (a NUL byte, a component over 255 bytes): looking it up would raise, not answer."""
    problem = rules.nameable_path(variant.get("net"))
    if problem is None:
        return variant
    report.add("net", f"a bundled net name or a .net.xml path: {problem}", variant["net"])
    return {k: v for k, v in variant.items() if k != "net"}


def _merge(defaults: dict[str, Any], entry: dict[str, Any]) -> dict[str, Any]:
    """``[defaults]`` overridden key by key by the scenario's known keys (but ``sweep``);
    ``criteria`` merged name by name."""
    merged: dict[str, Any] = copy.deepcopy(defaults)
    for key, value in entry.items():
        if key not in SCENARIO_KEYS or key in ("sweep", "search"):
            continue
        if key == "criteria" and isinstance(value, dict) and isinstance(
                merged.get("criteria"), dict):
            merged["criteria"] = {**merged["criteria"], **copy.deepcopy(value)}
        else:
            merged[key] = copy.deepcopy(value)
    return merged


def _combinations(items: list[tuple[str, Any]], merged: dict[str, Any], base: str
                  ) -> tuple[list[_Variant], list[tuple[str, str, str]]]:
    """One variant per element of the cartesian product, the first key varying slowest;
    and the (swept key, problem, variant name) of values that could not be set."""
    keys = [k for k, _ in items]
    shorts = sweep_shorts(keys)
    value_lists = [list(enumerate(v)) for _, v in items]
    out: list[_Variant] = []
    problems: list[tuple[str, str, str]] = []
    for combo in itertools.product(*value_lists) if value_lists else ():
        variant = copy.deepcopy(merged)
        vname = sweep_name(base, shorts, [v for _, v in combo], [p for p, _ in combo])
        bad = [(key, problem) for key, (_, value) in zip(keys, combo, strict=True)
               if (problem := set_path(variant, key, value)) is not None]
        if bad:
            problems.extend((key, problem, vname) for key, problem in bad)
            continue
        variant["name"] = vname
        out.append((variant, vname, {k: v for k, (_, v) in zip(keys, combo, strict=True)}))
    return out, problems
