"""The resolved, validated values a catalog yields: the specs of one scenario run
(:class:`EgoSpec`, :class:`StalledSpec`, :class:`ActorSpec` with its
:class:`ActorEventSpec`, :class:`TrafficSpec`, :class:`RampTrafficSpec`,
:class:`ReplaySpec`, :class:`ControllerSpec`),
the :class:`Scenario` itself and the :class:`Catalog` of them.

Each spec checks its own fields on construction (``_RULES``) and raises
:class:`~suite.catalog.errors.SpecError`; the loader checks raw values with the same rules
first, so that a catalog reports all of its problems.
"""

from __future__ import annotations

import copy
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

from suite.catalog import rules
from suite.catalog.actors import ActorEventSpec, ActorSpec, ActorWhenSpec
from suite.catalog.errors import SpecError
from suite.catalog.frozen import FrozenMap, thaw, thaw_map
from suite.catalog.replay_spec import REPLAY_LANE_CHANGES, REPLAY_MODES, ReplaySpec
from suite.catalog.rules import Rule
from suite.catalog.storyboard import Storyboard
from suite.catalog.vehicle_specs import (
    MAX_EGO_HEADING_RAD,
    MAX_EGO_LATERAL_OFFSET_M,
    EgoSpec,
    RampTrafficSpec,
    StalledSpec,
    TrafficSpec,
    _plain_dataclass,
)

__all__ = ["ActorEventSpec", "ActorSpec", "ActorWhenSpec", "CRITERION_OFF", "Catalog",
           "ControllerSpec", "DEFAULT_SUMO_STEP_S", "EgoSpec", "MAX_EGO_HEADING_RAD",
           "MAX_EGO_LATERAL_OFFSET_M", "REPLAY_LANE_CHANGES", "REPLAY_MODES", "RampTrafficSpec",
           "ReplaySpec", "Scenario", "StalledSpec", "TrafficSpec", "XfailSpec",
           "default_sumo_step", "openscenario_problem", "sumo_step_problem"]





DEFAULT_SUMO_STEP_S = 0.1  # SUMO's own step by default: the field's usual 10 Hz


def _ticks(t_s: float) -> int:
    """``t_s`` in SUMO's milliseconds (the catalog's steps are whole milliseconds)."""
    return int(round(t_s / rules.SUMO_TICK_S))


