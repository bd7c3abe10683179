"""The one TOML writer for the catalogs hwyeval writes (the stress generator's, a
search's ``found.toml``, an import's ``catalog.toml``): ``[defaults]`` and
``[[scenario]]`` tables whose values are strings, ints, floats, bools, lists and tables
(written inline). Floats are written so that they read back as floats (``25.0``), strings
and keys as TOML basic strings where they are not bare keys."""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping, Sequence
from typing import Any

__all__ = ["dumps_catalog", "toml_key", "toml_value"]

_BARE_KEY = re.compile(r"^[A-Za-z_][A-Za-z0-9_-]*$")


def toml_key(key: str) -> str:
    """``key`` bare where TOML allows, else a basic string (dotted sweep paths)."""
    return key if _BARE_KEY.match(key) else json.dumps(key)


def toml_value(value: Any) -> str:
    """One TOML value (inline tables for mappings)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"TOML catalogs take finite numbers, got {value!r}")
        text = repr(value)
        return text if any(c in text for c in ".en") else text + ".0"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, Mapping):
        inner = ", ".join(f"{toml_key(str(k))} = {toml_value(v)}" for k, v in value.items())
        return "{ " + inner + " }" if inner else "{}"
    if isinstance(value, Sequence):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    raise TypeError(f"no TOML form for {type(value).__name__}: {value!r}")


# a scenario's tables written as [scenario.<key>] sub-tables (after its other keys), one
# key a line: the sweep and search spaces and an import's openscenario table
_SUBTABLES = ("openscenario", "sweep", "search")


def _table(name: str, body: Mapping[str, Any]) -> list[str]:
    lines = [name]
    lines += [f"{toml_key(k)} = {toml_value(v)}" for k, v in body.items()
              if not (k in _SUBTABLES and isinstance(v, Mapping))]
    for key in _SUBTABLES:
        sub = body.get(key)
        if isinstance(sub, Mapping):
            lines += [f"[scenario.{key}]",
                      *(f"{toml_key(k)} = {toml_value(v)}" for k, v in sub.items())]
    return lines


def dumps_catalog(header: str, defaults: Mapping[str, Any],
                  scenarios: Sequence[Mapping[str, Any]]) -> str:
    """The catalog's text: ``header`` as comment lines, ``[defaults]``, every scenario."""
    lines = [f"# {line}".rstrip() for line in header.splitlines()]
    lines += ["", *_table("[defaults]", defaults)]
    for sc in scenarios:
        lines += ["", *_table("[[scenario]]", sc)]
    return "\n".join(lines) + "\n"
