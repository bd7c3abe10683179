"""Scenario catalog: parsing, validation messages, defaults, sweeps, filtering."""

from __future__ import annotations

import json
import math
import pickle
import textwrap
from pathlib import Path

import pytest

from suite.catalog import (
    CatalogError,
    ControllerSpec,
    EgoSpec,
    FrozenMap,
    Scenario,
    SpecError,
    StalledSpec,
    TrafficSpec,
    expand_filter,
    format_sweep_value,
    load_catalog,
    sweep_name,
    sweep_shorts,
)
from tests.plain_nets import PlainNet

KNOWN = {"lane_keep", "sumo", "unregistered_ctrl"}
DATA = Path(__file__).parent / "data" / "catalogs"

# 3 lanes with a hard shoulder (lane 0) on e0, 3 lanes on e1, a drop to 2 lanes on e2.
NODES = """<nodes>
  <node id="a" x="0" y="0"/> <node id="b" x="600" y="0"/>
  <node id="c" x="1000" y="150"/> <node id="d" x="1500" y="150"/>
</nodes>"""
EDGES = """<edges>
  <edge id="e0" from="a" to="b" numLanes="3" speed="30">
    <lane index="0" allow="emergency authority"/>
  </edge>
  <edge id="e1" from="b" to="c" numLanes="3" speed="30" shape="600,0 800,20 1000,150"/>
  <edge id="e2" from="c" to="d" numLanes="2" speed="30"/>
</edges>"""

HEADER = """
[defaults]
controller = "lane_keep"
duration_s = 10.0
step_s = 0.05
seed = 3
criteria = { max_rms_lat_dev_m = 1.0, min_ttc_s = 2.0 }
"""

GOOD = """
[[scenario]]
name = "base"
net = "nets/test.net.xml"
ego = { lane = 1, pos_m = 20.0, speed_mps = 20.0 }
"""


@pytest.fixture(scope="module")
def net_dir(tmp_path_factory: pytest.TempPathFactory, plain_net: PlainNet) -> Path:
    root = tmp_path_factory.mktemp("catalog")
    plain_net(root / "nets", "test", NODES, EDGES)
    return root


_counter = [0]


def write(net_dir: Path, body: str, header: str = HEADER) -> Path:
    _counter[0] += 1
    path = net_dir / f"cat{_counter[0]}.toml"
    path.write_text(textwrap.dedent(header) + textwrap.dedent(body))
    return path


def load(path: Path, **kw: object):  # type: ignore[no-untyped-def]
    kw.setdefault("known_controllers", KNOWN)
    return load_catalog(path, **kw)  # type: ignore[arg-type]


def errors_of(path: Path, **kw: object) -> CatalogError:
    with pytest.raises(CatalogError) as info:
        load(path, **kw)
    return info.value


# ====================================================================== pure helpers
@pytest.mark.parametrize("value, text", [
    (300.0, "300"), (300, "300"), (2.5, "2p5"), (-1, "m1"), (-0.25, "m0p25"),
    (0, "0"), (True, "true"), (False, "false"), ("lane_keep", "lane_keep"),
    ("Fast-Car", "fast_car"), ([1, 2], "v0"),
])
def test_format_sweep_value(value: object, text: str) -> None:
    assert format_sweep_value(value) == text


def test_sweep_shorts_abbreviations_and_disambiguation() -> None:
    assert sweep_shorts(["stalled.0.pos_m", "traffic.vehicles_per_hour"]) == ["pos", "vph"]
    assert sweep_shorts(["ego.speed_mps", "ego.target_speed_mps", "duration_s", "seed"]) == [
        "speed", "vt", "duration", "seed"]
    assert sweep_shorts(["ego.pos_m", "stalled.0.pos_m"]) == ["egopos", "stalled0pos"]
    assert sweep_shorts(["stalled.0.pos_m", "stalled.1.pos_m", "traffic.seed"]) == [
        "stalled0pos", "stalled1pos", "seed"]
    shorts = sweep_shorts(["a.b", "a.b"])
    assert len(set(shorts)) == 2


