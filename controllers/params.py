"""Catalog options -> nested frozen parameter dataclasses, with dotted keys.

A *parameter class* is a frozen dataclass whose fields are leaves (``float``, ``int``,
``bool``, ``str`` or a ``Literal`` of strings) or nested parameter classes
(*sections*). A leaf declares its unit and meaning with :func:`param`
(``field(metadata={"unit": ..., "doc": ...})``), a section its meaning with
:func:`section`. A class validates its own values in ``__post_init__`` by raising
:class:`ParamError` naming the field (a dotted path relative to the class for checks
that span sections, e.g. ``"inner.lookahead_s"``); :func:`check_leaves` does the type
and finiteness checks every class shares.

:func:`build` turns a catalog table into such a class. For ``controller = { name =
"two_loop", outer = { c_y = 2.0 }, inner = { preview = false } }`` the factory passes
``{"outer": {"c_y": 2.0}, "inner": {"preview": False}}`` and gets the nested
parameters back, or a :class:`controllers.protocol.ConfigError` whose ``key`` is the
dotted path of the first bad option (``controller.outer.c_y``) and whose
``expected`` says what fits:

* every key must be a field of its section (an unknown key is an error, never
  ignored); a section must be given a table, a leaf a value;
* types: a bool is not a number, an int is accepted (and converted) where a float is
  expected, a float is not an int, floats must be finite, a ``Literal`` field takes
  one of its strings;
* flat aliases: ``aliases`` maps a top-level flat name to a dotted path (``"cost":
  "outer.cost"``); the alias and its dotted form together are an error. An alias
  stands for a leaf, so a table under the same name is the section of that name
  (``launch = true`` is ``launch.enabled``, ``launch = {...}`` the launch section);
* a :class:`ParamError` raised while a section is constructed becomes a ConfigError
  at ``<section path>.<field>``; a plain ``ValueError`` whose message starts with
  ``"<ClassName>.<field>"`` (the convention of :class:`ObstaclePolicy`) is mapped to
  that field, any other to the section.

:func:`to_dict` gives the nested plain dict of a parameter object (what
``Controller.parameters()`` returns; :func:`build` accepts it back unchanged) and
:func:`describe` lists every option (dotted path, type, default, unit, meaning) for
docs and ``hwyeval controllers --describe``. A leaf without metadata (a class this
module does not own) gets its unit from its name's suffix (``_m`` -> m, ...).
"""

from __future__ import annotations

import dataclasses
import math
import typing
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal, TypeVar

from controllers.protocol import ConfigError

__all__ = ["OptionDoc", "ParamError", "build", "check_leaves", "check_range", "describe",
           "param", "section", "to_dict"]

T = TypeVar("T")
P = TypeVar("P")

# Unit of a leaf without metadata, from its name's suffix (longest suffix first).
_SUFFIX_UNITS = (("_mps2", "m/s²"), ("_mps3", "m/s³"), ("_mps", "m/s"), ("_radps", "rad/s"),
                 ("_rad", "rad"), ("_nm", "N m"), ("_kg", "kg"), ("_ms", "m s"),
                 ("_m", "m"), ("_s", "s"))


class ParamError(ValueError):
    """A parameter's value does not fit: raised by ``__post_init__``.

    field: the field's name, or a dotted path relative to the class that raised it;
    expected: what would fit; got: the value given.
    """

    def __init__(self, field: str, expected: str, got: Any = None) -> None:
        self.field = field
        self.expected = expected
        self.got = got
        super().__init__(f"{field}: expected {expected}, got {got!r}")


def param(default: T, unit: str, doc: str) -> T:
    """A leaf field: default value, unit ('-' if dimensionless) and one-line meaning."""
    return dataclasses.field(default=default, metadata={"unit": unit, "doc": doc})


def section(factory: Callable[[], T], doc: str) -> T:
    """A nested section field, defaulting to ``factory()``."""
    return dataclasses.field(default_factory=factory, metadata={"doc": doc})


@dataclass(frozen=True)
class OptionDoc:
    """One option of a parameter class: dotted ``path``, ``type`` ('float', 'int',
    'bool', 'str' or "one of 'a', 'b'"), ``default``, ``unit`` and ``doc``."""

    path: str
    type: str
    default: Any
    unit: str
    doc: str


# ----------------------------------------------------------------------------- types
_HINTS: dict[type, dict[str, Any]] = {}


def _hints(cls: type) -> dict[str, Any]:
    """The resolved field types of ``cls`` (cached per class)."""
    if cls not in _HINTS:
        _HINTS[cls] = typing.get_type_hints(cls)
    return _HINTS[cls]


