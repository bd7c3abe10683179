"""TOML scenario catalogs (see :mod:`suite.catalog.loader` for the format)."""

from suite.catalog.loader import (
    Catalog,
    CatalogError,
    CatalogIssue,
    ControllerSpec,
    EgoSpec,
    FrozenMap,
    Scenario,
    SpecError,
    StalledSpec,
    TrafficSpec,
    bundled_nets,
    expand_filter,
    format_sweep_value,
    load_catalog,
    sweep_name,
    sweep_shorts,
)

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
