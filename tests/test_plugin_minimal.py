"""docs/plugins.md's minimal controller (ControllerBase: reset + step) is a whole plug-in:
the code block is taken from the page, run by ``hwyeval run --plugin`` through a real
libsumo scenario, and its results read back. Also the registry's class factory."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from controllers import registry
from controllers.protocol import Command, ConfigError, Controller, ControllerBase

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "plugins.md"
CATALOG = """
[defaults]
duration_s = 8.0
step_s = 0.05

[[scenario]]
name = "minimal_lane_keeper"
net = "straight_3lane"
ego = { lane = 1, pos_m = 60.0, speed_mps = 20.0, target_speed_mps = 22.0 }
controller = "lane_keeper"
"""


def minimal_example() -> str:
    """The first python block after the heading 'The minimal controller'."""
    text = DOC.read_text()
    start = text.index("## The minimal controller")
    match = re.search(r"```python\n(.*?)```", text[start:], re.S)
    assert match is not None, "docs/plugins.md: no python block after the heading"
    return match.group(1)


def test_the_minimal_example_is_at_most_30_lines_and_needs_only_reset_and_step() -> None:
    code = minimal_example()
    assert len(code.splitlines()) <= 30
    defs = re.findall(r"^    def (\w+)\(", code, re.M)
    assert defs == ["reset", "step"]


@pytest.mark.sumo
def test_the_minimal_example_runs_a_real_scenario(tmp_path: Path) -> None:
    plugin = tmp_path / "my_controller.py"
    plugin.write_text(minimal_example())
    catalog = tmp_path / "minimal.toml"
    catalog.write_text(CATALOG)
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "suite", "run", str(catalog), "--out", str(out),
                           "--jobs", "1", "--no-log", "--plugin", str(plugin)], cwd=ROOT,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    row = pd.read_csv(out / "results.csv").set_index("scenario").loc["minimal_lane_keeper"]
    assert row["controller"] == "lane_keeper"
    assert row["status"] == "pass"
    assert not bool(row["collision"])
    assert row["max_abs_lat_dev_m"] < 0.5  # it keeps its lane
    assert 19.0 < row["mean_speed_mps"] < 23.0  # and drives near the set speed
    assert row["progress_m"] > 140.0


class _Keeper(ControllerBase):
    def reset(self, context: object) -> None:
        del context

    def step(self, observation: object) -> Command:
        del observation
        return Command(0.0, 0.0)


def test_a_registered_class_is_its_own_factory_named_by_the_registry() -> None:
    factory = registry.class_factory("keeper_test", _Keeper)
    ctl = factory({})
    assert isinstance(ctl, Controller)
    assert ctl.name == "keeper_test"
    assert ctl.parameters() == {}
    assert ctl.obstacle_policy is None
    assert factory({"name": "keeper_test"}).name == "keeper_test"
    with pytest.raises(ConfigError) as err:
        factory({"gain": 1.0})
    assert err.value.key == "controller.gain"
    with pytest.raises(ConfigError):
        factory({"name": "other"})


def test_the_base_class_alone_is_not_a_controller() -> None:
    with pytest.raises(NotImplementedError):
        ControllerBase().step(None)  # type: ignore[arg-type]
