"""``r157_reference``: UN R157's careful and competent human driver (docs/baselines.md).

Known answers on the model's timeline, without SUMO: the controller driven directly on a
straight road with the plant, other vehicles given as obstacles whose motion is known in
closed form (a lead braking at t0, a car cutting in at a known lateral speed). A lead
braking at t0 is perceived within one step of it; the braking starts 0.4 + 0.75 s after
the risk is perceived (within one step), ramps at 0.774 g / 0.6 s = 12.65 m/s³ and
holds 0.774 g = 7.59 m/s². A cut-in is perceived at the step its centre's deviation from
its lane centre passes 0.375 m. Free driving and following a slower car (production's
plant-only loop) never brake critically. One SUMO run with a scripted cut-in reads the
same timeline back from the trace.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from controllers import registry
from controllers.baselines.r157_reference import (
    G_MPS2,
    Phase,
    R157Diagnostics,
    R157ReferenceController,
    Trigger,
    make_r157_reference,
)
from controllers.behaviour.types import Obstacles
from controllers.plant.vehicle_model import SingleTrackPlant, VehicleParams
from controllers.protocol import ConfigError, Controller, Observation, ScenarioContext
from suite.run.scripted import PlantStart, run_plant
from suite.world.scripted import ScriptedRoad, ScriptedVehicle

DT = 0.02
LANE = 3.5
EGO = VehicleParams()
FULL = 0.774 * G_MPS2  # 7.59 m/s²
JERK = FULL / 0.6  # 12.65 m/s³
DELAY = 0.4 + 0.75
EPS = 1e-9


@dataclass(frozen=True)
class Car:
    """Another vehicle at one instant: centre (s, y) [m], velocity along / across [m/s]."""

    s_m: float
    y_m: float
    speed_mps: float
    lateral_mps: float = 0.0
    key: str = "other"
    length_m: float = 4.5


def _obstacles(cars: list[Car]) -> Obstacles:
    if not cars:
        return Obstacles.empty()

    def arr(f: Callable[[Car], float]) -> np.ndarray:
        return np.array([f(c) for c in cars], dtype=np.float64)

    return Obstacles(s_m=arr(lambda c: c.s_m), y_m=arr(lambda c: c.y_m),
                     speed_s_mps=arr(lambda c: c.speed_mps),
                     speed_y_mps=arr(lambda c: c.lateral_mps),
                     semi_a_m=np.full(len(cars), 8.0), semi_b_m=np.full(len(cars), 2.5),
                     vehicle_ids=tuple(c.key for c in cars),
                     half_length_m=arr(lambda c: 0.5 * (c.length_m + EGO.length_m)))


@dataclass(frozen=True)
class Drive:
    """A direct drive: per step, its time, diagnostics, the ego's s and speed, and the
    bumper gap to the first car (inf without one)."""

    t_s: np.ndarray
    diags: list[R157Diagnostics]
    s_m: np.ndarray
    speed_mps: np.ndarray
    gap_m: np.ndarray

    def column(self, name: str) -> np.ndarray:
        return np.array([float(getattr(d, name)) for d in self.diags])


def _drive(cars: Callable[[float], list[Car]], duration_s: float, speed_mps: float = 16.7,
           options: dict[str, object] | None = None) -> Drive:
    """The controller and the plant on a straight road (s = x), ``cars(t)`` around."""
    ctrl = make_r157_reference(options or {})
    state = np.array([50.0, 0.0, 0.0, speed_mps, 0.0, 0.0])
    ctx = ScenarioContext(np.array([[0.0, 0.0], [5000.0, 0.0]]), LANE, speed_mps, DT, EGO,
                          state)
    ctrl.reset(ctx)
    plant = SingleTrackPlant(EGO, state)
    t_s, diags, s, v, gaps = [], [], [], [], []
    for k in range(int(round(duration_s / DT))):
        t = k * DT
        st = plant.state.copy()
        now = cars(t)
        cmd = ctrl.step(Observation(t, st, speed_mps, obstacles=_obstacles(now)))
        assert isinstance(cmd.diagnostics, R157Diagnostics)
        t_s.append(t)
        diags.append(cmd.diagnostics)
        s.append(float(st[0]))
        v.append(math.hypot(float(st[3]), float(st[4])))
        gaps.append(now[0].s_m - float(st[0]) - 0.5 * (now[0].length_m + EGO.length_m)
                    if now else math.inf)
        plant.step(cmd.steer_rad, cmd.torque_nm, DT)
    return Drive(np.array(t_s), diags, np.array(s), np.array(v), np.array(gaps))


# ------------------------------------------------------------------ registration
def test_registered_and_round_trips_its_parameters() -> None:
    assert "r157_reference" in registry.names()
    ctrl = registry.make("r157_reference")
    assert isinstance(ctrl, Controller) and isinstance(ctrl, R157ReferenceController)
    assert ctrl.obstacle_policy is not None and ctrl.obstacle_policy.offset_m == 0.0
    params = ctrl.parameters()
    assert registry.make("r157_reference", params).parameters() == params
    assert params["model"]["brake_decel_g"] == 0.774
    assert {d.path for d in registry.options("r157_reference")} >= {
        "controller.model.risk_perception_s", "controller.model.reaction_s",
        "controller.model.wandering_m", "controller.follow.time_gap_s",
        "controller.steering.lookahead_gain_s"}
    with pytest.raises(ConfigError) as info:
        registry.make("r157_reference", {"model": {"reaction_s": -1.0}})
    assert info.value.key == "controller.model.reaction_s"


# ------------------------------------------------------------------ lead braking
T0 = 2.0
LEAD_DECEL = 6.0


def _braking_lead(t: float) -> list[Car]:
    """A lead 45 m ahead (centre) at the ego's 16.7 m/s, braking at 6 m/s² from T0 to a stop."""
    v0, s0 = 16.7, 95.0
    tb = max(t - T0, 0.0)
    t_stop = v0 / LEAD_DECEL
    tb = min(tb, t_stop)
    s = s0 + v0 * min(t, T0) + v0 * tb - 0.5 * LEAD_DECEL * tb * tb
    return [Car(s, 0.0, v0 - LEAD_DECEL * tb, key="lead")]


