"""docs/two_loop.md's option tables are the generated ones (suite.cli.params_doc)."""

from __future__ import annotations

from pathlib import Path

import pytest

from controllers import registry
from suite.cli.params_doc import BEGIN, DOC_PATH, END, main, options_block, render


def _row(block: str, option: str) -> list[str]:
    line = next(li for li in block.splitlines() if li.startswith(f"| `{option}` |"))
    return [c.strip() for c in line.strip("|").split("|")]


def test_two_loop_doc_has_the_generated_tables() -> None:
    text = DOC_PATH.read_text(encoding="utf-8")
    assert render(text) == text, "run: python -m suite.cli.params_doc --write"


def test_every_option_of_both_controllers_is_a_row() -> None:
    block = options_block()
    for name in ("two_loop", "ipopt_nmpc"):
        for opt in registry.options(name):
            assert f"| `{opt.path.removeprefix('controller.')}` |" in block


def test_known_rows() -> None:
    block = options_block()
    assert _row(block, "outer.horizon_s") == ["`outer.horizon_s`", "float", "`2.4`", "s",
                                             "prediction horizon T", "`horizon_s`"]
    assert _row(block, "launch.handover_speed_mps")[2:4] == ["`1.5`", "m/s"]
    assert _row(block, "launch.handover_speed_mps")[5] == "`launch_speed_mps`"
    assert _row(block, "jerk.enabled")[1:3] == ["bool", "`true`"]
    assert _row(block, "fallback.decel_mps2")[5] == "—"
    assert _row(block, "outer.tol")[2] == "`1e-06`"
    assert _row(block, "outer.tol")[5] == "`ipopt_tol`"
    sections = [li for li in block.splitlines() if li.startswith("**`")]
    assert [s.split("`")[1] for s in sections] == ["outer", "inner", "lateral", "launch",
                                                   "policy", "fallback", "jerk", "threat"]


def test_render_replaces_only_between_markers() -> None:
    text = f"head\n{BEGIN}\nold\n{END}\ntail\n"
    assert render(text, "new") == f"head\n{BEGIN}\nnew\n{END}\ntail\n"
    with pytest.raises(ValueError):
        render("no markers", "new")


def test_check_and_write(tmp_path: Path) -> None:
    doc = tmp_path / "two_loop.md"
    doc.write_text(f"# t\n{BEGIN}\nstale\n{END}\n", encoding="utf-8")
    assert main(["--check", "--path", str(doc)]) == 1
    assert main(["--write", "--path", str(doc)]) == 0
    assert main(["--check", "--path", str(doc)]) == 0
    assert options_block() in doc.read_text(encoding="utf-8")
