"""``hwyeval bench``'s printed lines: the figures of every phase, issue 25's table with
the whole command's wall-time account, and a line per target (met / not met)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from suite.bench.figures import (
    CommandFigures,
    DenseRunFigures,
    FloorFigures,
    floor_realtime_factor,
    glue_budget_per_step_us,
    share_of_floor_pct,
    share_of_floor_without_pct,
)
from suite.bench.floor import GLUE_STAGES
from suite.bench.targets import target

if TYPE_CHECKING:
    from suite.bench import BenchResult

__all__ = ["summary_lines"]

COMMAND_LABELS = ("dense_jobs1_log", "catalog_jobs1_log", "catalog_jobs2_log",
                  "dense_jobs1_nolog", "matrix_jobs1_log")


def _fmt(x: Any, digits: int = 1) -> str:
    return f"{x:.{digits}f}" if isinstance(x, int | float) else str(x)


def summary_lines(result: BenchResult) -> list[str]:
    """Human-readable lines (the JSON has everything)."""
    f = result.figures
    m = f["machine"]
    quick = " (--quick: a reduced set to exercise the bench, not figures to quote)" \
        if result.options.quick else ""
    lines = [f"machine: {m['cpus']} CPU(s), {m['processor']}, Python {m['python']}; load "
             f"average (1, 5, 15 min) at start {f['load_start']}, at end {f.get('load_end')}; "
             f"the bench took {_fmt(f.get('elapsed_s'))} s{quick}"]
    c = f["controller"]
    ou, cs = c["outer_update"], c["control_step"]
    lines.append(f"harness (plant only): C/GMRES outer update p50 {_fmt(ou.get('p50_us'))} us, "
                 f"p99 {_fmt(ou.get('p99_us'))} us; control step p50 {_fmt(cs['p50_us'])} us, "
                 f"p99 {_fmt(cs['p99_us'])} us")
    lines += _solver_lines(f.get("solvers"))
    lines += _extrapolation_lines(f.get("extrapolation"))
    if result.dense is not None and result.floor is not None:
        lines += dense_lines(result.dense, result.floor)
    if result.command is not None:
        lines += command_lines(result.command, result.floor, f["machine"]["cpus"],
                               f["load_start"])
    lines += _command_lines(f.get("commands"))
    for r in result.results:
        lines.append(r.line())
    if result.results:
        judged = [r for r in result.results if r.judged]
        met = sum(r.met for r in judged)
        reported = len(result.results) - len(judged)
        lines.append(f"targets: {met} of {len(judged)} met"
                     + (f" ({reported} reported only: --isolated judges it)" if reported else ""))
    else:
        lines.append("targets: not judged (--controller-only)")
    return lines


def dense_lines(d: DenseRunFigures, fl: FloorFigures) -> list[str]:
    """The one-run figures: real-time factor, the floor and the share of it, the Python
    per step (the glue) and its share of the loop, the worst step."""
    floor_x = floor_realtime_factor(d.duration_s, fl)
    glue_share = 100.0 * fl.glue_per_run_s / fl.loop_per_run_s if fl.loop_per_run_s > 0 \
        else float("nan")
    return [
        f"dense target (two_loop, 3 lanes, 2400 veh/h, a stalled car, logs on), {d.runs} x "
        f"{d.duration_s:g} s, --jobs 1:",
        f"  floor: the kernel and SUMO's step alone (no Python, no build) run a "
        f"{d.duration_s:g} s run at x{floor_x:.1f} real time (floor study, {fl.runs} runs: "
        f"kernel {fl.kernel_per_run_s:.3f} s + SUMO's step {fl.sumo_per_run_s:.3f} s a run)",
        f"  one run, real-time factor on results.csv wall_s (build and loop): median "
        f"x{d.realtime_factor_median:.1f} over {d.runs} traffic seeds (x{d.realtime_factor_min:.1f}"
        f" to x{d.realtime_factor_max:.1f}) = "
        f"{share_of_floor_pct(d.realtime_factor_median, floor_x):.0f} % of the floor; on the "
        f"run's whole life, start to run.json: median x{d.life_realtime_factor_median:.1f}",
        f"  glue, the Python between SUMO's step and the C/GMRES kernel: "
        f"{fl.glue_per_step_us:.1f} us a control step ({fl.glue_per_run_s:.3f} s per run of "
        f"{fl.steps_per_run:.0f} steps) = {glue_share:.0f} % of the loop "
        f"({fl.loop_per_run_s:.3f} s a run)",
        f"  behaviour + controller step, worst run: p99 {d.step_p99_ms_worst:.3f} ms "
        f"({d.step_p99_worst_run}), max {d.step_max_ms_worst:.3f} ms ({d.step_max_worst_run}); "
        f"p99 over the run's own C/GMRES outer update p99: worst "
        f"x{d.step_p99_over_outer_p99_worst:.2f} ({d.step_p99_over_outer_p99_worst_run}); "
        f"the controller's step alone (no behaviour): worst "
        f"x{d.controller_p99_over_outer_p99_worst:.2f} "
        f"({d.controller_p99_over_outer_p99_worst_run})",
        *glue_stage_lines(d, fl),
    ]


def glue_stage_lines(d: DenseRunFigures, fl: FloorFigures) -> list[str]:
    """The glue split by stage (the floor study's stage timers), each with the share of
    the floor one run would reach were that stage free, and the glue a step may cost for
    the one-run target to hold (the runs' build and the floor's parts as measured)."""
    if not fl.glue_stages_per_run_s or not fl.steps_per_run > 0:
        return []
    steps = fl.steps_per_run
    lines = ["  the glue by stage, a control step (floor study), and the share of the floor "
             "one run would reach were that stage free:"]
    for (name, what), per_run_s in zip(GLUE_STAGES, fl.glue_stages_per_run_s, strict=True):
        lines.append(f"    {per_run_s / steps * 1e6:6.1f} us  {name:<10} -> "
                     f"{share_of_floor_without_pct(d, fl, per_run_s):3.0f} %  ({what})")
    goal = target("one_run_share_of_floor").target_value
    lines.append(f"    all of it free -> "
                 f"{share_of_floor_without_pct(d, fl, fl.glue_per_run_s):.0f} %; for {goal:g} % "
                 f"of the floor the glue may cost {glue_budget_per_step_us(d, fl, goal):.0f} us "
                 f"a step (today {fl.glue_per_step_us:.0f} us)")
    return lines


def command_lines(c: CommandFigures, fl: FloorFigures | None, cpus: int | None,
                  load_start: list[float]) -> list[str]:
    """The whole command: real-time factor, every part of its wall time, --jobs 2."""
    a = c.account
    outside = a.outside_runs_wall_s
    lines = [f"whole command, {c.runs} dense runs, --jobs 1, logs on: {c.sim_s:.0f} s "
             f"simulated in {c.wall_s:.2f} s -> x{c.realtime_factor:.1f}; the runs' own "
             f"wall_s add up to {a.runs_wall_s:.2f} s, {outside:.2f} s ({outside / a.runs:.3f} s "
             f"a run) go outside them:"]
    lines += [f"  {v:7.3f} s  {what}" for what, v in a.parts_s]
    ref = (f"; for reference, in a fresh interpreter: third-party imports "
           f"{fl.third_party_import_s:.2f} s, then the rest of the scenario processes' preload "
           f"{fl.preload_s:.2f} s (in the command the forkserver does these beside the first "
           f"part)" if fl is not None else "")
    lines.append(f"  {a.accounted_s:7.3f} s  accounted of {a.command_s:.3f} s (unaccounted "
                 f"{a.unaccounted_s:.3f} s){ref}")
    busy = load_start[0] if load_start else float("nan")
    note = ""
    if cpus is not None and cpus <= 2:
        note = (f"; on {cpus} CPU(s) at load {busy:.2f} at the start (others' processes "
                f"share the cores: two workers cannot have a core each)" if busy >= 0.5
                else f"; on {cpus} CPU(s), load {busy:.2f} at the start")
    lines.append(f"--jobs 2 / --jobs 1 on {c.runs} dense runs: scenario phase "
                 f"x{c.jobs1_over_jobs2_scenario_phase:.2f} ({c.jobs1_scenario_phase_s:.2f} s -> "
                 f"{c.jobs2_scenario_phase_s:.2f} s), whole command "
                 f"x{c.jobs1_over_jobs2_whole_command:.2f} ({c.wall_s:.2f} s -> "
                 f"{c.jobs2_wall_s:.2f} s){note}")
    return lines


def _solver_lines(sv: dict[str, Any] | None) -> list[str]:
    if not sv:
        return []
    if "skipped" in sv:
        return [f"solvers: skipped ({sv['skipped']})"]
    lines = []
    for name in ("ipopt_barrier", "ipopt_hard"):
        r = sv[f"{name}_over_cgmres"]
        lines.append(f"{name} / C/GMRES: p50 x{_fmt(r['raw']['p50_s'])}, variance "
                     f"x{_fmt(r['raw']['var_s2'], 0)} raw; per-update min of {sv['repeats']} "
                     f"repeats: p50 x{_fmt(r['min_of_repeats']['p50_s'])}, variance "
                     f"x{_fmt(r['min_of_repeats']['var_s2'], 0)}"
                     + "".join(f"; {label}: variance x{_fmt(r[key]['var_s2'], 0)}"
                               for label, key in (("without the obstacle",
                                                   "min_of_repeats_without_obstacle"),
                                                  ("with it", "min_of_repeats_with_obstacle"))
                               if key in r))
    cg = sv["cgmres"]["raw"]
    lines.append(f"C/GMRES update p50 {cg['p50_s'] * 1e6:.1f} us; Ipopt (barrier) p50 "
                 f"{sv['ipopt_barrier']['raw']['p50_s'] * 1e6:.0f} us")
    return lines


def _extrapolation_lines(ex: dict[str, Any] | None) -> list[str]:
    if not ex:
        return []
    lines = []
    for name, v in ex.items():
        if not isinstance(v, dict):
            continue
        e = v["errors"]
        lines.append(f"extrapolation {name} ({ex['sumo_step_s']} s SUMO vs 50 Hz): constant "
                     f"speed p50 {e['velocity']['all']['p50_m']:.4f} m, p99 "
                     f"{e['velocity']['all']['p99_m']:.4f} m, max "
                     f"{e['velocity']['all']['max_m']:.3f} m (no extrapolation: p99 "
                     f"{e['hold']['all']['p99_m']:.2f} m)")
    return lines


def _command_lines(cmd: dict[str, Any] | None) -> list[str]:
    if not cmd:
        return []
    lines = []
    for label in COMMAND_LABELS:
        if label not in cmd:
            continue
        t = cmd[label]
        st = t["steps_us"]
        lines.append(
            f"{label}: {t['sim_s']:.0f} s simulated in {t['wall_s']:.2f} s -> "
            f"x{t['realtime_factor']:.1f} real time over the whole command, "
            f"x{t['runs_realtime_factor']:.1f} over the scenario phase "
            f"({_fmt(t['before_runs_s'], 2)} s before the first run, {t['runs_span_s']:.2f} s "
            f"of runs, {_fmt(t['after_runs_s'], 2)} s after the last); controller step "
            f"p50 {_fmt(st['controller_step']['p50_us'])} / p99 "
            f"{_fmt(st['controller_step']['p99_us'])} us, behaviour + controller p50 "
            f"{_fmt(st['behaviour_and_controller']['p50_us'])} / p99 "
            f"{_fmt(st['behaviour_and_controller']['p99_us'])} us; peak RSS "
            f"{max(r['peak_rss_mb'] for r in t['runs']):.0f} MB")
    if "matrix_jobs1_log" in cmd:
        runs = cmd["matrix_jobs1_log"]["runs"]
        lines.append("matrix real-time factors per run (results.csv wall_s): " + ", ".join(
            f"{r['scenario']} x{r['realtime_factor']:.0f}" for r in runs))
    lines += _floor_lines(cmd.get("floor"), cmd["dense_jobs1_log"])
    if "logging_overhead" in cmd:
        lines.append(f"logging on / off (dense runs, --jobs 1): x{cmd['logging_overhead']:.2f}")
    return lines


def _floor_lines(floor: dict[str, Any] | None, dense: dict[str, Any]) -> list[str]:
    if not floor:
        return []
    b = floor["bound"]
    return [f"floor: dense_jobs1_log ({dense['wall_s']:.2f} s) without the Python between "
            f"SUMO and the kernel: {b['wall_s']:.2f} s -> x{b['realtime_factor']:.1f} real time "
            f"(that Python is {100 * b['glue_share']:.0f} % of the command)"]