def test_a_braking_lead_starts_the_timeline_and_the_brake_ramps_to_0774g() -> None:
    d = _drive(_braking_lead, 9.0)
    phase, risk = d.column("phase"), d.column("risk_t_s")
    decel = d.column("decel_cmd_mps2")
    trig = d.column("trigger")
    first = int(np.argmax(phase > 0))
    t_risk = d.t_s[first]
    assert T0 <= t_risk <= T0 + DT + EPS  # perceived within one step of the lead's braking
    assert risk[first] == pytest.approx(t_risk) and trig[first] == Trigger.LEAD_BRAKING
    # perceiving 0.4 s, reacting 0.75 s, braking from t_r + 1.15 s (within one step)
    perceiving = d.t_s[phase == Phase.PERCEIVING]
    reacting = d.t_s[phase == Phase.REACTING]
    braking = d.t_s[phase == Phase.BRAKING]
    assert perceiving[0] == pytest.approx(t_risk)
    assert perceiving[-1] < t_risk + 0.4 <= perceiving[-1] + DT + EPS
    assert reacting[-1] < t_risk + DELAY <= reacting[-1] + DT + EPS
    assert 0.0 <= braking[0] - (t_risk + DELAY) < DT + EPS
    # no harder braking than normal driving's before the reaction
    assert decel[d.t_s < braking[0]].max() <= 3.0 + 1e-9
    # the ramp: J per second, reached 0.6 s after the start, then held
    k0 = int(np.flatnonzero(phase == Phase.BRAKING)[0])
    ramp = decel[k0:k0 + 40]
    assert ramp[0] == pytest.approx(JERK * (d.t_s[k0] + DT - (t_risk + DELAY)), abs=1e-6)
    steps = np.diff(ramp)
    rising = steps[ramp[1:] < FULL - 1e-9]
    assert rising.size >= 25 and np.allclose(rising, JERK * DT, atol=1e-6)
    full = np.flatnonzero(decel >= FULL - 1e-9)
    assert full.size and d.t_s[full[0]] - (t_risk + DELAY) == pytest.approx(0.6, abs=DT + EPS)
    assert decel.max() == pytest.approx(FULL, abs=1e-9)
    # held until the ego stops (the lead stopped first), without touching the lead; then
    # normal driving closes up to the standstill gap
    hold = (phase == Phase.BRAKING) & (d.t_s >= d.t_s[full[0]])
    assert np.allclose(decel[hold], FULL)
    end = int(np.flatnonzero(phase == Phase.BRAKING)[-1])
    assert d.speed_mps[end + 1] < 0.5 and (phase[end + 1:] == Phase.NORMAL).all()
    assert d.gap_m.min() > 3.0


