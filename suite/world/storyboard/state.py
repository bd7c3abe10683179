"""What the storyboard knows of an entity at a step: its place on the route, speed and
box, and the measures the conditions compare (distances, headway, time to collision)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from suite.catalog.storyboard import Entity

__all__ = ["EntityView", "headway_s", "longitudinal_gap_m", "relative_distance_m", "ttc_s"]


@dataclass(frozen=True)
class EntityView:
    """An entity at one instant: front bumper route position ``pos_m`` [m], lateral
    place ``y_m`` [m, left +, from the left border of the road's leftmost lane:
    :mod:`suite.world.storyboard.road`], world
    front bumper ``x_m``, ``y_world_m`` [m], heading [rad], speed [m/s], distance
    travelled since t = 0 [m], and its box."""

    entity: Entity
    pos_m: float
    y_m: float
    x_m: float
    y_world_m: float
    heading_rad: float
    speed_mps: float
    travelled_m: float = 0.0

    @property
    def ref_pos_m(self) -> float:
        """Route position [m] of the OpenSCENARIO reference point."""
        return self.pos_m - self.entity.front_m


def longitudinal_gap_m(a: EntityView, b: EntityView, freespace: bool) -> float:
    """Signed distance [m] along the route from a to b (> 0: b ahead): between the
    reference points, or bumper to bumper (``freespace``; 0 when they overlap)."""
    if not freespace:
        return b.ref_pos_m - a.ref_pos_m
    if b.pos_m - b.entity.length_m >= a.pos_m:  # b ahead: its rear to a's front
        return b.pos_m - b.entity.length_m - a.pos_m
    if a.pos_m - a.entity.length_m >= b.pos_m:  # b behind
        return -(a.pos_m - a.entity.length_m - b.pos_m)
    return 0.0


def _lateral_gap_m(a: EntityView, b: EntityView, freespace: bool) -> float:
    d = abs(b.y_m - a.y_m)
    return max(d - 0.5 * (a.entity.width_m + b.entity.width_m), 0.0) if freespace else d


def relative_distance_m(a: EntityView, b: EntityView, kind: str, freespace: bool) -> float:
    """The (unsigned) distance [m] of ``kind`` (longitudinal, lateral, cartesian)."""
    if kind == "longitudinal":
        return abs(longitudinal_gap_m(a, b, freespace))
    if kind == "lateral":
        return _lateral_gap_m(a, b, freespace)
    return math.hypot(longitudinal_gap_m(a, b, freespace), _lateral_gap_m(a, b, freespace))


def headway_s(a: EntityView, b: EntityView, freespace: bool) -> float:
    """Time headway [s] of a to b ahead: gap / a's speed (inf: b not ahead, a still)."""
    gap = longitudinal_gap_m(a, b, freespace)
    if gap < 0.0 or a.speed_mps <= 0.0:
        return math.inf
    return gap / a.speed_mps


def ttc_s(a: EntityView, b: EntityView, freespace: bool) -> float:
    """Time to collision [s] of a with b ahead: gap / (v_a - v_b) (inf: not closing)."""
    gap = longitudinal_gap_m(a, b, freespace)
    closing = a.speed_mps - b.speed_mps
    if gap < 0.0 or closing <= 0.0:
        return math.inf
    return gap / closing
