"""Controller registry: name -> factory(options) -> Controller (or SumoDriverModel, or
RecordedDriverModel: the ego driven by SUMO's driver or by its recording).

The built-in factories come from :data:`controllers.builtin.FACTORIES` (read lazily,
so that importing ``controllers`` stays light); :func:`register` adds a plug-in. A
name is registered once only. A factory must be cheap (no compilation, no solver
set-up) and must validate the options, raising :class:`controllers.protocol.ConfigError`
naming the dotted key, so that a whole catalog is checked before anything runs.

Plug-ins (docs/plugins.md) come two ways:

* **Entry points** of the group :data:`ENTRY_POINT_GROUP` (``hwyeval.controllers``) of
  every installed distribution, loaded on the first look-up: the entry point's name
  is the controller name, its object a :class:`ControllerPlugin` (factory and
  parameter class) or a bare factory. Every process that looks a name up loads them
  itself (scenario processes, Ray workers): the distribution must be installed there.
* **Modules** (:func:`load_plugin`, ``--plugin MODULE``): an importable module name,
  or the path of a ``.py`` file, imported once; the module calls :func:`register`.
  :func:`plugin_module` captures a file's source in a :class:`PluginModule` so that a
  job can carry it to a process (a forked scenario process, a Ray worker on another
  machine) which imports it again with :func:`load_plugin_modules` before it builds
  the controller.

A plug-in that fails to load does not break the built-ins: its error is kept
(:func:`plugin_errors`) and a catalog naming it gets that error.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import re
import sys
import types
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

from controllers.baselines.recorded_driver import RecordedDriverModel
from controllers.params import OptionDoc, build, describe
from controllers.protocol import ConfigError, Controller, ControllerBase, SumoDriverModel

if TYPE_CHECKING:
    from controllers.builtin import ControllerFactory

ENTRY_POINT_GROUP = "hwyeval.controllers"
_NAME = re.compile(r"[a-z0-9_]+")
_PLUGINS: dict[str, ControllerFactory] = {}
_PLUGIN_PARAMETERS: dict[str, type] = {}
_ORIGINS: dict[str, str] = {}  # controller name -> where it came from
_ERRORS: dict[str, str] = {}  # plug-in (entry point or module) -> why it did not load
_LOADED_MODULES: set[str] = set()
_entry_points_loaded = False


@dataclass(frozen=True)
class ControllerPlugin:
    """What an entry point of :data:`ENTRY_POINT_GROUP` names: the factory
    ``options -> Controller`` and the parameter dataclass its options build (None:
    no options), for :func:`options`."""

    factory: Callable[[Mapping[str, Any]], Controller | SumoDriverModel | RecordedDriverModel]
    parameters: type | None = None


@dataclass(frozen=True)
class PluginModule:
    """A ``--plugin`` module as a job carries it: its module name, and for a file its
    path and source text (None for an importable module, imported by name)."""

    name: str
    path: str = ""
    source: str | None = None

    @property
    def label(self) -> str:
        return self.path or self.name


def _builtins() -> Mapping[str, ControllerFactory]:
    from controllers.builtin import FACTORIES

    return FACTORIES


def _all() -> dict[str, ControllerFactory]:
    load_entry_points()
    return {**_builtins(), **_PLUGINS}


def _register(name: str, factory: ControllerFactory, parameters: type | None,
              origin: str) -> None:
    if not _NAME.fullmatch(name or ""):
        raise ValueError(f"controller name must match [a-z0-9_]+, got {name!r}")
    if name in _builtins() or name in _PLUGINS:
        raise ValueError(f"controller {name!r} is already registered "
                         f"({_ORIGINS.get(name, 'built in')})")
    if not callable(factory):
        raise ValueError(f"controller {name!r}: the factory must be callable, got {factory!r}")
    _PLUGINS[name] = factory
    _ORIGINS[name] = origin
    if parameters is not None:
        _PLUGIN_PARAMETERS[name] = parameters


def load_entry_points() -> None:
    """Register every controller of the installed distributions' entry points (once
    per process; a broken one is recorded in :func:`plugin_errors`)."""
    global _entry_points_loaded
    if _entry_points_loaded:
        return
    _entry_points_loaded = True
    for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        dist = ep.dist
        origin = (f"entry point {ep.value} of {dist.metadata['Name']} {dist.version}"
                  if dist is not None else f"entry point {ep.value}")
        try:
            obj = ep.load()
            if isinstance(obj, ControllerPlugin):
                _register(ep.name, obj.factory, obj.parameters, origin)
            else:
                _register(ep.name, obj, None, origin)
        except Exception as exc:  # noqa: BLE001 - one broken plug-in must not hide the rest
            _ERRORS[ep.name] = f"{origin}: {type(exc).__name__}: {exc}"


def plugin_module(spec: str) -> PluginModule:
    """A ``--plugin`` argument as a :class:`PluginModule`: a path ending in ``.py`` (or
    an existing file) is read; anything else must be an importable module name.
    Raises ValueError for a file that cannot be read or a malformed name."""
    path = Path(spec)
    if spec.endswith(".py") or path.is_file():
        try:
            source = path.read_text()
        except OSError as exc:
            raise ValueError(f"--plugin {spec}: cannot read it ({exc})") from exc
        name = "hwyeval_plugin_" + re.sub(r"\W", "_", path.stem)
        return PluginModule(name=name, path=str(path.resolve()), source=source)
    if not re.fullmatch(r"[A-Za-z_][\w.]*", spec):
        raise ValueError(f"--plugin {spec!r}: neither a .py file nor a module name")
    return PluginModule(name=spec)


def load_plugin(plugin: PluginModule | str) -> str:
    """Import a plug-in module once in this process (it registers its controllers);
    returns its module name. Raises what the module raises (ImportError, ValueError
    for a name already registered, ...)."""
    module = plugin_module(plugin) if isinstance(plugin, str) else plugin
    if module.name in _LOADED_MODULES:
        return module.name
    load_entry_points()  # a module's name clash with an entry point is then an error
    if module.source is None:
        importlib.import_module(module.name)
    else:
        mod = types.ModuleType(module.name)
        mod.__file__ = module.path
        sys.modules[module.name] = mod
        try:
            exec(compile(module.source, module.path or module.name, "exec"), mod.__dict__)
        except BaseException:
            sys.modules.pop(module.name, None)
            raise
    _LOADED_MODULES.add(module.name)
    return module.name


def load_plugin_modules(modules: Iterable[PluginModule]) -> None:
    """:func:`load_plugin` for each (what a scenario process does before it builds its
    controller)."""
    for module in modules:
        load_plugin(module)


def plugin_errors() -> dict[str, str]:
    """Entry points that failed to load: name -> why."""
    load_entry_points()
    return dict(_ERRORS)


def factory_module(name: str) -> str:
    """The module that defines controller ``name``'s factory (what a plug-in's source
    hash covers); KeyError for an unknown name."""
    factory = _all()[name]
    return str(getattr(factory, "__module__", "") or "")


def origin(name: str) -> str:
    """Where controller ``name`` comes from: 'built in', an entry point, a module."""
    load_entry_points()
    return _ORIGINS.get(name, "built in")


def register(name: str, factory: ControllerFactory | type[ControllerBase],
             parameters: type | None = None) -> None:
    """Add a plug-in controller; a name may be registered once only. ``factory``: a
    function ``options -> Controller``, or a :class:`controllers.protocol.ControllerBase`
    subclass (:func:`class_factory` makes the factory). ``parameters``: the dataclass its
    options build, if it has options (for :func:`options`)."""
    load_entry_points()
    caller = sys._getframe(1).f_globals
    where = caller.get("__file__") or caller.get("__name__", "?")
    made = (class_factory(name, factory, parameters)
            if isinstance(factory, type) and issubclass(factory, ControllerBase)
            else cast("ControllerFactory", factory))
    _register(name, made, parameters, f"module {where}")


def class_factory(name: str, cls: type[ControllerBase],
                  parameters: type | None = None) -> ControllerFactory:
    """The factory of a :class:`ControllerBase` subclass registered as ``name``: with
    ``parameters`` (a frozen dataclass of ``controllers.params.param`` fields) it builds
    ``cls(build(parameters, options))``, else ``cls()`` and any option is a ConfigError;
    the instance's ``name`` is ``name``. ``options["name"]``, if given, must be ``name``."""

    def make_controller(options: Mapping[str, Any]) -> Controller:
        opts = dict(options)
        given = opts.pop("name", name)
        if given != name:
            raise ConfigError("controller.name", repr(name), given)
        if parameters is not None:
            ctl = cls(build(parameters, opts))  # type: ignore[call-arg]
        elif opts:
            key = sorted(opts)[0]
            raise ConfigError(f"controller.{key}", f"no options ({name} takes none)",
                              opts[key])
        else:
            ctl = cls()
        ctl.name = name
        return ctl

    make_controller.__module__ = cls.__module__
    make_controller.__qualname__ = f"class_factory({cls.__qualname__})"
    return make_controller


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


def make(name: str, options: Mapping[str, Any] | None = None
         ) -> Controller | SumoDriverModel | RecordedDriverModel:
    """Build controller ``name`` with ``options`` (validated by its factory)."""
    factories = _all()
    if name not in factories:
        if name in _ERRORS:
            raise ConfigError("controller.name", f"a plug-in that loads ({_ERRORS[name]})",
                              name)
        raise ConfigError("controller.name", f"one of {sorted(factories)}", name)
    return factories[name](dict(options or {}))
