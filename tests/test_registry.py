"""Controller registry, the Controller protocol and the dotted-key options adapter (no SUMO)."""

from __future__ import annotations

import ast
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from controllers import registry
from controllers.params import ParamError, build, check_leaves, describe, param, section, to_dict
from controllers.plant.vehicle_model import VehicleParams
from controllers.protocol import (
    ConfigError,
    Controller,
    Observation,
    ScenarioContext,
    SumoDriverModel,
)

ROOT = Path(__file__).resolve().parents[1]


def test_builtins_are_registered() -> None:
    assert {"lane_keep", "sumo", "two_loop", "ipopt_nmpc"} <= set(registry.names())


def test_duplicate_names_are_refused() -> None:
    with pytest.raises(ValueError, match="already registered"):
        registry.register("lane_keep", lambda options: registry.make("lane_keep"))


def test_bad_names_are_refused() -> None:
    with pytest.raises(ValueError, match="a-z0-9_"):
        registry.register("Lane-Keep", lambda options: registry.make("lane_keep"))


def test_a_plug_in_is_registered_once() -> None:
    registry.register("test_plugin_lane_keep", lambda options: registry.make("lane_keep"))
    assert "test_plugin_lane_keep" in registry.names()
    assert registry.make("test_plugin_lane_keep").name == "lane_keep"
    with pytest.raises(ValueError, match="already registered"):
        registry.register("test_plugin_lane_keep", lambda options: registry.make("lane_keep"))


def test_unknown_controller_names_the_key() -> None:
    with pytest.raises(ConfigError) as info:
        registry.make("no_such_controller")
    assert info.value.key == "controller.name"


@pytest.mark.parametrize("name", ["lane_keep", "two_loop", "ipopt_nmpc", "r157_reference"])
def test_every_builtin_controller_satisfies_the_protocol(name: str) -> None:
    controller = registry.make(name, {})
    assert isinstance(controller, Controller)
    assert controller.name == name
    params = dict(controller.parameters())
    assert params and json.loads(json.dumps(params)) == params  # JSON-able, for logs
    assert registry.make(name, params).parameters() == params  # and accepted back


def test_sumo_is_the_sumo_driver_model_and_takes_no_options() -> None:
    model = registry.make("sumo", {})
    assert isinstance(model, SumoDriverModel) and not isinstance(model, Controller)
    assert model.name == "sumo" and model.parameters()
    with pytest.raises(ConfigError) as info:
        registry.make("sumo", {"speed_factor": 1.1})
    assert info.value.key == "controller.speed_factor"


def test_unknown_option_is_a_config_error_naming_it() -> None:
    with pytest.raises(ConfigError) as info:
        registry.make("lane_keep", {"lookahead_gain": 1.0})
    assert info.value.key == "controller.lookahead_gain"
    with pytest.raises(ConfigError) as info:
        registry.make("lane_keep", {"lookahead_min_m": True})
    assert info.value.key == "controller.lookahead_min_m"
    with pytest.raises(ConfigError) as info:  # a check of __post_init__, at its key
        registry.make("lane_keep", {"lookahead_max_m": 1.0})
    assert info.value.key == "controller.lookahead_max_m"


def test_lane_keep_tracks_a_straight_lane_from_an_offset() -> None:
    from controllers.plant.vehicle_model import SingleTrackPlant

    vehicle = VehicleParams()
    ref = np.array([[0.0, 0.0], [3000.0, 0.0]])
    state = np.array([10.0, 1.0, 0.0, 20.0, 0.0, 0.0])
    ctrl = registry.make("lane_keep")
    assert isinstance(ctrl, Controller) and ctrl.obstacle_policy is None
    ctrl.reset(ScenarioContext(ref, 3.5, 25.0, 0.02, vehicle, state))
    plant = SingleTrackPlant(vehicle, state)
    for k in range(1000):
        cmd = ctrl.step(Observation(k * 0.02, plant.state.copy(), 25.0))
        plant.step(cmd.steer_rad, cmd.torque_nm, 0.02)
    assert type(cmd.diagnostics) is ctrl.diagnostics_type
    assert abs(plant.state[1]) < 0.05  # converged onto the lane centre
    assert plant.state[3] == pytest.approx(25.0, abs=0.2)  # PI speed reached the target


# ----------------------------------------------------------------- import structure
def _imports(path: Path) -> set[str]:
    """Modules a source file imports (at any level, also inside functions)."""
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            out.add(node.module)
            out.update(f"{node.module}.{alias.name}" for alias in node.names)
    return out


def test_no_registry_builtin_cycle() -> None:
    """The registry reads builtin's table; builtin and every controller module import
    nothing of the registry (import-linter's layers say the same)."""
    assert "controllers.builtin" in _imports(ROOT / "controllers" / "registry.py")
    for path in (ROOT / "controllers").rglob("*.py"):
        if path.name == "registry.py":
            continue
        assert "controllers.registry" not in _imports(path), path


