"""The paper's page without SUMO: each measure on signals with a known answer, the
findings on hand-made results (they follow the numbers both ways), the number format
and the README's Results block's form."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from reports.paper.findings import (
    FAR_MORE,
    cost_findings,
    num,
    preview_findings,
    solver_findings,
)
from reports.paper.measures import (
    STEER_CUTOFF_HZ,
    ResidualStats,
    TimingStats,
    Window,
    decay_time_s,
    energy_interval,
    highpass,
    horizon_reach_row,
    mean_square,
    obstacle_window,
    plan_lateral_error,
    residual_stats,
    second_difference_rms,
    timing_stats,
)
from reports.paper.results import CostResult, PreviewResult, SolverResult, arc_length_along
from reports.paper.table import BEGIN, END

DT = 0.02
README = Path(__file__).resolve().parents[1] / "README.md"


# ----------------------------------------------------------------------- measures


def test_obstacle_window_is_the_first_block() -> None:
    n = np.array([0, 0, 1, 2, 1, 0, 0, 1, 1, 0])
    assert obstacle_window(n) == Window(2, 5)
    assert obstacle_window(np.zeros(4, dtype=np.int64)) is None
    assert obstacle_window(np.array([1, 1])) == Window(0, 2)
    with pytest.raises(ValueError):
        Window(3, 3)


def test_decay_time_of_an_exponential_is_its_time_constant() -> None:
    t = np.arange(0.0, 20.0, 0.001)
    for tau in (0.1, 0.4, 1.5):
        assert decay_time_s(t, 3.0 * np.exp(-t / tau)) == pytest.approx(tau, rel=2e-3)
    # a residual that comes back later in the window decays "more slowly"
    e = np.exp(-t / 0.4) + 0.5 * np.exp(-((t - 5.0) ** 2))
    assert decay_time_s(t, e) > 0.4
    assert math.isnan(decay_time_s(t, np.zeros_like(t)))


def test_residual_stats_over_a_window() -> None:
    t = np.arange(100) * DT
    e = np.zeros(100)
    e[20:40] = np.linspace(1.0, 0.0, 20)
    s = residual_stats(t, e, Window(20, 60))
    assert s.peak == 1.0 and s.peak_after_s == 0.0
    assert s.rms == pytest.approx(math.sqrt(np.sum(e[20:60] ** 2) / 40))
    assert s.decay_s == pytest.approx(decay_time_s(t[20:60], e[20:60]))


def test_highpass_keeps_the_chatter_and_drops_the_lane_change() -> None:
    t = np.arange(0.0, 20.0, DT)
    slow = 0.03 * np.sin(2 * np.pi * 0.3 * t)
    fast = 1e-3 * np.sin(2 * np.pi * 8.0 * t)
    w = Window(100, 900)  # away from the ends
    assert mean_square(highpass(slow + fast, DT), w) == pytest.approx(0.5e-6, rel=0.02)
    assert mean_square(highpass(slow, DT), w) < 1e-4 * mean_square(slow, w)
    assert STEER_CUTOFF_HZ == 2.0
    assert np.isnan(highpass(np.ones(5), DT)).all()  # shorter than the filter's padding


def test_second_difference_rms_of_a_flip_flop() -> None:
    a = 0.01
    x = a * (-1.0) ** np.arange(50)
    assert second_difference_rms(x, DT, Window(0, 50)) == pytest.approx(4 * a / DT**2)
    ramp = np.arange(50) * 0.1
    assert second_difference_rms(ramp, DT, Window(0, 50)) == pytest.approx(0.0, abs=1e-9)


def test_energy_interval_brackets_the_burst() -> None:
    x = np.arange(200, dtype=float)
    p = np.zeros(200)
    p[50:60] = 1.0
    lo, hi = energy_interval(x, p, Window(0, 200))
    assert 50 <= lo < hi <= 59
    assert all(math.isnan(v) for v in energy_interval(x, np.zeros(200), Window(0, 200)))


def _straight_plans(n: int, n_nodes: int, y: float = 0.0) -> np.ndarray:
    """Plans along +x from x = 0 to 100 m at lateral position y, one per row."""
    xs = np.linspace(0.0, 100.0, n_nodes)
    plan = np.stack([xs, np.full(n_nodes, y)], axis=1)
    return np.repeat(plan[None], n, axis=0)


def test_plan_lateral_error_is_the_signed_distance_to_the_plan() -> None:
    n = 200
    t = np.arange(1, n + 1) * DT
    x = 25.0 * t
    y = np.where(t > 1.0, 0.2, -0.1)  # the car steps left at 1 s
    plans = _straight_plans(n, 21)
    err = plan_lateral_error(t, x, y, plans, DT, 0.5)
    # row k's plan was made at t_k - dt; the car is looked at 0.5 s later
    k_before, k_after = 10, 80
    assert err[k_before] == pytest.approx(-0.1)
    assert err[k_after] == pytest.approx(0.2)
    assert np.isnan(err[-5])  # 0.5 s later is past the trace
    # a plan that ends before where the car got to: not measured
    short = _straight_plans(n, 21)
    short[:, :, 0] *= 0.01  # 0..1 m
    assert np.isnan(plan_lateral_error(t, x, y, short, DT, 0.5)[50])
    # NaN-padded plans use their finite points; a plan of one point is not measured
    padded = plans.copy()
    padded[:, 15:, :] = np.nan
    assert plan_lateral_error(t, x, y, padded, DT, 0.5)[10] == pytest.approx(-0.1)
    padded[:, 1:, :] = np.nan
    assert np.isnan(plan_lateral_error(t, x, y, padded, DT, 0.5)).all()


def test_horizon_reach_row() -> None:
    n = 10
    plans = np.zeros((n, 3, 2))
    plans[:, :, 0] = np.arange(n)[:, None] * 10.0 + np.array([0.0, 25.0, 50.0])
    ell = np.zeros((n, 1, 6))
    ell[:, 0] = [100.0, 0.0, 0.0, 10.0, 2.0, 1.0]  # centre 100 m, A = 10 m, active
    # plan end = 10 k + 50 reaches 90 m at k = 4
    assert horizon_reach_row(plans, ell) == 4
    ell[:, 0, 5] = 0.0
    assert horizon_reach_row(plans, ell) == -1


def test_timing_stats_robust_spread_ignores_preempted_steps() -> None:
    rng = np.random.default_rng(1)
    fast = 1e-4 + 1e-6 * rng.standard_normal(1000)
    fast[::100] = 12e-3  # 1 % preempted steps
    slow = 6e-3 + 2e-3 * rng.standard_normal(1000)
    obstacle = np.zeros(1000, dtype=bool)
    obstacle[:300] = True
    a, b = timing_stats(fast, obstacle), timing_stats(slow, obstacle)
    assert a.var > 1e-6  # the raw variance is the preemption's
    assert a.var_robust == pytest.approx(1e-12, rel=0.2)
    assert b.var_robust == pytest.approx(4e-6, rel=0.2)
    assert a.p50 == pytest.approx(1e-4, rel=1e-3) and a.max == 12e-3 and a.n == 1000
    assert b.p50_obstacle == pytest.approx(np.median(slow[:300]))
    empty = timing_stats(np.array([np.nan]), np.array([False]))
    assert empty.n == 0 and math.isnan(empty.mean)


def test_arc_length_along_a_polyline() -> None:
    line = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 100.0]])
    pts = np.array([[30.0, 2.0], [101.0, 40.0]])
    assert arc_length_along(pts, line) == pytest.approx([30.0, 140.0])


# ----------------------------------------------------------------------- findings


def _cost(name: str, rms: float, decay: float, hf: float) -> CostResult:
    return CostResult(run=f"paper_costs__{name}", cost=name, entry_m=5.0, exit_m=58.0,
                      horizon_entry_m=39.0, residual=ResidualStats(rms, 2 * rms, 1.0, decay),
                      run_max_residual=4.0, run_max_at_m=70.0, steer_hf_rad2=hf,
                      steer_d2_rms_radps2=1.0, hf_from_m=10.0, hf_to_m=14.0,
                      max_abs_lat_dev_m=3.5, at_fault_collisions=0.0)


def test_cost_findings_follow_the_numbers() -> None:
    good = cost_findings([_cost("J1", 0.12, 2.6, 5e-6), _cost("J2", 0.07, 1.6, 2e-7),
                          _cost("J3", 0.06, 1.9, 1e-7)])
    assert [f.holds for f in good] == [True, True, True]
    bad = cost_findings([_cost("J1", 0.05, 1.0, 1e-7), _cost("J2", 0.07, 1.6, 2e-7),
                         _cost("J3", 0.06, 0.9, 1e-7)])
    assert [f.holds for f in bad] == [False, False, False]
    assert all(f.why for f in bad)
    assert "J2" in bad[1].why and "J3" not in bad[1].why  # J1's τ_E is above J3's only
    missing = cost_findings([_cost("J2", 0.07, 1.6, 2e-7)])
    assert [f.holds for f in missing] == [None, None, None]


def _preview(preview: bool, ff: bool, err: float, lat: float) -> PreviewResult:
    return PreviewResult(run="p", preview=preview, feedforward=ff, tau_s=0.5,
                         error_rms_m=err, error_max_m=2 * err, lat_acc_peak_mps2=lat,
                         lat_acc_rms_mps2=lat / 2, steer_corr_rms_rad=0.01 if preview else 0.0,
                         steer_corr_p_rms_rad=0.003, steer_corr_i_rms_rad=0.009,
                         final_offset_m=0.1, at_fault_collisions=0.0)


def test_preview_findings_per_conversion() -> None:
    found = preview_findings([_preview(True, False, 0.08, 3.0), _preview(False, False, 0.14, 3.2),
                              _preview(True, True, 0.03, 3.1), _preview(False, True, 0.02, 2.9)])
    by_key = {f.key: f for f in found}
    assert by_key["fig12_error"].holds and by_key["fig13_lat_acc"].holds
    assert by_key["fig12_error_ff"].holds is False and by_key["fig13_lat_acc_ff"].holds is False
    assert "feed-forward" in by_key["fig12_error_ff"].why
    only_paper = preview_findings([_preview(True, False, 0.08, 3.0),
                                   _preview(False, False, 0.14, 3.2)])
    assert [f.holds for f in only_paper] == [True, True, None, None]


def _solver(name: str, times: np.ndarray, obstacle: np.ndarray) -> SolverResult:
    return SolverResult(run=name, solver=name, outer=timing_stats(times, obstacle),
                        step_mean_s=float(np.mean(times)), at_fault_collisions=0.0,
                        min_gap_m=1.6)


def test_solver_findings_follow_the_numbers() -> None:
    rng = np.random.default_rng(2)
    obstacle = np.arange(400) < 100
    cg = 1e-4 + 2e-6 * rng.standard_normal(400)
    ip = np.where(obstacle, 9e-3, 6e-3) + 2e-3 * rng.standard_normal(400)
    found = {f.key: f for f in solver_findings([_solver("C/GMRES", cg, obstacle),
                                                _solver("Ipopt", ip, obstacle)])}
    assert all(f.holds for f in found.values()), found
    # same spread: not "far more variable"; same times with and without: no rise
    flat = np.full(400, 6e-3)
    found = {f.key: f for f in solver_findings([_solver("C/GMRES", cg, obstacle),
                                                _solver("Ipopt", flat, obstacle)])}
    assert found["fig15_mean"].holds and not found["fig15_variance"].holds
    assert found["fig15_rise"].holds is False and found["fig15_rise"].why
    assert FAR_MORE == 10.0
    assert [f.holds for f in solver_findings([])] == [None] * 4


def test_num_format() -> None:
    assert [num(v) for v in (0.119, 0.066847, 5.0691e-6, 1319.3, 142351.0, 0.0, 38.9, 2.0)] \
        == ["0.119", "0.0668", "5.07e-6", "1319", "1.42e5", "0", "38.9", "2"]
    assert num(math.nan) == "–" and num(math.inf) == "∞"


def test_timing_stats_type() -> None:
    assert [f for f in TimingStats.__dataclass_fields__][:6] == ["mean", "var", "max", "p50",
                                                                 "p99", "var_robust"]


# ------------------------------------------------------------------------ README


def readme_block(text: str) -> list[str]:
    """The lines between the README's paper-results markers."""
    start, stop = text.index(BEGIN), text.index(END)
    return text[start + len(BEGIN):stop].strip("\n").splitlines()


def test_readme_has_the_results_block() -> None:
    text = README.read_text(encoding="utf-8")
    assert "## Results" in text
    assert "hwyeval paper --run runs/paper" in text
    block = readme_block(text)
    assert block[0] == "| fig. | quantity | unit | ours | paper |"
    assert any(line.startswith("| 9 | E RMS") for line in block)
    assert any("| the paper's finding |" in line for line in block)
