"""An example hwyeval controller plug-in: ``pd_follow``.

The entry point ``pd_follow = "hwyeval_example_controller:PLUGIN"`` (group
``hwyeval.controllers``, see pyproject.toml) makes hwyeval's registry find it in every
process that looks a controller up: ``hwyeval controllers`` lists it and a catalog can
say ``controller = { name = "pd_follow", time_gap_s = 1.8 }``.
"""

from controllers.registry import ControllerPlugin
from hwyeval_example_controller.controller import (
    PdFollowController,
    PdFollowDiagnostics,
    PdFollowParams,
    make_pd_follow,
)

PLUGIN = ControllerPlugin(factory=make_pd_follow, parameters=PdFollowParams)

__all__ = ["PLUGIN", "PdFollowController", "PdFollowDiagnostics", "PdFollowParams",
           "make_pd_follow"]
