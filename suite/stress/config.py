"""The distributions of a stress catalog (:class:`StressConfig`) and the features it
covers (:data:`FEATURES`).

Every range is a closed interval ``(low, high)`` drawn uniformly; every ``*_share`` is the
fraction of scenarios with that feature, assigned by a stratified schedule (see
:func:`suite.stress.plan.has_feature`) so that any n scenarios hold floor(n share) or
ceil(n share) of them. Units are in the names.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import TypeGuard

__all__ = ["FEATURES", "StressConfig"]

Range = tuple[float, float]

FEATURES: tuple[str, ...] = (
    "lanes_2", "lanes_3", "lanes_4", "shoulder", "no_shoulder", "curve", "stalled_1",
    "stalled_2", "stalled_3", "several_stalled", "close_stall", "free_road", "traffic",
    "slow_passing_lane", "merge", "real_net",
)
"""What a stress catalog covers, measured on the catalog it wrote
(:mod:`suite.stress.coverage`): generated nets of 2, 3 and 4 lanes, with and without a
hard shoulder, with a curve; 1, 2, 3 and several (4+) stalled cars; a stalled car close
ahead at the start; no traffic and traffic; slower traffic in the passing lane; traffic
merging from an on-ramp; the real motorways (when present)."""


@dataclass(frozen=True)
class StressConfig:
    """The stress distribution (docs/stress.md). Defaults: the issue's distribution
    (2-4 lanes, shoulder or not, one curve of R 300-1500 m over 25-70 deg, 1-3 stalled
    cars 250-1500 m ahead, ego at 18-31 m/s, 0-2400 veh/h, 40 s) plus its features."""

    duration_s: float = 40.0
    step_s: float = 0.02
    lanes: tuple[int, ...] = (2, 3, 4)
    shoulder_share: float = 0.5
    curve_radius_m: Range = (300.0, 1500.0)
    curve_angle_deg: Range = (25.0, 70.0)
    curve_ahead_m: Range = (100.0, 900.0)  # curve start ahead of the ego
    ego_start_m: Range = (200.0, 400.0)  # ego position on a generated route
    ego_speed_mps: Range = (18.0, 31.0)
    stalled_count: tuple[int, int] = (1, 3)
    stalled_ahead_m: Range = (250.0, 1500.0)
    stalled_spacing_m: float = 120.0  # any two stalled cars at least this far apart
    free_road_share: float = 0.15  # no background traffic
    traffic_vph: Range = (100.0, 2400.0)  # otherwise, on all lanes together
    slow_passing_share: float = 0.25
    slow_passing_below_mps: Range = (4.0, 10.0)  # passing-lane speed below the ego's
    slow_passing_min_mps: float = 12.0
    slow_passing_min_vph: float = 600.0
    merge_share: float = 0.25
    merge_ahead_m: Range = (150.0, 800.0)  # where the ramp joins, ahead of the ego
    ramp_vph: Range = (200.0, 900.0)
    ramp_speed_mps: Range = (18.0, 25.0)
    several_stalled_share: float = 0.1
    several_stalled_count: tuple[int, int] = (4, 6)
    close_stall_share: float = 0.15
    close_stall_ahead_m: Range = (40.0, 90.0)
    close_stall_speed_mps: Range = (20.0, 27.0)
    close_stall_decel_mps2: float = 7.0  # a stop at this deceleration must fit ...
    close_stall_reaction_s: float = 0.3  # ... after this reaction time
    real_share: float = 0.2
    wet_share: float = 0.0
    wet_friction: Range = (0.5, 0.7)
    controllers: tuple[str, ...] = ("two_loop",)

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.name not in ("lanes", "controllers"):
                _check_value(f.name, getattr(self, f.name))
        self._check_names()
        self._check_consistency()

    def _check_names(self) -> None:
        """Raise ValueError unless ``lanes`` lists lane counts in 1..6 and
        ``controllers`` non-empty controller names."""
        if not self.lanes or any(not isinstance(n, int) or not 1 <= n <= 6 for n in self.lanes):
            raise ValueError(f"StressConfig.lanes must list lane counts in 1..6, got "
                             f"{self.lanes!r}")
        if not self.controllers or any(not isinstance(c, str) or not c
                                       for c in self.controllers):
            raise ValueError(f"StressConfig.controllers must name controllers, got "
                             f"{self.controllers!r}")

    def _check_consistency(self) -> None:
        """Raise ValueError unless the fields agree with each other: a step within the
        duration, the stalled counts ordered, several stalled cars fitting their range,
        the wet friction in (0, 2]."""
        if self.step_s > self.duration_s:
            raise ValueError("StressConfig.step_s must not exceed duration_s")
        if self.stalled_count[0] < 1 or self.several_stalled_count[0] <= self.stalled_count[1]:
            raise ValueError("StressConfig: stalled_count must start at 1 and several_stalled_"
                             "count above it")
        span = self.stalled_ahead_m[1] - self.stalled_ahead_m[0]
        if (self.several_stalled_count[1] - 1) * self.stalled_spacing_m > span:
            raise ValueError("StressConfig: several_stalled_count cars do not fit "
                             "stalled_ahead_m at stalled_spacing_m")
        if not 0.0 < self.wet_friction[0] <= self.wet_friction[1] <= 2.0:
            raise ValueError(f"StressConfig.wet_friction must lie in (0, 2], got "
                             f"{self.wet_friction!r}")


def _check_value(name: str, value: object) -> None:
    """Raise ValueError unless field ``name`` holds what its kind needs: a share in
    [0, 1], a range (low, high) with 0 <= low <= high, else a number > 0."""
    if name.endswith("_share"):
        if not (_real(value) and 0.0 <= value <= 1.0):
            raise ValueError(f"StressConfig.{name} must be in [0, 1], got {value!r}")
    elif isinstance(value, tuple):
        if len(value) != 2 or not all(_real(v) for v in value) or value[0] > value[1] \
                or value[0] < 0:
            raise ValueError(f"StressConfig.{name} must be a range (low, high) with "
                             f"0 <= low <= high, got {value!r}")
    elif not (_real(value) and value > 0):
        raise ValueError(f"StressConfig.{name} must be a number > 0, got {value!r}")


def _real(value: object) -> TypeGuard[float]:
    """Whether ``value`` is a finite int or float (not a bool)."""
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