def test_sweep_name() -> None:
    assert sweep_name("s3_stall_mid", ["pos", "vph"], [300.0, 2000]) == \
        "s3_stall_mid__pos300__vph2000"


def test_frozen_map_immutable_picklable_jsonable() -> None:
    m = FrozenMap({"a": 1, "b": {"c": [1, 2]}})
    with pytest.raises(TypeError):
        m["a"] = 2  # type: ignore[index]
    with pytest.raises(AttributeError):
        m.x = 1  # type: ignore[attr-defined]
    assert isinstance(m["b"], FrozenMap) and m["b"]["c"] == (1, 2)
    assert pickle.loads(pickle.dumps(m)) == m
    assert json.loads(json.dumps(m.to_dict())) == {"a": 1, "b": {"c": [1, 2]}}
    assert hash(m) == hash(FrozenMap({"a": 1, "b": {"c": [1, 2]}}))


def test_spec_post_init_validation() -> None:
    ego = EgoSpec(lane=1, pos_m=5, speed_mps=20)
    assert ego.target_speed_mps == 20.0 and isinstance(ego.pos_m, float)
    with pytest.raises(SpecError, match="lane"):
        EgoSpec(lane=True, pos_m=5, speed_mps=20)  # bool is not an int here
    with pytest.raises(SpecError, match="speed_mps"):
        EgoSpec(lane=0, pos_m=5, speed_mps=-1)
    with pytest.raises(SpecError, match="pos_m"):
        StalledSpec(lane=0, pos_m=math.inf)
    with pytest.raises(SpecError, match="length_m"):
        StalledSpec(lane=0, pos_m=1, length_m=0)
    with pytest.raises(SpecError, match="lanes"):
        TrafficSpec(vehicles_per_hour=10, seed=1, lanes=(1, 1))
    assert TrafficSpec(vehicles_per_hour=10, seed=1, lanes=[0, 2]).lanes == (0, 2)  # type: ignore[arg-type]
    c = ControllerSpec("lane_keep", {"k": {"x": 1}})
    with pytest.raises(TypeError):
        c.options["k"] = 1  # type: ignore[index]
    assert c.options_dict() == {"k": {"x": 1}}
    with pytest.raises(SpecError):
        ControllerSpec("Bad Name", {})


def _scenario(name: str, family: str | None = None, **kw: object) -> Scenario:
    base: dict[str, object] = dict(
        name=name, family=family or name, catalog_path=Path("x.toml"), net="n",
        net_path=Path("n.net.xml"), route=("e0",), ego=EgoSpec(0, 0.0, 1.0), stalled=(),
        traffic=None, controller=ControllerSpec("lane_keep", {}), duration_s=1.0,
        step_s=0.1, seed=0)
    base.update(kw)
    return Scenario(**base)  # type: ignore[arg-type]


def test_scenario_post_init_and_as_dict() -> None:
    sc = _scenario("a", criteria={"min_ttc_s": 2}, sweep_values={"seed": 1})
    assert sc.steps == 10
    d = sc.as_dict()
    assert json.loads(json.dumps(d)) == d
    assert d["criteria"] == {"min_ttc_s": 2.0}
    with pytest.raises(SpecError, match="step_s"):
        _scenario("a", step_s=2.0)
    with pytest.raises(SpecError, match="duration_s"):
        _scenario("a", duration_s=0)
    with pytest.raises(SpecError, match="name"):
        _scenario("A")
    with pytest.raises(SpecError, match="criteria"):
        _scenario("a", criteria={"x": True})
    assert pickle.loads(pickle.dumps(sc)) == sc


def test_expand_filter() -> None:
    items = [_scenario("s3_stall__pos300", "s3_stall"), _scenario("s3_stall__pos500", "s3_stall"),
             _scenario("curve_cruise")]
    assert [s.name for s in expand_filter(items, "s3_*")] == [
        "s3_stall__pos300", "s3_stall__pos500"]
    assert len(expand_filter(items, "s3_stall")) == 2  # a family name selects its variants
    assert [s.name for s in expand_filter(items, "*pos500,curve*")] == [
        "s3_stall__pos500", "curve_cruise"]
    assert expand_filter(items, "nothing") == ()
    assert len(expand_filter(items, "*")) == 3 and len(expand_filter(items, None)) == 3


