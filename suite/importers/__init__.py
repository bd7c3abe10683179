"""Importers: turn recorded scenarios of other formats into hwyeval catalogs.

* :mod:`suite.importers.commonroad`: CommonRoad XML files (a SUMO net from the lanelet
  network, a tracks file of the recorded vehicles, a catalog scenario; docs/recorded.md).
* :mod:`suite.importers.openscenario`: ASAM OpenSCENARIO 1.x files on OpenDRIVE roads (a
  SUMO net and its lane map, a typed storyboard, a catalog scenario; docs/openscenario.md).

An importer may use :mod:`suite.catalog`, :mod:`suite.road`, :mod:`sumo_nets` and
:mod:`controllers.plant`, never the run machinery (``suite.run``/``exec``/``world``):
what it writes is an ordinary catalog that ``hwyeval run`` reads without the importer.
"""
