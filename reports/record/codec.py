"""Typed JSON for the run record: frozen dataclasses to plain JSON and back, checked.

:func:`to_plain` turns a dataclass (nested dataclasses, tuples, dicts, numpy scalars and
arrays, paths) into JSON-able values. :func:`decode_dataclass` rebuilds a dataclass
from parsed JSON using its type hints and raises :class:`RecordError` naming the file,
the dotted key, what was expected and what was found: a malformed ``run.json`` is
reported, never half-read.

Supported field types: ``float`` (ints accepted; NaN/±inf as JSON's NaN/Infinity),
``int``, ``bool``, ``str``, ``X | None``, ``tuple[T, ...]``, ``dict[str, Any]``,
``Any`` and nested dataclasses.
"""

from __future__ import annotations

import dataclasses
import inspect
import json
import math
import os
import re
import types
import typing
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

T = TypeVar("T")
_SURROGATE = re.compile("[\ud800-\udfff]")
_SURROGATE_ESCAPE = re.compile(r"\\u[dD][89a-fA-F]")  # JSON's escape of one


class RecordError(ValueError):
    """A run record is malformed: ``path`` (file), ``key`` (dotted), ``expected``, ``got``."""

    def __init__(self, path: str | Path, key: str, expected: str, got: Any = None) -> None:
        self.path = str(path)
        self.key = key
        self.expected = expected
        self.got = got
        shown = repr(got)
        if len(shown) > 120:
            shown = shown[:117] + "..."
        super().__init__(f"{path}: {key or '<root>'}: expected {expected}, got {shown}")


def to_plain(value: Any) -> Any:
    """JSON-able copy of ``value`` (dataclasses become dicts, tuples lists)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: to_plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, Mapping):
        return {str(k): to_plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [to_plain(v) for v in value]
    return _plain_leaf(value)


def _plain_leaf(value: Any) -> Any:
    """JSON-able form of a value that holds no others: numpy arrays as nested lists,
    numpy scalars as Python ones, paths as strings, anything else as it is."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    return value


def _type_name(tp: Any) -> str:
    if tp is float:
        return "a number"
    if tp is int:
        return "an integer"
    if tp is bool:
        return "true or false"
    if tp is str:
        return "a string"
    return getattr(tp, "__name__", str(tp))


# The decoder: one function per field type, made once per type (:func:`_decoder`) and
# calling those of the types it holds; a dataclass's follows a plan of its fields made
# once (:func:`_dataclass_decoder`). A decoder takes the parsed JSON value and returns
# the typed one; a value that does not fit raises :class:`_Bad`, which carries the key
# path out (each enclosing decoder adds its key) and becomes a RecordError naming the
# file and the dotted key only then (:func:`decode_dataclass`): no key is built while
# decoding (~800 fields a run.json), no type is looked at again.
Decoder = Callable[[Any], Any]


class _Stop(Exception):
    """Why decoding stopped; ``keys``: the key path from where it stopped up to the
    decoder catching it, innermost first (field names, list indices, table keys)."""

    def __init__(self) -> None:
        super().__init__()
        self.keys: list[Any] = []

    def dotted(self, key: str) -> str:
        """The dotted key of where it stopped, below ``key`` (the root's key)."""
        below = ".".join(f"{k}" for k in reversed(self.keys))
        if not below:
            return key
        return f"{key}.{below}" if key else below


class _Bad(_Stop):
    """A value that does not fit: ``expected`` (what a RecordError says), ``got``."""

    def __init__(self, expected: str, got: Any) -> None:
        super().__init__()
        self.expected = expected
        self.got = got


class _Unsupported(_Stop):
    """A field type the codec cannot decode (a bug of the record class: TypeError)."""

    def __init__(self, tp: Any) -> None:
        super().__init__()
        self.tp = tp


def _as_is(value: Any) -> Any:
    return value