# ====================================================================== file problems
def test_missing_file_and_toml_syntax_error(tmp_path: Path) -> None:
    with pytest.raises(CatalogError, match="nope.toml"):
        load_catalog(tmp_path / "nope.toml", known_controllers=KNOWN)
    bad = tmp_path / "bad.toml"
    bad.write_text("[defaults]\nduration_s = 3\n[[scenario]\nname = 'x'\n")
    with pytest.raises(CatalogError) as info:
        load_catalog(bad, known_controllers=KNOWN)
    msg = str(info.value)
    assert "bad.toml" in msg and "line 3" in msg


def test_empty_catalog(tmp_path: Path) -> None:
    path = tmp_path / "empty.toml"
    path.write_text("[defaults]\nduration_s = 3.0\n")
    err = errors_of(path)
    assert "empty.toml" in str(err) and "scenario" in str(err)


# ====================================================================== good catalogs
@pytest.mark.sumo
def test_good_catalog_defaults_and_resolution(net_dir: Path) -> None:
    path = write(net_dir, GOOD + """
    [[scenario]]
    name = "explicit"
    net = "nets/test.net.xml"
    route = ["e0", "e1"]
    ego = { lane = 2, pos_m = 0.0, speed_mps = 25, target_speed_mps = 30 }
    stalled = [ { lane = 1, pos_m = 300 }, { lane = 0, pos_m = 100, length_m = 10 } ]
    traffic = { vehicles_per_hour = 1200, lanes = [1, 2], speed_mps = 25 }
    controller = { name = "unregistered_ctrl", horizon = 20, weights = { q = 1.0 } }
    duration_s = 20
    criteria = { min_ttc_s = 3.0, max_abs_jerk_mps3 = 5 }
    allow_shoulder = true
    record_radius_m = 80
    timeout_s = 60
    """)
    cat = load(path)
    assert cat.path == path.resolve()
    assert cat.names() == ["base", "explicit"]
    base, explicit = cat.scenarios
    assert base.route == ("e0", "e1", "e2")  # default: longest path
    assert base.net_path == (net_dir / "nets" / "test.net.xml").resolve()
    assert base.controller == ControllerSpec("lane_keep", {})
    assert (base.duration_s, base.step_s, base.seed) == (10.0, 0.05, 3)
    assert dict(base.criteria) == {"max_rms_lat_dev_m": 1.0, "min_ttc_s": 2.0}
    assert base.traffic is None and base.stalled == () and base.timeout_s is None
    assert base.ego.target_speed_mps == 20.0 and base.family == "base"
    assert explicit.route == ("e0", "e1")
    assert explicit.duration_s == 20.0 and explicit.allow_shoulder
    assert dict(explicit.criteria) == {"max_rms_lat_dev_m": 1.0, "min_ttc_s": 3.0,
                                       "max_abs_jerk_mps3": 5.0}
    assert explicit.traffic == TrafficSpec(1200.0, 3, 25.0, (1, 2), 0.1)  # seed from scenario
    assert explicit.stalled[1].length_m == 10.0
    assert explicit.controller.name == "unregistered_ctrl"
    assert explicit.controller.options_dict() == {"horizon": 20, "weights": {"q": 1.0}}
    assert (explicit.record_radius_m, explicit.timeout_s) == (80.0, 60.0)
    for sc in cat:
        d = sc.as_dict()
        assert json.loads(json.dumps(d)) == d
        assert pickle.loads(pickle.dumps(sc)) == sc


