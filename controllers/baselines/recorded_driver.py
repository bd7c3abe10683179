"""``recorded``: the ego drives its own recorded trajectory (the human's drive).

Not a controller: the factory returns :class:`RecordedDriverModel`, and the run moves
the ego along the track its scenario names (``replay.ego_track``: a recorded vehicle of
the scenario's tracks file) instead of integrating a plant, its pose pushed into the
world each step as the replayed cars' are (``suite.run.recorded``). nuPlan's log-replay
expert: every recorded scenario with a recorded ego gets the human's verdict beside the
controllers', judged by the same metrics. It has no options (a catalog option would be
accepted and ignored: it is refused), and a scenario without ``replay.ego_track`` cannot
use it (a catalog error).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from controllers.protocol import ConfigError

NAME = "recorded"


@dataclass(frozen=True)
class RecordedDriverModel:
    """Not a controller: the recorded driver drives the ego (catalog name ``recorded``).

    The run then takes the ego's pose from its recorded track, linearly interpolated at
    every control step (docs/recorded.md); steer and torque are not known (NaN)."""

    name: str = NAME
    source: str = "recorded track (replay.ego_track), linearly interpolated"

    def parameters(self) -> Mapping[str, Any]:
        return {"driver": self.source}


def make_recorded_driver(options: Mapping[str, Any]) -> RecordedDriverModel:
    """The recorded driver; ``options`` may only repeat ``name = "recorded"``."""
    for key, value in options.items():
        if key == "name":
            if value != NAME:
                raise ConfigError("controller.name", f"{NAME!r}", value)
            continue
        raise ConfigError(f"controller.{key}",
                          "no options (the recorded driver drives its recording)", key)
    return RecordedDriverModel()
