"""What every importer does with its output folder, whatever the format it reads
(docs/recorded.md, "The output folder"; docs/openscenario.md).

* :mod:`.outputs`: :class:`~.outputs.Outputs`, what one importer writes (its command,
  its input suffix, the suffixes of its outputs, its catalog's header).
* :mod:`.out_guard`: the checks before anything is written (two inputs of one stem,
  files the import did not write, a hand-written or edited ``catalog.toml``), and the
  removal of what a killed import left.
* :mod:`.staging`: a file's outputs written into a staging folder and renamed into the
  output folder once all of them are.
* :mod:`.catalog`: one ``<stem>.scenario.json`` per scenario and ``catalog.toml``
  rebuilt from all of them, under the generated-by line of :mod:`.catalog_mark`.

Nothing here reads a scenario format; an importer passes its :class:`~.outputs.Outputs`.
"""

from suite.importers.common.errors import OutputRefused
from suite.importers.common.outputs import Outputs

__all__ = ["OutputRefused", "Outputs"]