@pytest.mark.sumo
def test_sweep_expansion_names_order_and_values(net_dir: Path) -> None:
    path = write(net_dir, """
    [[scenario]]
    name = "stall"
    net = "nets/test.net.xml"
    ego = { lane = 1, pos_m = 20.0, speed_mps = 20.0 }
    stalled = [ { lane = 1, pos_m = 400.0 } ]
    traffic = { vehicles_per_hour = 1500, seed = 7 }
    [scenario.sweep]
    "stalled.0.pos_m" = [300.0, 500.0, 612.5]
    "traffic.vehicles_per_hour" = [0, 2000]
    ego.target_speed_mps = [25, 30]
    """ + GOOD)
    cat = load(path)
    assert len(cat) == 3 * 2 * 2 + 1
    assert cat.names()[:3] == ["stall__pos300__vph0__vt25", "stall__pos300__vph0__vt30",
                               "stall__pos300__vph2000__vt25"]
    assert cat.names()[-2] == "stall__pos612p5__vph2000__vt30"
    assert cat.names()[-1] == "base"
    first = cat.scenarios[0]
    assert first.family == "stall"
    assert dict(first.sweep_values) == {"stalled.0.pos_m": 300.0,
                                        "traffic.vehicles_per_hour": 0,
                                        "ego.target_speed_mps": 25}
    assert first.stalled[0].pos_m == 300.0 and first.traffic is not None
    assert first.traffic.vehicles_per_hour == 0.0 and first.ego.target_speed_mps == 25.0
    assert len(expand_filter(cat.scenarios, "stall")) == 12


@pytest.mark.sumo
def test_sweep_same_short_is_disambiguated(net_dir: Path) -> None:
    path = write(net_dir, """
    [[scenario]]
    name = "two"
    net = "nets/test.net.xml"
    ego = { lane = 1, pos_m = 20.0, speed_mps = 20.0 }
    stalled = [ { lane = 1, pos_m = 400.0 }, { lane = 2, pos_m = 400.0 } ]
    [scenario.sweep]
    "stalled.0.pos_m" = [300]
    "stalled.1.pos_m" = [350, 450]
    """)
    assert load(path).names() == [
        "two__stalled0pos300__stalled1pos350", "two__stalled0pos300__stalled1pos450"]


def test_sweeping_the_controller_names_variants_by_controller(net_dir: Path) -> None:
    path = write(net_dir, """
    [[scenario]]
    name = "cmp"
    net = "nets/test.net.xml"
    ego = { lane = 1, pos_m = 20.0, speed_mps = 20.0 }
    [scenario.sweep]
    controller = ["lane_keep", { name = "sumo" }]
    """)
    cat = load(path)
    assert cat.names() == ["cmp__lane_keep", "cmp__sumo"]
    assert [s.controller.name for s in cat.scenarios] == ["lane_keep", "sumo"]


@pytest.mark.sumo
def test_example_fixture_catalog_on_bundled_nets() -> None:
    sumo_nets = pytest.importorskip("sumo_nets")
    if "straight_3lane" not in sumo_nets.available():
        pytest.skip("bundled nets not built")
    cat = load(DATA / "example.toml")
    assert cat.names() == ["s3_stall_mid__pos300__vph0", "s3_stall_mid__pos300__vph2000",
                           "s3_stall_mid__pos500__vph0", "s3_stall_mid__pos500__vph2000",
                           "shoulder_cruise"]
    assert cat.scenarios[0].net_path == sumo_nets.net_path("straight_3lane")
    assert cat.get("shoulder_cruise").stalled[0].lane == 0


