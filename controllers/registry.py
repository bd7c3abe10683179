"""Controller registry: name -> factory(options) -> Controller (or SumoDriverModel).

The built-in factories come from :data:`controllers.builtin.FACTORIES` (read lazily,
so that importing ``controllers`` stays light); :func:`register` adds a plug-in. A
name is registered once only. A factory must be cheap (no compilation, no solver
set-up) and must validate the options, raising :class:`controllers.protocol.ConfigError`
naming the dotted key, so that a whole catalog is checked before anything runs.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from controllers.params import OptionDoc, describe
from controllers.protocol import ConfigError, Controller, SumoDriverModel

if TYPE_CHECKING:
    from controllers.builtin import ControllerFactory

_NAME = re.compile(r"[a-z0-9_]+")
_PLUGINS: dict[str, ControllerFactory] = {}
_PLUGIN_PARAMETERS: dict[str, type] = {}


def _builtins() -> Mapping[str, ControllerFactory]:
    from controllers.builtin import FACTORIES

    return FACTORIES


def _all() -> dict[str, ControllerFactory]:
    return {**_builtins(), **_PLUGINS}


def register(name: str, factory: ControllerFactory, parameters: type | None = None) -> None:
    """Add a plug-in controller; a name may be registered once only. ``parameters``:
    the dataclass its options build, if it has options (for :func:`options`)."""
    if not _NAME.fullmatch(name or ""):
        raise ValueError(f"controller name must match [a-z0-9_]+, got {name!r}")
    if name in _all():
        raise ValueError(f"controller {name!r} is already registered")
    _PLUGINS[name] = factory
    if parameters is not None:
        _PLUGIN_PARAMETERS[name] = parameters


def options(name: str) -> list[OptionDoc]:
    """Every option of controller ``name``: dotted path, type, default, unit, meaning
    (empty for a controller without options)."""
    from controllers.builtin import PARAMETERS

    if name not in _all():
        raise ConfigError("controller.name", f"one of {names()}", name)
    cls = {**PARAMETERS, **_PLUGIN_PARAMETERS}.get(name)
    return describe(cls) if cls is not None else []


def names() -> list[str]:
    """Every registered controller name, sorted."""
    return sorted(_all())


def make(name: str, options: Mapping[str, Any] | None = None) -> Controller | SumoDriverModel:
    """Build controller ``name`` with ``options`` (validated by its factory)."""
    factories = _all()
    if name not in factories:
        raise ConfigError("controller.name", f"one of {sorted(factories)}", name)
    return factories[name](dict(options or {}))
