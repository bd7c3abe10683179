"""The stress table (python -m suite.stress.summary) on synthetic run directories with
known comfort outcomes and residuals."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from suite.stress.summary import main, summarise
from tests.synthetic_runs import accel_ramp_trace, base_info, straight_trace, write_run


def _runs(tmp_path: Path) -> Path:
    out = tmp_path / "runs"
    out.mkdir()
    calm = straight_trace(duration_s=4.0, dt_s=0.02)
    calm.controller.residual[:] = np.linspace(0.0, 2.0, len(calm.t_s))  # E > 1 on half
    calm.controller.fallback[:10] = True
    # a(t) = 6 t: a jerk of 6 m/s³, beyond nuPlan's 4.13 long jerk (a comfort failure).
    jerky = accel_ramp_trace(jerk_mps3=6.0, duration_s=1.0, dt_s=0.02)
    for name, trace in (("st0000_g2__two_loop", calm), ("st0001_g3_close__two_loop", jerky),
                        ("st0000_g2__sumo", straight_trace(duration_s=4.0, dt_s=0.02))):
        write_run(out / name, trace, info=base_info(name, controller=name.rsplit("__")[1]))
    return out


def test_counts_comfort_by_tag_fallback_share_and_residuals(tmp_path: Path) -> None:
    from reports.record import iter_run_dirs

    table = {s.controller: s for s in summarise(iter_run_dirs(_runs(tmp_path)))}
    assert set(table) == {"two_loop", "sumo"}
    tl = table["two_loop"]
    assert tl.runs == 2 and tl.at_fault == [] and tl.collided == []
    assert (tl.comfort["all"].passed, tl.comfort["all"].runs) == (1, 2)
    assert (tl.comfort["close"].passed, tl.comfort["close"].runs) == (0, 1)
    assert (tl.comfort["not close"].passed, tl.comfort["not close"].runs) == (1, 1)
    assert tl.fallback_steps == 10 and tl.steps == 200 + 50
    assert tl.fallback_percent == pytest.approx(100.0 * 10 / 250)
    assert tl.residual_percentiles["p100"] == pytest.approx(2.0)
    assert table["sumo"].comfort["all"].percent == 100.0


def test_command_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main([str(_runs(tmp_path))]) == 0
    text = capsys.readouterr().out
    assert "two_loop: 2 runs" in text and "close 0/1 = 0.0 %" in text
    assert main([str(tmp_path / "nothing")]) == 2
