"""Typed JSON for the run record: frozen dataclasses to plain JSON and back, checked.

:func:`to_plain` turns a dataclass (nested dataclasses, tuples, dicts, numpy scalars and
arrays, paths) into JSON-able values. :func:`from_plain` rebuilds a dataclass from
parsed JSON using its type hints and raises :class:`RecordError` naming the file, the
dotted key, what was expected and what was found: a malformed ``run.json`` is
reported, never half-read.

Supported field types: ``float`` (ints accepted; NaN/±inf as JSON's NaN/Infinity),
``int``, ``bool``, ``str``, ``X | None``, ``tuple[T, ...]``, ``dict[str, Any]``,
``Any`` and nested dataclasses.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import re
import types
import typing
from collections.abc import Mapping
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


def _decode_union(tp: Any, value: Any, key: str, path: str) -> Any:
    args = typing.get_args(tp)
    if value is None and type(None) in args:
        return None
    errors = []
    for arg in args:
        if arg is type(None):
            continue
        try:
            return _decode(arg, value, key, path)
        except RecordError as exc:
            errors.append(exc.expected)
    raise RecordError(path, key, " or ".join(errors) + (" or null" if type(None) in args
                                                        else ""), value)


def _decode_tuple(tp: Any, value: Any, key: str, path: str) -> Any:
    args = typing.get_args(tp)
    if not isinstance(value, list | tuple):
        raise RecordError(path, key, "a list", value)
    item_tp = args[0] if args else Any
    return tuple(_decode(item_tp, v, f"{key}.{i}", path) for i, v in enumerate(value))


def _decode_dict(tp: Any, value: Any, key: str, path: str) -> Any:
    if not isinstance(value, Mapping):
        raise RecordError(path, key, "a table (JSON object)", value)
    args = typing.get_args(tp)
    val_tp = args[1] if len(args) == 2 else Any
    return {str(k): _decode(val_tp, v, f"{key}.{k}", path) for k, v in value.items()}


def _decode_scalar(tp: Any, value: Any, key: str, path: str) -> Any:
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise RecordError(path, key, "a number", value)
        return float(value)
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise RecordError(path, key, "an integer", value)
        return int(value)
    if tp in (bool, str):
        if not isinstance(value, tp):
            raise RecordError(path, key, _type_name(tp), value)
        return value
    raise TypeError(f"codec: unsupported field type {tp!r} at {key}")  # pragma: no cover


# How a field type is decoded, found once per type (typing's introspection costs more
# than the decoding: 1 000 look-ups per run.json).
_KINDS: dict[Any, str] = {}


def _kind(tp: Any) -> str:
    """'any' | 'union' | 'dataclass' | 'tuple' | 'dict' | 'scalar' of a field type."""
    kind = _KINDS.get(tp)
    if kind is None:
        origin = typing.get_origin(tp)
        if tp is Any:
            kind = "any"
        elif origin in (typing.Union, types.UnionType):
            kind = "union"
        elif dataclasses.is_dataclass(tp):
            kind = "dataclass"
        elif origin is tuple:
            kind = "tuple"
        elif origin is dict or tp is dict:
            kind = "dict"
        else:
            kind = "scalar"
        _KINDS[tp] = kind
    return kind


def _decode(tp: Any, value: Any, key: str, path: str) -> Any:
    kind = _kind(tp)
    if kind == "scalar":
        return _decode_scalar(tp, value, key, path)
    if kind == "any":
        return value
    if kind == "union":
        return _decode_union(tp, value, key, path)
    if kind == "dataclass":
        return decode_dataclass(tp, value, path, key)
    if kind == "tuple":
        return _decode_tuple(tp, value, key, path)
    return _decode_dict(tp, value, key, path)


@dataclasses.dataclass(frozen=True)
class _Field:
    """A dataclass field as the decoder needs it: its name, resolved type, whether it
    must be given (no default)."""

    name: str
    tp: Any
    required: bool


_FIELDS: dict[type, tuple[_Field, ...]] = {}


def _fields_of(cls: type) -> tuple[_Field, ...]:
    """The fields of a record class with their resolved types, once per process
    (``typing.get_type_hints`` evaluates every annotation string anew: 30 us a call)."""
    found = _FIELDS.get(cls)
    if found is None:
        hints = typing.get_type_hints(cls)
        found = _FIELDS[cls] = tuple(
            _Field(f.name, hints[f.name], f.default is dataclasses.MISSING
                   and f.default_factory is dataclasses.MISSING)
            for f in dataclasses.fields(cls))
    return found


def decode_dataclass(cls: type[T], data: Any, path: str | Path, key: str = "") -> T:
    """Build ``cls`` from parsed JSON ``data``; missing fields with defaults get them."""
    path = str(path)
    if not isinstance(data, Mapping):
        raise RecordError(path, key, f"a table of {cls.__name__} fields", data)
    kwargs: dict[str, Any] = {}
    for f in _fields_of(cls):
        sub = f"{key}.{f.name}" if key else f.name
        if f.name not in data:
            if f.required:
                raise RecordError(path, sub, f"this required key ({_type_name(f.tp)})",
                                  "<missing>")
            continue
        kwargs[f.name] = _decode(f.tp, data[f.name], sub, path)
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as exc:
        raise RecordError(path, key, f"valid {cls.__name__} fields ({exc})", data) from exc


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