# ------------------------------------------------------------------- the adapter
@dataclass(frozen=True)
class _Inner:
    gain: float = param(1.0, "1/s", "a gain")
    steps: int = param(3, "-", "a count")
    on: bool = param(True, "-", "a switch")

    def __post_init__(self) -> None:
        check_leaves(self)
        if self.gain > 10.0:
            raise ParamError("gain", "a number <= 10", self.gain)


@dataclass(frozen=True)
class _Outer:
    speed_mps: float = param(2.0, "m/s", "a speed")
    inner: _Inner = section(_Inner, "the inner section")

    def __post_init__(self) -> None:
        check_leaves(self)
        if self.inner.steps * self.speed_mps > 100.0:
            raise ParamError("inner.steps", "steps * speed_mps <= 100", self.inner.steps)


def test_adapter_builds_nested_parameters_and_converts_ints() -> None:
    p = build(_Outer, {"speed_mps": 3, "inner": {"gain": 2, "on": False}})
    assert p == _Outer(3.0, _Inner(2.0, 3, False))
    assert isinstance(p.speed_mps, float) and isinstance(p.inner.gain, float)
    assert build(_Outer, to_dict(p)) == p  # round trip
    assert to_dict(p) == {"speed_mps": 3.0, "inner": {"gain": 2.0, "steps": 3, "on": False}}


@pytest.mark.parametrize(("options", "key", "expected"), [
    ({"inner": {"xyz": 1}}, "controller.inner.xyz", "one of the keys"),
    ({"xyz": 1}, "controller.xyz", "one of the keys"),
    ({"inner": {"gain": True}}, "controller.inner.gain", "a finite number"),
    ({"inner": {"gain": "1"}}, "controller.inner.gain", "a finite number"),
    ({"inner": {"gain": math.inf}}, "controller.inner.gain", "a finite number"),
    ({"inner": {"steps": 2.0}}, "controller.inner.steps", "an integer"),
    ({"inner": {"on": 1}}, "controller.inner.on", "true or false"),
    ({"inner": 3}, "controller.inner", "a table"),
    ({"inner": {"gain": 11.0}}, "controller.inner.gain", "<= 10"),  # nested __post_init__
    ({"inner": {"steps": 60}}, "controller.inner.steps", "<= 100"),  # cross-section check
])
def test_adapter_names_the_dotted_key(options: dict[str, object], key: str,
                                      expected: str) -> None:
    with pytest.raises(ConfigError) as err:
        build(_Outer, options)
    assert err.value.key == key
    assert expected in err.value.expected


def test_adapter_aliases() -> None:
    aliases = {"gain": "inner.gain", "speed": "speed_mps"}
    assert build(_Outer, {"gain": 4.0, "speed": 1.0}, aliases=aliases) == _Outer(
        1.0, _Inner(gain=4.0))
    with pytest.raises(ConfigError) as err:  # both spellings at once
        build(_Outer, {"gain": 4.0, "inner": {"gain": 5.0}}, aliases=aliases)
    assert err.value.key == "controller.gain"
    with pytest.raises(ConfigError) as err:  # the alias's value is type-checked at its path
        build(_Outer, {"gain": False}, aliases=aliases)
    assert err.value.key == "controller.inner.gain"


def test_describe_lists_every_option_with_unit_and_default() -> None:
    docs = {d.path: d for d in describe(_Outer)}
    assert list(docs) == ["controller.speed_mps", "controller.inner.gain",
                          "controller.inner.steps", "controller.inner.on"]
    assert docs["controller.inner.gain"].unit == "1/s"
    assert docs["controller.inner.steps"].type == "int"
    assert docs["controller.speed_mps"].default == 2.0 and docs["controller.speed_mps"].doc


def test_two_loop_options_are_described_with_units() -> None:
    from controllers.two_loop.params import FLAT_ALIASES, TwoLoopParams

    docs = describe(TwoLoopParams)
    paths = {d.path for d in docs}
    assert {"controller.outer.c_y", "controller.outer.k_max", "controller.inner.preview",
            "controller.lateral.c_y_engaged", "controller.launch.enabled",
            "controller.policy.max_obstacles"} <= paths
    assert all(d.unit for d in docs)  # every option has a unit ('-' if dimensionless)
    assert all(d.doc for d in docs if not d.path.startswith("controller.policy."))
    # Every alias points to an option, and every option of the former flat class has one.
    assert {f"controller.{v}" for v in FLAT_ALIASES.values()} <= paths
    assert set(FLAT_ALIASES) == FORMER_FLAT_OPTIONS - {"outer"}


