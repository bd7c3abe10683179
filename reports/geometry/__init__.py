"""The one home of geometry and reference points, the lowest layer of ``reports``.

Below ``reports.record``; ``suite`` imports it too (the simulation loop's per-step
safety check ``suite.run.safety``, the SUMO world's poses, the replay, the road and the
importers), so every layer that handles poses and polylines takes them from here.
(``controllers`` keeps its own Frenet path: the top-level contract lets it import no
other hwyeval package.)

One module per job:

* :mod:`~reports.geometry.boxes`: oriented boxes (corners, overlap, distance, gaps,
  swept TTC), compiled kernels; a box is (cx, cy, heading_rad, length_m, width_m), its
  corners (4, 2) front-left, rear-left, rear-right, front-right;
* :mod:`~reports.geometry.excess`: the signed excess of points over a union of convex
  polygons (the drivable area);
* :mod:`~reports.geometry.frenet`: points in the Frenet frame of a polyline (compiled);
* :mod:`~reports.geometry.polyline`: polyline length, cumulative arc length,
  resampling and the projection of points;
* :mod:`~reports.geometry.poses`: headings (SUMO's navigation degrees <-> radians) and
  reference points (box centre <-> front bumper, the ego's box from its CG);
* :mod:`~reports.geometry.segments`: segments against convex quads;
* :mod:`~reports.geometry.motion`: a track's motion against its speeds and headings.

The names of each are re-exported here.
"""

from __future__ import annotations

import numpy as np

from reports.geometry.boxes import (
    box_corners,
    box_distance,
    box_gaps,
    boxes_overlap,
    nearest_box,
    swept_box_ttc,
)
from reports.geometry.excess import polygons_excess
from reports.geometry.frenet import PathFrame, polyline_frenet
from reports.geometry.motion import jump_excess_mps
from reports.geometry.polyline import (
    Feet,
    Projection,
    angle_diff_rad,
    arc_lengths_m,
    end_heading_rad,
    polyline_length_m,
    project,
    project_points,
    resample,
    segment_lengths_m,
)
from reports.geometry.poses import (
    BoxShape,
    box_centre_from_front,
    box_centres_from_fronts,
    box_front,
    box_fronts,
    ego_box_centre,
    ego_box_centres,
    ego_box_corners,
    math_rad_to_nav_deg,
    math_rad_to_nav_deg_array,
    nav_deg_to_math_rad,
    nav_deg_to_math_rad_scalar,
    point_ahead,
    points_ahead,
)
from reports.geometry.segments import segment_box_distance_m, segment_hits_box

__all__ = [
    "BoxShape", "Feet", "PathFrame", "Projection", "angle_diff_rad", "arc_lengths_m",
    "box_centre_from_front", "box_centres_from_fronts", "box_corners", "box_distance",
    "box_front", "box_fronts", "box_gaps", "boxes_overlap", "ego_box_centre",
    "ego_box_centres", "ego_box_corners", "end_heading_rad", "jump_excess_mps",
    "load_kernels", "math_rad_to_nav_deg", "math_rad_to_nav_deg_array",
    "nav_deg_to_math_rad", "nav_deg_to_math_rad_scalar", "nearest_box", "point_ahead",
    "points_ahead", "polygons_excess", "polyline_frenet", "polyline_length_m", "project",
    "project_points", "resample", "segment_box_distance_m", "segment_hits_box",
    "segment_lengths_m", "swept_box_ttc",
]


def load_kernels() -> None:
    """Load (or compile once) every compiled kernel of this package by calling it on tiny
    inputs: a process that forks scenario processes calls it once, so that they inherit
    the compiled code instead of each loading it from numba's cache."""
    one = box_corners(0.0, 0.0, 0.0, 4.0, 2.0)[None]
    boxes_overlap(one, one)
    box_distance(one, one)
    swept_box_ttc(one, np.zeros((1, 2)), one, np.zeros((1, 2)), 1.0)
    z = np.zeros(1)
    box_gaps(0.0, 0.0, 0.0, 4.0, 2.0, z, z, z, z + 4.0, z + 2.0)
    nearest_box(0.0, 0.0, 0.0, 4.0, 2.0, z, z, z, z + 4.0, z + 2.0)
    polygons_excess(np.zeros((1, 2)), one)
    polyline_frenet(np.array([[0.0, 0.0], [1.0, 0.0]]), z, z, z, z, track=True)
