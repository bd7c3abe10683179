"""The report at scale (issue 11 item 5), on 200 realistic runs (the 1000-run figures:
``python tests/report_scale.py OUT 1000``): one run in memory at a time, ≤ 20 kB of HTML
per run (≤ 20 MB for 1000), the index opening in headless Chromium in ≤ 3 s."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from browser import needs_chromium
from report_scale import make_output, open_time_s

from reports import write_reports

pytestmark = [pytest.mark.slow, *needs_chromium]


def test_two_hundred_runs_stream_into_small_pages_and_a_fast_index(tmp_path: Path) -> None:
    runs = make_output(tmp_path, 200)
    t0 = time.perf_counter()
    paths = write_reports(runs)
    took = time.perf_counter() - t0
    pages = list(paths.run_pages.glob("*.html"))
    assert len(pages) == 200
    total = sum(p.stat().st_size for p in pages) + paths.report_html.stat().st_size
    print(f"200 runs: {took:.1f} s, {total / 1e6:.2f} MB of HTML")
    assert total <= 200 * 20_000
    assert took <= 200 * 0.06 * 2  # 60 s per 1000 runs, with room for a shared machine
    assert open_time_s(paths.report_html) <= 3.0
