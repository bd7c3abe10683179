"""Controller registry: name -> factory(options) -> Controller. Refuses duplicate names.

A factory must be cheap (no compilation, no solver set-up) and must validate the
options, raising :class:`controllers.protocol.ConfigError` naming the bad key, so
that the catalog can check a whole catalog before running anything.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from controllers.protocol import ConfigError, Controller

ControllerFactory = Callable[[Mapping[str, Any]], Controller]

_REGISTRY: dict[str, ControllerFactory] = {}


def register(name: str, factory: ControllerFactory) -> None:
    """Add a controller; a name may be registered once only."""
    if not name or not name.replace("_", "").isalnum() or name.lower() != name:
        raise ValueError(f"controller name must match [a-z0-9_]+, got {name!r}")
    if name in _REGISTRY:
        raise ValueError(f"controller {name!r} is already registered")
    _REGISTRY[name] = factory


def _load_builtins() -> None:
    # Importing registers; kept lazy so that `controllers` imports stay light.
    import controllers.builtin  # noqa: F401


def names() -> list[str]:
    _load_builtins()
    return sorted(_REGISTRY)


def make(name: str, options: Mapping[str, Any] | None = None) -> Controller:
    """Build controller ``name`` with ``options`` (validated by its factory)."""
    _load_builtins()
    if name not in _REGISTRY:
        raise ConfigError("controller.name", f"one of {sorted(_REGISTRY)}", name)
    return _REGISTRY[name](dict(options or {}))


def check_options(options: Mapping[str, Any],
                  allowed: Mapping[str, type | tuple[type, ...]]) -> None:
    """Raise ConfigError for an unknown key or a value of the wrong type."""
    for key, value in options.items():
        if key not in allowed:
            raise ConfigError(f"controller.{key}", f"one of the keys {sorted(allowed)}", key)
        kind = allowed[key]
        if isinstance(value, bool) and kind in (int, float, (int, float)):
            raise ConfigError(f"controller.{key}", "a number", value)
        if not isinstance(value, kind):
            raise ConfigError(f"controller.{key}", f"a value of type {kind}", value)
