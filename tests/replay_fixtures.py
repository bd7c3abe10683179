"""Synthetic recorded traffic on the bundled straight 3-lane net (lanes at y = -3.5, 0,
3.5 m; x along the road from 0 to 2500 m) for the replay tests: tracks files written
with :func:`suite.catalog.tracks.write_tracks` and a catalog using them."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from suite.catalog.tracks import Track, TrackSet, write_tracks

LANE_Y_M = {0: -3.5, 1: 0.0, 2: 3.5}
EGO_LENGTH_M = 4.8  # VehicleParams' box: the ego's front bumper at pos_m


def track(tid: str, t_s: np.ndarray, x_m: np.ndarray, y_m: np.ndarray, *,
          length_m: float = 4.5, width_m: float = 1.8, kind: str = "car") -> Track:
    """A track whose heading and speed follow its path (finite differences)."""
    dx, dy = np.gradient(x_m, t_s), np.gradient(y_m, t_s)
    return Track(tid, kind, length_m, width_m, t_s, x_m, y_m,
                 np.unwrap(np.arctan2(dy, dx)), np.hypot(dx, dy))


def lane_change_y(t_s: np.ndarray, y0_m: float, y1_m: float, t0_s: float,
                  dur_s: float) -> np.ndarray:
    """y(t): y0 until t0, a linear move to y1 over ``dur_s``, then y1."""
    return y0_m + (y1_m - y0_m) * np.clip((t_s - t0_s) / dur_s, 0.0, 1.0)


def fidelity_tracks() -> TrackSet:
    """rec_1: lane 2 ahead of the ego, weaving by 1 m, samples every 0.25 s (SUMO steps
    between samples); rec_2: a truck in lane 0 appearing at 2.05 s (off SUMO's grid)
    and leaving after 6.0 s; rec_3: present from 1.0 s to 3.3 s in lane 2, further on."""
    t1 = np.arange(0.0, 10.01, 0.25)
    x1 = 140.0 + 22.0 * t1
    y1 = LANE_Y_M[2] - 0.5 + 0.5 * np.cos(0.6 * t1)
    t2 = np.arange(2.05, 6.001, 0.1)
    x2 = 70.0 + 24.0 * (t2 - 2.05) + 0.3 * (t2 - 2.05) ** 2
    t3 = np.arange(1.0, 3.301, 0.1)
    x3 = 260.0 + 18.0 * (t3 - 1.0)
    return TrackSet((track("rec_1", t1, x1, y1),
                     track("rec_2", t2, x2, np.full_like(t2, LANE_Y_M[0]), length_m=12.0,
                           width_m=2.5, kind="truck"),
                     track("rec_3", t3, x3, np.full_like(t3, LANE_Y_M[2]))), 0.1,
                    ("synthetic: written by tests/replay_fixtures.py",))


def rear_end_tracks() -> TrackSet:
    """rec_9: in lane 1 from x = 100 m at 20 m/s, straight at an ego ahead."""
    t = np.arange(0.0, 12.01, 0.1)
    return TrackSet((track("rec_9", t, 100.0 + 20.0 * t, np.zeros_like(t)),), 0.1)


def cut_in_tracks() -> TrackSet:
    """rec_5: in lane 0, 47.6 m behind the ego's centre at 25 m/s (the ego drives 20),
    moving into lane 1 from 4 s over 3 s."""
    t = np.arange(0.0, 10.01, 0.1)
    return TrackSet((track("rec_5", t, 50.0 + 25.0 * t,
                           lane_change_y(t, LANE_Y_M[0], LANE_Y_M[1], 4.0, 3.0)),), 0.1)


CATALOG = """
[defaults]
controller = "lane_keep"
step_s = 0.02
net = "straight_3lane"
route = ["e0", "e1", "e2", "e3", "e4"]

[[scenario]]
name = "rp_fidelity"
duration_s = 8.0
ego = { lane = 1, pos_m = 100.0, speed_mps = 20.0 }
replay = { tracks = "fidelity.tracks.parquet" }
stalled = [ { lane = 0, pos_m = 600.0 } ]
actors = [ { id = "a1", lane = 2, pos_m = 60.0, speed_mps = 15.0 } ]

[[scenario]]
name = "rp_rear_end"
duration_s = 9.0
ego = { lane = 1, pos_m = 200.0, speed_mps = 3.0 }
replay = { tracks = "rear_end.tracks.parquet", mode = "replay" }
[scenario.sweep]
"replay.mode" = ["replay", "reactive"]

[[scenario]]
name = "rp_cut_in"
duration_s = 8.0
ego = { lane = 1, pos_m = 100.0, speed_mps = 20.0 }
replay = { tracks = "cut_in.tracks.parquet", mode = "reactive", handover_time_gap_s = 1.0 }
"""


def write_replay_catalog(base: Path) -> Path:
    """The tracks files and ``catalog.toml`` in ``base``; returns the catalog's path."""
    base.mkdir(parents=True, exist_ok=True)
    write_tracks(base / "fidelity.tracks.parquet", fidelity_tracks())
    write_tracks(base / "rear_end.tracks.parquet", rear_end_tracks())
    write_tracks(base / "cut_in.tracks.parquet", cut_in_tracks())
    path = base / "catalog.toml"
    path.write_text(CATALOG)
    return path