def _float(value: Any) -> Any:
    if type(value) is float:
        return value
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise _Bad("a number", value)
    return float(value)


def _int(value: Any) -> Any:
    if type(value) is int:
        return value
    if isinstance(value, bool) or not isinstance(value, int):
        raise _Bad("an integer", value)
    return int(value)


def _str(value: Any) -> Any:
    if isinstance(value, str):
        return value
    raise _Bad("a string", value)


def _bool(value: Any) -> Any:
    if isinstance(value, bool):
        return value
    raise _Bad("true or false", value)


_SCALARS: dict[Any, Decoder] = {float: _float, int: _int, str: _str, bool: _bool,
                                Any: _as_is}


class _NoValue:
    """A type no value has: the exact type (:data:`_EXACT`) of a field whose decoder
    returns no value as it is."""


# The type whose values a scalar decoder returns as they are (the same object): a field
# value of exactly that type is taken without calling it (~600 calls a run.json).
_EXACT: dict[Decoder, type] = {_float: float, _int: int, _str: str, _bool: bool}


def _unsupported(tp: Any) -> Decoder:
    """A field type the codec cannot decode: TypeError when a value of it is met."""

    def decode(value: Any) -> Any:
        raise _Unsupported(tp)
    return decode


def _union_decoder(tp: Any) -> Decoder:
    """``X | Y | None``: null if allowed, else the first member that fits."""
    args = typing.get_args(tp)
    nullable = type(None) in args
    members = tuple(_decoder(arg) for arg in args if arg is not type(None))
    null_text = " or null" if nullable else ""
    first, rest = members[0], members[1:]  # most often the only one

    def decode(value: Any) -> Any:
        if value is None and nullable:
            return None
        try:
            return first(value)
        except _Bad as bad:
            expected = [bad.expected]
        for member in rest:
            try:
                return member(value)
            except _Bad as bad:
                expected.append(bad.expected)
        raise _Bad(" or ".join(expected) + null_text, value)
    return decode


def _tuple_decoder(tp: Any) -> Decoder:
    """``tuple[T, ...]`` from a JSON list (every item a T)."""
    args = typing.get_args(tp)
    item = _decoder(args[0] if args else Any)

    def decode(value: Any) -> Any:
        if not isinstance(value, list | tuple):
            raise _Bad("a list", value)
        if item is _as_is:
            return tuple(value)
        out: list[Any] = []
        try:
            for v in value:
                out.append(item(v))
        except _Stop as stop:
            stop.keys.append(len(out))  # the index of the item that stopped
            raise
        return tuple(out)
    return decode


def _dict_decoder(tp: Any) -> Decoder:
    """``dict[str, V]`` from a JSON object (keys as strings, every value a V)."""
    args = typing.get_args(tp)
    val = _decoder(args[1] if len(args) == 2 else Any)

    def decode(value: Any) -> Any:
        if not isinstance(value, Mapping):
            raise _Bad("a table (JSON object)", value)
        if val is _as_is:
            return {str(k): v for k, v in value.items()}
        out: dict[str, Any] = {}
        k: Any = None
        try:
            for k, v in value.items():
                out[str(k)] = val(v)
        except _Stop as stop:
            stop.keys.append(k)
            raise
        return out
    return decode


_REQUIRED = object()  # stands in for a missing field without a default: none can
_OMIT = object()  # stands in for a missing field left out of a call by keywords


@dataclasses.dataclass(frozen=True)
class _Plan:
    """How a record class is decoded. ``steps``: per field, in order, its name, the
    decoder of its resolved type, what stands in when it is missing (_REQUIRED, _OMIT,
    or its default as the constructor has it) and the type that decoder returns as it
    is (:data:`_EXACT`; :class:`_NoValue` for none); ``missing``: how a missing
    required field is reported, by name; ``positional``: the constructor takes every
    field positionally, in that order (else it is called with keywords)."""

    steps: tuple[tuple[str, Decoder, Any, type], ...]
    missing: dict[str, str]
    positional: bool

    def keywords(self, values: list[Any]) -> dict[str, Any]:
        """The call by keywords with ``values`` (one per step), missing ones left out."""
        return {step[0]: v for step, v in zip(self.steps, values, strict=True)
                if v is not _OMIT}