# ====================================================================== bad catalogs
BAD_CASES = [
    # (scenario body, key expected in the message)
    ('name = "Bad-Name"', "scenario[0].name"),
    ('extra_key = 1', "scenario[0].extra_key"),
    ('duration_s = 0', "scenario[0].duration_s"),
    ('duration_s = -3.0', "scenario[0].duration_s"),
    ('step_s = 0.0', "scenario[0].step_s"),
    ('step_s = 60.0', "scenario[0].step_s"),
    ('duration_s = inf', "scenario[0].duration_s"),
    ('duration_s = nan', "scenario[0].duration_s"),
    ('duration_s = true', "scenario[0].duration_s"),
    ('duration_s = "10"', "scenario[0].duration_s"),
    ('seed = 1.5', "scenario[0].seed"),
    ('seed = -1', "scenario[0].seed"),
    ('allow_shoulder = 1', "scenario[0].allow_shoulder"),
    ('record_radius_m = 0', "scenario[0].record_radius_m"),
    ('timeout_s = -1', "scenario[0].timeout_s"),
    ('criteria = { min_ttc_s = "x" }', "scenario[0].criteria.min_ttc_s"),
    ('criteria = { min_ttc_s = false }', "scenario[0].criteria.min_ttc_s"),
    ('criteria = { max_lateral_error = 1.0 }', "scenario[0].criteria.max_lateral_error"),
    ('criteria = 3', "scenario[0].criteria"),
    ('ego = { lane = 1, pos_m = 2.0 }', "scenario[0].ego.speed_mps"),
    ('ego = { lane = 1, pos_m = 2.0, speed_mps = -1 }', "scenario[0].ego.speed_mps"),
    ('ego = { lane = 1, pos_m = 2.0, speed_mps = true }', "scenario[0].ego.speed_mps"),
    ('ego = { lane = 1.0, pos_m = 2.0, speed_mps = 1 }', "scenario[0].ego.lane"),
    ('ego = { lane = 1, pos_m = 2.0, speed_mps = 1, colour = "red" }', "scenario[0].ego.colour"),
    ('ego = { lane = 3, pos_m = 2.0, speed_mps = 1 }', "scenario[0].ego.lane"),
    ('ego = { lane = 2, pos_m = 1200.0, speed_mps = 1 }', "scenario[0].ego.lane"),  # lane drop
    ('ego = { lane = 0, pos_m = 2.0, speed_mps = 1 }', "scenario[0].ego.lane"),  # shoulder
    ('ego = { lane = 1, pos_m = -2.0, speed_mps = 1 }', "scenario[0].ego.pos_m"),
    ('ego = { lane = 1, pos_m = 99999.0, speed_mps = 1 }', "scenario[0].ego.pos_m"),
    ('ego = 5', "scenario[0].ego"),
    ('stalled = [ { lane = 1, pos_m = 99999.0 } ]', "scenario[0].stalled.0.pos_m"),
    ('stalled = [ { lane = 1, pos_m = 5.0 }, { lane = 2, pos_m = 1300.0 } ]',
     "scenario[0].stalled.1.lane"),
    ('stalled = [ { lane = true, pos_m = 5.0 } ]', "scenario[0].stalled.0.lane"),
    ('stalled = [ { lane = 1 } ]', "scenario[0].stalled.0.pos_m"),
    ('stalled = [ { lane = 1, pos_m = 5.0, width_m = 0 } ]', "scenario[0].stalled.0.width_m"),
    ('stalled = { lane = 1, pos_m = 5.0 }', "scenario[0].stalled"),
    ('traffic = { seed = 1 }', "scenario[0].traffic.vehicles_per_hour"),
    ('traffic = { vehicles_per_hour = -5 }', "scenario[0].traffic.vehicles_per_hour"),
    ('traffic = { vehicles_per_hour = 5, lanes = [5] }', "scenario[0].traffic.lanes.0"),
    ('traffic = { vehicles_per_hour = 5, lanes = [0] }', "scenario[0].traffic.lanes.0"),
    ('traffic = { vehicles_per_hour = 5, lanes = [] }', "scenario[0].traffic.lanes"),
    ('traffic = { vehicles_per_hour = 5, speed_mps = 0 }', "scenario[0].traffic.speed_mps"),
    ('traffic = { vehicles_per_hour = 5, rate = 1 }', "scenario[0].traffic.rate"),
    ('net = "no_such_net"', "scenario[0].net"),
    ('net = 3', "scenario[0].net"),
    ('route = ["e0", "zz"]', "scenario[0].route.1"),
    ('route = ["e0", "e2"]', "scenario[0].route.1"),
    ('route = []', "scenario[0].route"),
    ('route = "e0"', "scenario[0].route"),
    ('controller = "warp_drive"', "scenario[0].controller.name"),
    ('controller = { gain = 1 }', "scenario[0].controller.name"),
    ('controller = { name = "lane_keep", when = 1979-05-27 }', "scenario[0].controller.when"),
    ('controller = 5', "scenario[0].controller"),
    ('sweep = { "ego.pos_m" = [] }', 'scenario[0].sweep."ego.pos_m"'),
    ('sweep = { "ego.pos_m" = 5 }', 'scenario[0].sweep."ego.pos_m"'),
    ('sweep = { "ego.nope.x" = [1] }', 'scenario[0].sweep."ego.nope.x"'),
    ('sweep = { "stalled.0.pos_m" = [1] }', 'scenario[0].sweep."stalled.0.pos_m"'),
    ('sweep = { "traffic.vehicles_per_hour" = [1] }',
     'scenario[0].sweep."traffic.vehicles_per_hour"'),
    ('sweep = { "name" = ["x"] }', 'scenario[0].sweep."name"'),
    ('sweep = { "ego.lane" = [1, 7] }', "scenario[0].ego.lane"),
    ('sweep = { "ego.lane" = [1, 1.0] }', "scenario[0].ego.lane"),
    ('sweep = 3', "scenario[0].sweep"),
]


