"""What an import will write, known before anything is: each input's stem and the
road (``.xodr``) it is on, so the shared guards (:mod:`suite.importers.common.
out_guard`) can refuse two inputs of one stem and two roads of one net name before the
first file is written. Several files on one road (one real path) share its net and lane
map: one output, not a collision."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from suite.importers.common import out_guard
from suite.importers.openscenario.catalog_out import OUTPUTS, net_stem
from suite.importers.openscenario.errors import OscImportError, fail_at
from suite.importers.openscenario.params import declare, resolve_tree
from suite.importers.openscenario.variation import template_of
from suite.importers.openscenario.xml_safe import read_xml

__all__ = ["check_plan", "road_file", "road_of"]


def road_file(root: Any, source: Path) -> Path:
    """The OpenDRIVE file of the (resolved) scenario ``root`` read from ``source``."""
    logic = root.find("RoadNetwork/LogicFile")
    if logic is None or not logic.get("filepath"):
        raise fail_at(root.find("RoadNetwork") if root.find("RoadNetwork") is not None
                      else root, "a RoadNetwork LogicFile (OpenDRIVE) is required")
    xodr = (source.parent / str(logic.get("filepath"))).resolve()
    if not xodr.is_file():
        raise fail_at(logic, f"no OpenDRIVE file {xodr}")
    return xodr


def road_of(source: Path) -> Path | None:
    """The road ``source`` (a scenario, or a variation file: its template's) is on, with
    its declared parameter values; None when that cannot be told (the import of the file
    fails and says why)."""
    try:
        root = read_xml(source).getroot()
        if root.find("ParameterValueDistribution") is not None:
            source = template_of(root, source)
            root = read_xml(source).getroot()
        resolve_tree(root, declare(root, None, ignore_constraints=True))
        return road_file(root, source)
    except OscImportError:
        return None


def check_plan(sources: Sequence[Path], out_dir: Path, overwrite: bool) -> tuple[Path, ...]:
    """``sources`` without repeats, after every check of :mod:`suite.importers.common.
    out_guard` (OutputRefused; nothing is written)."""
    sources = out_guard.check_inputs(sources, OUTPUTS)
    roads = [(net_stem(r), r) for r in map(road_of, sources) if r is not None]
    out_guard.check_shared(roads, OUTPUTS)
    names = [n for s in sources
             for n in out_guard.output_names(out_guard.output_stem(s, OUTPUTS),
                                             OUTPUTS.per_input)]
    names += [n for stem, _ in roads for n in out_guard.output_names(stem, OUTPUTS.shared)]
    out_guard.check_out_dir(out_dir, names, OUTPUTS, overwrite)
    return sources
