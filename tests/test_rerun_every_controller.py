"""Every controller gets a Rerun log, with or without a plan, preview or diagnostics.

The SUMO part runs each built-in controller and the example plug-in on one short
scenario in real SUMO and reads every ``run.rrd`` back with Rerun's own reader: the
ego at every recorded step, the other vehicles, the stalled car and the verdict (the
recording's ``run`` property and the run.json status agree). The in-process part
forces a log failure and checks that it reaches the terminal line, the short summary
and the report (a badge, no link to a missing file), and that no file is left half
written.
"""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from rerun_fixtures import make_record, read_chunks

import suite.rerun.log as rerun_log
from reports.record import RRD, ControllerArrays, load_run, write_run
from reports.write import write_reports
from suite.exec.progress import short_summary, status_line
from suite.run import runner
from suite.run.options import RunOptions

ROOT = Path(__file__).resolve().parents[1]

CONTROLLERS = ["two_loop", "lane_keep", "sumo", "ipopt_nmpc", "pd_follow", "r157_reference"]
SCENARIO = """
[[scenario]]
name = "log_{name}"
net = "straight_3lane"
ego = {{ lane = 1, pos_m = 60.0, speed_mps = 22.0 }}
stalled = [ {{ lane = 2, pos_m = 200.0 }} ]
traffic = {{ vehicles_per_hour = 1200, seed = 3, lanes = [0] }}
controller = {{ name = "{name}" }}
"""


def _has_ipopt() -> bool:
    from controllers import registry

    return "ipopt_nmpc" in registry.names() and "pd_follow" in registry.names()


def _temporal_steps(chunks: list, entity: str) -> list[int]:
    steps: list[int] = []
    for c in chunks:
        if c.entity_path == entity and not c.is_static:
            steps += c.to_record_batch().column("step").to_pylist()
    return steps


def _run_property(chunks: list) -> dict[str, str]:
    for c in chunks:
        if c.entity_path == "/__properties/run":
            row = c.to_record_batch().to_pylist()[-1]
            return {k: v[0] for k, v in row.items() if isinstance(v, list)}
    return {}


