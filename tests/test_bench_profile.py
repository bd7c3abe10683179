"""suite.bench.profile: py-spy raw stacks -> shares of the loop (known answers)."""

from __future__ import annotations

from pathlib import Path

import pytest

from suite.bench.profile import main, read_shares

LOOP = "<module> (x.py:1);run_loop (suite/run/loop.py:59);_steps (suite/run/loop.py:77)"
DECIDE = "decide (controllers/behaviour/decision.py:147)"
RAW = "\n".join([
    f"{LOOP};{DECIDE};_scene (controllers/behaviour/decision.py:165) 30",
    f"{LOOP};decide (controllers/behaviour/decision.py:150) 10",
    f"{LOOP};step (controllers/two_loop/controller.py:220) 50",
    "<module> (x.py:1);run_loop (suite/run/loop.py:59);_steps (suite/run/loop.py:80) 10",
    "<module> (x.py:1);build (suite/run/runner.py:10) 400",
]) + "\n"


def test_shares_count_only_the_loop_and_merge_lines() -> None:
    sh = read_shares(RAW)
    assert sh.samples == 100  # the 400 build samples are outside the loop
    assert sh.inclusive["decide decision.py"] == 40  # two lines of one function
    assert sh.inclusive["_scene decision.py"] == 30
    assert sh.self_["decide decision.py"] == 10 and sh.self_["step controller.py"] == 50
    assert sh.self_["_steps (itself)"] == 10
    assert sum(sh.self_.values()) == sh.samples


def test_bad_raw_file_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "prof.txt"
    bad.write_text("this is not py-spy output\n")
    assert main(["shares", str(bad)]) == 2
    assert str(bad) in capsys.readouterr().err
    good = tmp_path / "good.txt"
    good.write_text(RAW)
    assert main(["shares", str(good), "--top", "3"]) == 0
    assert "samples inside the loop: 100" in capsys.readouterr().out


def test_the_machine_bound_is_the_run_over_kernel_and_sumo() -> None:
    from suite.bench.figures import DenseRunFigures, FloorFigures, floor_realtime_factor
    from suite.bench.summary import dense_lines

    d = DenseRunFigures(runs=4, duration_s=40.0, realtime_factor_median=16.0,
                        realtime_factor_min=12.0, realtime_factor_max=17.0,
                        life_realtime_factor_median=14.0, step_p99_ms_worst=2.0,
                        step_p99_worst_run="a", step_max_ms_worst=5.0, step_max_worst_run="b")
    fl = FloorFigures(runs=4, glue_per_step_us=780.0, glue_per_run_s=1.56, kernel_per_run_s=0.4,
                      sumo_per_run_s=0.4, loop_per_run_s=2.36, steps_per_run=2000.0,
                      third_party_import_s=2.0, preload_s=1.3)
    assert floor_realtime_factor(d.duration_s, fl) == 50.0
    assert any("x50.0" in line for line in dense_lines(d, fl))
