"""Reference points and headings: one home for the conversions every layer makes.

* Headings: SUMO's navigation degrees (0 = north, clockwise) and the math radians
  (CCW from +X) of everything else (:func:`nav_deg_to_math_rad`,
  :func:`math_rad_to_nav_deg`), each as numpy (arrays) and as ``math`` (one float).
* Reference points along a heading: a point ``distance_m`` ahead
  (:func:`point_ahead`, :func:`points_ahead`); a box's front bumper from its centre
  (:func:`box_front`) and back (:func:`box_centre_from_front`), SUMO's vehicle
  position being the front bumper's middle and a box's centre the geometry's.
* The ego's body box from its CG (:func:`ego_box_centre`, :func:`ego_box_centres`,
  :func:`ego_box_corners`).

The scalar forms use ``math`` and the array forms numpy, with the arithmetic written
once, so that every caller gets the same bits it computed itself before.
"""

from __future__ import annotations

import math
from typing import Any, Protocol

import numpy as np

from reports.geometry.boxes import box_corners

# ------------------------------------------------------------------ headings


def nav_deg_to_math_rad(angle_deg: Any) -> Any:
    """SUMO navigation degrees (0 = north, clockwise) -> radians CCW from +X."""
    return np.deg2rad(90.0 - np.asarray(angle_deg, dtype=np.float64))


def nav_deg_to_math_rad_scalar(angle_deg: float) -> float:
    """:func:`nav_deg_to_math_rad` of one angle with math: the same single multiply by
    pi/180 as numpy's deg2rad (bit-identical), without wrapping a scalar in an array."""
    return math.radians(90.0 - angle_deg)


def math_rad_to_nav_deg(psi_rad: float) -> float:
    """Radians CCW from +X -> SUMO navigation degrees in [0, 360)."""
    return float((90.0 - math.degrees(psi_rad)) % 360.0)


def math_rad_to_nav_deg_array(psi_rad: np.ndarray) -> np.ndarray:
    """:func:`math_rad_to_nav_deg` of an array (numpy's degrees and mod)."""
    out: np.ndarray = np.mod(90.0 - np.degrees(psi_rad), 360.0)
    return out


# ------------------------------------------------------------------ reference points


def point_ahead(x_m: float, y_m: float, heading_rad: float,
                distance_m: float) -> tuple[float, float]:
    """The point ``distance_m`` [m] ahead of (x_m, y_m) along ``heading_rad`` (behind
    for a negative distance)."""
    return (x_m + distance_m * math.cos(heading_rad),
            y_m + distance_m * math.sin(heading_rad))


def points_ahead(x_m: Any, y_m: Any, heading_rad: Any, distance_m: Any) -> tuple[Any, Any]:
    """:func:`point_ahead` of arrays (numpy's cos and sin)."""
    return (x_m + distance_m * np.cos(heading_rad), y_m + distance_m * np.sin(heading_rad))


def box_front(cx_m: float, cy_m: float, heading_rad: float,
              length_m: float) -> tuple[float, float]:
    """The middle of a box's front bumper [m] from its centre (half its length ahead)."""
    half = 0.5 * length_m
    return cx_m + half * math.cos(heading_rad), cy_m + half * math.sin(heading_rad)


def box_fronts(cx_m: Any, cy_m: Any, heading_rad: Any, length_m: Any) -> tuple[Any, Any]:
    """:func:`box_front` of arrays."""
    half = 0.5 * length_m
    return cx_m + half * np.cos(heading_rad), cy_m + half * np.sin(heading_rad)


def box_centre_from_front(fx_m: float, fy_m: float, heading_rad: float,
                          length_m: float) -> tuple[float, float]:
    """A box's centre [m] from the middle of its front bumper (SUMO's vehicle
    position): half its length behind."""
    half = 0.5 * length_m
    return fx_m - half * math.cos(heading_rad), fy_m - half * math.sin(heading_rad)


def box_centres_from_fronts(fx_m: Any, fy_m: Any, heading_rad: Any,
                            length_m: Any) -> tuple[Any, Any]:
    """:func:`box_centre_from_front` of arrays."""
    half = 0.5 * length_m
    return fx_m - half * np.cos(heading_rad), fy_m - half * np.sin(heading_rad)


# ------------------------------------------------------------------ the ego's box


class BoxShape(Protocol):
    """A body box relative to its CG [m] (``reports.record.meta.EgoBox`` is one)."""

    @property
    def length_m(self) -> float: ...

    @property
    def width_m(self) -> float: ...

    @property
    def cg_to_box_centre_m(self) -> float: ...


def ego_box_centre(x_cg: float, y_cg: float, psi_rad: float,
                   cg_to_box_centre_m: float) -> tuple[float, float]:
    """The ego's box centre [m] from its CG (the box centre lies ahead of the CG by the
    offset [m] along the yaw psi_rad)."""
    return (float(x_cg + cg_to_box_centre_m * np.cos(psi_rad)),
            float(y_cg + cg_to_box_centre_m * np.sin(psi_rad)))


def ego_box_centres(x_m: np.ndarray, y_m: np.ndarray, psi_rad: np.ndarray,
                    ego: BoxShape) -> tuple[np.ndarray, np.ndarray]:
    """Box centres (T,) [m] along a CG path (T,): ``cg_to_box_centre_m`` ahead of the CG
    along the yaw."""
    psi = np.asarray(psi_rad, dtype=np.float64)
    return (np.asarray(x_m, dtype=np.float64) + ego.cg_to_box_centre_m * np.cos(psi),
            np.asarray(y_m, dtype=np.float64) + ego.cg_to_box_centre_m * np.sin(psi))


def ego_box_corners(x_m: np.ndarray, y_m: np.ndarray, psi_rad: np.ndarray,
                    ego: BoxShape) -> np.ndarray:
    """Corners (T, 4, 2) [m] of the ego box along a CG path (T,)."""
    cx, cy = ego_box_centres(x_m, y_m, psi_rad, ego)
    return box_corners(cx, cy, psi_rad, ego.length_m, ego.width_m).reshape(cx.shape[0], 4, 2)