def _base_table(override: str) -> str:
    """The GOOD scenario with one line replaced/added (TOML keys must stay unique)."""
    keys = {"name": 'name = "base"', "net": 'net = "nets/test.net.xml"',
            "ego": 'ego = { lane = 1, pos_m = 20.0, speed_mps = 20.0 }'}
    key = override.split("=", 1)[0].strip()
    keys[key] = override
    return "[[scenario]]\n" + "\n".join(keys.values()) + "\n"


@pytest.mark.sumo
@pytest.mark.parametrize("override, key", BAD_CASES)
def test_bad_input_names_file_scenario_key(net_dir: Path, override: str, key: str) -> None:
    path = write(net_dir, _base_table(override))
    err = errors_of(path)
    msg = str(err)
    lines = [ln for ln in msg.splitlines()[1:] if key in ln]
    assert lines, msg
    assert all(ln.startswith(str(path)) for ln in msg.splitlines()[1:]), msg
    assert any("scenario '" in ln for ln in lines), msg  # scenario named (name or label)
    assert any("expected" in ln for ln in lines), msg
    assert err.issues and err.path == path.resolve()


@pytest.mark.sumo
def test_bad_net_message_lists_bundled_names(net_dir: Path) -> None:
    sumo_nets = pytest.importorskip("sumo_nets")
    msg = str(errors_of(write(net_dir, _base_table('net = "nowhere"'))))
    for name in sumo_nets.available():
        assert name in msg


@pytest.mark.sumo
def test_all_errors_collected(net_dir: Path) -> None:
    path = write(net_dir, """
    [[scenario]]
    name = "one"
    net = "nets/test.net.xml"
    ego = { lane = 9, pos_m = 20.0, speed_mps = -1 }
    stalled = [ { lane = 1, pos_m = -4.0 } ]
    [[scenario]]
    name = "two"
    net = "nets/test.net.xml"
    ego = { lane = 1, pos_m = 20.0, speed_mps = 1 }
    duration_s = 0.0
    controller = "nope"
    """, header="bogus_top = 1\n" + HEADER + "unknown_default = 1\n")
    err = errors_of(path)
    keys = {i.key for i in err.issues}
    assert {"bogus_top", "defaults.unknown_default", "scenario[0].ego.lane",
            "scenario[0].ego.speed_mps", "scenario[0].stalled.0.pos_m",
            "scenario[1].duration_s", "scenario[1].controller.name"} <= keys
    assert len(str(err).splitlines()) == len(err.issues) + 1


@pytest.mark.sumo
def test_missing_required_keys(net_dir: Path) -> None:
    path = write(net_dir, """
    [[scenario]]
    net = "nets/test.net.xml"
    """, header="")
    keys = {i.key for i in errors_of(path).issues}
    assert {"scenario[0].name", "scenario[0].ego", "scenario[0].controller",
            "scenario[0].duration_s", "scenario[0].step_s"} <= keys


