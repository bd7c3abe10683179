"""Sweeps: variant names (:func:`sweep_shorts`, :func:`format_sweep_value`,
:func:`sweep_name`), and the dotted paths of a ``[scenario.sweep]`` table (flattening,
checking a path's target, setting a value at a path)."""

from __future__ import annotations

import copy
import math
import re
from collections.abc import Mapping, Sequence
from typing import Any

from suite.catalog.errors import type_name
from suite.catalog.keys import DEFAULT_KEYS, OPTIONAL_SUBKEYS

__all__ = ["flatten_sweep", "format_sweep_value", "overlapping", "path_target", "set_path",
           "sweep_name", "sweep_shorts"]

# ------------------------------------------------------------------ naming
_ABBREV = {
    "pos_m": "pos",
    "vehicles_per_hour": "vph",
    "speed_mps": "speed",
    "target_speed_mps": "vt",
    # Sweeping the controller names variants by the controller alone: s3_stall__two_loop.
    "controller": "",
}
_UNIT_SUFFIX = re.compile(r"_(m|s|mps|mps2|rad|radps|deg|hz|nm|kg|ms|kmh|n)$")


def _abbrev(component: str) -> str:
    if component in _ABBREV:
        return _ABBREV[component]
    short = _UNIT_SUFFIX.sub("", component)
    return short or component


def sweep_shorts(keys: Sequence[str]) -> list[str]:
    """Short labels for swept dotted keys, lengthened until they are distinct."""
    parts = [k.split(".") for k in keys]
    depth = [1] * len(keys)

    def label(i: int) -> str:
        comps = parts[i][-depth[i]:]
        return "".join(_abbrev(c) for c in comps)

    for _ in range(max((len(p) for p in parts), default=0) + 1):
        labels = [label(i) for i in range(len(keys))]
        clash = [i for i, lab in enumerate(labels) if labels.count(lab) > 1]
        grow = [i for i in clash if depth[i] < len(parts[i])]
        if not grow:
            break
        for i in grow:
            depth[i] += 1
            # a bare list index is not readable on its own: take its parent too
            while depth[i] < len(parts[i]) and parts[i][-depth[i]].isdigit():
                depth[i] += 1
    labels = [label(i) for i in range(len(keys))]
    seen: dict[str, int] = {}
    out = []
    for lab in labels:
        if labels.count(lab) > 1:  # identical full paths after abbreviation
            seen[lab] = seen.get(lab, 0) + 1
            lab = f"{lab}{seen[lab]}x"
        out.append(re.sub(r"[^a-z0-9_]", "_", lab.lower()))
    return out


