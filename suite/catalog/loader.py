"""TOML scenario catalogs: parse, validate against the road network, expand sweeps.

This file format is a public contract. A catalog looks like::

    [defaults]                      # optional, merged into every scenario
    controller = "lane_keep"        # a registered controller name, or {name = ..., options...}
    duration_s = 30.0
    step_s = 0.02
    seed = 0

    [[scenario]]
    name = "s3_stall_mid"           # unique; [a-z0-9_]+
    net = "straight_3lane"          # a bundled net, or a .net.xml path relative to this file
    route = ["e0"]                  # optional; default: the longest edge path through the net
    ego = { lane = 1, pos_m = 50.0, speed_mps = 25.0, target_speed_mps = 25.0 }
    stalled = [ { lane = 1, pos_m = 400.0 } ]        # zero or more; pos_m along the route
    traffic = { vehicles_per_hour = 1500, seed = 7 } # optional background traffic
    controller = { name = "lane_keep" }              # a table may carry options
    [scenario.sweep]                # optional: cartesian product, one scenario per combination
    "stalled.0.pos_m" = [300.0, 500.0]
    "traffic.vehicles_per_hour" = [0, 2000]

Keys of a scenario (all may also appear in ``[defaults]`` except ``name`` and ``sweep``):

=================== =========================================================================
``name``            required, ``[a-z0-9_]+``, unique (also after sweep expansion).
``net``             required; a bundled net name (``sumo_nets.available()``), else a path to a
                    ``.net.xml`` file, relative to the catalog file (or absolute).
``route``           list of edge ids, each consecutive pair connected. Default: the
                    network's longest edge path (:meth:`RoadNetwork.default_route`).
``ego``             required table: ``lane`` (int), ``pos_m``, ``speed_mps`` (required),
                    ``target_speed_mps`` (default: ``speed_mps``).
``stalled``         list of tables: ``lane``, ``pos_m`` (required), ``length_m`` (4.8),
                    ``width_m`` (1.9). Default: none.
``traffic``         table: ``vehicles_per_hour`` (required, >= 0), ``seed`` (default: the
                    scenario's ``seed``), ``speed_mps`` (default: lane speed limit),
                    ``lanes`` (default: every lane of the first route edge that admits
                    passenger cars), ``speed_factor_dev`` (0.1). Default: no traffic.
``controller``      required (usually from ``[defaults]``): a name, or a table with ``name``
                    and the controller's options.
``duration_s``      required, > 0.         ``step_s``: required, > 0 and <= ``duration_s``.
``seed``            int in [0, 2**31 - 1]; default 0.
``allow_shoulder``  bool, default false: the ego may use a hard shoulder.
``criteria``        table name -> number: pass/fail limits overriding the defaults of the
                    metrics (names are not checked here).
``record_radius_m`` > 0, default 150: vehicles within this distance of the ego are logged.
``timeout_s``       > 0: wall-clock limit of one run. Default: none.
``sweep``           table dotted-path -> non-empty list (see below).
=================== =========================================================================

Every other key, anywhere, is an error. Numbers: ints or floats, never bools, finite.
Lane indices count from 0 = rightmost, as in SUMO.

Merging: ``[defaults]`` is merged into every scenario key by key; the scenario's value
replaces the default's wholesale, except ``criteria`` which is merged name by name
(defaults first, then the scenario).

Sweeps: each key of ``[scenario.sweep]`` is a dotted path into the merged scenario (list
indices numeric, e.g. ``"stalled.0.pos_m"``; unquoted dotted TOML keys work too); its
target must exist after merging, or be an optional key of an existing table (e.g.
``ego.target_speed_mps``). The scenario expands to the cartesian product of the value
lists, the first key varying slowest. Variant names are
``<name>__<short><value>[__<short><value>...]``: ``short`` is the last path component,
abbreviated (``pos_m``->``pos``, ``vehicles_per_hour``->``vph``, ``speed_mps``->``speed``,
``target_speed_mps``->``vt``, otherwise the component without its unit suffix); when two
keys of a sweep share a short, preceding components are prepended until they differ
(``ego.pos_m``->``egopos``, ``stalled.0.pos_m``->``stalled0pos``). Values: numbers compactly
(``300.0``->``300``, ``2.5``->``2p5``, ``-1``->``m1``), bools ``true``/``false``, strings as
is (characters outside ``[a-z0-9_]`` become ``_``), lists/tables by their position in the
sweep list (``v0``, ``v1``...). ``Scenario.family`` is the unexpanded name and
``Scenario.sweep_values`` maps each swept path to its value.

Validation against the network: route edges exist and connect; ``ego`` and ``stalled``
positions lie in ``[0, route length)``; their lanes exist at that position
(:meth:`RoadNetwork.lanes_at`); the ego's start lane admits passenger cars, or is a hard
shoulder and ``allow_shoulder`` is true; traffic lanes exist on the first route edge and
admit passenger cars.

Controllers: the name must be one of ``controllers.registry.names()``; the options are
checked by building the controller once per distinct (name, options) with
``controllers.registry.make`` (a ``ConfigError`` becomes an error at
``scenario[i].controller.<key>``). If ``known_controllers`` is given to
:func:`load_catalog`, names are checked against it instead and, **only in that case**, the
option check is skipped for a name the registry cannot build because the registry (or
``controllers.builtin``) cannot be imported or does not know that name.

All problems of a catalog are collected and raised together as one :class:`CatalogError`
(``.issues`` holds them as :class:`CatalogIssue`), one line each::

    <file>: scenario[2].stalled.0.lane (scenario 's3_stall_mid'): expected ..., got 5 [note]

naming the file, the key, the scenario (its name, or ``scenario[i]`` without a valid name)
and what was expected. Notes: ``value from [defaults]`` when the bad value was inherited;
``value from scenario[i].sweep."<key>"`` (the scenario is then the variant) when a swept
value is bad; ``all sweep variants`` for a problem shared by every variant (reported once,
under the family name). A scenario whose network or route is unusable is not checked
further against the network (no cascade of follow-up errors).
"""

from __future__ import annotations