@pytest.mark.sumo
def test_duplicate_names_also_after_sweep(net_dir: Path) -> None:
    path = write(net_dir, GOOD + GOOD)
    assert "unique" in str(errors_of(path))
    path = write(net_dir, GOOD + """
    [[scenario]]
    name = "x"
    net = "nets/test.net.xml"
    ego = { lane = 1, pos_m = 20.0, speed_mps = 20.0 }
    [scenario.sweep]
    "ego.pos_m" = [30.0, 30]
    """)
    err = errors_of(path)
    assert any(i.key == "scenario[1].name" and "x__pos30" in str(i.got) for i in err.issues)


@pytest.mark.sumo
def test_sweep_error_points_at_sweep_and_variant(net_dir: Path) -> None:
    path = write(net_dir, """
    [[scenario]]
    name = "sw"
    net = "nets/test.net.xml"
    ego = { lane = 1, pos_m = 20.0, speed_mps = 20.0 }
    step_s = 100.0
    [scenario.sweep]
    "ego.lane" = [1, 2, 5]
    "seed" = [1, 2]
    """)
    err = errors_of(path)
    lane_lines = [i for i in err.issues if i.key == "scenario[0].ego.lane"]
    assert {i.scenario for i in lane_lines} == {"sw__lane5__seed1", "sw__lane5__seed2"}
    assert all('sweep."ego.lane"' in i.note for i in lane_lines)
    step_lines = [i for i in err.issues if i.key == "scenario[0].step_s"]
    assert len(step_lines) == 1 and step_lines[0].scenario == "sw"  # once per family


@pytest.mark.sumo
def test_shoulder_allowed_when_requested(net_dir: Path) -> None:
    path = write(net_dir, """
    [[scenario]]
    name = "on_shoulder"
    net = "nets/test.net.xml"
    ego = { lane = 0, pos_m = 20.0, speed_mps = 20.0 }
    allow_shoulder = true
    """)
    assert load(path).scenarios[0].ego.lane == 0


@pytest.mark.sumo
def test_absolute_net_path_and_defaults_net(net_dir: Path, tmp_path: Path) -> None:
    net = (net_dir / "nets" / "test.net.xml").resolve()
    path = tmp_path / "abs.toml"
    path.write_text(HEADER + f'net = "{net}"\n' + """
    [[scenario]]
    name = "abs"
    ego = { lane = 1, pos_m = 20.0, speed_mps = 20.0 }
    """.replace("\n    ", "\n"))
    cat = load(path)
    assert cat.scenarios[0].net_path == net


# ====================================================================== controller registry
def _registry_names() -> list[str]:
    try:
        from controllers import registry
        return registry.names()
    except Exception:
        return []


@pytest.mark.sumo
def test_controller_options_checked_by_registry(net_dir: Path) -> None:
    names = _registry_names()
    if "lane_keep" not in names:
        pytest.skip("controller registry (lane_keep) not available")
    path = write(net_dir, _base_table('controller = { name = "lane_keep", no_such_gain = 1 }'))
    for kw in ({}, {"known_controllers": KNOWN}):
        err = errors_of(path, **kw)
        assert any(i.key == "scenario[0].controller.no_such_gain" for i in err.issues), err
    # without known_controllers the registry's names are the reference
    path = write(net_dir, _base_table('controller = "two_loop_typo"'))
    assert "scenario[0].controller.name" in str(errors_of(path, known_controllers=None))


@pytest.mark.sumo
def test_explicit_known_controllers_skip_unbuildable(net_dir: Path) -> None:
    # "fancy" is not in the registry: with an explicit list, its options are not checked.
    path = write(net_dir, _base_table('controller = { name = "fancy", anything = 1 }'))
    cat = load(path, known_controllers={"fancy"})
    assert cat.scenarios[0].controller.options_dict() == {"anything": 1}
    assert "controller.name" in str(errors_of(path, known_controllers={"lane_keep"}))
