"""The report at scale (issue 11 item 5), on 200 realistic runs (the 1000-run figures:
``python tests/report_scale.py OUT 1000``): one run in memory at a time, ≤ 20 kB of HTML
per run (≤ 20 MB for 1000), every run in the index, the CSV and its own page, and the
index opening in headless Chromium without errors, its filter still working.

What scale must not break is asserted; how long the report takes to write and to open
is printed, not asserted (no wall-clock limits in a test: timing belongs in the bench)."""

from __future__ import annotations

import csv
import time
from pathlib import Path
from typing import Any

import pytest
from browser import chromium, console_errors, needs_chromium
from report_scale import make_output

from reports import write_reports

pytestmark = [pytest.mark.slow, *needs_chromium]

N_RUNS = 200
MAX_HTML_PER_RUN_B = 20_000  # the pages and the index together, per run [bytes]

# (scenario, link) of every row of the index's run table, as the browser shows it
_RUN_ROWS = """
  return Array.from(document.querySelectorAll('table.runs tbody tr')).map(function(r){
    var a = r.querySelector('a'); return [a.textContent, a.getAttribute('href')];});"""
# Navigation start to the load event [ms]
_LOAD_MS = "return performance.getEntriesByType('navigation')[0].loadEventEnd;"


def _shown_for(driver: Any, text: str) -> list[str]:
    """The scenarios the run table shows once its filter holds ``text``, and check the
    count it prints agrees."""
    from selenium.webdriver.common.by import By

    driver.find_element(By.ID, "filter").send_keys(text)
    shown = [r.find_element(By.TAG_NAME, "a").text
             for r in driver.find_elements(By.CSS_SELECTOR, "table.runs tbody tr")
             if r.is_displayed()]
    assert driver.find_element(By.ID, "shown").text == str(len(shown))
    return shown


def test_two_hundred_runs_stream_into_small_pages_and_a_working_index(tmp_path: Path
                                                                       ) -> None:
    runs = make_output(tmp_path, N_RUNS)
    names = {f"case_{k:04d}" for k in range(N_RUNS)}
    t0 = time.perf_counter()
    paths = write_reports(runs)
    took = time.perf_counter() - t0

    pages = list(paths.run_pages.glob("*.html"))
    assert len(pages) == N_RUNS
    assert {p.stem.split("__")[0] for p in pages} == names
    total = sum(p.stat().st_size for p in pages) + paths.report_html.stat().st_size
    print(f"{N_RUNS} runs: report written in {took:.1f} s, {total / 1e6:.2f} MB of HTML")
    assert total <= N_RUNS * MAX_HTML_PER_RUN_B
    with paths.results_csv.open(newline="") as f:
        assert sorted(row["scenario"] for row in csv.DictReader(f)) == sorted(names)

    for driver in chromium():
        driver.get(paths.report_html.resolve().as_uri())
        print(f"index opens in headless Chromium in "
              f"{float(driver.execute_script(_LOAD_MS)) / 1e3:.2f} s")
        assert console_errors(driver) == []
        rows = driver.execute_script(_RUN_ROWS)
        assert sorted(scenario for scenario, _ in rows) == sorted(names)
        index_dir = paths.report_html.parent
        assert all((index_dir / href).is_file() for _, href in rows)
        assert _shown_for(driver, "case_0042") == ["case_0042"]
        assert console_errors(driver) == []
