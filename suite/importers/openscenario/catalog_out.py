"""The catalog side: one scenario table per imported file (``<stem>.scenario.json``
beside its ``<stem>.story.json``) and ``catalog.toml`` rebuilt from every such file
of the folder, as ``import commonroad`` does."""

from __future__ import annotations

import json
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from suite.catalog.toml_write import dumps_catalog

__all__ = ["CATALOG_NAME", "FRAGMENT_SUFFIX", "scenario_name", "write_atomic", "write_catalog",
           "write_fragment"]

CATALOG_NAME = "catalog.toml"
FRAGMENT_SUFFIX = ".scenario.json"
DEFAULT_CONTROLLER = "two_loop"
STEP_S = 0.02


def scenario_name(stem: str) -> str:
    """A catalog name ``[a-z0-9_]+`` from a file stem."""
    return re.sub(r"[^a-z0-9_]+", "_", stem.lower()).strip("_") or "openscenario"


def write_atomic(path: Path, text: str) -> Path:
    partial = path.with_name(path.name + ".partial")
    partial.write_text(text, encoding="utf-8")
    partial.replace(path)
    return path


def write_fragment(out_dir: Path, stem: str, table: Mapping[str, Any], notes: Sequence[str],
                   source: str) -> Path:
    """``<stem>.scenario.json``: the scenario table, its source and notes."""
    return write_atomic(out_dir / f"{stem}{FRAGMENT_SUFFIX}", json.dumps(
        {"name": table["name"], "source": source, "notes": list(notes),
         "scenario": dict(table)}, indent=1) + "\n")


def write_catalog(out_dir: Path, failed: Sequence[str] = ()) -> Path:
    """``catalog.toml`` from every ``*.scenario.json`` of ``out_dir`` with a storyboard
    (names kept unique with ``_2``, ``_3``...)."""
    header = ["OpenSCENARIO scenarios imported by `hwyeval import openscenario`",
              "(docs/openscenario.md). Rebuilt from the *.scenario.json files of this folder."]
    scenarios: list[dict[str, Any]] = []
    used: set[str] = set()
    for p in sorted(out_dir.glob(f"*{FRAGMENT_SUFFIX}")):
        try:
            frag = json.loads(p.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        table = dict(frag.get("scenario") or {})
        if "storyboard" not in table:
            continue
        base = name = str(table.get("name", "openscenario"))
        k = 2
        while name in used:
            name, k = f"{base}_{k}", k + 1
        used.add(name)
        table["name"] = name
        scenarios.append(table)
        header += ["", f"{name} <- {frag.get('source', '?')}:"]
        header += [f"  {n}" for n in frag.get("notes", [])]
    if failed:
        header += ["", "Not imported (see the command's errors): " + ", ".join(failed)]
    text = dumps_catalog("\n".join(header), {"controller": DEFAULT_CONTROLLER,
                                             "step_s": STEP_S, "seed": 0}, scenarios)
    return write_atomic(out_dir / CATALOG_NAME, text)
