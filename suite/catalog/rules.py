"""Field rules: a rule takes a value and returns ``None`` if it fits, else what would.

The spec classes list theirs in ``_RULES``; the loader runs the same rules on raw TOML
values so that every bad field is reported, not just the first.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping
from typing import Any

from suite.catalog.errors import SpecError

__all__ = ["MAX_NAME_LEN", "MAX_SEED", "NAME_RE", "Rule", "as_float", "boolean", "check_fields",
           "edge_id", "friction", "integer", "is_number", "lane_change", "lane_key",
           "lane_speeds", "lanes", "name_rule", "nameable_path", "non_json_path", "num",
           "number_map", "table_list"]

NAME_RE = re.compile(r"^[a-z0-9_]+$")
MAX_SEED = 2**31 - 1
# A scenario name is a directory name (OUT/<name>/, and OUT/.partial-<name>-<pid>/ while
# it is written): file systems allow 255 bytes per name; this leaves room for the rest.
MAX_NAME_LEN = 200

Rule = Callable[[Any], str | None]


def is_number(v: Any) -> bool:
    """An int or float, not a bool, finite."""
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def num(lo: float | None = None, *, strict: bool = False, optional: bool = False) -> Rule:
    """A finite number, ``>= lo`` (``> lo`` if ``strict``); ``None`` too if ``optional``."""
    if lo is None:
        what = "a finite number"
    else:
        what = f"a finite number {'>' if strict else '>='} {lo:g}"

    def check(v: Any) -> str | None:
        if v is None and optional:
            return None
        if not is_number(v):
            return what
        if lo is not None and (v < lo or (strict and v == lo)):
            return what
        return None

    return check


SUMO_TICK_S = 0.001  # SUMO counts time in milliseconds


def sumo_step(v: Any) -> str | None:
    """A simulation step SUMO can run: a whole number of milliseconds, at least one."""
    what = "a step of at least 0.001 s and a whole number of milliseconds (SUMO's clock)"
    if not is_number(v) or v < SUMO_TICK_S - 1e-12:
        return what
    ticks = v / SUMO_TICK_S
    return None if abs(ticks - round(ticks)) < 1e-6 else what


MAX_FRICTION = 2.0  # racing slicks reach ~1.7; beyond 2 a value is a typo


def friction(v: Any) -> str | None:
    """A tyre-road friction coefficient mu in (0, 2]."""
    if is_number(v) and 0.0 < v <= MAX_FRICTION:
        return None
    return f"a friction coefficient in (0, {MAX_FRICTION:g}] (1.0 dry asphalt, ~0.6 wet)"


def edge_id(v: Any) -> str | None:
    return None if isinstance(v, str) and v else "an edge id (a non-empty string)"


def lane_speeds(v: Any) -> str | None:
    """None, or a non-empty table lane index -> speed [m/s] > 0; TOML keys are strings,
    so an index may be written ``2`` (a bare key) or ``"2"``."""
    what = ("null or a non-empty table of lane index -> speed in m/s > 0 "
            "(e.g. { 2 = 20.0 })")
    if v is None:
        return None
    if not isinstance(v, Mapping) or not v:
        return what
    for key, speed in v.items():
        index = lane_key(key)
        if index is None or not is_number(speed) or speed <= 0:
            return what
    return None


def lane_key(key: Any) -> int | None:
    """A lane index from a table key (an int >= 0, or its decimal string); else None."""
    if isinstance(key, int) and not isinstance(key, bool):
        return key if key >= 0 else None
    if isinstance(key, str) and key.isdigit() and key.isascii():
        return int(key)
    return None


def lane_change(v: Any) -> str | None:
    """A lane change: a non-zero number of lanes, left > 0, right < 0 (0: none)."""
    if isinstance(v, int) and not isinstance(v, bool) and abs(v) <= 8:
        return None
    return "a number of lanes to change, left > 0 or right < 0 (e.g. 1 or -1)"


def table_list(v: Any) -> str | None:
    """A list (or tuple) of tables."""
    if isinstance(v, list | tuple) and all(isinstance(x, Mapping) or hasattr(x, "t_s")
                                           for x in v):
        return None
    return "a list of tables [{...}, ...]"


def integer(lo: int = 0, hi: int | None = None) -> Rule:
    """An int (not a bool) in ``[lo, hi]``, or ``>= lo`` without ``hi``."""
    what = f"an integer >= {lo}" if hi is None else f"an integer in [{lo}, {hi}]"

    def check(v: Any) -> str | None:
        if not isinstance(v, int) or isinstance(v, bool):
            return what
        if v < lo or (hi is not None and v > hi):
            return what
        return None

    return check


def boolean(v: Any) -> str | None:
    return None if isinstance(v, bool) else "a boolean (true/false)"


def name_rule(v: Any) -> str | None:
    """A scenario or controller name: ``[a-z0-9_]+``, at most :data:`MAX_NAME_LEN`
    characters."""
    if isinstance(v, str) and NAME_RE.match(v) and len(v) <= MAX_NAME_LEN:
        return None
    if isinstance(v, str) and NAME_RE.match(v):
        return f"a name of at most {MAX_NAME_LEN} characters (it names a directory), not {len(v)}"
    return "a name matching [a-z0-9_]+"


MAX_PATH_COMPONENT_BYTES = 255  # what file systems allow per name


def nameable_path(v: Any) -> str | None:
    """A string a file system can name as a path: no NUL character, no component longer
    than 255 bytes (UTF-8). Other values are left to the key's own rule (None)."""
    if not isinstance(v, str):
        return None
    if "\x00" in v:
        return "a path without NUL characters"
    longest = max((len(part.encode("utf-8", "surrogatepass")) for part in v.split("/")),
                  default=0)
    if longest > MAX_PATH_COMPONENT_BYTES:
        return (f"a path whose every component has at most {MAX_PATH_COMPONENT_BYTES} bytes "
                f"(one has {longest})")
    return None


