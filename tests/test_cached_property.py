"""controllers.cached.cached_property: computed once per instance, frozen dataclasses too."""

from __future__ import annotations

from dataclasses import dataclass

from controllers.cached import cached_property


@dataclass(frozen=True)
class _Scene:
    x: float
    calls: list[int]

    @cached_property
    def doubled(self) -> float:
        self.calls.append(1)
        return 2.0 * self.x


def test_computed_once_per_instance_and_stored() -> None:
    calls: list[int] = []
    a, b = _Scene(1.5, calls), _Scene(4.0, calls)
    assert a.doubled == 3.0 and a.doubled == 3.0 and b.doubled == 8.0
    assert len(calls) == 2
    assert a.__dict__["doubled"] == 3.0
    assert isinstance(_Scene.__dict__["doubled"], cached_property)
