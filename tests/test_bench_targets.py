"""hwyeval bench's targets (issue 25): the comparison logic and the wall-time account
(known answers), the command's exit codes, and the quick bench run for real."""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from suite.bench import QUICK, BenchOptions, BenchResult
from suite.bench.account import WallAccount, account
from suite.bench.command import CommandTiming, RunFigures, StampedLine
from suite.bench.figures import CommandFigures, DenseRunFigures, FloorFigures, measured_targets
from suite.bench.targets import (
    TARGETS,
    Comparison,
    Measured,
    Target,
    TargetResult,
    all_met,
    judge,
    target,
)
from suite.cli import main

ROOT = Path(__file__).resolve().parents[1]


def test_the_targets_are_declared_once_with_the_issues_values() -> None:
    names = [t.name for t in TARGETS]
    assert len(names) == len(set(names))
    got = {t.name: (t.comparison.value, t.target_value, t.unit, t.isolated_only)
           for t in TARGETS if t.issue in (25, 36)}
    assert got == {"one_run_share_of_floor": (">=", 70.0, "%", False),
                   "command_share_of_floor_jobs1": (">=", 60.0, "%", False),
                   "step_p99_over_outer_p99": ("<=", 1.5, "x", False),
                   "step_max_ms_worst_run": ("<=", 1.0, "ms", True),
                   "jobs2_over_jobs1_scenario_phase": (">=", 1.8, "x", False)}
    assert target("ipopt_over_cgmres_var").target_value == 1000.0
    with pytest.raises(KeyError):
        target("nope")


def test_comparison_known_answers() -> None:
    at_least = Target("rtf", "x", Comparison.AT_LEAST, 100.0, "a ratio", 25)
    at_most = Target("p99", "ms", Comparison.AT_MOST, 0.25, "a time", 25)
    assert at_least.is_met_by(100.0) and at_least.is_met_by(1e9)
    assert not at_least.is_met_by(99.999) and not at_least.is_met_by(math.nan)
    assert at_most.is_met_by(0.25) and at_most.is_met_by(0.0)
    assert not at_most.is_met_by(0.2501) and not at_most.is_met_by(math.nan)
    assert not at_least.is_met_by(-math.inf) and at_most.is_met_by(-math.inf)
    assert at_least.text() == ">= x100" and at_most.text() == "<= 0.25 ms"


@pytest.mark.parametrize("bad", [
    dict(name="two words"), dict(unit="s"), dict(target_value=0.0),
    dict(target_value=math.inf), dict(target_value=math.nan), dict(issue=0)])
def test_a_bad_target_is_refused(bad: dict) -> None:  # type: ignore[type-arg]
    fields = dict(name="t", unit="x", comparison=Comparison.AT_LEAST, target_value=1.0,
                  what="", issue=25)
    with pytest.raises(ValueError):
        Target(**{**fields, **bad})  # type: ignore[arg-type]
    with pytest.raises(TypeError):
        Target(**{**fields, "comparison": ">="})  # type: ignore[arg-type]


def test_judge_known_answers() -> None:
    measured = [Measured("one_run_share_of_floor", 72.0),
                Measured("step_max_ms_worst_run", 1.7),
                Measured("step_p99_over_outer_p99", math.nan, "no outer_ms_p99")]
    results = judge(measured)
    assert [r.target for r in results] == list(TARGETS)  # one each, in order
    by = {r.target.name: r for r in results}
    assert by["one_run_share_of_floor"].met
    ratio = by["step_p99_over_outer_p99"]
    assert not ratio.measured and not ratio.met and ratio.why_not == "no outer_ms_p99"
    assert by["command_share_of_floor_jobs1"].why_not == "not part of this bench run"
    assert not all_met(results) and all_met(()) and all_met(results[:1])
    # the step max is measured and missed, but judged only when the bench ran isolated
    step_max = by["step_max_ms_worst_run"]
    assert step_max.measured and not step_max.met and not step_max.judged
    assert all_met([by["one_run_share_of_floor"], step_max])
    isolated = {r.target.name: r for r in judge(measured, isolated=True)}
    assert isolated["step_max_ms_worst_run"].judged
    assert not all_met([isolated["one_run_share_of_floor"], isolated["step_max_ms_worst_run"]])
    with pytest.raises(KeyError):
        judge([Measured("nope", 1.0)])
    with pytest.raises(ValueError):
        Measured("one_run_share_of_floor", math.nan)  # not measured needs a reason


