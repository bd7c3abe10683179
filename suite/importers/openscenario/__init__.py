"""``hwyeval import openscenario``: ASAM OpenSCENARIO 1.0-1.3 files on OpenDRIVE roads ->
a catalog folder whose scenarios carry a typed storyboard (docs/openscenario.md).

One job per module: :mod:`.xml_safe` (safe reading), :mod:`.expr` (expressions),
:mod:`.params` (declarations, references, constraints), :mod:`.catalogs` (catalog
references), :mod:`.road` (OpenDRIVE -> SUMO net and lane map), :mod:`.lane_bands`
(lanes across a road), :mod:`.positions` and :mod:`.position_xml` (positions on the
route), :mod:`.entities`, :mod:`.conditions_xml`, :mod:`.actions_xml`, :mod:`.story`
(the storyboard), :mod:`.variation` (parameter distributions), :mod:`.catalog_out`
(writing), :mod:`.plan` (what will be written, checked before anything is, with
:mod:`suite.importers.common`) and :mod:`.pipeline` (the whole import).
"""

from suite.importers.common.errors import OutputRefused
from suite.importers.openscenario.errors import OscImportError
from suite.importers.openscenario.pipeline import ImportOptions, ImportOutcome, import_files

__all__ = ["ImportOptions", "ImportOutcome", "OscImportError", "OutputRefused", "import_files"]