@pytest.fixture(scope="module")
def every_controller(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if not _has_ipopt():
        pytest.fail("the test environment needs the 'baselines' extra (ipopt_nmpc) and the "
                    "example plug-in (pd_follow) installed: python3 bootstrap.py test does both")
    base = tmp_path_factory.mktemp("every_controller")
    catalog = base / "every.toml"
    catalog.write_text('[defaults]\nduration_s = 6.0\nstep_s = 0.02\nseed = 1\n'
                       + "".join(SCENARIO.format(name=n) for n in CONTROLLERS))
    out = base / "out"
    proc = subprocess.run([sys.executable, "-m", "suite", "run", str(catalog), "--out",
                           str(out), "--jobs", "2"], cwd=ROOT, capture_output=True, text=True,
                          timeout=900)
    assert proc.returncode in (0, 1), proc.stdout + proc.stderr
    assert "no Rerun log" not in proc.stdout, proc.stdout
    return out


@pytest.mark.sumo
@pytest.mark.slow
@pytest.mark.parametrize("name", CONTROLLERS)
def test_every_controller_writes_a_readable_log(every_controller: Path, name: str) -> None:
    run_dir = every_controller / f"log_{name}"
    run_json = json.loads((run_dir / "run.json").read_text())
    assert run_json["outcome"].get("log_error") in (None, "")
    assert not (run_dir / (RRD + ".partial")).exists()
    chunks = read_chunks(run_dir / RRD)
    trace = pd.read_parquet(run_dir / "trace.parquet")
    assert sorted(_temporal_steps(chunks, "/world/ego/box")) == trace["step"].tolist()
    assert _temporal_steps(chunks, "/world/vehicles"), "the background traffic is in the log"
    assert any(c.entity_path == "/world/stalled" for c in chunks)
    prop = _run_property(chunks)
    status = load_run(run_dir).status
    assert prop["status"] == status and prop["controller"] == name
    assert any(c.entity_path == "/events" for c in chunks)


# ------------------------------------------------------------------ without SUMO


def _no_plan(record):  # type: ignore[no-untyped-def]
    """The record of a controller that returns no plan, preview or diagnostics."""
    n = len(record.trace)
    record.arrays = ControllerArrays(plan_xy_m=np.zeros((n, 0, 2)),
                                     preview_xy_m=np.zeros((n, 0, 2)),
                                     ellipses=np.zeros((n, 0, 6)), detection_radius_m=0.0)
    record.trace.extra.clear()
    return record


@pytest.mark.parametrize("arrays", ["none", "empty", "all_nan", "one_point"])
def test_a_log_is_written_whatever_the_controller_recorded(tmp_path: Path, arrays: str) -> None:
    record = make_record(steps=120)
    n = len(record.trace)
    if arrays == "none":
        record = _no_plan(record)
    elif arrays == "empty":
        record.arrays = ControllerArrays()
    elif arrays == "all_nan":
        record.arrays = ControllerArrays(plan_xy_m=np.full((n, 5, 2), np.nan),
                                         preview_xy_m=np.full((n, 3, 2), np.nan),
                                         ellipses=np.full((n, 2, 6), np.nan))
    else:  # a single valid point per step: no strip, but a preview end
        plan = np.full((n, 4, 2), np.nan)
        plan[:, 0] = 1.0
        record.arrays = ControllerArrays(plan_xy_m=plan, preview_xy_m=plan.copy(),
                                         ellipses=np.zeros((n, 0, 6)))
    out = rerun_log.log_record(record, tmp_path / RRD)
    chunks = read_chunks(out)
    assert len(_temporal_steps(chunks, "/world/ego/box")) == n
    assert _run_property(chunks)["status"] == record.status


def test_a_failing_log_leaves_no_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def broken(log: object) -> None:
        raise RuntimeError("vehicles layer broke")

    monkeypatch.setattr(rerun_log, "log_vehicles", broken)
    with pytest.raises(RuntimeError):
        rerun_log.log_record(make_record(steps=60), tmp_path / RRD)
    assert list(tmp_path.iterdir()) == []


def test_a_log_failure_is_shown_in_the_terminal_and_the_report(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def broken(*args: object, **kw: object) -> Path:
        raise ValueError("cannot draw this run")

    out = tmp_path / "night"
    logged = make_record(scenario="logged", steps=80, seed=2)
    write_run(logged, out / "logged")
    rerun_log.write_rrd(out / "logged")
    monkeypatch.setattr(rerun_log, "log_record", broken)
    failed = runner._judge_and_write(make_record(scenario="unlogged", steps=80),
                                     out / "unlogged", RunOptions(write_rrd=True))
    assert failed.outcome.log_error and "cannot draw this run" in failed.outcome.log_error
    assert not (out / "unlogged" / RRD).exists()
    assert load_run(out / "unlogged").outcome.log_error == failed.outcome.log_error
    # terminal: the run's line and the short summary name the log failure
    assert "cannot draw this run" in status_line(failed, 1, 2)
    # both runs passed: only the log failure puts a passing run in the short summary
    summary = short_summary([failed, replace(logged)], 1.0)
    words = [set(line.replace(",", " ").replace(":", " ").split()) for line in summary]
    assert any("unlogged" in w for w in words)
    assert not any("logged" in w for w in words)
    # report: a badge for the failed log, a link only to the log that exists
    paths = write_reports(out)
    html = Path(paths.report_html).read_text()
    assert 'id="log-failures"' in html
    assert html.count('class="badge nolog"') >= 2  # header count and the run's row
    links = [h for h in _hrefs(html) if h.endswith(RRD)]
    assert links and all((Path(paths.report_html).parent / h).is_file() for h in links)
    page = (Path(paths.report_html).parent / "report-runs" / "unlogged.html").read_text()
    assert 'class="badge nolog"' in page
    assert not [h for h in _hrefs(page) if h.endswith(RRD)]


def _hrefs(html: str) -> list[str]:
    import re

    return re.findall(r'href="([^"]+)"', html)
