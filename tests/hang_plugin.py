"""A controller plug-in for tests (``--plugin tests/hang_plugin.py``): drives like
lane_keep and hangs at its 20th step in a loop that never gives the GIL back (as a step
stuck in C would), so only a process-level backstop can end the run."""

from __future__ import annotations

import ctypes
from collections.abc import Mapping
from typing import Any

from controllers import registry
from controllers.protocol import Command, Observation, ScenarioContext


class HangAtStep20:
    name = "hang_at_step_20"

    def __init__(self) -> None:
        self.inner: Any = registry.make("lane_keep")
        self.steps = 0

    def reset(self, context: ScenarioContext) -> None:
        self.inner.reset(context)

    def step(self, observation: Observation) -> Command:
        self.steps += 1
        if self.steps == 20:
            # sleep(3600) in C, holding the GIL: nothing in this process runs again
            libc = ctypes.PyDLL(None)
            libc.sleep(3600)
        result: Command = self.inner.step(observation)
        return result

    def parameters(self) -> dict[str, Any]:
        return {"name": self.name}

    def __getattr__(self, attr: str) -> Any:  # obstacle policy, diagnostics type: lane_keep's
        return getattr(self.inner, attr)


def make(options: Mapping[str, Any]) -> HangAtStep20:
    del options
    return HangAtStep20()


registry.register("hang_at_step_20", make)
