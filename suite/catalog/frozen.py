"""Immutable catalog values: :class:`FrozenMap`, and freezing/thawing nested data."""

from __future__ import annotations

import copy
import json
from collections.abc import Iterable, Iterator, Mapping
from typing import Any

__all__ = ["FrozenMap", "freeze", "thaw", "thaw_map"]


class FrozenMap(Mapping[str, Any]):
    """An immutable, picklable, hashable-if-possible mapping (nested maps/lists frozen)."""

    __slots__ = ("_data",)
    _data: dict[str, Any]

    def __init__(self, data: Mapping[str, Any] | Iterable[tuple[str, Any]] = ()) -> None:
        object.__setattr__(self, "_data", {k: freeze(v) for k, v in dict(data).items()})

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
        return hash(json.dumps(thaw(self), sort_keys=True, default=str))

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError("FrozenMap is immutable")

    def __reduce__(self) -> tuple[Any, ...]:
        return (FrozenMap, (thaw(self),))

    def to_dict(self) -> dict[str, Any]:
        """A deep, mutable, JSON-able copy."""
        return thaw_map(self)


def freeze(value: Any) -> Any:
    """``value`` with mappings as :class:`FrozenMap`, lists as tuples, the rest copied."""
    if isinstance(value, FrozenMap):
        return value
    if isinstance(value, Mapping):
        return FrozenMap(value)
    if isinstance(value, list | tuple):
        return tuple(freeze(v) for v in value)
    return copy.deepcopy(value)


def thaw(value: Any) -> Any:
    """A deep mutable copy: mappings as dicts (keys as str), lists/tuples as lists."""
    if isinstance(value, Mapping):
        return thaw_map(value)
    if isinstance(value, list | tuple):
        return [thaw(v) for v in value]
    return value


def thaw_map(value: Mapping[Any, Any]) -> dict[str, Any]:
    """:func:`thaw` of a mapping, typed as the dict it is."""
    return {str(k): thaw(v) for k, v in value.items()}