def _fields(cls: type) -> dict[str, dataclasses.Field[Any]]:
    return {f.name: f for f in dataclasses.fields(cls) if f.init}


def _is_section(kind: Any) -> bool:
    return isinstance(kind, type) and dataclasses.is_dataclass(kind)


def _type_name(kind: Any) -> str:
    if typing.get_origin(kind) is Literal:
        return "one of " + ", ".join(repr(a) for a in typing.get_args(kind))
    return getattr(kind, "__name__", str(kind))


def _leaf_problem(kind: Any, value: Any) -> str | None:
    """What a leaf of type ``kind`` expects if ``value`` does not fit, else None."""
    if typing.get_origin(kind) is Literal:
        choices = typing.get_args(kind)
        return None if value in choices else f"one of {list(choices)}"
    if kind is bool:
        return None if isinstance(value, bool) else "true or false"
    if kind is int:
        return None if isinstance(value, int) and not isinstance(value, bool) else "an integer"
    if kind is float:
        ok = (isinstance(value, int | float) and not isinstance(value, bool)
              and math.isfinite(value))
        return None if ok else "a finite number"
    if kind is str:
        return None if isinstance(value, str) else "a string"
    raise TypeError(f"unsupported parameter type {kind!r}")


def check_leaves(obj: object) -> None:
    """Type and finiteness of every leaf of ``obj`` (sections are checked by their own
    ``__post_init__``); raises :class:`ParamError` for the first that does not fit."""
    cls = type(obj)
    hints = _hints(cls)
    for name in _fields(cls):
        kind = hints[name]
        value = getattr(obj, name)
        if _is_section(kind):
            if not isinstance(value, kind):
                raise ParamError(name, f"a {kind.__name__}", value)
            continue
        problem = _leaf_problem(kind, value)
        if problem is not None:
            raise ParamError(name, problem, value)


def check_range(obj: object, name: str, *, gt: float | None = None, ge: float | None = None,
                lt: float | None = None, le: float | None = None) -> None:
    """Raise :class:`ParamError` unless the number ``obj.name`` is within the bounds."""
    value = getattr(obj, name)
    ok = ((gt is None or value > gt) and (ge is None or value >= ge)
          and (lt is None or value < lt) and (le is None or value <= le))
    if ok:
        return
    bounds = [f"> {gt:g}" if gt is not None else "", f">= {ge:g}" if ge is not None else "",
              f"< {lt:g}" if lt is not None else "", f"<= {le:g}" if le is not None else ""]
    kind = "an integer" if _hints(type(obj))[name] is int else "a number"
    raise ParamError(name, f"{kind} {' and '.join(b for b in bounds if b)}", value)


# ----------------------------------------------------------------------------- build
def build(cls: type[P], options: Mapping[str, Any], *, prefix: str = "controller",
          aliases: Mapping[str, str] | None = None) -> P:
    """Parameters of class ``cls`` from a catalog table (see the module docstring).

    options: nested tables (dicts) keyed by field names, plus any flat ``aliases``;
    prefix: dotted path of the table itself, for error keys. Raises ConfigError.
    """
    nested = resolve_aliases(options, aliases or {}, prefix)
    return _build(cls, nested, prefix)


def resolve_aliases(options: Mapping[str, Any], aliases: Mapping[str, str],
                    prefix: str = "controller") -> dict[str, Any]:
    """A copy of ``options`` with every flat alias moved to its dotted path."""
    if not isinstance(options, Mapping):
        raise ConfigError(prefix, "a table of options", options)
    def is_alias(key: str, value: Any) -> bool:
        return key in aliases and not isinstance(value, Mapping)

    out: dict[str, Any] = {k: _copy(v) for k, v in options.items() if not is_alias(k, v)}
    for key, value in options.items():
        if not is_alias(key, value):
            continue
        comps = aliases[key].split(".")
        node = out
        for depth, comp in enumerate(comps[:-1]):
            child = node.setdefault(comp, {})
            if not isinstance(child, dict):
                raise ConfigError(f"{prefix}.{'.'.join(comps[:depth + 1])}",
                                  "a table of options", child)
            node = child
        if comps[-1] in node:
            raise ConfigError(f"{prefix}.{key}", f"either {key!r} or its dotted form "
                              f"{prefix}.{aliases[key]}, not both", value)
        node[comps[-1]] = _copy(value)
    return out


