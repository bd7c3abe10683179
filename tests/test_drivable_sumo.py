"""End to end in SUMO: a scripted plug-in controller drives the lane drop and the taper of
tests/feature_nets.py (both spreads); the run's verdict says off-road only where the ego
left the road, naming the boundary and the excess, and the report shows it."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from feature_nets import lane_drop_net, taper_net

from reports.geometry import ego_box_corners
from reports.metrics.drivable import OFFROAD_TOLERANCE_M
from reports.record import RunRecord, load_run
from reports.record.verdict import fmt_value

REPO = Path(__file__).resolve().parents[1]
pytestmark = [pytest.mark.sumo, pytest.mark.slow]

PLUGIN = r'''"""``lateral_script``: drives the ego along a scripted world y(x) (knots joined by
smoothsteps, for nets that head +X) with a PD law and feed-forward of the script's
curvature; without knots it keeps the reference path."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from controllers import registry
from controllers.protocol import (
    Command,
    ConfigError,
    Observation,
    ScenarioContext,
    StepDiagnostics,
)

NAME = "lateral_script"


@dataclass(frozen=True, slots=True)
class ScriptDiagnostics(StepDiagnostics):
    lateral_target_m: float = math.nan


def target_y_m(x_m: float, xs: tuple[float, ...], ys: tuple[float, ...]
               ) -> tuple[float, float, float]:
    """World y [m] at world x and its first two derivatives in x: smoothstep between
    consecutive knots, constant outside."""
    if x_m <= xs[0]:
        return ys[0], 0.0, 0.0
    for k in range(len(xs) - 1):
        if x_m <= xs[k + 1]:
            length = xs[k + 1] - xs[k]
            u = (x_m - xs[k]) / length
            dy = ys[k + 1] - ys[k]
            return (ys[k] + dy * u * u * (3.0 - 2.0 * u), dy * 6.0 * u * (1.0 - u) / length,
                    dy * (6.0 - 12.0 * u) / length ** 2)
    return ys[-1], 0.0, 0.0


class LateralScript:
    name = NAME
    diagnostics_type: ClassVar[type[StepDiagnostics]] = ScriptDiagnostics
    obstacle_policy = None

    def __init__(self, xs: tuple[float, ...], ys: tuple[float, ...]) -> None:
        self.xs, self.ys = xs, ys
        self._ctx: ScenarioContext | None = None
        self._s = 0.0

    def reset(self, context: ScenarioContext) -> None:
        self._ctx = context
        s, _ = context.reference_path().project(float(context.initial_state[0]),
                                                float(context.initial_state[1]))
        self._s = float(s)

    def step(self, observation: Observation) -> Command:
        assert self._ctx is not None
        ctx = self._ctx
        veh, path = ctx.vehicle, ctx.reference_path()
        x, y, psi, u, v = (float(observation.state[i]) for i in range(5))
        speed = math.hypot(u, v)
        s_a, d_a, e_a = path.project_pose(x, y, psi, s_hint=self._s)
        s, d, e_psi = float(s_a), float(d_a), float(e_a)
        self._s = s
        omega, zeta = 1.5, 1.0
        if self.ys:
            # scripted world y (the feature nets head +X), tracked with its derivatives
            _, y_ref = path.point(s)
            y_t, dy_t, ddy_t = target_y_m(x, self.xs, self.ys)
            target = y_t - float(y_ref)
            e_y, e_y_dot = y - y_t, u * math.sin(psi) - u * math.cos(psi) * dy_t
            a_y = u * u * ddy_t - omega ** 2 * e_y - 2 * zeta * omega * e_y_dot
            kappa = a_y / max(speed, 3.0) ** 2
        else:
            target = 0.0
            a_y = -omega ** 2 * d - 2 * zeta * omega * speed * math.sin(e_psi)
            kappa = float(path.kappa(s)) + a_y / max(speed, 3.0) ** 2
        steer = min(max(math.atan(veh.wheelbase_m * kappa), -veh.max_steer_rad), veh.max_steer_rad)
        accel = min(max(0.5 * (observation.target_speed_mps - speed), -3.0), 1.5)
        return Command(steer_rad=steer, torque_nm=veh.mass_kg * veh.wheel_radius_m * accel,
                       diagnostics=ScriptDiagnostics(outer_s=0.0, inner_s=0.0,
                                                     lateral_target_m=target))

    def parameters(self) -> dict[str, Any]:
        return {"name": self.name, "knots_x_m": list(self.xs), "knots_y_m": list(self.ys)}


