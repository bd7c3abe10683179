"""hwyeval bench's pieces: its catalogs, figures and summary, the extrapolation-error
arithmetic (known answers), and one real command timed (SUMO test); the targets and the
whole quick bench: tests/test_bench_targets.py."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from suite.bench import BenchOptions, BenchResult, _solver_targets, summary_lines
from suite.bench.account import account
from suite.bench.catalogs import MATRIX_CATALOG, TARGET_CATALOG, dense_catalog, with_defaults
from suite.bench.command import CommandTiming, RunFigures, StepStats, run_command
from suite.bench.figures import (
    DenseRunFigures,
    FloorFigures,
    glue_budget_per_step_us,
    share_of_floor_without_pct,
)
from suite.bench.floor import GLUE_STAGES, FloorRun, bound, floor_study, glue_per_step_us
from suite.bench.multirate import _Frame, extrapolation_errors
from suite.bench.summary import glue_stage_lines
from suite.bench.targets import judge
from suite.catalog import load_catalog


def test_catalogs(tmp_path: Path) -> None:
    (tmp_path / "m.toml").write_text(MATRIX_CATALOG)
    matrix = load_catalog(tmp_path / "m.toml").scenarios
    assert len(matrix) == 12
    assert {s.net for s in matrix} == {"straight_2lane", "straight_3lane"}
    assert {s.controller.name for s in matrix} == {"two_loop", "lane_keep"}
    assert sorted({s.traffic.vehicles_per_hour if s.traffic else 0 for s in matrix}) == \
        [0, 1200, 2400]
    (tmp_path / "t.toml").write_text(with_defaults(TARGET_CATALOG, sumo_step_s=0.02))
    target = load_catalog(tmp_path / "t.toml").scenarios
    assert len(target) == 4 and all(s.steps_per_world_step == 1 for s in target)
    assert sum(s.duration_s for s in target) == pytest.approx(160.0)
    with pytest.raises(ValueError):
        with_defaults("[[scenario]]\n", sumo_step_s=0.02)
    (tmp_path / "d.toml").write_text(dense_catalog(24, 40.0))
    dense = load_catalog(tmp_path / "d.toml").scenarios
    assert len(dense) == 24 and sum(s.duration_s for s in dense) == pytest.approx(960.0)
    assert sorted(s.traffic.seed for s in dense if s.traffic) == list(range(3, 27))
    assert dense_catalog(4, 40.0) == TARGET_CATALOG
    for bad in ((0, 40.0), (2, 0.0)):
        with pytest.raises(ValueError):
            dense_catalog(*bad)


def test_step_stats_known_answers() -> None:
    st = StepStats.of(np.array([1e-6, 2e-6, 3e-6, np.nan]))
    assert st.n == 3 and st.p50_us == pytest.approx(2.0) and st.max_us == pytest.approx(3.0)
    assert math.isnan(StepStats.of(np.zeros(0)).p50_us)
    with pytest.raises(ValueError):
        StepStats(-1, 0.0, 0.0, 0.0, 0.0)
    run = RunFigures("a", "pass", wall_s=2.0, stages_s=1.5, sim_s=40.0, peak_rss_mb=200.0,
                     log_s=0.1)
    assert run.realtime_factor == pytest.approx(20.0)
    cmd = CommandTiming(jobs=1, log=True, wall_s=8.0, runs_span_s=4.0, sim_s=160.0,
                        exit_code=0, runs=(run,))
    assert cmd.realtime_factor == pytest.approx(20.0)
    assert cmd.runs_realtime_factor == pytest.approx(40.0)
    with pytest.raises(ValueError):
        CommandTiming(jobs=0, log=True, wall_s=1.0, runs_span_s=1.0, sim_s=1.0, exit_code=0,
                      runs=())


def _figures() -> dict:  # type: ignore[type-arg]
    steps = {k: {"n": 10, "p50_us": 100.0, "p95_us": 150.0, "p99_us": 240.0,
                 "max_us": 400.0}
             for k in ("controller_step", "behaviour_and_controller", "behaviour", "dynamics")}
    run = {"scenario": "a", "realtime_factor": 30.0, "peak_rss_mb": 210.0}
    wall = 160.0 / 55.0
    command = {"sim_s": 160.0, "wall_s": wall, "realtime_factor": 55.0,
               "runs_realtime_factor": 55.0 * 1.5, "runs_span_s": wall / 1.5,
               "before_runs_s": wall / 4, "after_runs_s": wall - wall / 1.5 - wall / 4,
               "steps_us": steps, "runs": [run]}
    ratio = {"raw": {"p50_s": 35.0, "var_s2": 500.0},
             "min_of_repeats": {"p50_s": 33.0, "var_s2": 2000.0},
             "min_of_repeats_with_obstacle": {"p50_s": 30.0, "var_s2": 4000.0}}
    return {"machine": {"cpus": 2, "processor": "x86_64", "python": "3.11"},
            "load_start": [0.1, 0.1, 0.1], "load_end": [0.2, 0.1, 0.1], "elapsed_s": 80.0,
            "controller": {"outer_update": {"p50_us": 24.0, "p99_us": 40.0},
                           "control_step": {"p50_us": 110.0, "p99_us": 150.0}},
            "solvers": {"repeats": 3, "cgmres": {"raw": {"p50_s": 7e-5}},
                        "ipopt_barrier": {"raw": {"p50_s": 2.6e-3}},
                        "ipopt_barrier_over_cgmres": ratio, "ipopt_hard_over_cgmres": ratio},
            "commands": {"dense_jobs1_log": command, "catalog_jobs2_log": command,
                         "floor": {"bound": {"wall_s": 2.0, "realtime_factor": 80.0,
                                             "glue_share": 0.3}},
                         "jobs2_over_jobs1": {"whole_command": 1.5, "scenario_phase": 1.8},
                         "logging_overhead": 1.05}}


def test_solver_targets_and_summary() -> None:
    """The solver figures are judged as before (the per-update minimum's variance), and
    the summary prints every part present and a line per target."""
    fig = _figures()
    measured = _solver_targets(fig["solvers"])
    assert [m.value for m in measured] == [35.0, 2000.0]
    got = {r.target.name: r for r in judge(measured)}
    assert got["ipopt_over_cgmres_p50"].met and got["ipopt_over_cgmres_var"].met
    assert not got["one_run_share_of_floor"].measured
    result = BenchResult(BenchOptions(), fig, results=judge(measured))
    text = "\n".join(summary_lines(result))
    assert "TARGET ipopt_over_cgmres_p50: x35.00 (target >= x30; issue #11) -> met" in text
    assert ("TARGET one_run_share_of_floor: not measured (not part of this bench run) "
            "(target >= 70 %; issue #36) -> NOT met") in text
    assert "(0.73 s before the first run, 1.94 s of runs, 0.24 s after the last)" in text
    assert "variance x2000; with it: variance x4000" in text  # the pooled one is judged
    assert "logging on / off (dense runs, --jobs 1): x1.05" in text
    assert "targets: 2 of 6 met" in text  # the step max is reported only (not --isolated)
    skipped = _solver_targets({"skipped": "no casadi"})
    assert all(not m.value == m.value and m.why_not == "no casadi" for m in skipped)
    assert "targets: not judged" in "\n".join(summary_lines(BenchResult(BenchOptions(), fig)))


def _frames(n: int, step_s: float, accel: float) -> list[_Frame]:
    """Two vehicles: one at 20 m/s plus ``accel`` along +X, one stalled."""
    out = []
    for k in range(n):
        t = k * step_s
        x = np.array([20.0 * t + 0.5 * accel * t * t, 50.0])
        out.append(_Frame({"a": 0, "s": 1}, x, np.array([0.0, 3.5]), np.zeros(2),
                          np.array([20.0 + accel * t, 0.0])))
    return out


def test_extrapolation_errors_known_answers() -> None:
    errs = extrapolation_errors(_frames(60, 0.02, 0.0), 5, 0.02)
    assert errs["velocity"]["all"]["max_m"] == pytest.approx(0.0, abs=1e-9)
    assert errs["velocity"]["moving"]["n"] == errs["velocity"]["all"]["n"] // 2
    # no extrapolation: the moving car's error is v tau, at most 20 m/s x 0.08 s
    assert errs["hold"]["by_tau_s"]["0.08"]["max_m"] == pytest.approx(1.6)
    assert errs["hold"]["by_tau_s"]["0.02"]["max_m"] == pytest.approx(0.4)
    braking = extrapolation_errors(_frames(60, 0.02, -4.0), 5, 0.02)
    # constant speed misses a tau^2 / 2 (0.0128 m at 0.08 s); constant acceleration is exact
    assert braking["velocity"]["all"]["max_m"] == pytest.approx(0.5 * 4.0 * 0.08 ** 2)
    assert braking["acceleration"]["all"]["max_m"] == pytest.approx(0.0, abs=1e-9)
    with pytest.raises(ValueError):
        extrapolation_errors([], 1, 0.02)


@pytest.mark.slow
@pytest.mark.sumo
def test_a_real_command_is_timed(tmp_path: Path) -> None:
    catalog = tmp_path / "c.toml"
    catalog.write_text(TARGET_CATALOG.replace("duration_s = 40.0", "duration_s = 2.0")
                       .replace('"traffic.seed" = [3, 4, 5, 6]', '"traffic.seed" = [3, 4]'))
    timing = run_command(catalog, tmp_path / "out", jobs=1, log=False)
    assert timing.exit_code in (0, 1) and len(timing.runs) == 2
    assert timing.sim_s == pytest.approx(4.0, abs=0.05)
    assert 0.0 < timing.runs_span_s < timing.wall_s
    # the three phases make up the command (file mtimes against the parent's clock)
    assert 0.0 < timing.before_runs_s < timing.wall_s and 0.0 < timing.after_runs_s
    assert timing.before_runs_s + timing.runs_span_s + timing.after_runs_s == pytest.approx(
        timing.wall_s, abs=1e-6)
    assert all(r.peak_rss_mb > 50.0 and 0.0 < r.stages_s < r.wall_s for r in timing.runs)
    st = timing.steps["controller_step"]
    assert st.n == 200 and 0.0 < st.p50_us <= st.p99_us <= st.max_us
    # results.csv's step columns, and when each run ran (file times, ~4 ms granularity)
    for r in timing.runs:
        assert 0.0 < r.step_p99_ms <= r.step_max_ms
        assert r.start_epoch_s < r.loop_end_epoch_s <= r.end_epoch_s + 0.01
        assert r.span_s == pytest.approx(r.wall_s + r.after_loop_s)
    assert timing.lines and timing.lines[0].text.startswith("hwyeval ")
    assert any(line.text.startswith("[2/2] ") for line in timing.lines)
    parts = account(timing)
    assert parts.runs == 2 and parts.unaccounted_s == pytest.approx(0.0, abs=1e-9)
    assert parts.to_first_line_s > 0.0 and parts.runs_log_s == 0.0  # --no-log
    assert parts.runs_wall_s == pytest.approx(sum(r.wall_s for r in timing.runs))
    assert min(v for _, v in parts.parts_s) > -0.01
    with pytest.raises(FileExistsError):
        run_command(catalog, tmp_path / "out", jobs=1, log=False)


def test_floor_bound_known_answers() -> None:
    """Two measured runs with 0.5 and 0.7 s of glue (mean 0.6 s) bound a 4-run, 160 s
    command of 6.4 s to 6.4 - 4 x 0.6 = 4.0 s: x40 real time, glue 37.5 % of it."""
    runs = [FloorRun("a", "pass", 1.0, 0.8, 0.2, 0.1, steps=2000),
            FloorRun("b", "pass", 1.2, 1.0, 0.2, 0.1, steps=2000)]
    assert [r.glue_s for r in runs] == pytest.approx([0.5, 0.7])
    assert [r.glue_per_step_us for r in runs] == pytest.approx([250.0, 350.0])
    assert glue_per_step_us(runs) == pytest.approx(300.0)
    assert math.isnan(FloorRun("z", "pass", 1.0, 0.8, 0.2, 0.1).glue_per_step_us)
    floor = {"runs": [{**r.__dict__, "glue_s": r.glue_s} for r in runs]}
    command = {"wall_s": 6.4, "sim_s": 160.0, "runs": [{}] * 4}
    got = bound(floor, command)
    assert got["wall_s"] == pytest.approx(4.0)
    assert got["realtime_factor"] == pytest.approx(40.0)
    assert got["glue_share"] == pytest.approx(2.4 / 6.4)
    with pytest.raises(ValueError):
        FloorRun("c", "pass", 1.0, 0.5, 0.4, 0.2)  # kernel + SUMO beyond the loop
    with pytest.raises(ValueError):
        bound(floor, {"wall_s": 2.0, "sim_s": 160.0, "runs": [{}] * 4})


def test_the_glue_splits_by_stage_known_answers() -> None:
    """A loop of 2.0 s: kernel 0.5 inside the controller's 0.8, SUMO 0.3 inside the
    world's 0.45 inside the dynamics' 0.6, behaviour 0.2, monitor 0.05, recorder 0.1:
    the glue (1.2 s) splits as 0.2, 0.3, 0.15, 0.15, 0.05, 0.1 and the loop's own 0.25."""
    run = FloorRun("a", "pass", run_s=2.5, loop_s=2.0, kernel_s=0.5, sumo_s=0.3, steps=1000,
                   behaviour_s=0.2, controller_s=0.8, dynamics_s=0.6, world_s=0.45,
                   monitor_s=0.05, recorder_s=0.1)
    parts = run.glue_by_stage_s()
    assert [name for name, _ in GLUE_STAGES] == ["behaviour", "controller", "world", "plant",
                                                 "monitor", "recorder", "loop"]
    assert parts == pytest.approx((0.2, 0.3, 0.15, 0.15, 0.05, 0.1, 0.25))
    assert sum(parts) == pytest.approx(run.glue_s)
    assert not FloorRun("z", "pass", 1.0, 0.8, 0.2, 0.1).staged
    assert all(math.isnan(v) for v in FloorRun("z", "pass", 1.0, 0.8, 0.2, 0.1)
               .glue_by_stage_s())
    good = dict(run_s=2.5, loop_s=2.0, kernel_s=0.5, sumo_s=0.3, behaviour_s=0.2,
                controller_s=0.8, dynamics_s=0.6, world_s=0.45, monitor_s=0.05, recorder_s=0.1)
    for bad in (dict(controller_s=0.4),  # the kernel beyond the controller's step
                dict(world_s=0.2),  # SUMO's step beyond the world's
                dict(world_s=0.7),  # the world's step beyond the dynamics'
                dict(recorder_s=0.5),  # the stages beyond the loop
                dict(wall_s=1.5),  # the loop beyond wall_s
                dict(wall_s=2.6),  # wall_s beyond the run
                dict(monitor_s=-0.01)):
        with pytest.raises(ValueError):
            FloorRun("c", "pass", **{**good, **bad})  # type: ignore[arg-type]


def test_share_of_the_floor_were_a_stage_free() -> None:
    """Floor x50 (kernel 0.5 + SUMO 0.3 s a 40 s run); runs at x20 take 2.0 s: free of a
    0.4 s stage they take 1.6 s, x25, half the floor; the 70 % target leaves
    40 / 35 - (2.0 - 1.0) = 0.143 s of glue a run, 71 us a step of 2000."""
    d = DenseRunFigures(runs=2, duration_s=40.0, realtime_factor_median=20.0,
                        realtime_factor_min=20.0, realtime_factor_max=20.0,
                        life_realtime_factor_median=18.0, step_p99_ms_worst=1.0,
                        step_p99_worst_run="a", step_max_ms_worst=2.0, step_max_worst_run="a")
    fl = FloorFigures(runs=2, glue_per_step_us=500.0, glue_per_run_s=1.0, kernel_per_run_s=0.5,
                      sumo_per_run_s=0.3, loop_per_run_s=1.8, steps_per_run=2000.0,
                      third_party_import_s=1.0, preload_s=1.0,
                      glue_stages_per_run_s=(0.4, 0.2, 0.1, 0.1, 0.05, 0.1, 0.05))
    assert share_of_floor_without_pct(d, fl, 0.4) == pytest.approx(50.0)
    assert share_of_floor_without_pct(d, fl, 0.0) == pytest.approx(40.0)
    assert math.isnan(share_of_floor_without_pct(d, fl, 2.0))  # nothing left of the run
    assert glue_budget_per_step_us(d, fl, 70.0) == pytest.approx((40 / 35 - 1.0) / 2000 * 1e6)
    assert glue_budget_per_step_us(d, fl, 40.0) == pytest.approx(500.0)  # today's share
    assert len(glue_stage_lines(d, fl)) == 1 + len(GLUE_STAGES) + 1
    # from the floor study's own runs' wall_s (1.9 s) where it has them: free of the
    # 0.4 s stage 1.5 s, 53 %; of all the glue 0.9 s, (0.5 + 0.3) / 0.9 = 89 %, never
    # above 100 % (the build is left); the target leaves 40 / 35 - 0.9 s a run
    fl_own = dataclasses.replace(fl, wall_per_run_s=1.9)
    assert share_of_floor_without_pct(d, fl_own, 0.4) == pytest.approx(100.0 * (40 / 1.5) / 50)
    assert share_of_floor_without_pct(d, fl_own, fl_own.glue_per_run_s) == pytest.approx(
        100.0 * 0.8 / 0.9)
    assert glue_budget_per_step_us(d, fl_own, 70.0) == pytest.approx(
        (40 / 35 - 0.9) / 2000 * 1e6)
    with pytest.raises(ValueError):
        FloorFigures(runs=2, glue_per_step_us=500.0, glue_per_run_s=1.0, kernel_per_run_s=0.5,
                     sumo_per_run_s=0.3, loop_per_run_s=1.8, steps_per_run=2000.0,
                     third_party_import_s=1.0, preload_s=1.0, glue_stages_per_run_s=(0.1,))


@pytest.mark.slow
@pytest.mark.sumo
def test_the_floor_study_times_real_runs(tmp_path: Path) -> None:
    catalog = tmp_path / "c.toml"
    catalog.write_text(TARGET_CATALOG.replace("duration_s = 40.0", "duration_s = 2.0")
                       .replace('"traffic.seed" = [3, 4, 5, 6]', '"traffic.seed" = [3, 4]'))
    floor = floor_study(catalog, tmp_path / "out")
    assert floor["third_party_import_s"] > 0.0
    assert [r["scenario"] for r in floor["runs"]] == ["target_stall_3lane_2400__seed3",
                                                      "target_stall_3lane_2400__seed4"]
    for r in floor["runs"]:
        assert r["status"] in ("pass", "fail")
        # every timer ran, and each part fits in the one around it (FloorRun checks it)
        assert r["kernel_s"] > 0.0 and r["sumo_s"] > 0.0 and r["glue_s"] > 0.0
        assert r["kernel_s"] + r["sumo_s"] + r["glue_s"] == pytest.approx(r["loop_s"])
        assert r["loop_s"] < r["run_s"]
        assert r["steps"] == 100
        assert r["glue_per_step_us"] == pytest.approx(r["glue_s"] / 100 * 1e6)
        # every stage timed, nested as the loop calls them (FloorRun checks the nesting),
        # and the split adds up to the glue
        assert FloorRun(**{k: v for k, v in r.items()
                           if k not in ("glue_s", "glue_per_step_us")}).staged
        assert min(r[k] for k in ("behaviour_s", "controller_s", "dynamics_s", "world_s",
                                  "monitor_s", "recorder_s")) > 0.0
        assert r["loop_s"] < r["wall_s"] < r["run_s"]
    for r, split in zip(floor["runs"], floor["glue_stages_s"], strict=True):
        assert list(split) == [name for name, _ in GLUE_STAGES]
        assert sum(split.values()) == pytest.approx(r["glue_s"])
        assert min(split.values()) > 0.0
    assert floor["preload_s"] > 0.0
    assert floor["glue_per_step_us"] == pytest.approx(
        sum(r["glue_s"] for r in floor["runs"]) / 200 * 1e6)
    with pytest.raises(FileExistsError):
        floor_study(catalog, tmp_path / "out")