def _plan(cls: type) -> _Plan:
    """The plan of record class ``cls`` (its fields with their resolved types)."""
    hints = typing.get_type_hints(cls)
    fields = dataclasses.fields(cls)
    required = {f.name: f.default is dataclasses.MISSING
                and f.default_factory is dataclasses.MISSING for f in fields}
    defaults = _positional_defaults(cls, required)
    decoders = {f.name: _decoder(hints[f.name]) for f in fields}
    steps = tuple((f.name, decoders[f.name],
                   _REQUIRED if required[f.name] else
                   defaults[f.name] if defaults is not None else _OMIT,
                   _EXACT.get(decoders[f.name], _NoValue)) for f in fields)
    missing = {f.name: f"this required key ({_type_name(hints[f.name])})" for f in fields}
    return _Plan(steps, missing, defaults is not None)


def _positional_defaults(cls: type, required: dict[str, bool]) -> dict[str, Any] | None:
    """The defaults of the parameters of ``cls``'s ``__init__`` by name, when they are
    the fields of ``required``, in its order, each positional and without a default
    exactly when required; else None. A call passing every field positionally, a missing
    one as its parameter's default (the very object a call without it binds), is then
    the call by keywords without it, a third faster (0.8 us of a field-by-field
    constructor's 2.3 us for 8 fields): not for a class whose metaclass ``__call__`` or
    ``__new__`` would see the arguments too."""
    klass: Any = cls  # its __new__ and __init__ as they are, not as typeshed has them
    if type(klass).__call__ is not type.__call__ or klass.__new__ is not object.__new__:
        return None
    try:
        params = list(inspect.signature(klass.__init__).parameters.values())[1:]
    except (TypeError, ValueError):  # pragma: no cover - a dataclass's __init__ has one
        return None
    if [p.name for p in params] != list(required) or any(
            p.kind is not p.POSITIONAL_OR_KEYWORD or (p.default is p.empty) != required[p.name]
            for p in params):
        return None
    return {p.name: p.default for p in params}


def _dataclass_decoder(cls: type) -> Decoder:
    """A dataclass from a JSON object: each field given decoded by its type's decoder,
    each missing one its default (a missing field without one stops it), then built by
    its constructor. The plan is made at the first call (``typing.get_type_hints``
    evaluates every annotation: once per class, and only for a class that is decoded;
    a class may hold itself)."""
    plans: list[_Plan] = []
    table_text = f"a table of {cls.__name__} fields"

    def decode(data: Any) -> Any:
        if type(data) is not dict and not isinstance(data, Mapping):
            raise _Bad(table_text, data)
        if not plans:
            plans.append(_plan(cls))
        plan = plans[0]
        values: list[Any] = []
        name = ""
        try:
            for name, field_decoder, default, exact in plan.steps:
                if name in data:
                    value = data[name]
                    values.append(value if type(value) is exact else field_decoder(value))
                elif default is _REQUIRED:
                    raise _Bad(plan.missing[name], "<missing>")
                else:
                    values.append(default)
        except _Stop as stop:
            stop.keys.append(name)
            raise
        try:
            return cls(*values) if plan.positional else cls(**plan.keywords(values))
        except (TypeError, ValueError) as exc:
            raise _Bad(f"valid {cls.__name__} fields ({exc})", data) from exc
    return decode


_DECODERS: dict[Any, Decoder] = {}


