"""The catalog side: one scenario table per imported file (``<stem>.scenario.json``
beside its ``<stem>.story.json``) and ``catalog.toml`` rebuilt from every such file of
the folder that has a storyboard, written by :mod:`suite.importers.common.catalog` as
``import commonroad``'s (:data:`OUTPUTS` says what this import writes)."""

from __future__ import annotations

from pathlib import Path

from suite.importers.common import catalog
from suite.importers.common.catalog import FRAGMENT_SUFFIX, write_atomic, write_fragment
from suite.importers.common.outputs import Outputs

__all__ = ["FRAGMENT_SUFFIX", "OUTPUTS", "net_stem", "scenario_name", "write_atomic",
           "write_fragment"]

OUTPUTS = Outputs(
    command="openscenario", input_suffix=".xosc",
    per_input=(".story.json", ".sets.json", FRAGMENT_SUFFIX), shared=(".net.xml", ".lanes.json"),
    doc="docs/openscenario.md",
    header=("OpenSCENARIO scenarios imported by `hwyeval import openscenario`",
            "(docs/openscenario.md). Rebuilt from the *.scenario.json files of this folder."),
    fallback_name="openscenario", requires="storyboard")
"""What the import writes (:mod:`suite.importers.common`): per file ``<stem>.story.json``,
``<stem>.scenario.json`` (and a variation file's ``<stem>.sets.json``, its sets'
``<stem>__set<k>.*``); per road ``<road>.net.xml`` and ``<road>.lanes.json``, one for
every file on that road; and ``catalog.toml``."""


def scenario_name(stem: str) -> str:
    """A catalog name ``[a-z0-9_]+`` from a file stem."""
    return catalog.scenario_name(stem, OUTPUTS.fallback_name)


def net_stem(xodr: Path) -> str:
    """The stem of the outputs of the road ``xodr`` (``<stem>.net.xml``,
    ``<stem>.lanes.json``)."""
    return scenario_name(xodr.stem)