def _timing() -> CommandTiming:
    """A 2-run --jobs 1 command started at epoch 1000 s, 10 s long: first line at 1.0 s,
    run a from 2.5 s (wall_s 3.0 to its loop's end at 5.5 s, Rerun log 0.5 s, run.json at
    6.5 s), run b from 6.7 s (wall_s 2.0, loop end 8.7 s, log 0.2 s, run.json 9.0 s),
    manifest at 9.6 s."""
    a = RunFigures("a", "pass", wall_s=3.0, stages_s=2.0, sim_s=40.0, peak_rss_mb=1.0,
                   log_s=0.5, step_p99_ms=0.4, step_max_ms=2.0, start_epoch_s=1002.5,
                   loop_end_epoch_s=1005.5, end_epoch_s=1006.5, outer_p99_ms=0.1,
                   controller_p99_ms=0.15)
    b = RunFigures("b", "pass", wall_s=2.0, stages_s=1.0, sim_s=40.0, peak_rss_mb=1.0,
                   log_s=0.2, step_p99_ms=0.6, step_max_ms=1.5, start_epoch_s=1006.7,
                   loop_end_epoch_s=1008.7, end_epoch_s=1009.0, outer_p99_ms=0.3,
                   controller_p99_ms=0.5)
    return CommandTiming(jobs=1, log=True, wall_s=10.0, runs_span_s=6.5, sim_s=80.0,
                         exit_code=0, runs=(b, a), start_epoch_s=1000.0,
                         manifest_epoch_s=1009.6,
                         lines=(StampedLine(1.0, "hwyeval ..."), StampedLine(9.7, "report:")))


def test_wall_account_known_answers() -> None:
    got = account(_timing())
    assert got.runs == 2
    assert got.to_first_line_s == pytest.approx(1.0)
    assert got.to_first_run_s == pytest.approx(1.5)
    assert got.runs_wall_s == pytest.approx(5.0)
    assert got.runs_log_s == pytest.approx(0.7)
    assert got.runs_after_loop_s == pytest.approx(0.5 + 0.1)  # 1.0 - 0.5 and 0.3 - 0.2
    assert got.between_runs_s == pytest.approx(0.2)
    assert got.reports_s == pytest.approx(0.6)
    assert got.exit_s == pytest.approx(0.4)
    assert got.accounted_s == pytest.approx(10.0) and got.unaccounted_s == pytest.approx(0.0)
    assert got.outside_runs_wall_s == pytest.approx(5.0)
    with pytest.raises(ValueError):
        account(CommandTiming(jobs=2, log=True, wall_s=1.0, runs_span_s=1.0, sim_s=1.0,
                              exit_code=0, runs=()))
    with pytest.raises(ValueError):
        WallAccount(command_s=1.0, runs=1, to_first_line_s=math.nan, to_first_run_s=0.0,
                    runs_wall_s=0.0, runs_log_s=0.0, runs_after_loop_s=0.0,
                    between_runs_s=0.0, reports_s=0.0, exit_s=0.0)