def _decoder(tp: Any) -> Decoder:
    """The decoder of field type ``tp``, made once per type."""
    found = _DECODERS.get(tp) or _SCALARS.get(tp)
    if found is None:
        origin = typing.get_origin(tp)
        if origin in (typing.Union, types.UnionType):
            found = _union_decoder(tp)
        elif dataclasses.is_dataclass(tp):
            found = _dataclass_decoder(typing.cast(type, tp))
        elif origin is tuple:
            found = _tuple_decoder(tp)
        elif origin is dict or tp is dict:
            found = _dict_decoder(tp)
        else:
            found = _unsupported(tp)
        _DECODERS[tp] = found
    return found


def decode_dataclass(cls: type[T], data: Any, path: str | Path, key: str = "") -> T:
    """Build ``cls`` from parsed JSON ``data``; missing fields with defaults get them.
    Raises :class:`RecordError` (``path``, the dotted key below ``key``) for a value
    that does not fit its field."""
    decoder = _DECODERS.get(cls)
    if decoder is None:  # not a dataclass: TypeError once it is a table, as fields() says
        decoder = _decoder(cls) if dataclasses.is_dataclass(cls) else _dataclass_decoder(cls)
    try:
        out: T = decoder(data)
    except _Bad as bad:
        raise RecordError(path, bad.dotted(key), bad.expected, bad.got) \
            from bad.__cause__
    except _Unsupported as stop:  # a record class's bug
        raise TypeError(f"codec: unsupported field type {stop.tp!r} at "
                        f"{stop.dotted(key)}") from None
    return out


def write_json_atomic(path: Path, data: Any, *, indent: int | None = 1) -> None:
    """Write ``data`` as JSON to ``path`` atomically (a reader never sees half a file);
    ``indent`` None writes it on one line (json's C encoder: 4x faster for bulk data)."""
    write_text_atomic(path, json.dumps(to_plain(data), indent=indent, allow_nan=True))


def write_text_atomic(path: Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically: into a temporary file beside it,
    renamed over ``path`` once complete. On any error (a full disk, a read-only
    directory) the temporary file is removed, ``path`` keeps what it held, and the
    OSError propagates."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(text, encoding="utf-8")
        tmp.replace(path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        if exc.filename is None:  # a full disk is met at close, which names no file
            raise OSError(exc.errno, exc.strerror, str(path)) from exc
        raise
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def read_json(path: Path) -> Any:
    """Parsed JSON of ``path``; RecordError if unreadable, not JSON, or holding text that
    is not Unicode (a lone surrogate escape such as ``"\\ud800"``: nothing could write it
    out again, not the HTML, the CSV, nor pandas)."""
    try:
        text = path.read_text()
        doc = json.loads(text)
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise RecordError(path, "", "a readable JSON file", f"{type(exc).__name__}: {exc}") \
            from exc
    # UTF-8 text holds no surrogate: only an escape can make one, so without one
    # (nearly always) the walk through every value (9 ms for a road.json) is skipped
    bad = _lone_surrogate(doc) if _SURROGATE_ESCAPE.search(text) else None
    if bad is not None:
        raise RecordError(path, bad[0], "text without lone surrogate escapes (\\ud800-\\udfff)",
                          bad[1])
    return doc


def _lone_surrogate(value: Any, key: str = "") -> tuple[str, str] | None:
    """(dotted key, text) of the first string or key holding a lone surrogate."""
    if isinstance(value, str):
        return (key, value) if _SURROGATE.search(value) else None
    if isinstance(value, dict):
        for k, v in value.items():
            sub = f"{key}.{k}" if key else str(k)
            if _SURROGATE.search(k):
                return sub, k
            found = _lone_surrogate(v, sub)
            if found is not None:
                return found
    elif isinstance(value, list):
        for i, v in enumerate(value):
            found = _lone_surrogate(v, f"{key}.{i}" if key else str(i))
            if found is not None:
                return found
    return None


def finite_or_nan(value: Any) -> float:
    """float(value), NaN where it is not a number."""
    try:
        out = float(value)
    except (TypeError, ValueError):
        return math.nan
    return out
