"""Runs that do not finish, and the catalog a run works from (W5, W9, W16, W17), on a
real libsumo: a default wall-clock budget, fresh records for killed and timed-out runs
with their controller and NaN metrics, the backstop for a hung process, and workers
that never read the catalog file."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pandas as pd
import pytest

from controllers import registry
from reports.record import load_run
from suite.catalog import ControllerSpec, load_catalog
from suite.cli import main
from suite.exec import budget, local
from suite.exec.build import build_jobs
from suite.exec.command import Plugins
from suite.exec.executors import LocalExecutor, RunJob
from suite.run.runner import RunOptions
from tests.reliability_support import hwyeval, plugin_file, scenario_toml, write_catalog

pytestmark = pytest.mark.sumo

STOPPED = scenario_toml("stopped", speed_mps=0.0)  # never reaches the end of the route


def _plugin(tmp_path: Path) -> registry.PluginModule:
    module = registry.plugin_module(str(plugin_file(tmp_path)))
    registry.load_plugin(module)
    return module


def _no_metric_values(record_dir: Path) -> None:
    record = load_run(record_dir, trace=False, neighbours=False, arrays=False, series=False)
    assert record.verdict is not None and record.verdict.metrics
    assert all(math.isnan(m.value) for m in record.verdict.metrics)
    assert record.verdict.failures == ()


@pytest.mark.slow
def test_every_job_gets_a_finite_budget_and_the_default_ends_a_run(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """W5: no default wall-clock budget: a stopped ego with a huge duration never ended."""
    catalog = write_catalog(tmp_path / "w5.toml", [STOPPED], duration_s=10000.0)
    scenario = load_catalog(catalog).scenarios[0]
    assert scenario.timeout_s is None
    job = build_jobs([scenario], tmp_path / "o", "w5", True, Plugins())[0]
    assert job.timeout_s == job.options.timeout_s == budget.MAX_DEFAULT_S  # capped: 1 h
    assert budget.default_budget_s(1.0) == budget.STARTUP_S + budget.WALL_PER_SIM_S
    assert build_jobs([scenario], tmp_path / "o", "w5", True, Plugins(), 7.0)[0].timeout_s == 7.0
    # the default, made small here, ends the run as a timeout (what ran is kept)
    monkeypatch.setattr(budget, "STARTUP_S", 2.0)
    monkeypatch.setattr(budget, "MAX_DEFAULT_S", 3.0)
    out = tmp_path / "out"
    assert main(["run", str(catalog), "--out", str(out), "--no-log"]) == 1
    assert "TIMEOUT stopped" in capsys.readouterr().out
    record = load_run(out / "stopped", trace=True, neighbours=False, arrays=False, series=False)
    assert record.status == "timeout" and "budget of 3.0 s" in (record.outcome.error or "")
    assert 0 < len(record.trace) < scenario.steps
    assert record.info.controller == "lane_keep"
    _no_metric_values(out / "stopped")


@pytest.mark.slow
def test_a_duration_no_run_can_hold_is_refused_at_validation(tmp_path: Path) -> None:
    """W5: duration_s = 1e9 (2e10 steps) is an input error naming the key, not a hang or
    a MemoryError in the scenario process."""
    catalog = write_catalog(tmp_path / "huge.toml", [STOPPED], duration_s=1e9)
    proc = hwyeval("run", str(catalog), "--out", str(tmp_path / "out"))
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "scenario[0].duration_s (scenario 'stopped')" in proc.stderr
    assert not (tmp_path / "out").exists()


def test_a_worker_killed_at_the_start_of_a_rerun_inherits_nothing(tmp_path: Path) -> None:
    """W9: its error record kept the previous run's wall_s, sim_time_s and metrics."""
    module = _plugin(tmp_path)
    scenario = load_catalog(write_catalog(tmp_path / "w9.toml", [scenario_toml("victim")])
                            ).scenarios[0]
    out = tmp_path / "out"
    first = LocalExecutor(jobs=1).run([RunJob(scenario, out, RunOptions(write_rrd=False))])
    assert first[0].status == "pass" and first[0].outcome.wall_s > 0
    (out / "victim" / "left_by_the_old_run.txt").write_text("old")
    doomed = dataclasses.replace(scenario, controller=ControllerSpec("doomed_at_start"))
    again = LocalExecutor(jobs=1).run([RunJob(doomed, out, RunOptions(write_rrd=False),
                                              plugins=(module,))])
    assert again[0].status == "error"
    stored = load_run(out / "victim")
    assert "exited with code -9" in (stored.outcome.error or "")
    assert stored.info.controller == "doomed_at_start"
    assert math.isnan(stored.outcome.wall_s)
    assert stored.outcome.sim_time_s == 0.0 and stored.outcome.steps == 0
    assert len(stored.trace) == 0
    assert not (out / "victim" / "left_by_the_old_run.txt").exists()
    _no_metric_values(out / "victim")