# The keys the former flat TwoLoopParams took (``outer`` chose the solver: now the name).
FORMER_FLAT_OPTIONS = {
    "outer", "cost", "horizon_s", "n_stages", "chebyshev", "k_max", "zeta_s", "fd_step",
    "sub_updates", "c_z", "zeta", "c_y", "c_ydot", "c_sdot", "c_thetadot", "c_theta", "c_v",
    "c_y_terminal", "c_e_terminal", "horizon_growth_rate", "target_accel_mps2",
    "target_decel_mps2", "target_jerk_mps3", "z_guard", "obstacle_fade_s", "row_scaling",
    "fallback_residual", "fallback_decel_mps2", "fallback_hold_s", "preview", "n_preview",
    "preview_dt_s", "lookahead_s", "k_ps", "k_pv", "k_pvc", "k_psc", "k_isc",
    "integral_limit_ms", "feedforward", "lateral_ref_rate_mps", "lateral_ref_filter_s",
    "lateral_ref_heading_rad", "c_y_lateral_ref", "lateral_weight_time_s",
    "detection_distance_m", "rear_range_m", "margin_long_m", "margin_lat_m", "offset_m",
    "max_obstacles", "moving_obstacles", "launch", "launch_speed_mps",
    "launch_engage_speed_mps", "launch_blend_s", "launch_k_pv", "launch_max_speed_mps",
    "launch_k_heading", "launch_lookahead_m", "launch_max_heading_rad",
    "launch_steer_speed_mps", "launch_clearance_m", "launch_guard_decel_mps2",
    "launch_handover_free_m", "launch_hold_target_mps", "launch_hold_decel_mps2"}


def test_two_loop_flat_aliases_resolve_to_the_nested_options() -> None:
    flat = registry.make("two_loop", {"cost": "J1", "preview": False, "k_max": 16,
                                      "c_y_lateral_ref": 10.0, "launch": False,
                                      "launch_speed_mps": 2.0, "max_obstacles": 2})
    nested = registry.make("two_loop", {
        "outer": {"cost": "J1", "k_max": 16}, "inner": {"preview": False},
        "lateral": {"c_y_engaged": 10.0},
        "launch": {"enabled": False, "handover_speed_mps": 2.0},
        "policy": {"max_obstacles": 2}})
    assert flat.parameters() == nested.parameters()
    with pytest.raises(ConfigError) as err:
        registry.make("two_loop", {"outer": "ipopt"})  # the planner is the name's
    assert err.value.key == "controller.outer"


def test_ipopt_nmpc_rejects_cgmres_only_options() -> None:
    for options in ({"outer": {"k_max": 16}}, {"k_max": 16}):
        with pytest.raises(ConfigError) as err:
            registry.make("ipopt_nmpc", options)
        assert err.value.key == "controller.outer.k_max"
    ipopt = registry.make("ipopt_nmpc", {})
    cgmres = registry.make("two_loop", {})
    assert set(ipopt.parameters()["outer"]) - set(cgmres.parameters()["outer"]) == {
        "formulation", "max_iter", "tol"}


# ------------------------------------------------------------------ documentation
def test_docs_list_every_two_loop_option_and_alias() -> None:
    """docs/two_loop.md's option tables name every dotted option and its flat alias."""
    from controllers.two_loop.params import IPOPT_FLAT_ALIASES, IpoptNmpcParams, TwoLoopParams

    text = (ROOT / "docs" / "two_loop.md").read_text()
    cells = [line.split("|") for line in text.splitlines() if line.startswith("| `")]
    rows = {c[1].strip(" `"): c[6].strip(" `") for c in cells if len(c) == 8}  # option rows
    for cls in (TwoLoopParams, IpoptNmpcParams):
        for d in describe(cls):
            path = d.path[len("controller."):]
            assert path in rows, path
    for alias, path in IPOPT_FLAT_ALIASES.items():
        assert rows[path] == alias, (alias, path)


def test_method_sections_cited_by_the_code_exist() -> None:
    """Every "docs/method.md §N" in the controller modules and the catalogs names a
    section there, and nothing points outside the repository. (The behaviour layer,
    the plant-only simulator and controllers/protocol.py have their own owners.)"""
    import re

    sections = set(re.findall(r"^## (\d+)\. ", (ROOT / "docs" / "method.md").read_text(),
                              re.MULTILINE))
    ctl = ROOT / "controllers"
    others = {ctl / "behaviour", ctl / "sim"}
    files = [p for p in ctl.rglob("*.py")
             if not others & set(p.parents) and p != ctl / "protocol.py"]
    cited: set[str] = set()
    for path in [*files, *(ROOT / "catalogs").glob("*.toml")]:
        text = path.read_text()
        assert "METHOD.md" not in text and "../shared" not in text, path
        for first, last in re.findall(r"docs/method\.md §(\d+)(?:-§(\d+))?", text):
            cited.update(str(n) for n in range(int(first), int(last or first) + 1))
    assert cited and cited <= sections, cited - sections


def test_registry_describes_each_controllers_options() -> None:
    two_loop = {d.path: d for d in registry.options("two_loop")}
    assert two_loop["controller.outer.k_max"].default == 12
    assert "controller.outer.k_max" not in {d.path for d in registry.options("ipopt_nmpc")}
    assert {d.path for d in registry.options("lane_keep")} == {
        f"controller.{k}" for k in registry.make("lane_keep").parameters() if k != "name"}
    assert registry.options("sumo") == []
    with pytest.raises(ConfigError):
        registry.options("no_such_controller")
