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
