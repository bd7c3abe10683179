"""report.html in headless Chromium: renders without console errors or network requests."""

from __future__ import annotations

import os
import re
import shutil
import tempfile
from pathlib import Path

import pytest
import synthetic_runs as sr

from reports import write_reports

CHROMIUM = os.environ.get("HWYEVAL_CHROMIUM", "/usr/bin/chromium")
CHROMEDRIVER = os.environ.get("HWYEVAL_CHROMEDRIVER", "/usr/bin/chromedriver")

pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(not (Path(CHROMIUM).is_file() and Path(CHROMEDRIVER).is_file()),
                       reason="headless Chromium / chromedriver not installed"),
]


@pytest.fixture()
def driver(tmp_path: Path):
    webdriver = pytest.importorskip("selenium.webdriver")
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--disable-background-networking", "--disable-component-update",
                "--disable-sync", "--no-first-run", "--window-size=1400,2400"):
        options.add_argument(arg)
    profile = tempfile.mkdtemp(prefix="hwyeval-chromium-")
    options.add_argument(f"--user-data-dir={profile}")
    options.binary_location = CHROMIUM
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    drv = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    try:
        yield drv
    finally:
        drv.quit()
        shutil.rmtree(profile, ignore_errors=True)


def test_report_renders_offline(driver, tmp_path: Path) -> None:
    from selenium.webdriver.common.by import By

    out = sr.make_catalog(tmp_path / "catalog")
    html_path = write_reports(out).report_html
    text = html_path.read_text()
    assert not re.search(r"""(src|href)\s*=\s*["']?https?://""", text)
    assert "http://" not in text and "https://" not in text

    driver.get(html_path.resolve().as_uri())
    assert driver.title.startswith("hwyeval report")
    errors = [e for e in driver.get_log("browser") if e.get("level") in ("SEVERE", "ERROR")]
    assert errors == []

    resources = driver.execute_script(
        "return performance.getEntriesByType('resource').map(function(e){return e.name;})")
    assert all(str(r).startswith(("file:", "data:")) for r in resources), resources

    matrix = driver.find_element(By.ID, "scenario-matrix")
    cells = matrix.find_elements(By.CSS_SELECTOR, "td.cell")
    assert len(cells) == 12
    assert {c.text for c in cells} == {"pass", "fail", "error", "timeout"}
    svgs = driver.find_elements(By.CSS_SELECTOR, "svg")
    assert len(svgs) > 40
    assert driver.find_elements(By.CSS_SELECTOR, "svg.bev")
    assert len(driver.find_elements(By.CSS_SELECTOR, "details.run")) == 12
    size = svgs[0].size
    assert size["width"] > 100 and size["height"] > 50

    # a matrix link opens its (closed, passing) run section
    link = matrix.find_element(By.CSS_SELECTOR, 'a[href="#run-cruise_straight__ctrl_a"]')
    target = driver.find_element(By.ID, "run-cruise_straight__ctrl_a")
    assert target.get_attribute("open") is None
    link.click()
    assert target.get_attribute("open") is not None

    # a failed run is open and marks where its stored failure was located
    marks = driver.find_element(By.CSS_SELECTOR, "#run-sharp_curve__ctrl_a p.marks")
    assert marks.is_displayed()
    assert marks.text.startswith("✖ max_abs_lat_acc_mps2 at t=")

    # the filter hides non-matching runs
    box = driver.find_element(By.ID, "filter")
    box.send_keys("sharp_curve")
    visible = [d for d in driver.find_elements(By.CSS_SELECTOR, "details.run") if d.is_displayed()]
    assert len(visible) == 2
    box.clear()
    driver.execute_script("document.getElementById('filter').dispatchEvent(new Event('input'))")

    shot = Path(tempfile.gettempdir()) / "hwyeval_report_screenshot.png"
    driver.execute_script("window.scrollTo(0, 0)")
    assert driver.save_screenshot(str(shot))
    assert shot.stat().st_size > 10_000
    errors = [e for e in driver.get_log("browser") if e.get("level") in ("SEVERE", "ERROR")]
    assert errors == []
