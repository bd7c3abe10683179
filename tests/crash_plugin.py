"""A controller plug-in for tests (``--plugin tests/crash_plugin.py``): drives like
lane_keep and raises at its 50th step, so that a valid catalog fails at run time."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from controllers import registry
from controllers.protocol import Command, Observation, ScenarioContext


class CrashAtStep50:
    name = "crash_at_step_50"

    def __init__(self) -> None:
        self.inner: Any = registry.make("lane_keep")
        self.steps = 0

    def reset(self, context: ScenarioContext) -> None:
        self.inner.reset(context)

    def step(self, observation: Observation) -> Command:
        self.steps += 1
        if self.steps == 50:
            raise RuntimeError("deliberate crash at step 50")
        result: Command = self.inner.step(observation)
        return result

    def parameters(self) -> dict[str, Any]:
        return {"name": self.name}

    def __getattr__(self, attr: str) -> Any:  # obstacle policy, diagnostics type: lane_keep's
        return getattr(self.inner, attr)


def make(options: Mapping[str, Any]) -> CrashAtStep50:
    del options
    return CrashAtStep50()


registry.register("crash_at_step_50", make)
