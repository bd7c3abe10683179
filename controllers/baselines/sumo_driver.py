"""``sumo``: the ego is driven by SUMO's own driver model (Krauss + LC2013).

Not a controller: the factory returns :class:`controllers.protocol.SumoDriverModel`,
and the run takes the ego's pose from SUMO instead of a plant. It has no options (a
catalog option would be accepted and ignored: it is refused).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from controllers.protocol import ConfigError, SumoDriverModel

NAME = "sumo"


def make_sumo_driver(options: Mapping[str, Any]) -> SumoDriverModel:
    """SUMO's driver model; ``options`` may only repeat ``name = "sumo"``."""
    for key, value in options.items():
        if key == "name":
            if value != NAME:
                raise ConfigError("controller.name", f"{NAME!r}", value)
            continue
        raise ConfigError(f"controller.{key}", "no options (SUMO's own driver takes none)",
                          key)
    return SumoDriverModel()
