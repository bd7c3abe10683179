"""Actors' ``when`` triggers and relative starts in real SUMO runs, checked on the run's
own files: the neighbours file's positions (box centres) and the trace's CG, not the
trigger's code path."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from controllers.plant.vehicle_model import VehicleParams
from tests.catalog_runs import run_catalog

pytestmark = [pytest.mark.slow, pytest.mark.sumo]

CATALOG = """
[defaults]
controller = "lane_keep"
net = "straight_3lane"
duration_s = 12.0
step_s = 0.02
ego = { lane = 1, pos_m = 50.0, speed_mps = 25.0 }

[[scenario]]
name = "gap_trigger"
[[scenario.actors]]
id = "cutter"
lane = 2
ahead_of_ego_m = 60.0
speed_mps = 20.0
events = [ { when = { ahead_gap_m = 20.0 }, lane_change = -1 } ]

[[scenario]]
name = "headway_trigger"
[[scenario.actors]]
id = "braker"
lane = 2
ahead_of_ego_m = 60.0
speed_mps = 20.0
events = [ { when = { time_headway_s = 1.0, delay_s = 0.5 }, speed_mps = 10.0, accel_mps2 = 3.0 } ]
[[scenario.actors]]
id = "behind"
lane = 0
ahead_of_ego_m = -30.0
speed_mps = 25.0
"""

VP = VehicleParams()


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return run_catalog(tmp_path_factory.mktemp("triggers"), CATALOG)


def _frames(run_dir: Path, vehicle: str) -> pd.DataFrame:
    """Per trace row: time, the ego's front bumper x and speed, the vehicle's centre x,
    y, speed and length (the road runs along +x)."""
    tr = pd.read_parquet(run_dir / "trace.parquet").set_index("step")
    nb = pd.read_parquet(run_dir / "neighbours.parquet")
    car = nb[nb["id"] == f"actor_{vehicle}"].set_index("step")
    out = pd.DataFrame({"t_s": tr["t_s"], "ego_front_x": tr["x_m"] + VP.cg_to_front_bumper_m,
                        "ego_speed": tr["speed_mps"]})
    for col in ("x_m", "y_m", "speed_mps", "length_m"):
        out[col] = car[col].reindex(out.index)
    out["gap_m"] = out["x_m"] - 0.5 * out["length_m"] - out["ego_front_x"]
    return out.dropna()


def test_a_gap_trigger_starts_the_lane_change_where_the_gap_crosses(runs: Path) -> None:
    f = _frames(runs / "gap_trigger", "cutter")
    # relative start: its front bumper 60 m ahead of the ego's at the first row
    first = f.iloc[0]
    assert first["x_m"] + 0.5 * first["length_m"] - first["ego_front_x"] == pytest.approx(
        60.0, abs=25.0 * 0.1 + 0.1)
    moving = np.flatnonzero(np.abs(f["y_m"].to_numpy() - first["y_m"]) > 0.02)
    assert moving.size, "the cutter never changed lanes"
    start = f.iloc[moving[0]]
    # The trigger is tested at SUMO steps (0.1 s), the lane change moves from the next
    # one: the gap where it starts moving is at most 20 m and at most two SUMO steps of
    # closing (5 m/s) below it.
    assert 20.0 - 2 * 0.1 * 5.0 - 0.2 <= start["gap_m"] <= 20.0 + 1e-6
    # and it did not move while the gap was still above 20 m + a step of closing
    before = f[f["gap_m"] > 20.0 + 0.1 * 5.0 + 0.2]
    assert np.all(np.abs(before["y_m"] - first["y_m"]) <= 0.02)


def test_a_headway_trigger_brakes_after_its_delay(runs: Path) -> None:
    f = _frames(runs / "headway_trigger", "braker")
    headway = (f["gap_m"] / f["ego_speed"]).to_numpy()
    crossed = f["t_s"].to_numpy()[np.flatnonzero(headway <= 1.0)[0]]
    speed = f["speed_mps"].to_numpy()
    slowing = f["t_s"].to_numpy()[np.flatnonzero(speed < 20.0 - 0.05)[0]]
    # 0.5 s after the headway first fell to 1.0 s: the trigger is tested at SUMO steps
    # (up to one 0.1 s step after the crossing) and a speed set before a SUMO step shows
    # at its end (one more step), so 0.5 s to 0.7 s, a control step of slack
    assert 0.5 - 0.02 <= slowing - crossed <= 0.7 + 0.02
    # then the 3 m/s² ramp to 10 m/s: 3.3 s later it is there (within 0.3 s)
    reached = f["t_s"].to_numpy()[np.flatnonzero(speed <= 10.0 + 0.05)[0]]
    assert reached - slowing == pytest.approx(10.0 / 3.0, abs=0.3)


def test_a_relative_start_behind_the_ego(runs: Path) -> None:
    f = _frames(runs / "headway_trigger", "behind")
    first = f.iloc[0]
    front_offset = first["x_m"] + 0.5 * first["length_m"] - first["ego_front_x"]
    assert front_offset == pytest.approx(-30.0, abs=25.0 * 0.1 + 0.1)
