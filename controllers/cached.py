"""A per-instance cached attribute without functools.cached_property's lock.

Python 3.11's ``functools.cached_property`` takes a re-entrant lock on every first access
(removed in 3.12 as useless); the behaviour builds a scene every control step and reads
a handful of its cached attributes once each, so the lock was a measurable part of the
step. Like the functools one this is a non-data descriptor: the first access computes
the value and stores it in the instance's ``__dict__``, where every later access finds it
without calling the descriptor. Not for instances shared between threads while they are
being filled (none here: a scene lives inside one step).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Generic, TypeVar, overload

T = TypeVar("T")


class cached_property(Generic[T]):  # noqa: N801 - the name of the stdlib one it replaces
    """``@cached_property`` on a method of a class whose instances have a ``__dict__``
    (frozen dataclasses included: the value goes into ``__dict__`` directly)."""

    def __init__(self, func: Callable[[Any], T]) -> None:
        self.func = func
        self.attrname: str | None = None
        self.__doc__ = func.__doc__

    def __set_name__(self, owner: type, name: str) -> None:
        self.attrname = name

    @overload
    def __get__(self, instance: None, owner: type | None = None) -> cached_property[T]: ...

    @overload
    def __get__(self, instance: object, owner: type | None = None) -> T: ...

    def __get__(self, instance: object | None, owner: type | None = None) -> Any:
        if instance is None:
            return self
        if self.attrname is None:
            raise TypeError("cached_property used without __set_name__")
        value = self.func(instance)
        instance.__dict__[self.attrname] = value
        return value
