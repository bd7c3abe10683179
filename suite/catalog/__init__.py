"""TOML scenario catalogs: parse, validate against the road network, expand sweeps.

The file format is a public contract, documented in docs/catalog.md: every key with its
type, unit (the name's suffix: ``_m``, ``_s``, ``_mps``) and default, sweeps,
``[scenario.search]``, ``replay``, criteria overrides and ``"off"``, the validation
rules and the exit codes (``tests/test_docs_catalog.py`` loads its examples and checks
that every key of :data:`suite.catalog.keys.SCENARIO_KEYS` is there).

:func:`load_catalog` reads a file and returns the :class:`Catalog` of frozen, validated,
sweep-expanded :class:`Scenario` s, or raises one :class:`CatalogError` listing every
problem (``.issues``: :class:`CatalogIssue`, each naming the file, the dotted key, the
scenario and what was expected).

The package, one job per module: :mod:`~suite.catalog.errors` (problems and the error),
:mod:`~suite.catalog.frozen` (immutable values), :mod:`~suite.catalog.rules` (field
rules), :mod:`~suite.catalog.specs` (the resolved scenario), :mod:`~suite.catalog.keys`
(the allowed keys), :mod:`~suite.catalog.sweep` (sweep paths and names),
:mod:`~suite.catalog.nets` (bundled nets), :mod:`~suite.catalog.loader` (reading, merging,
expanding), :mod:`~suite.catalog.build` (checking and building one scenario),
:mod:`~suite.catalog.report` (where a problem is reported),
:mod:`~suite.catalog.controller_check` (controllers),
:mod:`~suite.catalog.network_checks` (the scenario against its network),
:mod:`~suite.catalog.traffic_checks` (lane speeds and on-ramp traffic against it),
:mod:`~suite.catalog.tracks` (recorded tracks files),
:mod:`~suite.catalog.storyboard` (the typed OpenSCENARIO storyboard a scenario runs) and
:mod:`~suite.catalog.filtering` (selecting scenarios by name).
"""

from suite.catalog.errors import CatalogError, CatalogIssue, SpecError
from suite.catalog.filtering import expand_filter
from suite.catalog.frozen import FrozenMap
from suite.catalog.loader import load_catalog
from suite.catalog.nets import bundled_nets
from suite.catalog.specs import (
    ActorEventSpec,
    ActorSpec,
    ActorWhenSpec,
    Catalog,
    ControllerSpec,
    EgoSpec,
    RampTrafficSpec,
    ReplaySpec,
    Scenario,
    StalledSpec,
    TrafficSpec,
)
from suite.catalog.sweep import format_sweep_value, sweep_name, sweep_shorts

__all__ = [
    "ActorEventSpec",
    "ActorSpec",
    "ActorWhenSpec",
    "Catalog",
    "CatalogError",
    "CatalogIssue",
    "ControllerSpec",
    "EgoSpec",
    "FrozenMap",
    "RampTrafficSpec",
    "ReplaySpec",
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
