"""``hwyeval bench``: the speed and memory targets, measured in one run, quoted as ratios.

Three parts, each in this one invocation so that the ratios share the machine's
momentary load (these machines are shared and noisy):

1. controller timing (plant only, :func:`controllers.bench.run_benchmark`): one
   C/GMRES outer update and the whole control step, p50/p95/p99/max, against the
   targets (update p50 <= 80 us, p99 <= 200 us; step p99 <= 0.5 ms);
2. C/GMRES vs the Ipopt NMPC on the same OCP (when CasADi is installed): time per
   update and its variance, as ratios;
3. the runner end to end on a small SUMO catalog, run twice through the local
   executor (with Rerun logs and with ``--no-log``): logging overhead as the ratio
   of wall times, plus per run the ratio (wall + log) / wall from the logged run
   itself, real-time factors and each scenario process's peak memory.
"""

from __future__ import annotations

import json
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

BENCH_CATALOG = """
[defaults]
controller = "two_loop"
duration_s = 20.0
step_s = 0.02
seed = 5

[[scenario]]
name = "bench_stall_straight3"
net = "straight_3lane"
ego = { lane = 1, pos_m = 100.0, speed_mps = 25.0 }
stalled = [ { lane = 1, pos_m = 400.0 } ]

[[scenario]]
name = "bench_stall_traffic_curve"
net = "curve_2lane"
ego = { lane = 0, pos_m = 300.0, speed_mps = 22.0 }
stalled = [ { lane = 0, pos_m = 600.0 } ]
traffic = { vehicles_per_hour = 2000, seed = 3, lanes = [1] }

[[scenario]]
name = "bench_lane_keep_traffic"
net = "straight_3lane"
ego = { lane = 0, pos_m = 100.0, speed_mps = 25.0 }
traffic = { vehicles_per_hour = 3000, seed = 4 }
controller = "lane_keep"
"""

TARGETS_US = {"outer_update_p50": 80.0, "outer_update_p99": 200.0, "control_step_p99": 500.0}


def _controller_timing() -> dict[str, Any]:
    from controllers.bench import run_benchmark

    res = run_benchmark(print_fn=None)
    out = {"outer_update": res["outer_update"], "control_step": res["control_step"],
           "inner_loop_per_step": res["inner_loop_per_step"],
           "residual_max": res["residual_max"], "fallbacks": res["fallbacks"]}
    ou, cs = res["outer_update"], res["control_step"]
    out["targets"] = {
        "outer_update_p50_us": [ou.get("p50_us"), TARGETS_US["outer_update_p50"]],
        "outer_update_p99_us": [ou.get("p99_us"), TARGETS_US["outer_update_p99"]],
        "control_step_p99_us": [cs.get("p99_us"), TARGETS_US["control_step_p99"]],
    }
    out["targets_met"] = bool(
        ou and ou["p50_us"] <= TARGETS_US["outer_update_p50"]
        and ou["p99_us"] <= TARGETS_US["outer_update_p99"]
        and cs["p99_us"] <= TARGETS_US["control_step_p99"])
    return out


def _ipopt_vs_cgmres() -> dict[str, Any]:
    import importlib.util

    if importlib.util.find_spec("casadi") is None:
        return {"skipped": "casadi not installed (pip install 'hwyeval[baselines]')"}
    from controllers.two_loop.outer.ipopt import compare_with_cgmres

    return dict(compare_with_cgmres())


def _runner_and_logging(jobs: int = 1) -> dict[str, Any]:
    from suite.catalog import load_catalog
    from suite.exec.executors import LocalExecutor, RunJob
    from suite.run.runner import RunOptions

    with tempfile.TemporaryDirectory(prefix="hwyeval-bench-") as tmp:
        tmp_path = Path(tmp)
        catalog = tmp_path / "bench.toml"
        catalog.write_text(BENCH_CATALOG)
        scenarios = load_catalog(catalog).scenarios
        out: dict[str, Any] = {"scenarios": [s.name for s in scenarios]}
        walls: dict[str, float] = {}
        records: dict[str, list[Any]] = {}
        # One untimed run first: it starts the forkserver (preload + numba warm-up).
        LocalExecutor(jobs=1).run([RunJob(scenarios[0], tmp_path / "warm",
                                          RunOptions(write_rrd=False))])
        # Logged and unlogged runs alternate so that both see the same load drift.
        for label, write_rrd in (("no_log", False), ("log", True), ("no_log2", False),
                                 ("log2", True)):
            run_dir = tmp_path / label
            jobs_list = [RunJob(sc, run_dir, RunOptions(write_rrd=write_rrd, catalog_name="bench"))
                         for sc in scenarios]
            t0 = time.perf_counter()
            records[label] = LocalExecutor(jobs=jobs).run(jobs_list)
            walls[label] = time.perf_counter() - t0
        no_log = walls["no_log"] + walls["no_log2"]
        log = walls["log"] + walls["log2"]
        out["catalog_wall_s"] = walls
        out["logging_overhead_ratio_end_to_end"] = log / no_log
        per_run = [(r.outcome.wall_s + r.outcome.log_s) / r.outcome.wall_s
                   for r in records["log"] + records["log2"]
                   if r.outcome.wall_s > 0 and r.outcome.log_s == r.outcome.log_s]
        out["logging_overhead_ratio_per_run"] = {
            "median": statistics.median(per_run), "max": max(per_run)}
        out["realtime_factor"] = {r.info.scenario: r.outcome.sim_time_s / r.outcome.wall_s
                                  for r in records["no_log"] if r.outcome.wall_s > 0}
        out["peak_rss_mb"] = {r.info.scenario: r.outcome.peak_rss_mb for r in records["log"]}
        out["statuses"] = {r.info.scenario: r.status for r in records["log"]}
        out["logging_target_met"] = out["logging_overhead_ratio_end_to_end"] <= 1.15
    return out


def run_all(include_runner: bool = True, include_ipopt: bool = True) -> dict[str, Any]:
    """Every benchmark part; a dict ready for JSON."""
    figures: dict[str, Any] = {"started": time.strftime("%Y-%m-%dT%H:%M:%S")}
    figures["controller"] = _controller_timing()
    if include_ipopt:
        figures["ipopt_vs_cgmres"] = _ipopt_vs_cgmres()
    if include_runner:
        figures["runner"] = _runner_and_logging()
    return figures


def summary_lines(figures: dict[str, Any]) -> list[str]:
    """Human-readable lines (the JSON has everything)."""
    lines = []
    c = figures["controller"]
    ou, cs = c["outer_update"], c["control_step"]
    lines.append(f"C/GMRES outer update: p50 {ou['p50_us']:.1f} us, p99 {ou['p99_us']:.1f} us "
                 f"(targets 80 / 200 us); control step p99 {cs['p99_us']:.1f} us (target 500 us)"
                 f" -> {'met' if c['targets_met'] else 'NOT met'}")
    ip = figures.get("ipopt_vs_cgmres")
    if ip and "skipped" not in ip:
        for key in ("ipopt_barrier_over_cgmres", "ipopt_hard_over_cgmres"):
            if key in ip:
                lines.append(f"{key}: " + json.dumps(ip[key], default=str))
    r = figures.get("runner")
    if r:
        lines.append(f"logging overhead (wall with logs / without, same run): "
                     f"{r['logging_overhead_ratio_end_to_end']:.3f} end to end, per run median "
                     f"{r['logging_overhead_ratio_per_run']['median']:.3f} (target <= 1.15)")
        lines.append(f"real-time factors: {r['realtime_factor']}")
        lines.append(f"peak RSS per scenario process [MB]: {r['peak_rss_mb']}")
    return lines
