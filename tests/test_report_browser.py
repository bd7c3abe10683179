"""report.html and the run pages in headless Chromium: the failures list first, tick
labels at their gridlines, no console errors, no network; screenshots kept in
tests/artifacts/."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import synthetic_runs as sr
from browser import check_tick_labels, chromium, console_errors, needs_chromium, screenshot

from reports import write_reports
from suite.rerun.log import write_rrd

pytestmark = [*needs_chromium, pytest.mark.slow]


@pytest.fixture()
def driver() -> Any:
    yield from chromium()


def _no_network(driver: Any) -> None:
    resources = driver.execute_script(
        "return performance.getEntriesByType('resource').map(function(e){return e.name;})")
    assert all(str(r).startswith(("file:", "data:")) for r in resources), resources


def test_the_failures_list_is_the_first_thing_under_the_header(driver: Any,
                                                               tmp_path: Path) -> None:
    from selenium.webdriver.common.by import By

    out = sr.make_catalog(tmp_path / "catalog")
    write_rrd(out / "sharp_curve__ctrl_a")  # the other synthetic runs have no log
    index = write_reports(out).report_html
    text = index.read_text()
    assert "http://" not in text and "https://" not in text
    driver.get(index.resolve().as_uri())
    assert driver.title.startswith("hwyeval report")
    assert console_errors(driver) == []
    _no_network(driver)
    first = driver.execute_script("return document.querySelector('main').firstElementChild.id")
    assert first == "failures"
    header = driver.find_element(By.TAG_NAME, "header")
    section = driver.find_element(By.ID, "failures")
    assert abs(section.location["y"] - (header.location["y"] + header.size["height"])) < 40
    rows = section.find_elements(By.CSS_SELECTOR, "table.failures tbody tr")
    assert len(rows) == 5  # 12 runs, 7 passed
    # the triage above it: the failures grouped, the counts add up, largest group first
    groups = section.find_elements(By.CSS_SELECTOR, "table.triage tbody tr")
    counts = [int(g.find_elements(By.TAG_NAME, "td")[1].text) for g in groups]
    assert sum(counts) == 5 and counts == sorted(counts, reverse=True)
    # a click on a column head sorts the table by it
    head = section.find_elements(By.CSS_SELECTOR, "table.failures thead th")[1]
    head.click()
    names = [r.find_elements(By.TAG_NAME, "td")[1].text for r in
             section.find_elements(By.CSS_SELECTOR, "table.failures tbody tr")]
    assert names == sorted(names, key=str.lower)
    head.click()  # and back, reversed
    names_back = [r.find_elements(By.TAG_NAME, "td")[1].text for r in
                  section.find_elements(By.CSS_SELECTOR, "table.failures tbody tr")]
    assert names_back == names[::-1]
    driver.refresh()
    section = driver.find_element(By.ID, "failures")
    rows = section.find_elements(By.CSS_SELECTOR, "table.failures tbody tr")
    # errors first, each row's reason visible in the first screen
    assert rows[0].get_attribute("class") == "error"
    assert "RuntimeError: solver diverged" in section.text
    fail = next(r for r in rows if "sharp_curve" in r.text)
    assert "max_abs_lat_acc_mps2" in fail.text and "m/s²" in fail.text and "t = " in fail.text
    assert fail.location["y"] + fail.size["height"] < driver.execute_script(
        "return window.innerHeight")
    screenshot(driver, "report_index")
    rrd = fail.find_element(By.LINK_TEXT, "run.rrd").get_attribute("href")
    assert rrd.endswith("/sharp_curve__ctrl_a/run.rrd")
    # a run without a log has a badge, not a dead link
    assert all(r.find_elements(By.CSS_SELECTOR, ".badge.nolog") for r in rows
               if "sharp_curve" not in r.text)
    # the variant columns and the run table
    matrix = driver.find_element(By.ID, "scenario-matrix")
    assert {c.text for c in matrix.find_elements(By.CSS_SELECTOR, "td.cell")} == {
        "pass", "fail", "error", "timeout"}
    box = driver.find_element(By.ID, "filter")
    box.send_keys("sharp_curve")
    shown = [r for r in driver.find_elements(By.CSS_SELECTOR, "table.runs tbody tr")
             if r.is_displayed()]
    assert len(shown) == 2
    # a failure's link opens its run page at its failures
    driver.get(fail.find_element(By.PARTIAL_LINK_TEXT, "sharp_curve").get_attribute("href"))
    assert driver.current_url.endswith("report-runs/sharp_curve__ctrl_a.html#failures")
    assert "max_abs_lat_acc_mps2" in driver.find_element(By.ID, "failures").text
    assert console_errors(driver) == []


def test_tick_labels_equal_their_gridline_values(driver: Any, tmp_path: Path) -> None:
    out = sr.make_catalog(tmp_path / "catalog")
    paths = write_reports(out)
    checked = 0
    for page in sorted(paths.run_pages.glob("*.html")):
        driver.get(page.resolve().as_uri())
        assert console_errors(driver) == []
        _no_network(driver)
        checked += check_tick_labels(driver, page.name, log_axes=False)
        if page.name == "sharp_curve__ctrl_a.html":
            screenshot(driver, "report_run_page")
    assert checked > 300
