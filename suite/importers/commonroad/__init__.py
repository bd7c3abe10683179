"""``hwyeval import commonroad``: CommonRoad XML scenarios -> a self-contained folder
(docs/recorded.md).

Per file ``<stem>``: ``<stem>.net.xml`` (:mod:`.net_build`, from the lanelet rows of
:mod:`.lanelets`; wedges and short skewed links become junction links,
:mod:`.connectors`; widths and bound pairing in :mod:`.geometry`),
``<stem>.tracks.parquet`` (:mod:`.tracks`, written with
:func:`suite.catalog.tracks.write_tracks`), its scenario in ``catalog.toml``
(:mod:`.catalog_out`, written by :mod:`suite.importers.common.catalog`); the checks of
:mod:`.checks` (time step, road membership), of :mod:`.reader` (uncertain states,
non-finite numbers), :mod:`.structure` (unique ids, goal lanelets) and :mod:`.limits`
(coordinates, times); what may be written where, :mod:`suite.importers.common.out_guard`
(before anything is written) and :mod:`suite.importers.common.staging`, shared with
``import openscenario``. :mod:`.pipeline` runs the stages; :mod:`.reader` is
the only module that imports commonroad-io (lazily): running an imported catalog needs
no CommonRoad package.
"""

from suite.importers.commonroad.errors import ImportFailure, OutputRefused
from suite.importers.commonroad.pipeline import (
    FileResult,
    ImportOutcome,
    ImportParams,
    import_file,
    import_files,
)

__all__ = ["FileResult", "ImportFailure", "ImportOutcome", "ImportParams", "OutputRefused",
           "import_file", "import_files"]
