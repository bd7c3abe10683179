"""Extrapolation error of multi-rate SUMO against SUMO at the control rate.

SUMO runs one scenario at the control step (``sumo_step_s = step_s``, 50 Hz) with
SUMO's own driver moving the ego (so the traffic is the same whatever the extrapolation),
and every step's vehicles within the sensing radius are kept: that is the truth. Every
m-th step (m = ``sumo_step_s / step_s``, 5 for 0.1 s) is taken as a SUMO step of the
multi-rate world; each vehicle present at such a step and at the k-th step after it
(k = 1 .. m-1, tau = k step_s) is extrapolated from the SUMO step by three rules and
compared with its true position at tau:

* ``hold``: no extrapolation (the position of the last SUMO step);
* ``velocity``: constant speed along the heading (what :mod:`suite.world.multirate`
  does): p + v tau (cos h, sin h);
* ``acceleration``: constant acceleration along the heading, the acceleration being
  the speed change over the preceding m steps / (m step_s) (speed >= 0):
  p + (v tau + a tau² / 2) (cos h, sin h).

Errors are Euclidean distances [m] of the box centre, pooled over vehicles and SUMO
steps (p50, p99, max), and split by tau and into the stalled/moving vehicles. This is
the extrapolation's own error; how a 10 Hz SUMO changes the traffic itself (SUMO's
step length changes its car-following and lane-change decisions) shows in the verdict
comparison of whole catalogs instead (docs/performance.md).
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

RULES = ("hold", "velocity", "acceleration")


@dataclass(frozen=True)
class ErrorStats:
    """Position errors [m] of one rule: p50, p99, max over ``n`` samples."""

    n: int
    p50_m: float
    p99_m: float
    max_m: float

    def __post_init__(self) -> None:
        if self.n < 0:
            raise ValueError(f"n must be >= 0, got {self.n}")

    @classmethod
    def of(cls, err_m: np.ndarray) -> ErrorStats:
        e = np.asarray(err_m, dtype=np.float64)
        if e.size == 0:
            return cls(0, float("nan"), float("nan"), float("nan"))
        p50, p99 = np.percentile(e, [50, 99])
        return cls(int(e.size), float(p50), float(p99), float(e.max()))


@dataclass(frozen=True)
class _Frame:
    """Vehicles of one 50 Hz step by id: x, y [m], heading [rad], speed [m/s]."""

    ids: dict[str, int]
    x: np.ndarray
    y: np.ndarray
    h: np.ndarray
    v: np.ndarray


def record_frames(scenario: Any, steps: int, work_dir: Path) -> list[_Frame]:
    """``steps`` control steps of ``scenario`` with SUMO at the control step and SUMO's
    driver moving the ego; every step's traffic."""
    import dataclasses

    from controllers.plant.vehicle_model import VehicleParams
    from suite.road.network import RoadNetwork
    from suite.world.sumo import SumoWorld

    sc = dataclasses.replace(scenario, sumo_step_s=scenario.step_s)
    world = SumoWorld(sc, RoadNetwork.load(sc.net_path), VehicleParams(), work_dir,
                      externally_driven=False)
    frames = []
    try:
        scene = world.start(None)
        for _ in range(steps):
            tr = scene.traffic
            frames.append(_Frame({vid: i for i, vid in enumerate(tr.ids)}, tr.x_m.copy(),
                                 tr.y_m.copy(), tr.heading_rad.copy(), tr.speed_mps.copy()))
            scene = world.step(None)
            if scene.ego is None:
                break
    finally:
        world.close()
    return frames


