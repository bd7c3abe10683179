"""The catalog side every importer shares: one ``<stem>.scenario.json`` per scenario
(its table, its source and notes) and ``catalog.toml`` rebuilt from every such file of
the folder, so a file that fails later never removes what an earlier import wrote and
``catalog.toml`` lists every scenario imported into the folder so far. Its first line
marks it generated, with the hash of the rest (:mod:`~suite.importers.common.
catalog_mark`): an edited copy is not replaced silently (:mod:`~suite.importers.common.
out_guard`)."""

from __future__ import annotations

import json
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from suite.catalog.toml_write import dumps_catalog
from suite.importers.common.catalog_mark import marked
from suite.importers.common.outputs import Outputs
from suite.importers.common.staging import PARTIAL_SUFFIX

__all__ = ["CATALOG_NAME", "DEFAULT_CONTROLLER", "FRAGMENT_SUFFIX", "STEP_S", "scenario_name",
           "write_atomic", "write_catalog", "write_fragment"]

CATALOG_NAME = "catalog.toml"
FRAGMENT_SUFFIX = ".scenario.json"
DEFAULT_CONTROLLER = "two_loop"
STEP_S = 0.02


def scenario_name(stem: str, fallback: str) -> str:
    """A catalog name ``[a-z0-9_]+`` from a file stem (``fallback`` when none is left)."""
    return re.sub(r"[^a-z0-9_]+", "_", stem.lower()).strip("_") or fallback


def write_atomic(path: Path, text: str) -> Path:
    """``text`` into ``path``, written beside it as ``*.partial`` and renamed."""
    partial = path.with_name(path.name + PARTIAL_SUFFIX)
    partial.write_text(text, encoding="utf-8")
    partial.replace(path)
    return path


def write_fragment(out_dir: Path, stem: str, name: str, table: Mapping[str, Any],
                   notes: Sequence[str], source: str) -> Path:
    """``<stem>.scenario.json``: the scenario table ``name``, its source and notes."""
    return write_atomic(out_dir / f"{stem}{FRAGMENT_SUFFIX}", json.dumps(
        {"name": name, "source": source, "notes": list(notes), "scenario": dict(table)},
        indent=1) + "\n")


def _fragments(out_dir: Path, outputs: Outputs) -> list[dict[str, Any]]:
    """The scenario files of ``out_dir`` (by name) that ``outputs``' catalog lists."""
    out = []
    for p in sorted(out_dir.glob(f"*{FRAGMENT_SUFFIX}")):
        try:
            data = json.loads(p.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if not (isinstance(data, dict) and isinstance(data.get("scenario"), dict)):
            continue
        if outputs.requires is None or outputs.requires in data["scenario"]:
            out.append(data)
    return out


def _unique(name: str, used: set[str]) -> str:
    """``name``, or ``name_2``, ``name_3``... the first not in ``used`` (added to it)."""
    unique, k = name, 2
    while unique in used:
        unique, k = f"{name}_{k}", k + 1
    used.add(unique)
    return unique


def write_catalog(out_dir: Path, outputs: Outputs, failed: Sequence[str] = ()) -> Path:
    """``catalog.toml`` from every scenario file in ``out_dir`` (atomically), under its
    generated-by line; names stay unique (a clash gets ``_2``, ``_3``...); ``failed``:
    the inputs that did not import, named in the header."""
    header = list(outputs.header)
    scenarios = []
    used: set[str] = set()
    for frag in _fragments(out_dir, outputs):
        table = dict(frag["scenario"])
        table["name"] = name = _unique(str(table.get("name", outputs.fallback_name)), used)
        scenarios.append(table)
        header += ["", f"{name} <- {frag.get('source', '?')}:"]
        header += [f"  {note}" for note in frag.get("notes", [])]
    if failed:
        header += ["", "Not imported (see the command's errors): " + ", ".join(failed)]
    text = dumps_catalog("\n".join(header), {"controller": DEFAULT_CONTROLLER,
                                             "step_s": STEP_S, "seed": 0}, scenarios)
    return write_atomic(out_dir / CATALOG_NAME, marked(text, outputs.command, outputs.doc))
