"""The OpenSCENARIO storyboard at run time (docs/openscenario.md): the element state
machine (:mod:`.engine`), condition edges and delays (:mod:`.triggers`), condition tests
(:mod:`.conditions`, on :mod:`.state`'s entity views), the actions' motions
(:mod:`.motion`, :mod:`.profiles`), the road's lanes (:mod:`.road`) and the SUMO side
(:mod:`.sumo_bridge`). It imports the typed model of :mod:`suite.catalog.storyboard`,
never the importer."""

from suite.world.storyboard.engine import StoryEngine, Transition
from suite.world.storyboard.sumo_bridge import StoryRunner, sumo_id

__all__ = ["StoryEngine", "StoryRunner", "Transition", "sumo_id"]