def test_a_lead_braking_below_the_threshold_is_followed_not_a_risk() -> None:
    def lead(t: float) -> list[Car]:
        v0, a = 16.7, 2.0
        after = max(t - T0, 0.0)
        tb = min(after, 4.0)  # from 16.7 to 8.7 m/s, then held
        s = 95.0 + v0 * t - a * (0.5 * tb * tb + tb * (after - tb))
        return [Car(s, 0.0, v0 - a * tb, key="lead")]

    d = _drive(lead, 10.0)
    assert (d.column("phase") == 0).all()
    assert d.column("decel_cmd_mps2").max() <= 3.0 + 1e-9 and d.gap_m.min() > 5.0


# ------------------------------------------------------------------ cut-in
T_CUT = 1.0
VY = 1.0


def _cutter(t: float, *, vy: float = VY, stop_at_m: float = 0.0, speed: float = 12.0
            ) -> list[Car]:
    """A car in the left lane (y = 3.5 m), its centre 22 m ahead of the ego's CG at
    t = 0 at 12 m/s, moving right at ``vy`` from T_CUT until its centre is at
    ``stop_at_m``."""
    moved = vy * max(t - T_CUT, 0.0)
    y = max(LANE - moved, stop_at_m)
    lateral = -vy if T_CUT < t and y > stop_at_m else 0.0
    return [Car(50.0 + 22.0 + speed * t, y, speed, lateral, key="cutter")]


def test_a_cut_in_is_perceived_when_its_centre_deviates_0375_m() -> None:
    d = _drive(_cutter, 6.0)
    phase = d.column("phase")
    first = int(np.argmax(phase > 0))
    t_perceived = T_CUT + 0.375 / VY  # the deviation passes the wandering distance
    assert 0.0 <= d.t_s[first] - t_perceived < DT + EPS
    assert d.column("trigger")[first] == Trigger.CUT_IN
    braking = d.t_s[phase == Phase.BRAKING]
    assert 0.0 <= braking[0] - (d.t_s[first] + DELAY) < DT + EPS
    assert d.column("decel_cmd_mps2").max() == pytest.approx(FULL, abs=1e-9)
    # braking ends once the ego is no faster than the car that cut in
    end = int(np.flatnonzero(phase == Phase.BRAKING)[-1])
    assert d.speed_mps[end + 1] <= 12.0 + 0.2 and phase[end + 1] == Phase.NORMAL
    assert d.gap_m.min() > 0.0


def test_wandering_within_the_lane_is_not_a_cut_in() -> None:
    d = _drive(lambda t: _cutter(t, stop_at_m=LANE - 0.35), 6.0)
    assert (d.column("phase") == 0).all()


def test_a_car_moving_away_or_far_ahead_is_not_a_cut_in() -> None:
    away = _drive(lambda t: [Car(80.0 + 16.7 * t, LANE - 0.5 + 0.2 * t, 16.7, 0.2)], 4.0)
    assert (away.column("phase") == 0).all()
    # at the ego's speed, 60 m ahead: outside the following gap, never closing
    far = _drive(lambda t: _cutter(t, speed=16.7)[:0] + [
        Car(110.0 + 16.7 * t, max(LANE - VY * max(t - T_CUT, 0.0), 0.0), 16.7, -VY)], 6.0)
    assert (far.column("phase") == 0).all()


# ------------------------------------------------------------------ production's loop
def _road(lanes: int = 1) -> ScriptedRoad:
    return ScriptedRoad(np.array([[0.0, 0.0], [3000.0, 0.0]]), lane_count=lanes,
                        lane_width_m=LANE)