def default_sumo_step(step_s: float) -> float:
    """SUMO's step [s] when the catalog sets none: the largest whole multiple of ``step_s``
    [s] that is at most 0.1 s (``step_s`` itself when that is longer), in whole ms."""
    ticks = max(_ticks(step_s), 1)
    return max(_ticks(DEFAULT_SUMO_STEP_S) // ticks, 1) * ticks * rules.SUMO_TICK_S


def sumo_step_problem(sumo_step_s: Any, step_s: float) -> str | None:
    """Why ``sumo_step_s`` is no SUMO step for control period ``step_s`` (None: it is):
    a whole number of ms and a whole multiple (>= 1) of ``step_s``."""
    problem = rules.sumo_step(sumo_step_s)
    if problem:
        return problem
    ticks, base = _ticks(float(sumo_step_s)), max(_ticks(step_s), 1)
    if ticks < base or ticks % base:
        return f"a whole multiple (1, 2, ...) of step_s = {step_s:g} s"
    return None


def _optional_sumo_step(v: Any) -> str | None:
    return None if v is None else rules.sumo_step(v)


@dataclass(frozen=True)
class ControllerSpec:
    """A registered controller and its (immutable, JSON-able) options."""

    name: str
    options: Mapping[str, Any] = field(default_factory=lambda: FrozenMap())

    def __post_init__(self) -> None:
        if rules.name_rule(self.name):
            raise SpecError("name", "a controller name matching [a-z0-9_]+", self.name)
        if not isinstance(self.options, Mapping):
            raise SpecError("options", "a table of options", self.options)
        bad = rules.non_json_path(self.options)
        if bad is not None:
            raise SpecError(bad[0] or "options", "a JSON-able value (string, number, bool, "
                            "list, table)", bad[1])
        if not isinstance(self.options, FrozenMap):
            object.__setattr__(self, "options", FrozenMap(copy.deepcopy(dict(self.options))))

    def options_dict(self) -> dict[str, Any]:
        """A deep, mutable copy of the options (what the factory gets)."""
        return thaw_map(self.options)

    def as_dict(self) -> dict[str, Any]:
        return {"name": self.name, "options": self.options_dict()}


# ---------------------------------------------------------------- known failures (xfail)


def _reason(v: Any) -> str | None:
    return None if isinstance(v, str) and v.strip() else "a non-empty string: why it fails"


@dataclass(frozen=True)
class XfailSpec:
    """A known failure (pytest's ``xfail``; :mod:`reports.expectation`): the scenario is
    expected to fail its criteria, for ``reason``; with ``strict`` an unexpected pass
    fails the night. It is no part of the test: it changes what a result means, not the
    run."""

    reason: str
    strict: bool = False

    _RULES: ClassVar[dict[str, Rule]] = {"reason": _reason, "strict": rules.boolean}
    _REQUIRED: ClassVar[tuple[str, ...]] = ("reason",)

    def __post_init__(self) -> None:
        rules.check_fields(self)


# ---------------------------------------------------------------- labels

MAX_LABEL_LEN = 200  # characters of a label's value


def labels_problem(v: Any) -> str | None:
    """None when ``v`` is a table of label name ([a-z0-9_]+) -> non-empty string of at
    most :data:`MAX_LABEL_LEN` characters, else what was expected."""
    what = (f"a table of name ([a-z0-9_]+) -> non-empty string of at most {MAX_LABEL_LEN} "
            "characters")
    if not isinstance(v, Mapping):
        return what
    for k, x in v.items():
        if not isinstance(k, str) or rules.name_rule(k) is not None:
            return what
        if not isinstance(x, str) or not x.strip() or len(x) > MAX_LABEL_LEN:
            return what
    return None


OPENSCENARIO_KEYS = ("template", "parameters", "value_sets", "ego", "ignore_constraints")


def _parameter_table(v: Any) -> bool:
    return isinstance(v, Mapping) and all(
        isinstance(k, str) and k and (isinstance(x, str | bool) or rules.is_number(x))
        for k, x in v.items())


def openscenario_problem(v: Any) -> tuple[str, str, Any] | None:
    """None when ``v`` is an ``openscenario`` table (the template and parameter values a
    scenario was imported from: docs/catalog.md), else (the key at fault, what was
    expected, what was found)."""
    if not isinstance(v, Mapping):
        return "openscenario", ("a table { template = \"....xosc\", parameters = { Name = "
                                "value, ... } }"), v
    unknown = [k for k in v if k not in OPENSCENARIO_KEYS]
    if unknown:
        return f"openscenario.{unknown[0]}", f"only the keys {list(OPENSCENARIO_KEYS)}", \
            unknown[0]
    template = v.get("template")
    if not isinstance(template, str) or not template.strip():
        return "openscenario.template", ("an OpenSCENARIO file path (relative to the "
                                         "catalog, or absolute)"), template
    return _openscenario_values_problem(v)


def _openscenario_values_problem(v: Mapping[str, Any]) -> tuple[str, str, Any] | None:
    """:func:`openscenario_problem` of the keys besides the template: the parameter
    values, the value sets, the ego's name, ``ignore_constraints``."""
    what = "a table of parameter name -> string, finite number or bool"
    if not _parameter_table(v.get("parameters", {})):
        return "openscenario.parameters", what, v.get("parameters")
    sets = v.get("value_sets", [])
    if not isinstance(sets, list) or not all(_parameter_table(s) for s in sets):
        return "openscenario.value_sets", f"a list of tables, each {what}", sets
    if not isinstance(v.get("ego", ""), str):
        return "openscenario.ego", "the ego entity's name", v.get("ego")
    if not isinstance(v.get("ignore_constraints", False), bool):
        return "openscenario.ignore_constraints", "true or false", v.get("ignore_constraints")
    return None


# ---------------------------------------------------------------- criteria

CRITERION_OFF = "off"  # reports.metrics.criteria.OFF: switches a criterion off


def _criteria_map(v: Any) -> str | None:
    """A table of criterion name -> finite number or "off"."""
    what = 'a table of name -> finite number or "off"'
    if not isinstance(v, Mapping):
        return what
    if any(not isinstance(k, str) or not (rules.is_number(x) or x == CRITERION_OFF)
           for k, x in v.items()):
        return what
    return None


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
    criteria: Mapping[str, float | str] = field(default_factory=lambda: FrozenMap())
    sweep_values: Mapping[str, Any] = field(default_factory=lambda: FrozenMap())
    record_radius_m: float = 150.0
    timeout_s: float | None = None
    friction: float = 1.0
    ramp_traffic: tuple[RampTrafficSpec, ...] = ()
    actors: tuple[ActorSpec, ...] = ()
    sumo_step_s: float | None = None  # SUMO's step [s]; None: default_sumo_step(step_s)
    replay: ReplaySpec | None = None  # recorded traffic (suite.world.replay); None: none
    xfail: XfailSpec | None = None  # a known failure; None: expected to pass
    # an OpenSCENARIO storyboard (suite.catalog.storyboard, docs/openscenario.md): the
    # file as the catalog names it and its resolved content; None: none
    storyboard: str | None = None
    story: Storyboard | None = None
    # names of the groups the scenario belongs to (e.g. r157_section = "4.4"): read by
    # the reports to group runs, no part of the test (reports.identity.NOT_TEST_FIELDS)
    labels: Mapping[str, str] = field(default_factory=lambda: FrozenMap())

    _RULES: ClassVar[dict[str, Rule]] = {
        "name": rules.name_rule, "family": rules.name_rule,
        "duration_s": rules.num(0.0, strict=True), "step_s": rules.sumo_step,
        "seed": rules.integer(0, rules.MAX_SEED), "allow_shoulder": rules.boolean,
        "criteria": _criteria_map, "record_radius_m": rules.num(0.0, strict=True),
        "timeout_s": rules.num(0.0, strict=True, optional=True), "friction": rules.friction,
        "sumo_step_s": _optional_sumo_step, "labels": labels_problem,
    }

    def __post_init__(self) -> None:
        rules.check_fields(self)
        if self.step_s > self.duration_s:
            raise SpecError("step_s", f"a step <= duration_s ({self.duration_s})", self.step_s)
        self._resolve_sumo_step()
        self._check_spec_types()
        _check_story(self.storyboard, self.story)
        stalled = _tuple_of(self.stalled, StalledSpec, "stalled", "a sequence of StalledSpec")
        object.__setattr__(self, "ramp_traffic", _tuple_of(
            self.ramp_traffic, RampTrafficSpec, "ramp_traffic",
            "a sequence of RampTrafficSpec"))
        actors = _tuple_of(self.actors, ActorSpec, "actors", "a sequence of ActorSpec")
        ids = [a.id for a in actors]
        if len(set(ids)) != len(ids):
            raise SpecError("actors", "actors with distinct ids", ids)
        object.__setattr__(self, "actors", actors)
        route = tuple(self.route)
        if not route or any(not isinstance(e, str) for e in route):
            raise SpecError("route", "a non-empty sequence of edge ids", self.route)
        object.__setattr__(self, "stalled", stalled)
        object.__setattr__(self, "route", route)
        self._normalise()

    def _resolve_sumo_step(self) -> None:
        """SUMO's step: the default for ``step_s`` when not given, checked, a float."""
        if self.sumo_step_s is None:
            object.__setattr__(self, "sumo_step_s", default_sumo_step(float(self.step_s)))
        problem = sumo_step_problem(self.sumo_step_s, float(self.step_s))
        if problem:
            raise SpecError("sumo_step_s", problem, self.sumo_step_s)
        object.__setattr__(self, "sumo_step_s", float(self.sumo_step_s))  # type: ignore[arg-type]

    def _check_spec_types(self) -> None:
        """The nested specs are specs (the optional ones None or a spec)."""
        if not isinstance(self.ego, EgoSpec):
            raise SpecError("ego", "an EgoSpec", self.ego)
        if not isinstance(self.controller, ControllerSpec):
            raise SpecError("controller", "a ControllerSpec", self.controller)
        for name, kind, what in (("traffic", TrafficSpec, "a TrafficSpec or None"),
                                 ("replay", ReplaySpec, "a ReplaySpec or None"),
                                 ("xfail", XfailSpec, "an XfailSpec or None")):
            value = getattr(self, name)
            if value is not None and not isinstance(value, kind):
                raise SpecError(name, what, value)

    def _normalise(self) -> None:
        """Paths, frozen maps and floats of the plain fields."""
        object.__setattr__(self, "catalog_path", Path(self.catalog_path))
        object.__setattr__(self, "net_path", Path(self.net_path))
        object.__setattr__(self, "criteria", FrozenMap(
            {k: (v if v == CRITERION_OFF else float(v)) for k, v in self.criteria.items()}))
        object.__setattr__(self, "sweep_values", FrozenMap(self.sweep_values))
        object.__setattr__(self, "labels", FrozenMap(dict(self.labels)))
        rules.as_float(self, "duration_s", "step_s", "record_radius_m", "friction")
        if self.timeout_s is not None:
            rules.as_float(self, "timeout_s")

    @property
    def steps(self) -> int:
        """Number of simulation steps (``round(duration_s / step_s)``)."""
        return int(round(self.duration_s / self.step_s))

    @property
    def world_step_s(self) -> float:
        """SUMO's step [s] (``sumo_step_s``, resolved in ``__post_init__``)."""
        return float(self.sumo_step_s if self.sumo_step_s is not None else self.step_s)

    @property
    def steps_per_world_step(self) -> int:
        """Control steps per SUMO step (``sumo_step_s / step_s``, a whole number >= 1)."""
        return max(_ticks(self.world_step_s) // max(_ticks(self.step_s), 1), 1)

    def as_dict(self) -> dict[str, Any]:
        """JSON-serialisable dict of every field (``replay`` only when set, so that a
        scenario without recorded traffic keeps the dict, and the identity, it had)."""
        out = self._as_dict()
        if self.replay is not None:
            out["replay"] = self.replay.as_dict()
        if self.xfail is not None:  # likewise: an unmarked scenario keeps its identity
            out["xfail"] = _plain_dataclass(self.xfail)
        if self.story is not None:  # likewise; its content, not only its file name
            from suite.catalog.storyboard import story_to_json

            out["storyboard"] = {"file": self.storyboard,
                                 "sha256": _sha256(story_to_json(self.story))}
        if self.labels:  # likewise: an unlabelled scenario keeps its dict
            out["labels"] = thaw(self.labels)
        return out

    def _as_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "family": self.family,
            "catalog_path": str(self.catalog_path),
            "net": self.net,
            "net_path": str(self.net_path),
            "route": list(self.route),
            "ego": self.ego.as_dict(),
            "stalled": [_plain_dataclass(s) for s in self.stalled],
            "traffic": None if self.traffic is None else _plain_dataclass(self.traffic),
            "controller": self.controller.as_dict(),
            "duration_s": self.duration_s,
            "step_s": self.step_s,
            "sumo_step_s": self.sumo_step_s,
            "seed": self.seed,
            "allow_shoulder": self.allow_shoulder,
            "criteria": thaw(self.criteria),
            "sweep_values": thaw(self.sweep_values),
            "record_radius_m": self.record_radius_m,
            "timeout_s": self.timeout_s,
            "friction": self.friction,
            "ramp_traffic": [_plain_dataclass(r) for r in self.ramp_traffic],
            "actors": [a.as_dict() for a in self.actors],
        }


def _tuple_of(values: Any, kind: type, name: str, what: str) -> tuple[Any, ...]:
    """``values`` as a tuple, each a ``kind`` (else a SpecError on field ``name``)."""
    out = tuple(values)
    if any(not isinstance(v, kind) for v in out):
        raise SpecError(name, what, values)
    return out


def _check_story(storyboard: str | None, story: Storyboard | None) -> None:
    """A storyboard file name and its :class:`Storyboard`, or neither."""
    if (storyboard is None) != (story is None) or (
            story is not None and not isinstance(story, Storyboard)):
        raise SpecError("storyboard", "a storyboard file and its Storyboard, or neither",
                        storyboard)


def _sha256(text: str) -> str:
    import hashlib

    return hashlib.sha256(text.encode("utf-8")).hexdigest()




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