@pytest.mark.slow
def test_killed_and_timed_out_runs_carry_their_controller_and_nan_metrics(
        tmp_path: Path) -> None:
    """W16: an empty controller, and collision = 0.0 in results.csv for runs without a
    trace, so that the totals counted them as collision-free."""
    plugin = plugin_file(tmp_path)
    catalog = write_catalog(tmp_path / "w16.toml", [
        scenario_toml("killed", extra='controller = "doomed_at_start"\n'),
        scenario_toml("too_slow", speed_mps=0.0, extra="timeout_s = 1.5\n"),
        scenario_toml("fine"),
    ], duration_s=10000.0)  # 200000 steps: far more than 1.5 s of wall time
    out = tmp_path / "out"
    proc = hwyeval("run", str(catalog), "--out", str(out), "--no-log", "--plugin", str(plugin))
    assert proc.returncode == 1, proc.stdout + proc.stderr
    res = pd.read_csv(out / "results.csv").set_index("scenario")
    assert res.loc["killed", "status"] == "error" and res.loc["too_slow", "status"] == "timeout"
    assert res.loc["fine", "status"] == "pass"
    assert res.loc["killed", "controller"] == "doomed_at_start"
    assert res.loc["too_slow", "controller"] == "lane_keep"
    for name in ("killed", "too_slow"):
        for metric in ("collision", "min_gap_m", "progress_m", "max_abs_lat_acc_mps2"):
            assert math.isnan(res.loc[name, metric]), (name, metric)
        _no_metric_values(out / name)
    assert res.loc["fine", "collision"] == 0.0
    summary = pd.read_csv(out / "summary.csv")
    lane_keep = summary[(summary["controller"] == "lane_keep") & (summary["family"] == "ALL")]
    assert lane_keep["sum_collision"].iloc[0] == 0.0 and lane_keep["runs"].iloc[0] == 2


@pytest.mark.slow
def test_a_process_that_hangs_before_its_loop_is_killed_at_its_budget(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The executor's backstop: the runner cannot stop a run that never reaches its loop."""
    module = _plugin(tmp_path)
    monkeypatch.setattr(local, "KILL_GRACE_S", 1.0)
    scenario = load_catalog(write_catalog(tmp_path / "hang.toml", [
        scenario_toml("hung", extra='controller = "hangs_at_start"\n')])).scenarios[0]
    out = tmp_path / "out"
    record = LocalExecutor(jobs=1).run([RunJob(scenario, out, RunOptions(
        write_rrd=False, timeout_s=1.0), 1.0, (module,))])[0]
    assert record.status == "timeout"
    assert "killed after" in (record.outcome.error or "")
    stored = load_run(out / "hung", trace=False)
    assert stored.status == "timeout" and stored.info.controller == "hangs_at_start"
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no staging left


def test_workers_never_read_the_catalog_file(tmp_path: Path) -> None:
    """W17: each worker re-read and re-validated the catalog: an edit mid-run changed
    later scenarios (a rename gave KeyError) and big sweeps validated O(N^2)."""
    catalog = write_catalog(tmp_path / "w17.toml", [scenario_toml("first"),
                                                     scenario_toml("second", lane=1)])
    jobs = build_jobs(list(load_catalog(catalog).scenarios), tmp_path / "out", "w17", True,
                      Plugins())
    catalog.write_text(catalog.read_text().replace('"second"', '"renamed"')
                       .replace("lane = 1", "lane = 5"))
    jobs_after_edit = list(jobs)
    catalog.unlink()
    records = LocalExecutor(jobs=2).run(jobs_after_edit)
    assert sorted((r.info.scenario, r.status) for r in records) == [("first", "pass"),
                                                                    ("second", "pass")]


def test_the_next_run_starts_before_the_last_record_is_read(tmp_path: Path) -> None:
    """One worker: the executor starts the next scenario process, then reads the record
    of the one that ended (15-30 ms of every run no longer spent between two runs);
    every record still arrives, in the order the runs ended."""
    catalog = write_catalog(tmp_path / "two.toml",
                            [scenario_toml("first"), scenario_toml("second")], duration_s=3.0)
    jobs = build_jobs(load_catalog(catalog).scenarios, tmp_path / "out", "two", True,
                      Plugins())
    running_at_done: list[list[str]] = []

    def on_done(record: object) -> None:
        del record
        running_at_done.append(sorted(p.name for p in local.mp.active_children()
                                      if p.name in {"first", "second"}))

    records = LocalExecutor(jobs=1).run(jobs, on_done)
    assert [r.info.scenario for r in records] == ["first", "second"]
    assert [r.status for r in records] == ["pass", "pass"]
    assert running_at_done[0] == ["second"], running_at_done
    assert running_at_done[1] == []