import copy
import fnmatch
import itertools
import json
import math
import re
import tomllib
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, ClassVar

from suite.road.network import RoadNetwork, RoadNetworkError

__all__ = [
    "Catalog",
    "CatalogError",
    "CatalogIssue",
    "ControllerSpec",
    "EgoSpec",
    "FrozenMap",
    "Scenario",
    "SpecError",
    "StalledSpec",
    "TrafficSpec",
    "bundled_nets",
    "expand_filter",
    "format_sweep_value",
    "load_catalog",
    "sweep_name",
    "sweep_shorts",
]

NAME_RE = re.compile(r"^[a-z0-9_]+$")
MAX_SEED = 2**31 - 1


# ============================================================================ errors
class SpecError(ValueError):
    """A spec field is invalid: ``field`` names it, ``expected`` says what fits."""

    def __init__(self, field_name: str, expected: str, got: Any = None) -> None:
        self.field = field_name
        self.expected = expected
        self.got = got
        super().__init__(f"{field_name}: expected {expected}, got {got!r}")


@dataclass(frozen=True)
class CatalogIssue:
    """One problem: ``key`` is dotted from the catalog root, ``scenario`` its name/label."""

    key: str
    expected: str
    got: Any = None
    scenario: str | None = None
    note: str = ""

    def line(self, path: Path | str) -> str:
        where = f" (scenario {self.scenario!r})" if self.scenario else ""
        got = "" if self.got is _MISSING else f", got {_short_repr(self.got)}"
        note = f" [{self.note}]" if self.note else ""
        return f"{path}: {self.key}{where}: expected {self.expected}{got}{note}"


class CatalogError(ValueError):
    """A catalog is unusable. ``issues`` lists every problem; the message has one a line."""

    def __init__(self, path: Path | str, issues: Sequence[CatalogIssue]) -> None:
        self.path = Path(path)
        self.issues = tuple(issues)
        lines = [issue.line(path) for issue in self.issues]
        head = f"{path}: {len(lines)} problem{'s' if len(lines) != 1 else ''} in scenario catalog"
        super().__init__("\n".join([head, *lines]))


class _Missing:
    def __repr__(self) -> str:
        return "<missing>"


_MISSING: Any = _Missing()


def _short_repr(value: Any, limit: int = 120) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