def test_dense_figures_known_answers() -> None:
    d = DenseRunFigures.of(_timing())
    assert d.runs == 2 and d.duration_s == 40.0
    assert d.realtime_factor_median == pytest.approx((40 / 3 + 40 / 2) / 2)
    assert (d.realtime_factor_min, d.realtime_factor_max) == pytest.approx((40 / 3, 20.0))
    assert d.life_realtime_factor_median == pytest.approx((40 / 4 + 40 / 2.3) / 2)
    assert (d.step_p99_ms_worst, d.step_p99_worst_run) == (0.6, "b")
    assert (d.step_max_ms_worst, d.step_max_worst_run) == (2.0, "a")
    # the step p99 over the run's own outer-update p99: a 0.4 / 0.1, b 0.6 / 0.3
    assert d.step_p99_over_outer_p99_worst == pytest.approx(4.0)
    assert d.step_p99_over_outer_p99_worst_run == "a"
    # the controller's step alone: a 0.15 / 0.1, b 0.5 / 0.3
    assert d.controller_p99_over_outer_p99_worst == pytest.approx(0.5 / 0.3)
    assert d.controller_p99_over_outer_p99_worst_run == "b"
    values = {m.name: m.value for m in measured_targets(d, None, None)}
    assert values == {"step_p99_over_outer_p99": pytest.approx(4.0),
                      "step_max_ms_worst_run": 2.0}
    # with a floor: kernel 0.5 s + SUMO 0.3 s a 40 s run is x50; the runs' median
    # (x13.3 and x20) x16.7 is a third of it; the command's 80 s in 10 s, x8, is 16 %
    fl = FloorFigures(runs=2, glue_per_step_us=500.0, glue_per_run_s=1.0, kernel_per_run_s=0.5,
                      sumo_per_run_s=0.3, loop_per_run_s=1.8, steps_per_run=2000.0,
                      third_party_import_s=1.0, preload_s=1.0)
    jobs2 = CommandTiming(jobs=2, log=True, wall_s=8.0, runs_span_s=4.0, sim_s=80.0,
                          exit_code=0, runs=())
    values = {m.name: m.value
              for m in measured_targets(d, fl, CommandFigures.of(_timing(), jobs2))}
    assert values["one_run_share_of_floor"] == pytest.approx(100.0 * (50 / 3) / 50.0)
    assert values["command_share_of_floor_jobs1"] == pytest.approx(100.0 * 8.0 / 50.0)
    assert values["jobs2_over_jobs1_scenario_phase"] == pytest.approx(6.5 / 4.0)


def test_bench_options_are_checked() -> None:
    assert QUICK.quick and QUICK.seeds == QUICK.catalog_runs == 2
    assert QUICK.phases() == 6 and BenchOptions().phases() == 10
    assert not BenchOptions(include_runner=False, include_ipopt=False).judged
    for bad in (dict(seeds=0), dict(catalog_runs=0), dict(run_duration_s=0.0),
                dict(solver_repeats=0)):
        with pytest.raises(ValueError):
            BenchOptions(**bad)  # type: ignore[arg-type]


def _fake_run_all(met: bool):  # type: ignore[no-untyped-def]
    def run_all(options: BenchOptions, print_fn=None) -> BenchResult:  # type: ignore[no-untyped-def]
        assert options == QUICK
        t = Target("one_run_share_of_floor", "%", Comparison.AT_LEAST, 70.0, "", 36)
        fig = {"machine": {"cpus": 2, "processor": "p", "python": "3"}, "load_start": [0.0],
               "controller": {"outer_update": {}, "control_step": {"p50_us": 1.0,
                                                                   "p99_us": 2.0}}}
        return BenchResult(options, fig, results=(TargetResult(t, 75.0 if met else 50.0),))
    return run_all


@pytest.mark.parametrize(("met", "no_fail", "code"), [(True, False, 0), (False, False, 1),
                                                      (False, True, 0), (True, True, 0)])
def test_exit_codes(met: bool, no_fail: bool, code: int, monkeypatch: pytest.MonkeyPatch,
                    capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    import suite.bench

    monkeypatch.setattr(suite.bench, "run_all", _fake_run_all(met))
    out = tmp_path / "b.json"
    assert main(["bench", "--quick", "--out", str(out)] + (["--no-fail"] if no_fail else [])) \
        == code
    assert json.loads(out.read_text())["machine"]["cpus"] == 2
    text = capsys.readouterr().out
    assert ("-> met" if met else "-> NOT met") in text
    assert ("--no-fail: exit 0" in text) == (no_fail and not met)


def test_bad_input_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "--out", str(tmp_path / "missing" / "b.json")]) == 2
    assert main(["bench", "--out", str(tmp_path)]) == 2
    for bad in (["--seeds", "0"], ["--catalog-runs", "x"]):
        with pytest.raises(SystemExit) as exc:
            main(["bench", *bad])
        assert exc.value.code == 2