def test_free_driving_holds_the_set_speed_in_its_lane_without_braking() -> None:
    run = run_plant(make_r157_reference({}), _road(2), duration_s=20.0, step_s=DT,
                    start=PlantStart(speed_mps=14.0, lat_m=0.4), set_speed_mps=16.7)
    assert (run.diagnostic("phase") == 0).all()
    assert run.diagnostic("decel_cmd_mps2").max() <= 0.0 + 1e-9  # never brakes
    tr = run.trace
    late = tr.t_s > 12.0
    assert np.abs(tr.ego.speed_mps[late] - 16.7).max() < 0.1
    assert np.abs(tr.ego.lat_dev_m[late]).max() < 0.05


def test_a_slower_lead_is_followed_at_the_time_gap_without_a_critical_reaction() -> None:
    lead = ScriptedVehicle("lead", s_m=120.0, lane=0, speed_mps=12.0)
    run = run_plant(make_r157_reference({}), _road(1), (lead,), duration_s=40.0, step_s=DT,
                    start=PlantStart(speed_mps=16.7), set_speed_mps=16.7)
    assert (run.diagnostic("phase") == 0).all()
    tr = run.trace
    gap = (120.0 + 12.0 * tr.t_s) - tr.ego.s_m - 0.5 * (4.8 + EGO.length_m)
    assert gap.min() > 10.0
    late = tr.t_s > 30.0
    assert np.abs(tr.ego.speed_mps[late] - 12.0).max() < 0.2
    assert np.abs(gap[late] - (3.0 + 2.0 * 12.0)).max() < 1.5  # d_0 + T V


# ------------------------------------------------------------------ SUMO
SUMO_CATALOG = """
[defaults]
controller = "r157_reference"
step_s = 0.02

# ego 16.7 m/s in the right lane; a car at 11 m/s, 25 m ahead, cuts in from the left at 2 s
[[scenario]]
name = "r157_cut_in"
net = "straight_2lane"
duration_s = 10.0
ego = { lane = 0, pos_m = 50.0, speed_mps = 16.7, target_speed_mps = 16.7 }
[[scenario.actors]]
id = "cutter"
lane = 1
pos_m = 80.0
speed_mps = 11.0
events = [ { t_s = 2.0, lane_change = -1 } ]
"""


@pytest.mark.sumo
@pytest.mark.slow
def test_a_scripted_cut_in_in_sumo_follows_the_models_timeline(tmp_path: Path) -> None:
    from catalog_runs import run_catalog

    from reports.record import load_run

    out = run_catalog(tmp_path, SUMO_CATALOG)
    run = load_run(out / "r157_cut_in")
    trace = pd.read_parquet(out / "r157_cut_in" / "trace.parquet")
    phase = trace["phase"].to_numpy()
    t = trace["t_s"].to_numpy()
    assert (phase > 0).any(), "the cut-in was perceived"
    first = int(np.argmax(phase > 0))
    assert trace["trigger"].to_numpy()[first] == Trigger.CUT_IN
    t_risk = float(trace["risk_t_s"].to_numpy()[first])
    assert t_risk >= 2.0  # not before the lane change starts
    braking = t[phase == Phase.BRAKING]
    # trace rows are after the step (t = (k + 1) dt): the step's own time is t - dt
    assert 0.0 <= (braking[0] - DT) - (t_risk + DELAY) < DT + EPS
    decel = trace["decel_cmd_mps2"].to_numpy()
    assert decel.max() == pytest.approx(FULL, abs=1e-6)
    # the cutter's centre deviation from its lane's centre (lane 1 of straight_2lane:
    # y = 1.75 m) passes 0.375 m at the step the risk is perceived: the neighbours row at
    # t_risk is the traffic that step saw, the row before it the step before's
    nb = pd.read_parquet(out / "r157_cut_in" / "neighbours.parquet")
    nb = nb[nb["id"] == "actor_cutter"]

    def deviation(at_s: float) -> float:
        row = nb[(nb["t_s"] - at_s).abs() < DT / 4]
        return 1.75 - float(row["y_m"].iloc[0])

    assert deviation(t_risk - DT) < 0.375 <= deviation(t_risk)
    assert float(trace["min_gap_m"].min()) > 0.0 and not trace["sumo_collision"].any()
    assert run.status in ("pass", "fail")
