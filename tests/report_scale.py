"""A catalog output of N realistic runs for the report's scale figures (issue 11 item 5).

    python tests/report_scale.py OUT [N]    # writes OUT/runs with N runs, times the report

Ten distinct judged runs (24 s at 50 Hz = 1200 steps, a lead car and 20 neighbours
recorded at every step, two controllers, passes and failures) are written once, then
copied under N names (``run.json`` rewritten with the scenario's new name), so that
the N run directories cost seconds to make and the report reads N real run
directories of realistic size.
"""

from __future__ import annotations

import json
import shutil
import sys
import time
from pathlib import Path

import numpy as np
import synthetic_runs as sr

from reports.record import NeighbourColumns


def _traffic(trace: sr.Trace, n: int, seed: int) -> NeighbourColumns:
    rng = np.random.default_rng(seed)
    parts = []
    for k in range(n):
        lane = 2 + k % 2  # beside the ego's lanes: a nightly mostly passes
        speed = 20.0 + 6.0 * rng.random()
        x0 = -150.0 + 300.0 * rng.random()
        parts.append(sr.lead_vehicle(trace, x0 + speed * trace.t_s, sr.LANE_WIDTH_M * lane,
                                     speed, vid=f"flow.{k}"))
    return NeighbourColumns(**{name: np.concatenate([getattr(p, name) for p in parts])
                               for name in NeighbourColumns.names()})


def seed_runs(out: Path) -> list[Path]:
    """The ten distinct run directories under ``out/seed``."""
    dirs = []
    for i in range(10):
        ctrl = "ctrl_a" if i % 2 else "ctrl_b"
        if i % 3 == 0:
            trace = sr.lane_change_trace(duration_s=24.0, dt_s=0.02, seed=i)
        elif i % 3 == 1:
            trace = sr.turn_trace(radius_m=80.0 + 40 * i, duration_s=24.0, dt_s=0.02, seed=i)
        else:
            trace = sr.straight_trace(24.0, 0.02, 25.0, seed=i)
        nb = _traffic(trace, 20, i)
        road = sr.circle_road(80.0 + 40 * i) if i % 3 == 1 else sr.straight_road(2500.0)
        name = f"seed_{i}"
        dirs.append(sr.write_run(out / "seed" / name, trace, neighbours=nb, road=road,
                                 info=sr.base_info(name, ctrl, family=f"fam{i % 4}",
                                                   step_s=0.02, duration_s=24.0)))
    return dirs


def make_output(out: Path, n: int) -> Path:
    """``out/runs`` with ``n`` run directories (module doc); returns it."""
    seeds = seed_runs(out)
    runs = out / "runs"
    for k in range(n):
        src = seeds[k % len(seeds)]
        name = f"case_{k:04d}"
        dst = runs / name
        shutil.copytree(src, dst)
        doc = json.loads((dst / "run.json").read_text())
        doc["info"]["scenario"] = name
        (dst / "run.json").write_text(json.dumps(doc))
    shutil.rmtree(out / "seed")
    return runs


def open_time_s(index: Path) -> float:
    """Seconds from navigation start to the load event of ``index`` in headless Chromium."""
    from browser import chromium

    for driver in chromium():
        driver.get(index.resolve().as_uri())
        ms = driver.execute_script(
            "var t=performance.getEntriesByType('navigation')[0]; return t.loadEventEnd;")
        return float(ms) / 1e3
    raise RuntimeError("no browser")


if __name__ == "__main__":
    from reports import write_reports

    target = Path(sys.argv[1])
    count = int(sys.argv[2]) if len(sys.argv) > 2 else 1000
    runs_dir = make_output(target, count)
    t0 = time.perf_counter()
    paths = write_reports(runs_dir)
    took = time.perf_counter() - t0
    html = [paths.report_html, *paths.run_pages.glob("*.html")]
    size = sum(p.stat().st_size for p in html)
    print(f"{count} runs: report in {took:.1f} s, {size / 1e6:.1f} MB of HTML "
          f"(index {paths.report_html.stat().st_size / 1e6:.2f} MB, pages "
          f"{(size - paths.report_html.stat().st_size) / count / 1e3:.1f} kB each); index "
          f"opens in headless Chromium in {open_time_s(paths.report_html):.2f} s")
