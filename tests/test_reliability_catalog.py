"""Catalog problems found by the probe (W1, W6, W7, W14) and the earlier fuzz pass
(sweeps): each is exit 2 with the file, the key and what was expected, before anything
runs; or, where the scenario is valid, it runs without a surprise."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from suite.catalog import CatalogError, load_catalog
from suite.catalog.rules import MAX_NAME_LEN
from tests.reliability_support import ROOT, hwyeval, results, scenario_toml, write_catalog

DEFAULTS = '[defaults]\ncontroller = "lane_keep"\nduration_s = 1.0\nstep_s = 0.05\n'
EGO = 'net = "straight_2lane"\nego = { lane = 0, pos_m = 60.0, speed_mps = 20.0 }\n'


def _issues(tmp_path: Path, body: str) -> list[str]:
    path = tmp_path / "c.toml"
    path.write_text(DEFAULTS + body)
    with pytest.raises(CatalogError) as info:
        load_catalog(path)
    return [i.line(path) for i in info.value.issues]


def _one(tmp_path: Path, body: str, key: str) -> str:
    lines = _issues(tmp_path, body)
    assert len(lines) == 1, lines
    assert f": {key}" in lines[0], lines
    return lines[0]


def test_a_name_too_long_for_a_directory_is_an_input_error(tmp_path: Path) -> None:
    """W1: a 256+ character name passed, then the parent crashed (ENAMETOOLONG)."""
    line = _one(tmp_path, f'[[scenario]]\nname = "{"a" * 256}"\n{EGO}', "scenario[0].name")
    assert f"at most {MAX_NAME_LEN} characters" in line
    catalog = tmp_path / "long.toml"
    catalog.write_text(DEFAULTS + f'[[scenario]]\nname = "{"a" * 300}"\n{EGO}')
    proc = hwyeval("run", str(catalog), "--out", str(tmp_path / "out"))
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    assert not (tmp_path / "out").exists()


def test_sweep_suffixes_that_make_a_name_too_long_are_an_input_error(tmp_path: Path) -> None:
    base = "b" * (MAX_NAME_LEN - 5)
    line = _one(tmp_path, f'[[scenario]]\nname = "{base}"\n{EGO}'
                '[scenario.sweep]\n"ego.speed_mps" = [10.0, 20.0]\n', "scenario[0].name")
    assert "sweep variants" in line


@pytest.mark.slow
@pytest.mark.sumo
def test_the_longest_allowed_name_runs(tmp_path: Path) -> None:
    name = "n" * MAX_NAME_LEN
    catalog = write_catalog(tmp_path / "c.toml", [scenario_toml(name)], duration_s=1.0)
    proc = hwyeval("run", str(catalog), "--out", str(tmp_path / "out"), "--no-log")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert list(results(tmp_path / "out").index) == [name]


@pytest.mark.parametrize("name", ['""', "5", None], ids=["empty", "integer", "missing"])
def test_an_invalid_name_is_one_problem(tmp_path: Path, name: str | None) -> None:
    """W14: a second problem blamed the label 'scenario[0]' as if it were the name."""
    line = f"name = {name}\n" if name is not None else ""
    issue = _one(tmp_path, f"[[scenario]]\n{line}{EGO}", "scenario[0].name")
    assert "'scenario[0]'" not in issue and "[defaults]" not in issue


@pytest.mark.parametrize("stalled, key", [
    ("[ { lane = 0, pos_m = 60.0 } ]", "scenario[0].stalled.0.pos_m"),
    ("[ { lane = 0, pos_m = 300.0 }, { lane = 0, pos_m = 300.0 } ]",
     "scenario[0].stalled.1.pos_m"),
], ids=["on_the_ego", "two_at_one_spot"])
def test_stalled_cars_sumo_would_refuse_are_input_errors(tmp_path: Path, stalled: str,
                                                          key: str) -> None:
    """W6: validation passed, then a runtime error with a misleading message."""
    issue = _one(tmp_path, f'[[scenario]]\nname = "s"\n{EGO}stalled = {stalled}\n', key)
    assert "clear of" in issue


@pytest.mark.slow
@pytest.mark.sumo
def test_a_stalled_car_close_ahead_of_a_fast_ego_runs_without_an_error(tmp_path: Path) -> None:
    """W6: 40-90 m ahead of a 25 m/s ego: SUMO refused to insert the ego at runtime."""
    scenarios = [scenario_toml(f"ahead_{gap}", pos_m=100.0, speed_mps=25.0,
                               extra=f"stalled = [ {{ lane = 0, pos_m = {100.0 + gap} }} ]\n"
                               + ('controller = "sumo"\n' if gap == 90 else ""))
                 for gap in (40, 65, 90)]
    catalog = write_catalog(tmp_path / "c.toml", scenarios, duration_s=1.0)
    proc = hwyeval("run", str(catalog), "--out", str(tmp_path / "out"), "--no-log")
    assert proc.returncode in (0, 1), proc.stdout + proc.stderr
    statuses = results(tmp_path / "out")["status"]
    assert set(statuses) <= {"pass", "fail"}, statuses.to_dict()


def test_a_step_below_sumos_clock_is_an_input_error(tmp_path: Path) -> None:
    """W7: step_s = 1e-5 was accepted; the record then said 'TraCIException: Process
    Error'."""
    issue = _one(tmp_path, f'[[scenario]]\nname = "s"\n{EGO}step_s = 1e-5\n',
                 "scenario[0].step_s")
    assert "0.001 s" in issue


@pytest.mark.parametrize("sweep, key", [
    ('"criteria" = [[1, 2]]', "scenario[0].criteria"),
    ('"criteria.max_abs_lat_acc_mps2" = [[1, 2]]', "scenario[0].criteria.max_abs_lat_acc_mps2"),
    ('"criteria" = [[1]]\n"criteria.max_abs_lat_acc_mps2" = [2.0]',
     'scenario[0].sweep."criteria.max_abs_lat_acc_mps2"'),
    ('"stalled.0" = [[1]]\n"stalled.0.pos_m" = [5.0]', 'scenario[0].sweep."stalled.0.pos_m"'),
    ("a = {}\nb = {}", 'scenario[0].sweep."a"'),
], ids=["criteria_list", "criterion_list", "criteria_and_criterion", "stalled_and_pos",
        "empty_sub_tables"])
def test_sweeps_that_cannot_expand_are_input_errors(tmp_path: Path, sweep: str,
                                                    key: str) -> None:
    """The earlier fuzz pass: a raw ValueError in set_path; zero scenarios silently."""
    body = (f'[[scenario]]\nname = "s"\n{EGO}criteria = {{ max_abs_lat_acc_mps2 = 3.0 }}\n'
            'stalled = [ { lane = 1, pos_m = 300.0 } ]\n'
            f"[scenario.sweep]\n{sweep}\n")
    lines = _issues(tmp_path, body)
    assert any(f": {key} " in line for line in lines), lines


def test_the_readme_names_only_files_that_exist() -> None:
    """README referred to suite/catalog.py after it became a package."""
    text = (ROOT / "README.md").read_text()
    for path in re.findall(r"`((?:suite|reports|controllers|sumo_nets)/[\w/.]+\.py)`", text):
        assert (ROOT / path).is_file(), path