def make(options: Mapping[str, Any]) -> LateralScript:
    opts = dict(options)
    opts.pop("name", None)
    xs = tuple(float(v) for v in opts.pop("knots_x_m", ()))
    ys = tuple(float(v) for v in opts.pop("knots_y_m", ()))
    if not ys:
        xs = (0.0,)
    elif len(xs) != len(ys) or not xs or any(b <= a for a, b in zip(xs, xs[1:])):
        raise ConfigError("controller.knots_x_m", "increasing, as many as knots_y_m", xs)
    if opts:
        raise ConfigError(f"controller.{next(iter(opts))}", "knots_x_m or knots_y_m", opts)
    return LateralScript(xs, ys)


registry.register(NAME, make)
'''

# per net: (script name, knots x, knots y) -- world y of the ego's CG
SCRIPTS = {
    "drop_center": [("leave", [320, 420, 480, 596], [0, -3.5, -3.5, -1.75]),
                    ("late", [320, 420, 560, 620], [0, -3.5, -3.5, -1.75]),
                    ("beyond", [320, 420, 560, 640], [0, -3.5, -3.5, -4.6])],
    "drop_right": [("leave", [320, 420, 480, 596], [-5.25, -8.75, -8.75, -5.25]),
                   ("late", [320, 420, 550, 615], [-5.25, -8.75, -8.75, -5.25]),
                   ("beyond", [320, 420, 560, 640], [-5.25, -8.75, -8.75, -8.1])],
    "taper_center": [("leave", [320, 420, 480, 598, 700, 760],
                      [0, -3.5, -3.5, -0.875, -0.875, -1.75]),
                     ("late", [320, 420, 660, 730], [0, -3.5, -3.5, -1.75]),
                     ("beyond", [320, 420, 560, 600], [0, -3.5, -3.5, -4.0])],
    "taper_right": [("leave", [320, 420, 480, 598], [-5.25, -8.75, -8.75, -5.25]),
                    ("beyond", [320, 420], [-5.25, -8.75])],
}
# where the "beyond" runs are past a straight right edge: (x from, x to, lane)
BEYOND = {"drop_center": (640.0, 740.0, "b_0"), "drop_right": (650.0, 740.0, "b_0"),
          "taper_center": (612.0, 700.0, "t_0"), "taper_right": (612.0, 700.0, "t_0")}


def _catalog(out: Path) -> Path:
    blocks = ['[defaults]\ncontroller = { name = "lateral_script" }\nduration_s = 18.0\n'
              'step_s = 0.02\nseed = 0\n']
    for net, scripts in SCRIPTS.items():
        kind, spread = net.split("_")
        build = lane_drop_net if kind == "drop" else taper_net
        path = build(out, name=net, spread=spread)
        for lane in (1, 2):
            blocks.append(f'[[scenario]]\nname = "{net}_keep{lane}"\nnet = "{path}"\n'
                          f"ego = {{ lane = {lane}, pos_m = 300.0, speed_mps = 25.0, "
                          f"target_speed_mps = 25.0 }}\n")
        for name, xs, ys in scripts:
            blocks.append(f'[[scenario]]\nname = "{net}_{name}"\nnet = "{path}"\n'
                          f"ego = {{ lane = 1, pos_m = 300.0, speed_mps = 25.0, "
                          f"target_speed_mps = 25.0 }}\n"
                          f'controller = {{ name = "lateral_script", '
                          f"knots_x_m = {[float(x) for x in xs]}, "
                          f"knots_y_m = {[float(y) for y in ys]} }}\n")
    catalog = out / "catalog.toml"
    catalog.write_text("\n".join(blocks))
    return catalog


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("drivable_sumo")
    plugin = out / "lateral_script.py"
    plugin.write_text(PLUGIN)
    jobs = "2" if (os.cpu_count() or 1) > 1 else "1"
    res = subprocess.run([sys.executable, "-m", "suite", "run", str(_catalog(out)), "--out",
                          str(out / "runs"), "--jobs", jobs, "--no-log", "--plugin",
                          str(plugin)], cwd=REPO, capture_output=True, text=True, check=False)
    assert res.returncode == 1, res.stdout[-3000:] + res.stderr[-3000:]  # the beyond runs fail
    return out / "runs"


def _run(runs: Path, name: str) -> RunRecord:
    record = load_run(runs / name, neighbours=False, arrays=False)
    assert record.verdict is not None and record.outcome.end == "ok"
    return record


@pytest.mark.parametrize("name", [f"{net}_{s}" for net, scripts in SCRIPTS.items()
                                  for s in ("keep1", "keep2", *(n for n, _, _ in scripts))
                                  if s != "beyond"])
def test_keeping_a_lane_or_leaving_the_ending_one_is_never_off_road(runs: Path,
                                                                      name: str) -> None:
    record = _run(runs, name)
    assert record.verdict is not None
    assert record.verdict.value("offroad_s") == 0.0
    assert record.verdict.value("max_offroad_m") <= OFFROAD_TOLERANCE_M
    assert not any(f.criterion == "max_offroad_s" for f in record.verdict.failures)


@pytest.mark.parametrize("net", list(SCRIPTS))
def test_beyond_the_right_edge_is_off_road_naming_it(runs: Path, net: str) -> None:
    """Past the right edge of a straight lane the stored excess is the corner's distance to
    that edge, computed here from the lane's netconvert geometry; the verdict names a right
    edge and the report's failures list shows its lane and the excess."""
    record = _run(runs, f"{net}_beyond")
    verdict, series = record.verdict, record.series
    assert verdict is not None and series is not None
    assert verdict.value("offroad_s") > 0.0
    x_from, x_to, lane_id = BEYOND[net]
    lane = next(ln for ln in record.road.lanes if ln.id == lane_id)
    y_edge = float(lane.shape_xy_m[0, 1]) - 0.5 * lane.width_m
    ego = record.trace.ego
    corners = ego_box_corners(ego.x_m, ego.y_m, ego.psi_rad, record.info.ego)
    rows = np.all((corners[..., 0] > x_from) & (corners[..., 0] < x_to), axis=1)
    assert np.sum(rows) > 50
    expected = np.max(y_edge - corners[rows, :, 1], axis=1)
    assert np.all(expected > OFFROAD_TOLERANCE_M)
    np.testing.assert_allclose(series.offroad_excess_m[rows], expected, atol=1e-6)
    crossing = verdict.metric("offroad_s").crossing  # type: ignore[union-attr]
    assert crossing is not None and crossing.side == "right" and crossing.kind == "lane"
    assert crossing.excess_m == pytest.approx(verdict.value("max_offroad_m"))
    assert crossing.excess_m >= float(np.max(expected)) - 1e-6
    assert math.isfinite(crossing.t_s) and crossing.corner.endswith("right")
    html = (runs / "report.html").read_text()
    section = html[html.index('<table class="failures'):]  # the per-run rows, not the triage
    row = section[section.index(f"{net}_beyond"):]
    row = row[:row.index("</tr>")]
    assert crossing.lane_id in row and fmt_value(crossing.excess_m) in row