def extrapolation_errors(frames: list[_Frame], m: int, step_s: float
                         ) -> dict[str, dict[str, Any]]:
    """Errors of the three rules (module docstring) for SUMO steps every ``m`` frames:
    per rule, pooled :class:`ErrorStats` plus per-tau and moving-only ones."""
    if m < 2:
        raise ValueError(f"m must be >= 2 (a SUMO step longer than the control step), got {m}")
    errs: dict[str, dict[int, list[np.ndarray]]] = {r: {k: [] for k in range(1, m)}
                                                    for r in RULES}
    moving: dict[str, list[np.ndarray]] = {r: [] for r in RULES}
    for a in range(m, len(frames) - m, m):
        base, prev = frames[a], frames[a - m]
        for k in range(1, m):
            truth = frames[a + k]
            common = [vid for vid in base.ids if vid in truth.ids]
            if not common:
                continue
            ib = np.array([base.ids[v] for v in common])
            it = np.array([truth.ids[v] for v in common])
            ip = np.array([prev.ids.get(v, -1) for v in common])
            v0 = base.v[ib]
            v_prev = np.where(ip >= 0, prev.v[np.maximum(ip, 0)], v0)
            acc = (v0 - v_prev) / (m * step_s)
            tau = k * step_s
            dist = {"hold": np.zeros_like(v0), "velocity": v0 * tau,
                    "acceleration": np.maximum(v0 * tau + 0.5 * acc * tau * tau, 0.0)}
            c, s = np.cos(base.h[ib]), np.sin(base.h[ib])
            is_moving = (v0 > 0.1) | (truth.v[it] > 0.1)
            for rule in RULES:
                e = np.hypot(base.x[ib] + dist[rule] * c - truth.x[it],
                             base.y[ib] + dist[rule] * s - truth.y[it])
                errs[rule][k].append(e)
                moving[rule].append(e[is_moving])
    out: dict[str, dict[str, Any]] = {}
    for rule in RULES:
        pooled = [e for k in errs[rule] for e in errs[rule][k]]
        out[rule] = {
            "all": ErrorStats.of(np.concatenate(pooled) if pooled else np.zeros(0)).__dict__,
            "moving": ErrorStats.of(np.concatenate(moving[rule]) if moving[rule]
                                    else np.zeros(0)).__dict__,
            "by_tau_s": {f"{k * step_s:.2f}": ErrorStats.of(
                np.concatenate(errs[rule][k]) if errs[rule][k] else np.zeros(0)).__dict__
                for k in range(1, m)}}
    return out


STUDY_CATALOG = """
[defaults]
controller = "sumo"
duration_s = 60.0
step_s = 0.02
seed = 7

[[scenario]]
name = "extrapolation_3lane_2400"
net = "straight_3lane"
ego = { lane = 1, pos_m = 100.0, speed_mps = 25.0 }
stalled = [ { lane = 1, pos_m = 900.0 } ]
traffic = { vehicles_per_hour = 2400, seed = 3 }

[[scenario]]
name = "extrapolation_curve_2lane_2400"
net = "curve_2lane"
ego = { lane = 0, pos_m = 300.0, speed_mps = 22.0 }
traffic = { vehicles_per_hour = 2400, seed = 5 }
"""


def extrapolation_study(duration_s: float = 60.0, sumo_step_s: float = 0.1
                        ) -> dict[str, Any]:
    """The study on :data:`STUDY_CATALOG` (dense traffic on a straight 3-lane road with a
    stalled car, and on a curve): per scenario and rule, the errors."""
    from suite.catalog import load_catalog

    out: dict[str, Any] = {"sumo_step_s": sumo_step_s, "duration_s": duration_s}
    with tempfile.TemporaryDirectory(prefix="hwyeval-extrap-") as tmp:
        path = Path(tmp) / "study.toml"
        path.write_text(STUDY_CATALOG)
        for sc in load_catalog(path).scenarios:
            m = int(round(sumo_step_s / sc.step_s))
            frames = record_frames(sc, int(round(duration_s / sc.step_s)), Path(tmp) / sc.name)
            out[sc.name] = {"frames": len(frames), "vehicles_per_frame": float(np.mean(
                [len(f.ids) for f in frames])) if frames else 0.0,
                "errors": extrapolation_errors(frames, m, sc.step_s)}
    return out