def _copy(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {k: _copy(v) for k, v in value.items()}
    return value


def _unknown_key(path: str, key: str, fields: Sequence[str]) -> ConfigError:
    import difflib

    close = difflib.get_close_matches(str(key), list(fields), n=1)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    return ConfigError(f"{path}.{key}", f"one of the keys of {path}: {sorted(fields)}{hint}",
                       key)


def _build(cls: type[P], table: Any, path: str) -> P:
    """``cls`` from ``table``; every unknown key and bad value of the table and its
    sections is collected and raised together (:attr:`ConfigError.more`)."""
    if not isinstance(table, Mapping):
        raise ConfigError(path, f"a table of {cls.__name__} options", table)
    kwargs = _table_arguments(cls, table, path)
    return _construct(cls, kwargs, table, path)


def _table_arguments(cls: type, table: Mapping[str, Any], path: str) -> dict[str, Any]:
    """The keyword arguments of ``cls`` that ``table`` (at ``path``) gives, sections built
    and leaves checked; every unknown key and bad value is raised together."""
    hints = _hints(cls)
    fields = _fields(cls)
    problems = [_unknown_key(path, key, list(fields)) for key in table if key not in fields]
    kwargs: dict[str, Any] = {}
    for name, value in table.items():
        if name not in fields:
            continue
        try:
            kwargs[name] = _field_argument(hints[name], value, f"{path}.{name}")
        except ConfigError as exc:
            problems.extend(exc.all)
    if problems:
        raise ConfigError(problems[0].key, problems[0].expected, problems[0].got,
                          tuple(problems[1:]))
    return kwargs


def _field_argument(kind: Any, value: Any, path: str) -> Any:
    """The argument for a field of type ``kind`` (at ``path``) from its table value: a
    section built from its table, a leaf checked (a float leaf as a float); raises
    ConfigError."""
    if _is_section(kind):
        return _build(kind, value, path)
    problem = _leaf_problem(kind, value)
    if problem is not None:
        raise ConfigError(path, problem, value)
    return float(value) if kind is float else value


def _construct(cls: type[P], kwargs: dict[str, Any], table: Mapping[str, Any],
               path: str) -> P:
    """``cls(**kwargs)``, a ParamError or ValueError of its checks raised as a
    ConfigError naming the field at ``path`` (the table when no field is named)."""
    try:
        return cls(**kwargs)
    except ConfigError:
        raise
    except ParamError as exc:
        raise ConfigError(f"{path}.{exc.field}", exc.expected, exc.got) from exc
    except ValueError as exc:
        name = _field_named_in(cls, str(exc))
        got = kwargs.get(name, getattr(cls, name, None)) if name else dict(table)
        raise ConfigError(f"{path}.{name}" if name else path, str(exc), got) from exc


def _field_named_in(cls: type, message: str) -> str:
    """The field a ``"<ClassName>.<field> ..."`` message names ('' if none)."""
    head = f"{cls.__name__}."
    if not message.startswith(head):
        return ""
    rest = message[len(head):]
    names = sorted(_fields(cls), key=len, reverse=True)
    return next((n for n in names if rest.startswith(n) and not rest[len(n):][:1].isalnum()
                 and rest[len(n):][:1] != "_"), "")


# ----------------------------------------------------------------------------- read back
def to_dict(obj: object) -> dict[str, Any]:
    """The nested plain dict of a parameter object (sections as dicts)."""
    if not dataclasses.is_dataclass(obj) or isinstance(obj, type):
        raise TypeError(f"to_dict needs a dataclass instance, got {obj!r}")
    return dataclasses.asdict(obj)


def describe(cls: type, prefix: str = "controller") -> list[OptionDoc]:
    """Every leaf option of ``cls`` (depth first, declaration order) with its default."""
    return _describe(cls, cls(), prefix)


def _describe(cls: type, default: object, path: str) -> list[OptionDoc]:
    out: list[OptionDoc] = []
    hints = _hints(cls)
    for name, f in _fields(cls).items():
        kind = hints[name]
        value = getattr(default, name)
        if _is_section(kind):
            out.extend(_describe(kind, value, f"{path}.{name}"))
            continue
        unit = str(f.metadata.get("unit", "")) or _suffix_unit(name)
        out.append(OptionDoc(f"{path}.{name}", _type_name(kind), value, unit,
                             str(f.metadata.get("doc", ""))))
    return out


def _suffix_unit(name: str) -> str:
    for suffix, unit in _SUFFIX_UNITS:
        if name.endswith(suffix):
            return unit
    return "-"