def lanes(v: Any) -> str | None:
    what = "null or a non-empty list of distinct lane indices (integers >= 0)"
    if v is None:
        return None
    if not isinstance(v, list | tuple) or not v:
        return what
    if any(not isinstance(x, int) or isinstance(x, bool) or x < 0 for x in v):
        return what
    if len(set(v)) != len(v):
        return what
    return None


def number_map(v: Any) -> str | None:
    what = "a table of name -> finite number"
    if not isinstance(v, Mapping):
        return what
    if any(not isinstance(k, str) or not is_number(x) for k, x in v.items()):
        return what
    return None


def non_json_path(value: Any, prefix: str = "") -> tuple[str, Any] | None:
    """First (dotted path, value) that is not JSON-able, else None."""
    if isinstance(value, Mapping):
        return _non_json_in_table(value, prefix)
    if isinstance(value, list | tuple):
        return _non_json_in_list(value, prefix)
    if value is None or isinstance(value, str | bool | int):
        return None
    if isinstance(value, float) and math.isfinite(value):
        return None
    return prefix, value


def _non_json_in_table(value: Mapping[Any, Any], prefix: str) -> tuple[str, Any] | None:
    """:func:`non_json_path` of a table at ``prefix``: a key that is not a string, or
    the first non-JSON-able path of a value, in order."""
    for k, v in value.items():
        if not isinstance(k, str):
            return prefix or str(k), k
        bad = non_json_path(v, f"{prefix}.{k}" if prefix else k)
        if bad is not None:
            return bad
    return None


def _non_json_in_list(value: list[Any] | tuple[Any, ...], prefix: str
                      ) -> tuple[str, Any] | None:
    """:func:`non_json_path` of a list at ``prefix``: its items' paths are their indices."""
    for i, v in enumerate(value):
        bad = non_json_path(v, f"{prefix}.{i}" if prefix else str(i))
        if bad is not None:
            return bad
    return None


def check_fields(obj: Any) -> None:
    """Run the class's ``_RULES`` on ``obj``; raise SpecError on the first failure."""
    for name, rule in obj._RULES.items():
        value = getattr(obj, name)
        expected = rule(value)
        if expected is not None:
            raise SpecError(name, expected, value)


def as_float(obj: Any, *names: str) -> None:
    """Turn the int fields ``names`` of a frozen dataclass into floats."""
    for name in names:
        value = getattr(obj, name)
        if isinstance(value, int) and not isinstance(value, bool):
            object.__setattr__(obj, name, float(value))
