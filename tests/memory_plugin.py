"""A controller plug-in for tests (``--plugin tests/memory_plugin.py``): drives like
lane_keep and at its 20th step asks for :data:`ALLOCATE_BYTES` of memory (8 GiB, left
untouched, so that without a cap it costs no resident memory and the run goes on), as
a runaway controller would."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from controllers import registry
from controllers.protocol import Command, Observation, ScenarioContext

ALLOCATE_BYTES = 8 * 1024**3  # more than the tests' 6 GiB cap, less than a machine's [bytes]


class AllocateAtStep20:
    name = "allocate_at_step_20"

    def __init__(self) -> None:
        self.inner: Any = registry.make("lane_keep")
        self.steps = 0

    def reset(self, context: ScenarioContext) -> None:
        self.inner.reset(context)

    def step(self, observation: Observation) -> Command:
        self.steps += 1
        if self.steps == 20:
            block = np.empty(ALLOCATE_BYTES, dtype=np.uint8)  # untouched: address space only
            del block
        result: Command = self.inner.step(observation)
        return result

    def parameters(self) -> dict[str, Any]:
        return {"name": self.name}

    def __getattr__(self, attr: str) -> Any:  # obstacle policy, diagnostics type: lane_keep's
        return getattr(self.inner, attr)


def make(options: Mapping[str, Any]) -> AllocateAtStep20:
    del options
    return AllocateAtStep20()


registry.register("allocate_at_step_20", make)
