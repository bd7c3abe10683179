"""Stress catalogs (docs/stress.md): ``python -m suite.stress --n 300 --seed S --out DIR``.

The generator draws scenarios from :class:`~suite.stress.config.StressConfig` (the
distribution of issue 10 plus its features), builds their nets with netconvert, places
them on the built networks, writes a catalog ``hwyeval run`` accepts, validates it and
measures what it covers. One job per module: :mod:`~suite.stress.config` (the
distributions), :mod:`~suite.stress.plan` (what each scenario will be, before any net),
:mod:`~suite.stress.netgen` (generated nets), :mod:`~suite.stress.real` (the real
motorways), :mod:`~suite.stress.lanes` (through lanes and lane geometry of a route),
:mod:`~suite.stress.scenarios` (a plan placed on its net), :mod:`~suite.stress.tomlout`
(writing TOML), :mod:`~suite.stress.coverage` (what a catalog covers, measured) and
:mod:`~suite.stress.generate` (all of it, into a folder).
"""

from suite.stress.config import FEATURES, StressConfig
from suite.stress.generate import StressCatalog, generate

__all__ = ["FEATURES", "StressCatalog", "StressConfig", "generate"]