# ============================================================================ frozen map
class FrozenMap(Mapping[str, Any]):
    """An immutable, picklable, hashable-if-possible mapping (nested maps/lists frozen)."""

    __slots__ = ("_data",)
    _data: dict[str, Any]

    def __init__(self, data: Mapping[str, Any] | Iterable[tuple[str, Any]] = ()) -> None:
        object.__setattr__(self, "_data", {k: _freeze(v) for k, v in dict(data).items()})

    def __getitem__(self, key: str) -> Any:
        return self._data[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def __repr__(self) -> str:
        return f"FrozenMap({self._data!r})"

    def __eq__(self, other: object) -> bool:
        if isinstance(other, Mapping):
            return dict(self.items()) == dict(other.items())
        return NotImplemented

    def __hash__(self) -> int:
        return hash(json.dumps(_thaw(self), sort_keys=True, default=str))

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError("FrozenMap is immutable")

    def __reduce__(self) -> tuple[Any, ...]:
        return (FrozenMap, (_thaw(self),))

    def to_dict(self) -> dict[str, Any]:
        """A deep, mutable, JSON-able copy."""
        return _thaw(self)


def _freeze(value: Any) -> Any:
    if isinstance(value, FrozenMap):
        return value
    if isinstance(value, Mapping):
        return FrozenMap(value)
    if isinstance(value, list | tuple):
        return tuple(_freeze(v) for v in value)
    return copy.deepcopy(value)


def _thaw(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {str(k): _thaw(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_thaw(v) for v in value]
    return value


# ============================================================================ field rules
def _is_number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _num(lo: float | None = None, *, strict: bool = False, optional: bool = False
         ) -> Callable[[Any], str | None]:
    if lo is None:
        what = "a finite number"
    else:
        what = f"a finite number {'>' if strict else '>='} {lo:g}"

    def check(v: Any) -> str | None:
        if v is None and optional:
            return None
        if not _is_number(v):
            return what
        if lo is not None and (v < lo or (strict and v == lo)):
            return what
        return None

    return check


def _int(lo: int = 0, hi: int | None = None) -> Callable[[Any], str | None]:
    what = f"an integer >= {lo}" if hi is None else f"an integer in [{lo}, {hi}]"

    def check(v: Any) -> str | None:
        if not isinstance(v, int) or isinstance(v, bool):
            return what
        if v < lo or (hi is not None and v > hi):
            return what
        return None

    return check


def _bool(v: Any) -> str | None:
    return None if isinstance(v, bool) else "a boolean (true/false)"


def _name(v: Any) -> str | None:
    if isinstance(v, str) and NAME_RE.match(v):
        return None
    return "a name matching [a-z0-9_]+"


def _lanes(v: Any) -> str | None:
    what = "null or a non-empty list of distinct lane indices (integers >= 0)"
    if v is None:
        return None
    if not isinstance(v, list | tuple) or not v:
        return what
    if any(not isinstance(x, int) or isinstance(x, bool) or x < 0 for x in v):
        return what
    if len(set(v)) != len(v):
        return what
    return None


def _number_map(v: Any) -> str | None:
    what = "a table of name -> finite number"
    if not isinstance(v, Mapping):
        return what
    if any(not isinstance(k, str) or not _is_number(x) for k, x in v.items()):
        return what
    return None


def _check_fields(obj: Any) -> None:
    """Run the class's ``_RULES`` on ``obj``; raise SpecError on the first failure."""
    for name, rule in obj._RULES.items():
        value = getattr(obj, name)
        expected = rule(value)
        if expected is not None:
            raise SpecError(name, expected, value)


def _as_float(obj: Any, *names: str) -> None:
    for name in names:
        value = getattr(obj, name)
        if isinstance(value, int) and not isinstance(value, bool):
            object.__setattr__(obj, name, float(value))


# ============================================================================ specs
@dataclass(frozen=True)
class EgoSpec:
    """Ego start: lane index (0 = rightmost), route position, speed, cruise set-point.

    ``target_speed_mps`` defaults to ``speed_mps`` (NaN on input means "unset").
    """

    lane: int
    pos_m: float
    speed_mps: float
    target_speed_mps: float = math.nan

    _RULES: ClassVar[dict[str, Callable[[Any], str | None]]] = {
        "lane": _int(0), "pos_m": _num(0.0), "speed_mps": _num(0.0),
        "target_speed_mps": _num(0.0),
    }
    _REQUIRED: ClassVar[tuple[str, ...]] = ("lane", "pos_m", "speed_mps")

    def __post_init__(self) -> None:
        if isinstance(self.target_speed_mps, float) and math.isnan(self.target_speed_mps):
            object.__setattr__(self, "target_speed_mps", self.speed_mps)
        _check_fields(self)
        _as_float(self, "pos_m", "speed_mps", "target_speed_mps")


@dataclass(frozen=True)
class StalledSpec:
    """A stopped vehicle at route position ``pos_m`` on lane ``lane``."""

    lane: int
    pos_m: float
    length_m: float = 4.8
    width_m: float = 1.9

    _RULES: ClassVar[dict[str, Callable[[Any], str | None]]] = {
        "lane": _int(0), "pos_m": _num(0.0), "length_m": _num(0.0, strict=True),
        "width_m": _num(0.0, strict=True),
    }
    _REQUIRED: ClassVar[tuple[str, ...]] = ("lane", "pos_m")

    def __post_init__(self) -> None:
        _check_fields(self)
        _as_float(self, "pos_m", "length_m", "width_m")


@dataclass(frozen=True)
class TrafficSpec:
    """Background traffic. ``lanes`` None = every lane admitting passenger cars;
    ``speed_mps`` None = the lane speed limit; ``speed_factor_dev`` = SUMO speedDev."""

    vehicles_per_hour: float
    seed: int
    speed_mps: float | None = None
    lanes: tuple[int, ...] | None = None
    speed_factor_dev: float = 0.1

    _RULES: ClassVar[dict[str, Callable[[Any], str | None]]] = {
        "vehicles_per_hour": _num(0.0), "seed": _int(0, MAX_SEED),
        "speed_mps": _num(0.0, strict=True, optional=True), "lanes": _lanes,
        "speed_factor_dev": _num(0.0),
    }
    _REQUIRED: ClassVar[tuple[str, ...]] = ("vehicles_per_hour",)

    def __post_init__(self) -> None:
        _check_fields(self)
        if self.lanes is not None:
            object.__setattr__(self, "lanes", tuple(self.lanes))
        _as_float(self, "vehicles_per_hour", "speed_factor_dev")
        if self.speed_mps is not None:
            _as_float(self, "speed_mps")


@dataclass(frozen=True)
class ControllerSpec:
    """A registered controller and its (immutable, JSON-able) options."""

    name: str
    options: Mapping[str, Any] = field(default_factory=lambda: FrozenMap())

    def __post_init__(self) -> None:
        if _name(self.name):
            raise SpecError("name", "a controller name matching [a-z0-9_]+", self.name)
        if not isinstance(self.options, Mapping):
            raise SpecError("options", "a table of options", self.options)
        bad = _non_json_path(self.options)
        if bad is not None:
            raise SpecError(bad[0] or "options", "a JSON-able value (string, number, bool, "
                            "list, table)", bad[1])
        if not isinstance(self.options, FrozenMap):
            object.__setattr__(self, "options", FrozenMap(copy.deepcopy(dict(self.options))))

    def options_dict(self) -> dict[str, Any]:
        """A deep, mutable copy of the options (what the factory gets)."""
        return _thaw(self.options)

    def as_dict(self) -> dict[str, Any]:
        return {"name": self.name, "options": self.options_dict()}


def _non_json_path(value: Any, prefix: str = "") -> tuple[str, Any] | None:
    """First (dotted path, value) that is not JSON-able, else None."""
    if isinstance(value, Mapping):
        for k, v in value.items():
            if not isinstance(k, str):
                return prefix or str(k), k
            bad = _non_json_path(v, f"{prefix}.{k}" if prefix else k)
            if bad is not None:
                return bad
        return None
    if isinstance(value, list | tuple):
        for i, v in enumerate(value):
            bad = _non_json_path(v, f"{prefix}.{i}" if prefix else str(i))
            if bad is not None:
                return bad
        return None
    if value is None or isinstance(value, str | bool | int):
        return None
    if isinstance(value, float) and math.isfinite(value):
        return None
    return prefix, value


@dataclass(frozen=True)
class Scenario:
    """One fully resolved, validated scenario run."""

    name: str
    family: str
    catalog_path: Path
    net: str
    net_path: Path
    route: tuple[str, ...]
    ego: EgoSpec
    stalled: tuple[StalledSpec, ...]
    traffic: TrafficSpec | None
    controller: ControllerSpec
    duration_s: float
    step_s: float
    seed: int
    allow_shoulder: bool = False
    criteria: Mapping[str, float] = field(default_factory=lambda: FrozenMap())
    sweep_values: Mapping[str, Any] = field(default_factory=lambda: FrozenMap())
    record_radius_m: float = 150.0
    timeout_s: float | None = None

    _RULES: ClassVar[dict[str, Callable[[Any], str | None]]] = {
        "name": _name, "family": _name, "duration_s": _num(0.0, strict=True),
        "step_s": _num(0.0, strict=True), "seed": _int(0, MAX_SEED), "allow_shoulder": _bool,
        "criteria": _number_map, "record_radius_m": _num(0.0, strict=True),
        "timeout_s": _num(0.0, strict=True, optional=True),
    }

    def __post_init__(self) -> None:
        _check_fields(self)
        if self.step_s > self.duration_s:
            raise SpecError("step_s", f"a step <= duration_s ({self.duration_s})", self.step_s)
        if not isinstance(self.ego, EgoSpec):
            raise SpecError("ego", "an EgoSpec", self.ego)
        if not isinstance(self.controller, ControllerSpec):
            raise SpecError("controller", "a ControllerSpec", self.controller)
        if self.traffic is not None and not isinstance(self.traffic, TrafficSpec):
            raise SpecError("traffic", "a TrafficSpec or None", self.traffic)
        stalled = tuple(self.stalled)
        if any(not isinstance(s, StalledSpec) for s in stalled):
            raise SpecError("stalled", "a sequence of StalledSpec", self.stalled)
        route = tuple(self.route)
        if not route or any(not isinstance(e, str) for e in route):
            raise SpecError("route", "a non-empty sequence of edge ids", self.route)
        object.__setattr__(self, "stalled", stalled)
        object.__setattr__(self, "route", route)
        object.__setattr__(self, "catalog_path", Path(self.catalog_path))
        object.__setattr__(self, "net_path", Path(self.net_path))
        object.__setattr__(self, "criteria", FrozenMap(
            {k: float(v) for k, v in self.criteria.items()}))
        object.__setattr__(self, "sweep_values", FrozenMap(self.sweep_values))
        _as_float(self, "duration_s", "step_s", "record_radius_m")
        if self.timeout_s is not None:
            _as_float(self, "timeout_s")

    @property
    def steps(self) -> int:
        """Number of simulation steps (``round(duration_s / step_s)``)."""
        return int(round(self.duration_s / self.step_s))

    def as_dict(self) -> dict[str, Any]:
        """JSON-serialisable dict of every field."""
        return {
            "name": self.name,
            "family": self.family,
            "catalog_path": str(self.catalog_path),
            "net": self.net,
            "net_path": str(self.net_path),
            "route": list(self.route),
            "ego": _plain_dataclass(self.ego),
            "stalled": [_plain_dataclass(s) for s in self.stalled],
            "traffic": None if self.traffic is None else _plain_dataclass(self.traffic),
            "controller": self.controller.as_dict(),
            "duration_s": self.duration_s,
            "step_s": self.step_s,
            "seed": self.seed,
            "allow_shoulder": self.allow_shoulder,
            "criteria": _thaw(self.criteria),
            "sweep_values": _thaw(self.sweep_values),
            "record_radius_m": self.record_radius_m,
            "timeout_s": self.timeout_s,
        }


def _plain_dataclass(obj: Any) -> dict[str, Any]:
    return {f.name: _thaw(getattr(obj, f.name)) for f in fields(obj)}


@dataclass(frozen=True)
class Catalog:
    """A loaded catalog: its path and its scenarios in file order, sweeps expanded."""

    path: Path
    scenarios: tuple[Scenario, ...]

    def names(self) -> list[str]:
        return [s.name for s in self.scenarios]

    def get(self, name: str) -> Scenario:
        for s in self.scenarios:
            if s.name == name:
                return s
        raise KeyError(f"{self.path}: no scenario {name!r}")

    def __len__(self) -> int:
        return len(self.scenarios)

    def __iter__(self) -> Iterator[Scenario]:
        return iter(self.scenarios)


# ============================================================================ sweep naming
_ABBREV = {
    "pos_m": "pos",
    "vehicles_per_hour": "vph",
    "speed_mps": "speed",
    "target_speed_mps": "vt",
    # Sweeping the controller names variants by the controller alone: s3_stall__two_loop.
    "controller": "",
}
_UNIT_SUFFIX = re.compile(r"_(m|s|mps|mps2|rad|radps|deg|hz|nm|kg|ms|kmh|n)$")


def _abbrev(component: str) -> str:
    if component in _ABBREV:
        return _ABBREV[component]
    short = _UNIT_SUFFIX.sub("", component)
    return short or component


def sweep_shorts(keys: Sequence[str]) -> list[str]:
    """Short labels for swept dotted keys, lengthened until they are distinct."""
    parts = [k.split(".") for k in keys]
    depth = [1] * len(keys)

    def label(i: int) -> str:
        comps = parts[i][-depth[i]:]
        return "".join(_abbrev(c) for c in comps)

    for _ in range(max((len(p) for p in parts), default=0) + 1):
        labels = [label(i) for i in range(len(keys))]
        clash = [i for i, lab in enumerate(labels) if labels.count(lab) > 1]
        grow = [i for i in clash if depth[i] < len(parts[i])]
        if not grow:
            break
        for i in grow:
            depth[i] += 1
            # a bare list index is not readable on its own: take its parent too
            while depth[i] < len(parts[i]) and parts[i][-depth[i]].isdigit():
                depth[i] += 1
    labels = [label(i) for i in range(len(keys))]
    seen: dict[str, int] = {}
    out = []
    for lab in labels:
        if labels.count(lab) > 1:  # identical full paths after abbreviation
            seen[lab] = seen.get(lab, 0) + 1
            lab = f"{lab}{seen[lab]}x"
        out.append(re.sub(r"[^a-z0-9_]", "_", lab.lower()))
    return out


def format_sweep_value(value: Any, position: int = 0) -> str:
    """Compact, name-safe text of a swept value (``300.0``->``300``, ``2.5``->``2p5``)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        text = str(value)
    elif isinstance(value, float):
        if math.isfinite(value) and value == int(value) and abs(value) < 1e15:
            text = str(int(value))
        else:
            text = repr(value)
    elif isinstance(value, str):
        return re.sub(r"[^a-z0-9_]", "_", value.lower())
    elif isinstance(value, Mapping) and isinstance(value.get("name"), str) and len(value) == 1:
        return format_sweep_value(value["name"])
    else:
        return f"v{position}"
    return text.replace("-", "m").replace("+", "").replace(".", "p").lower()


def sweep_name(base: str, shorts: Sequence[str], values: Sequence[Any],
               positions: Sequence[int] | None = None) -> str:
    """``<base>__<short><value>...`` for one sweep combination."""
    positions = positions if positions is not None else [0] * len(values)
    parts = [f"{s}{format_sweep_value(v, p)}" for s, v, p in zip(shorts, values, positions,
                                                                   strict=True)]
    return "__".join([base, *parts])


# ============================================================================ nets
def bundled_nets() -> list[str]:
    """Names of the bundled nets; empty if ``sumo_nets`` is unavailable."""
    try:
        import sumo_nets
    except ImportError:
        return []
    try:
        return list(sumo_nets.available())
    except Exception:
        return []


def _bundled_net_path(name: str) -> Path | None:
    try:
        import sumo_nets
    except ImportError:
        return None
    try:
        return Path(sumo_nets.net_path(name))
    except (KeyError, ValueError, FileNotFoundError):
        return None


# ============================================================================ loading
_SCENARIO_KEYS = (
    "name", "net", "route", "ego", "stalled", "traffic", "controller", "duration_s", "step_s",
    "seed", "allow_shoulder", "criteria", "record_radius_m", "timeout_s", "sweep",
)
_DEFAULT_KEYS = tuple(k for k in _SCENARIO_KEYS if k not in ("name", "sweep"))
_REQUIRED_KEYS = ("name", "net", "ego", "controller", "duration_s", "step_s")
_OPTIONAL_SUBKEYS: dict[str, tuple[str, ...]] = {
    "ego": ("lane", "pos_m", "speed_mps", "target_speed_mps"),
    "stalled.*": ("lane", "pos_m", "length_m", "width_m"),
    "traffic": ("vehicles_per_hour", "seed", "speed_mps", "lanes", "speed_factor_dev"),
}


class _Collector:
    def __init__(self) -> None:
        self.issues: list[CatalogIssue] = []

    def add(self, key: str, expected: str, got: Any = _MISSING, scenario: str | None = None,
            note: str = "") -> None:
        self.issues.append(CatalogIssue(key, expected, got, scenario, note))


class _ControllerChecker:
    """Checks controller names and options; caches per distinct (name, options)."""

    def __init__(self, known: Iterable[str] | None) -> None:
        self.explicit = known is not None
        self._cache: dict[str, tuple[str, str, Any] | None] = {}
        self.registry_error: str | None = None
        if known is not None:
            self.known: list[str] = sorted(set(known))
        else:
            try:
                from controllers import registry
                self.known = list(registry.names())
            except Exception as exc:  # registry or builtins broken
                self.known = []
                self.registry_error = f"{type(exc).__name__}: {exc}"

    def check(self, name: str, options: dict[str, Any]) -> tuple[str, str, Any] | None:
        """None if fine, else (sub-key, expected, got)."""
        if name not in self.known:
            return "name", f"a registered controller, one of {self.known}", name
        cache_key = json.dumps([name, options], sort_keys=True, default=repr)
        if cache_key in self._cache:
            return self._cache[cache_key]
        result = self._build(name, options)
        self._cache[cache_key] = result
        return result

    def _build(self, name: str, options: dict[str, Any]) -> tuple[str, str, Any] | None:
        try:
            from controllers import registry
            from controllers.protocol import ConfigError
        except Exception:
            return None  # only reachable with explicit known_controllers
        if self.explicit:
            try:
                available = registry.names()
            except Exception:
                return None  # registry unavailable: explicit known_controllers only
            if name not in available:
                return None
        try:
            registry.make(name, copy.deepcopy(options))
        except ConfigError as exc:
            key = exc.key
            if key == "controller":
                key = ""
            elif key.startswith("controller."):
                key = key[len("controller."):]
            return key, exc.expected, exc.got
        except Exception as exc:
            return "name", f"a controller that can be built ({type(exc).__name__}: {exc})", name
        return None


def _type_name(value: Any) -> str:
    return type(value).__name__


def _flatten_sweep(table: Mapping[str, Any], prefix: str = "") -> list[tuple[str, Any]]:
    out: list[tuple[str, Any]] = []
    for k, v in table.items():
        key = f"{prefix}.{k}" if prefix else str(k)
        if isinstance(v, Mapping):
            out.extend(_flatten_sweep(v, key))
        else:
            out.append((key, v))
    return out


def _path_target(root: Any, path: str) -> tuple[bool, str]:
    """(ok, problem) for a dotted sweep path in a merged scenario dict."""
    comps = path.split(".")
    if not path or any(c == "" for c in comps):
        return False, "a dotted path such as \"stalled.0.pos_m\""
    if comps[0] in ("name", "sweep"):
        return False, "a path not under 'name' or 'sweep'"
    node = root
    for depth, comp in enumerate(comps):
        last = depth == len(comps) - 1
        parent = ".".join(comps[:depth])
        if isinstance(node, list):
            if not comp.isdigit() or int(comp) >= len(node):
                return False, (f"a list index in 0..{len(node) - 1} at {parent!r}" if node
                               else f"an existing list item ({parent!r} is empty)")
            node = node[int(comp)]
        elif isinstance(node, Mapping):
            if comp in node:
                node = node[comp]
                continue
            if last and _optional_subkey_ok(comps, root):
                return True, ""
            if depth >= 1 and comps[0] == "controller":
                return True, ""  # a nested controller option: the controller checks it
            return False, f"a path to an existing value ({path!r} does not exist after merging)"
        else:
            return False, f"a path into a table or list ({parent!r} is a {_type_name(node)})"
    return True, ""


def _optional_subkey_ok(comps: list[str], root: Mapping[str, Any]) -> bool:
    if len(comps) == 1:
        return comps[0] in _DEFAULT_KEYS
    if len(comps) == 2 and comps[0] in _OPTIONAL_SUBKEYS:
        return comps[1] in _OPTIONAL_SUBKEYS[comps[0]]
    if len(comps) == 3 and comps[0] == "stalled":
        return comps[2] in _OPTIONAL_SUBKEYS["stalled.*"]
    if len(comps) == 2 and comps[0] in ("criteria", "controller") and isinstance(
            root.get(comps[0]), Mapping):
        return True
    return False


def _set_path(root: dict[str, Any], path: str, value: Any) -> None:
    comps = path.split(".")
    node: Any = root
    for comp in comps[:-1]:
        if isinstance(node, dict) and comp not in node:
            node[comp] = {}  # a nested controller option table the scenario left out
        node = node[int(comp)] if isinstance(node, list) else node[comp]
    last = comps[-1]
    if isinstance(node, list):
        node[int(last)] = copy.deepcopy(value)
    else:
        node[last] = copy.deepcopy(value)


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
            "catalog", f"valid TOML ({exc})", _MISSING)]) from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise CatalogError(cat_path, [CatalogIssue(
            "catalog", f"a readable UTF-8 TOML file ({exc})", _MISSING)]) from exc
    return _Loader(cat_path, doc, known_controllers).run()


class _Loader:
    def __init__(self, path: Path, doc: dict[str, Any], known: Iterable[str] | None) -> None:
        self.path = path
        self.doc = doc
        self.err = _Collector()
        self.controllers = _ControllerChecker(known)
        self.bundled = bundled_nets()

    # ------------------------------------------------------------------ top level
    def run(self) -> Catalog:
        for key in self.doc:
            if key not in ("defaults", "scenario"):
                self.err.add(key, "only the top-level keys 'defaults' and 'scenario'",
                             self.doc[key] if not isinstance(self.doc[key], dict) else key)
        if self.controllers.registry_error and not self.controllers.explicit:
            self.err.add("controller", "an importable controller registry "
                         f"({self.controllers.registry_error})")
        defaults = self.doc.get("defaults", {})
        if not isinstance(defaults, dict):
            self.err.add("defaults", "a table [defaults]", defaults)
            defaults = {}
        for key in defaults:
            if key not in _DEFAULT_KEYS:
                expected = (f"a key allowed in [defaults], one of {list(_DEFAULT_KEYS)}"
                            if key not in ("name", "sweep")
                            else "no 'name' or 'sweep' in [defaults] (they are per scenario)")
                self.err.add(f"defaults.{key}", expected, key)
        defaults = {k: v for k, v in defaults.items() if k in _DEFAULT_KEYS}

        raw = self.doc.get("scenario", [])
        if not isinstance(raw, list):
            self.err.add("scenario", "an array of tables [[scenario]]", _type_name(raw))
            raw = []
        if not raw and isinstance(self.doc.get("scenario", []), list):
            self.err.add("scenario", "at least one [[scenario]] table")

        scenarios: list[Scenario] = []
        origin: dict[str, str] = {}
        for index, entry in enumerate(raw):
            for name, where, sc in self._scenario(index, entry, defaults):
                if name in origin:
                    self.err.add(f"{where}.name", f"a unique scenario name ({name!r} is "
                                 f"also produced by {origin[name]})", name, name)
                    continue
                origin[name] = where
                if sc is not None:
                    scenarios.append(sc)
        if self.err.issues:
            raise CatalogError(self.path, _dedupe(self.err.issues))
        return Catalog(self.path, tuple(scenarios))

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
        for key in entry:
            if key not in _SCENARIO_KEYS:
                self.err.add(f"{where}.{key}", f"a known scenario key, one of "
                             f"{list(_SCENARIO_KEYS)}", key, label)
        merged: dict[str, Any] = copy.deepcopy(defaults)
        for key, value in entry.items():
            if key not in _SCENARIO_KEYS or key == "sweep":
                continue
            if key == "criteria" and isinstance(value, dict) and isinstance(
                    merged.get("criteria"), dict):
                merged["criteria"] = {**merged["criteria"], **copy.deepcopy(value)}
            else:
                merged[key] = copy.deepcopy(value)
        for key in _REQUIRED_KEYS:
            if key not in merged:
                self.err.add(f"{where}.{key}", "this required key (in the scenario or "
                             "[defaults])" if key not in ("name",) else "a scenario name",
                             scenario=label)
        name_ok = "name" in merged and _name(merged["name"]) is None
        if "name" in merged and not name_ok:
            self.err.add(f"{where}.name", _name(merged["name"]) or "", merged["name"], label)
        # An invalid or missing name is reported; the rest is still checked under a label.
        base = merged["name"] if name_ok else (label or where)

        # ---- sweep
        sweep_raw = entry.get("sweep")
        combos: list[tuple[dict[str, Any], str, dict[str, Any]]] = []
        if sweep_raw is None:
            combos.append((merged, base, {}))
        elif not isinstance(sweep_raw, dict) or not sweep_raw:
            self.err.add(f"{where}.sweep", "a non-empty table of dotted path -> list of "
                         "values", sweep_raw, base)
            combos.append((merged, base, {}))  # still check the unswept scenario
        else:
            items = _flatten_sweep(sweep_raw)
            ok = True
            for key, values in items:
                target_ok, problem = _path_target(merged, key)
                if not target_ok:
                    self.err.add(f"{where}.sweep.{json.dumps(key)}", problem, key, base)
                    ok = False
                if not isinstance(values, list) or not values:
                    self.err.add(f"{where}.sweep.{json.dumps(key)}",
                                 "a non-empty list of values", values, base)
                    ok = False
            keys = [k for k, _ in items]
            shorts = sweep_shorts(keys)
            value_lists = [list(enumerate(v)) if isinstance(v, list) else [] for _, v in items]
            if not ok:
                value_lists = []
                combos.append((merged, base, {}))  # still check the unswept scenario
            for combo in itertools.product(*value_lists) if value_lists else ():
                variant = copy.deepcopy(merged)
                for key, (_, value) in zip(keys, combo, strict=True):
                    _set_path(variant, key, value)
                vname = sweep_name(base, shorts, [v for _, v in combo], [p for p, _ in combo])
                variant["name"] = vname
                combos.append((variant, vname, {k: v for k, (_, v) in zip(keys, combo,
                                                                             strict=True)}))
        out: list[tuple[str, str, Scenario | None]] = []
        for variant, vname, swept in combos:
            sc = self._build(index, variant, base, vname, swept, set(entry))
            out.append((vname, where, sc if name_ok else None))
        return out

    # ------------------------------------------------------------------ build + validate
    def _build(self, index: int, d: dict[str, Any], family: str, name: str,
               swept: dict[str, Any], own_keys: set[str]) -> Scenario | None:
        where = f"scenario[{index}]"
        n_before = len(self.err.issues)

        def add(key: str, expected: str, got: Any = _MISSING) -> None:
            full = f"{where}.{key}" if key else where
            from_sweep = [sk for sk in swept if key == sk or key.startswith(sk + ".")]
            if from_sweep:
                note = f"value from {where}.sweep.{json.dumps(from_sweep[0])}"
                self.err.add(full, expected, got, name, note)
            elif swept:  # not caused by the sweep: reported once per family (_dedupe)
                self.err.add(full, expected, got, family, "all sweep variants")
            else:
                top = key.split(".", 1)[0]
                note = "value from [defaults]" if top and top not in own_keys else ""
                self.err.add(full, expected, got, name, note)

        # simple scalars
        scalars: dict[str, Any] = {}
        for key, default in (("duration_s", _MISSING), ("step_s", _MISSING), ("seed", 0),
                             ("allow_shoulder", False), ("record_radius_m", 150.0),
                             ("timeout_s", None)):
            value = d.get(key, default)
            if value is _MISSING:
                continue  # reported as missing already
            problem = Scenario._RULES[key](value)
            if problem:
                add(key, problem, value)
            else:
                scalars[key] = value
        if ("duration_s" in scalars and "step_s" in scalars
                and scalars["step_s"] > scalars["duration_s"]):
            add("step_s", f"a step <= duration_s ({scalars['duration_s']:g})", scalars["step_s"])
        criteria = d.get("criteria", {})
        if not isinstance(criteria, dict):
            add("criteria", "a table of name -> finite number", criteria)
            criteria = {}
        else:
            from reports.metrics.criteria import Criteria

            valid = Criteria.names()
            for k, v in criteria.items():
                if k not in valid:
                    add(f"criteria.{k}", f"a known criterion, one of {', '.join(valid)}", k)
                elif not _is_number(v):
                    add(f"criteria.{k}", "a finite number", v)

        controller = self._controller(d.get("controller", _MISSING), add)
        net_path, network = self._net(d.get("net", _MISSING), add)
        route = self._route(d.get("route", _MISSING), network, add)

        ego = self._spec(EgoSpec, d.get("ego", _MISSING), "ego", add, required=True)
        stalled_raw = d.get("stalled", [])
        stalled: list[StalledSpec | None] = []
        if not isinstance(stalled_raw, list):
            add("stalled", "a list of tables [{lane = ..., pos_m = ...}, ...]", stalled_raw)
        else:
            for i, item in enumerate(stalled_raw):
                stalled.append(self._spec(StalledSpec, item, f"stalled.{i}", add, required=True))
        traffic_raw = d.get("traffic", _MISSING)
        traffic = None
        if traffic_raw is not _MISSING:
            if isinstance(traffic_raw, dict) and "seed" not in traffic_raw:
                traffic_raw = {**traffic_raw, "seed": scalars.get("seed", 0)}
            traffic = self._spec(TrafficSpec, traffic_raw, "traffic", add, required=True)

        # ---- against the network
        if network is not None and route is not None:
            length = network.route_length_m(route)
            allow_shoulder = bool(scalars.get("allow_shoulder", False))
            ego_lp = _lane_pos(d.get("ego"))
            if ego_lp is not None:
                lane, pos = ego_lp
                lanes = self._place(network, route, length, pos, lane, "ego", add)
                if lanes is not None:
                    shoulder, passenger = self._lane_props(network, route, pos, lane)
                    if shoulder and not allow_shoulder:
                        add("ego.lane", "a lane open to passenger cars (this lane is a hard "
                            "shoulder; set allow_shoulder = true to start on it)", lane)
                    elif not shoulder and not passenger:
                        add("ego.lane", "a lane open to passenger cars", lane)
            for i, item in enumerate(stalled_raw if isinstance(stalled_raw, list) else []):
                st_lp = _lane_pos(item)
                if st_lp is not None:
                    self._place(network, route, length, st_lp[1], st_lp[0], f"stalled.{i}",
                                add)
            if traffic is not None and traffic.lanes is not None:
                first = route[0]
                count = network.lane_count(first)
                for j, lane in enumerate(traffic.lanes):
                    if lane >= count:
                        add(f"traffic.lanes.{j}", f"a lane index in 0..{count - 1} (lanes of "
                            f"the first route edge {first!r})", lane)
                    elif not self._lane_allows_passenger(network, first, lane):
                        add(f"traffic.lanes.{j}", "a lane open to passenger cars (lane "
                            f"{lane} of {first!r} is not)", lane)

        if len(self.err.issues) != n_before:
            return None
        if (ego is None or controller is None or net_path is None or route is None
                or "duration_s" not in scalars or "step_s" not in scalars):
            return None  # a required key is missing (reported by _scenario)
        try:
            return Scenario(
                name=name, family=family, catalog_path=self.path, net=d["net"],
                net_path=net_path, route=route, ego=ego,
                stalled=tuple(s for s in stalled if s is not None), traffic=traffic,
                controller=controller, duration_s=scalars["duration_s"],
                step_s=scalars["step_s"], seed=scalars["seed"],
                allow_shoulder=scalars["allow_shoulder"], criteria=criteria,
                sweep_values=swept, record_radius_m=scalars["record_radius_m"],
                timeout_s=scalars["timeout_s"])
        except SpecError as exc:  # pragma: no cover - the checks above mirror these
            add(exc.field, exc.expected, exc.got)
            return None

    def _spec(self, cls: Any, raw: Any, key: str, add: Callable[..., None], *,
              required: bool) -> Any:
        if raw is _MISSING:
            return None  # a missing required table is reported by the required-key check
        if not isinstance(raw, dict):
            add(key, f"a table with keys {list(cls._RULES)}", raw)
            return None
        ok = True
        for k, v in raw.items():
            if k not in cls._RULES:
                add(f"{key}.{k}", f"one of the keys {list(cls._RULES)}", k)
                ok = False
            else:
                problem = cls._RULES[k](v)
                if problem:
                    add(f"{key}.{k}", problem, v)
                    ok = False
        for k in cls._REQUIRED:
            if k not in raw:
                add(f"{key}.{k}", "this required key")
                ok = False
        if not ok:
            return None
        try:
            return cls(**raw)
        except SpecError as exc:
            add(f"{key}.{exc.field}", exc.expected, exc.got)
            return None

    def _controller(self, raw: Any, add: Callable[..., None]) -> ControllerSpec | None:
        if raw is _MISSING:
            return None
        if isinstance(raw, str):
            name, options = raw, {}
        elif isinstance(raw, dict):
            if "name" not in raw:
                add("controller.name", "a controller name in the controller table")
                return None
            name = raw["name"]
            options = {k: v for k, v in raw.items() if k != "name"}
        else:
            add("controller", "a controller name or a table {name = ..., <options>}", raw)
            return None
        if not isinstance(name, str) or _name(name):
            add("controller.name", "a controller name matching [a-z0-9_]+", name)
            return None
        bad = _non_json_path(options)
        if bad is not None:
            add(f"controller.{bad[0]}", "a JSON-able value (string, number, bool, list, "
                "table)", bad[1])
            return None
        if not self.controllers.known and self.controllers.registry_error:
            return ControllerSpec(name, options)  # registry problem reported once
        problem = self.controllers.check(name, options)
        if problem is not None:
            sub, expected, got = problem
            add(f"controller.{sub}" if sub else "controller", expected, got)
            return None
        return ControllerSpec(name, options)

    def _net(self, raw: Any, add: Callable[..., None]
             ) -> tuple[Path | None, RoadNetwork | None]:
        if raw is _MISSING:
            return None, None
        if not isinstance(raw, str) or not raw:
            add("net", "a bundled net name or a .net.xml path", raw)
            return None, None
        path: Path | None = None
        if raw in self.bundled:
            path = _bundled_net_path(raw)
        if path is None:
            candidate = Path(raw).expanduser()
            if not candidate.is_absolute():
                candidate = self.path.parent / candidate
            if candidate.is_file():
                path = candidate.resolve()
        if path is None:
            add("net", f"a bundled net (one of {self.bundled}) or an existing .net.xml file "
                f"(relative to {self.path.parent})", raw)
            return None, None
        try:
            return path, RoadNetwork.load(path)
        except RoadNetworkError as exc:
            add("net", f"a readable SUMO network ({exc})", raw)
            return path, None

    def _route(self, raw: Any, network: RoadNetwork | None, add: Callable[..., None]
               ) -> tuple[str, ...] | None:
        if raw is _MISSING:
            return network.default_route() if network is not None else None
        if (not isinstance(raw, list) or not raw
                or any(not isinstance(e, str) for e in raw)):
            add("route", "a non-empty list of edge ids (strings)", raw)
            return None
        if network is None:
            return None
        ok = True
        for i, eid in enumerate(raw):
            if not network.has_edge(eid):
                edges = network.edge_ids()
                shown = edges if len(edges) <= 20 else [*edges[:20], "..."]
                add(f"route.{i}", f"an edge of {network.path.name} (one of {shown})", eid)
                ok = False
        if not ok:
            return None
        try:
            network.validate_route(raw)
        except ValueError as exc:
            m = re.match(r"route\[(\d+)\]: (.*)", str(exc))
            sub = f"route.{m.group(1)}" if m else "route"
            add(sub, f"an edge connected from the previous route edge ({m.group(2) if m else exc})",
                raw[int(m.group(1))] if m else raw)
            return None
        return tuple(raw)

    @staticmethod
    def _place(network: RoadNetwork, route: tuple[str, ...], length: float, pos: float,
               lane: int, key: str, add: Callable[..., None]) -> int | None:
        if not 0.0 <= pos < length:
            add(f"{key}.pos_m", f"a route position in [0, {length:.1f}) m", pos)
            return None
        lanes = network.lanes_at(route, pos)
        if lane >= lanes:
            edge, _ = network.locate(route, pos)
            add(f"{key}.lane", f"a lane index in 0..{lanes - 1} (edge {edge!r} at "
                f"{pos:g} m on the route has {lanes} lanes)", lane)
            return None
        return lanes

    @staticmethod
    def _lane_props(network: RoadNetwork, route: tuple[str, ...], pos: float, lane: int
                    ) -> tuple[bool, bool]:
        edge, _ = network.locate(route, pos)
        for info in network.lane_info((edge,)):
            if info.index == lane:
                return info.is_shoulder, info.allows_passenger
        return False, True  # pragma: no cover

    @staticmethod
    def _lane_allows_passenger(network: RoadNetwork, edge: str, lane: int) -> bool:
        return any(i.allows_passenger for i in network.lane_info((edge,)) if i.index == lane)


def _lane_pos(raw: Any) -> tuple[int, float] | None:
    """(lane, pos_m) of a raw ego/stalled table if both are individually valid."""
    if not isinstance(raw, dict) or "lane" not in raw or "pos_m" not in raw:
        return None
    if _int(0)(raw["lane"]) or _num(0.0)(raw["pos_m"]):
        return None
    return int(raw["lane"]), float(raw["pos_m"])


def _dedupe(issues: Sequence[CatalogIssue]) -> list[CatalogIssue]:
    seen: set[str] = set()
    out = []
    for issue in issues:
        key = json.dumps([issue.key, issue.expected, repr(issue.got), issue.scenario,
                          issue.note])
        if key not in seen:
            seen.add(key)
            out.append(issue)
    return out


# ============================================================================ filtering
def expand_filter(scenarios: Iterable[Scenario], glob: str | None) -> tuple[Scenario, ...]:
    """Scenarios whose name or family matches ``glob`` (fnmatch, case-sensitive; several
    patterns may be comma-separated). ``None``/``""``/``"*"`` keep everything."""
    items = tuple(scenarios)
    if not glob or glob.strip() == "*":
        return items
    patterns = [p.strip() for p in glob.split(",") if p.strip()]
    return tuple(s for s in items
                 if any(fnmatch.fnmatchcase(s.name, p) or fnmatch.fnmatchcase(s.family, p)
                        for p in patterns))