def format_sweep_value(value: Any, position: int = 0) -> str:
    """Compact, name-safe text of a swept value (``300.0``->``300``, ``2.5``->``2p5``)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        text = str(value)
    elif isinstance(value, float):
        if math.isfinite(value) and value == int(value) and abs(value) < 1e15:
            text = str(int(value))
        else:
            text = repr(value)
    elif isinstance(value, str):
        return re.sub(r"[^a-z0-9_]", "_", value.lower())
    elif isinstance(value, Mapping) and isinstance(value.get("name"), str) and len(value) == 1:
        return format_sweep_value(value["name"])
    else:
        return f"v{position}"
    return text.replace("-", "m").replace("+", "").replace(".", "p").lower()


def sweep_name(base: str, shorts: Sequence[str], values: Sequence[Any],
               positions: Sequence[int] | None = None) -> str:
    """``<base>__<short><value>...`` for one sweep combination."""
    positions = positions if positions is not None else [0] * len(values)
    parts = [f"{s}{format_sweep_value(v, p)}" for s, v, p in zip(shorts, values, positions,
                                                                   strict=True)]
    return "__".join([base, *parts])


# ------------------------------------------------------------------ paths
def flatten_sweep(table: Mapping[str, Any], prefix: str = "") -> list[tuple[str, Any]]:
    """(dotted path, values) of a sweep table; nested tables (unquoted dotted keys) joined.
    An empty nested table stays an item (with ``{}`` as its values: it sweeps nothing,
    which the loader reports instead of silently expanding to no scenario)."""
    out: list[tuple[str, Any]] = []
    for k, v in table.items():
        key = f"{prefix}.{k}" if prefix else str(k)
        if isinstance(v, Mapping) and v:
            out.extend(flatten_sweep(v, key))
        else:
            out.append((key, v))
    return out


def overlapping(keys: Sequence[str]) -> dict[str, str]:
    """Swept paths inside another swept path (``"stalled.0.pos_m"`` inside
    ``"stalled.0"``): each such key -> the path that contains it. Sweeping both would
    make one replace what the other sets."""
    out: dict[str, str] = {}
    for key in keys:
        for other in keys:
            if other != key and key.startswith(other + "."):
                out[key] = other
                break
    return out


def path_target(root: Any, path: str) -> tuple[bool, str]:
    """(ok, problem) for a dotted sweep path in a merged scenario dict."""
    comps = path.split(".")
    if not path or any(c == "" for c in comps):
        return False, "a dotted path such as \"stalled.0.pos_m\""
    if comps[0] in ("name", "sweep"):
        return False, "a path not under 'name' or 'sweep'"
    return _walk_target(root, path, comps)


def _walk_target(root: Any, path: str, comps: list[str]) -> tuple[bool, str]:
    """:func:`path_target` of a well-formed ``path`` (components ``comps``): each list
    index in range and each key present, but for an optional key that may be missing
    and the nested options of a controller (the controller checks them)."""
    node = root
    for depth, comp in enumerate(comps):
        last = depth == len(comps) - 1
        parent = ".".join(comps[:depth])
        if isinstance(node, list):
            if not comp.isdigit() or int(comp) >= len(node):
                return False, (f"a list index in 0..{len(node) - 1} at {parent!r}" if node
                               else f"an existing list item ({parent!r} is empty)")
            node = node[int(comp)]
        elif isinstance(node, Mapping):
            if comp in node:
                node = node[comp]
                continue
            if last and _optional_subkey_ok(comps, root):
                return True, ""
            if depth >= 1 and comps[0] == "controller":
                return True, ""  # a nested controller option: the controller checks it
            return False, f"a path to an existing value ({path!r} does not exist after merging)"
        else:
            return False, f"a path into a table or list ({parent!r} is a {type_name(node)})"
    return True, ""


def _optional_subkey_ok(comps: list[str], root: Mapping[str, Any]) -> bool:
    if len(comps) == 1:
        return comps[0] in DEFAULT_KEYS
    if len(comps) == 2 and comps[0] in OPTIONAL_SUBKEYS:
        return comps[1] in OPTIONAL_SUBKEYS[comps[0]]
    if len(comps) == 3 and comps[0] in ("stalled", "ramp_traffic", "actors"):
        return comps[2] in OPTIONAL_SUBKEYS[f"{comps[0]}.*"]
    if len(comps) == 2 and comps[0] in ("criteria", "controller") and isinstance(
            root.get(comps[0]), Mapping):
        return True
    return False


def set_path(root: dict[str, Any], path: str, value: Any) -> str | None:
    """Set (a copy of) ``value`` at the dotted ``path`` of a merged scenario dict.
    Returns None when set, else what the path would need (the scenario is then left
    partly set: the caller drops it); never raises for a path that does not fit."""
    comps = path.split(".")
    node: Any = root
    for depth, comp in enumerate(comps):
        last = depth == len(comps) - 1
        parent = ".".join(comps[:depth]) or "the scenario"
        if isinstance(node, list):
            if not comp.isdigit() or int(comp) >= len(node):
                return f"a list index in 0..{len(node) - 1} at {parent!r}" if node \
                    else f"an existing list item ({parent!r} is empty)"
            if last:
                node[int(comp)] = copy.deepcopy(value)
                return None
            node = node[int(comp)]
        elif isinstance(node, dict):
            if last:
                node[comp] = copy.deepcopy(value)
                return None
            if comp not in node:
                node[comp] = {}  # a nested controller option table the scenario left out
            node = node[comp]
        else:
            return f"a path into a table or list ({parent!r} is a {type_name(node)})"
    return None