@pytest.mark.slow
@pytest.mark.sumo
def test_the_quick_bench_judges_every_target(tmp_path: Path) -> None:
    """The real quick bench, its temporary folders in tmp_path: progress lines while it
    runs, every target with a value and met / not met, an exit code that says whether
    all were met, the same figures in --out."""
    out = tmp_path / "bench.json"
    env = dict(os.environ, TMPDIR=str(tmp_path), PYTHONUNBUFFERED="1")
    proc = subprocess.run([sys.executable, "-m", "suite", "bench", "--quick", "--out",
                           str(out)], cwd=ROOT, env=env, capture_output=True, text=True,
                          check=False, timeout=600)
    assert proc.returncode in (0, 1), proc.stderr[-2000:]
    lines = proc.stdout.splitlines()
    progress = [m for m in (re.match(r"bench \[\s*([\d.]+) s\] (\d+)/(\d+) ", line)
                            for line in lines) if m]
    assert [int(m.group(2)) for m in progress] == list(range(1, QUICK.phases() + 1))
    assert {int(m.group(3)) for m in progress} == {QUICK.phases()}
    elapsed = [float(m.group(1)) for m in progress]
    assert elapsed == sorted(elapsed) and elapsed[-1] > elapsed[0]
    verdicts = {}
    for t in TARGETS:
        [line] = [x for x in lines if x.startswith(f"TARGET {t.name}: ")]
        assert re.search(r": (x[\d.]+|[\d.]+ (us|ms|%)) \(target ", line), line  # a value
        reported = line.endswith(" (reported, judged only with --isolated)")
        assert reported == t.isolated_only  # the quick bench is not isolated
        verdict = line.removesuffix(" (reported, judged only with --isolated)")
        assert verdict.endswith("-> met") or verdict.endswith("-> NOT met")
        verdicts[t.name] = verdict.endswith("-> met")
    judged = [met for name, met in verdicts.items() if not target(name).isolated_only]
    figures = json.loads(out.read_text())
    assert figures["all_met"] == all(judged)
    assert proc.returncode == (0 if all(judged) else 1)
    assert {t["name"]: t["met"] for t in figures["targets"]} == verdicts
    assert figures["load_start"] and figures["load_end"] and figures["machine"]["cpus"]
    assert any(x.startswith("machine: ") and "load average" in x for x in lines)
    # the whole command's wall time, every part accounted
    account_line = [x for x in lines if "accounted of" in x]
    assert account_line and "(unaccounted 0.000 s)" in account_line[0]
    acc = figures["issue25"]["command"]["account"]
    assert sum(v for _, v in acc["parts_s"]) == pytest.approx(acc["command_s"])
    assert len(list(tmp_path.glob("hwyeval-bench-*"))) == 0  # cleaned up


def test_a_scenario_process_pins_itself_to_the_cpus_named() -> None:
    """suite.exec.worker.become_worker reads HWYEVAL_SCENARIO_CPUS (bench --isolated)."""
    cpu = max(os.sched_getaffinity(0))
    code = ("import os; from suite.exec.worker import become_worker; become_worker(); "
            "print(sorted(os.sched_getaffinity(0)))")
    env = dict(os.environ, HWYEVAL_SCENARIO_CPUS=str(cpu))
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, text=True,
                         capture_output=True, check=True).stdout
    assert out.strip() == f"[{cpu}]"
    env["HWYEVAL_SCENARIO_CPUS"] = "not-a-cpu"  # ignored: never a reason to fail a run
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, text=True,
                         capture_output=True, check=True).stdout
    assert out.strip() == str(sorted(os.sched_getaffinity(0)))
