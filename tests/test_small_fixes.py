"""The small fixes of issue 32: the failures table names the criterion its excess belongs
to; a collision that ended a run early is on its FAIL line, whoever hit whom; an
unknown controller name near a built-in one still points at --plugin; ``view DIR
--failed`` suggests a --web command that view accepts; the search's per-run overhead is
never negative."""

from __future__ import annotations

import dataclasses
import re
import subprocess
import sys
from pathlib import Path

import pytest
import synthetic_runs as sr

from reports.html.failures import failures_section
from reports.html.links import Links
from reports.record import SumoCollision, write_run
from reports.tables import collect_runs
from suite.catalog import CatalogError, load_catalog
from suite.exec.progress import reason
from suite.search.outcome import SearchOutput

ROOT = Path(__file__).resolve().parents[1]


def test_each_failures_row_shows_one_criterion_and_its_own_excess(tmp_path: Path) -> None:
    record = dict(sr.catalog_records(("ctrl_a",)))["sharp_curve__ctrl_a"]
    # a second, far worse failure after the first in criteria order
    judged = sr.judge(record, {"max_abs_lat_acc_mps2": 3.0, "max_abs_yaw_rate_radps": 0.01})
    assert [f.criterion for f in judged.verdict.failures][:1] != ["max_abs_yaw_rate_radps"]
    write_run(judged, tmp_path / "curve")
    (run,) = collect_runs(tmp_path)
    html = failures_section([run], Links(tmp_path))
    row = re.search(r'<table class="failures.*?<tbody>(.*?)</tbody>', html, re.S)
    assert row is not None
    cells = re.findall(r"<td[^>]*>(.*?)</td>", row.group(1), re.S)
    worst = max(run.failures, key=lambda f: abs(f.value - f.limit) / abs(f.limit))
    assert cells[3] == worst.criterion  # the criterion beside the excess is the worst one
    assert f"{100 * abs(worst.value - worst.limit) / abs(worst.limit):.0f} %" in cells[7]


def test_a_collision_that_ended_the_run_is_on_its_fail_line() -> None:
    record = sr.judge(dict(sr.catalog_records(("ctrl_a",)))["rear_end__ctrl_a"])
    hit = SumoCollision(t_s=3.8, collider="rec_12", victim="ego", type="collision")
    record.outcome = dataclasses.replace(record.outcome, stop_reason="collision at t = 3.80 s",
                                         sumo_collisions=(hit,))
    line = reason(record)
    assert "3.80" in line and "rec_12" in line
    # a run that ended at the end of its route says nothing of it
    record.outcome = dataclasses.replace(record.outcome, stop_reason="end of route")
    assert "rec_12" not in reason(record)


def test_an_unknown_controller_near_a_builtin_name_points_at_plugin(tmp_path: Path) -> None:
    path = tmp_path / "c.toml"
    path.write_text('[[scenario]]\nname = "a"\nnet = "straight_3lane"\n'
                    'ego = { lane = 1, pos_m = 60.0, speed_mps = 25.0 }\n'
                    'controller = "acc_keep"\nduration_s = 2.0\nstep_s = 0.02\n')
    with pytest.raises(CatalogError) as info:
        load_catalog(path)
    (issue,) = info.value.issues
    assert "--plugin" in issue.expected and "'lane_keep'" in issue.expected


@pytest.mark.slow  # the CLI in a subprocess
def test_view_failed_suggests_a_web_command_view_accepts(tmp_path: Path) -> None:
    out = sr.make_catalog(tmp_path / "night")  # several runs fail
    env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}  # no display
    proc = subprocess.run([sys.executable, "-m", "suite", "view", str(out), "--failed"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 0, proc.stderr
    (web,) = [line.split(": ", 1)[1] for line in proc.stdout.splitlines()
              if line.rstrip().endswith("--web")]
    words = web.split()
    assert words[:2] == ["hwyeval", "view"] and "--failed" in words
    assert len([w for w in words[2:] if not w.startswith("--")]) == 1  # one PATH


def test_the_search_overhead_per_run_is_never_negative() -> None:
    # two workers: the runs' own wall time summed exceeds the wall clock
    res = SearchOutput(wall_s=10.0, run_wall_s=19.5, workers=2)
    res.results = []
    assert res.overhead_per_run_s >= 0.0
    res = SearchOutput(wall_s=10.0, run_wall_s=25.0, workers=2)
    assert res.overhead_per_run_s == 0.0
