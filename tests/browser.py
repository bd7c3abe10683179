"""Headless Chromium for the report tests (Debian's chromium + chromedriver), and where
their screenshots go: ``tests/artifacts/`` (ignored by git, kept after the run)."""

from __future__ import annotations

import math
import os
import re
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

CHROMIUM = os.environ.get("HWYEVAL_CHROMIUM", "/usr/bin/chromium")
CHROMEDRIVER = os.environ.get("HWYEVAL_CHROMEDRIVER", "/usr/bin/chromedriver")
ARTIFACTS = Path(__file__).resolve().parent / "artifacts"

needs_chromium = [
    pytest.mark.browser,
    pytest.mark.skipif(not (Path(CHROMIUM).is_file() and Path(CHROMEDRIVER).is_file()),
                       reason="headless Chromium / chromedriver not installed"),
]


def chromium(width: int = 1400, height: int = 1000) -> Iterator[Any]:
    """A headless Chromium webdriver with its own profile (a generator for fixtures)."""
    webdriver = pytest.importorskip("selenium.webdriver")
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--disable-background-networking", "--disable-component-update",
                "--disable-sync", "--no-first-run", f"--window-size={width},{height}"):
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


def screenshot(driver: Any, name: str) -> Path:
    """Save the viewport as ``tests/artifacts/<name>.png`` and print where."""
    ARTIFACTS.mkdir(exist_ok=True)
    path = ARTIFACTS / f"{name}.png"
    assert driver.save_screenshot(str(path))
    print(f"screenshot: {path}")
    return path


def console_errors(driver: Any) -> list[Any]:
    return [e for e in driver.get_log("browser") if e.get("level") in ("SEVERE", "ERROR")]


def chart_ticks(driver: Any) -> list[dict[str, Any]]:
    """Every ``svg.chart`` of the page: its data range, plot box, gridlines and y labels."""
    return driver.execute_script("""
      return Array.from(document.querySelectorAll('svg.chart')).map(function(svg){
        return {y0: +svg.dataset.y0, y1: +svg.dataset.y1, top: +svg.dataset.top,
                h: +svg.dataset.h, log: svg.dataset.log === '1',
                grid: svg.querySelector('path.grid').getAttribute('d'),
                labels: Array.from(svg.querySelectorAll('text.yt')).map(function(t){
                  return [t.textContent, +t.getAttribute('y')];})};});""")


def check_tick_labels(driver: Any, where: str, log_axes: bool = True) -> int:
    """Assert that every y tick label of every chart sits on a gridline (within 0.01 px)
    and at its value's height (within 0.02 px; log axes in log10 units, skipped without
    ``log_axes``); returns how many labels were checked."""
    checked = 0
    for chart in chart_ticks(driver):
        if chart["log"] and not log_axes:
            continue
        grid_ys = [float(m) for m in re.findall(r"M64 ([-\d.]+)h", chart["grid"])]
        for text, label_y in chart["labels"]:
            line_y = label_y - 3.0  # a label sits 3 px below its gridline
            assert min(abs(g - line_y) for g in grid_ys) < 0.01, (where, text, line_y)
            value = float(text.replace("\u2212", "-"))
            if chart["log"]:  # the axis runs in log10 units
                value = math.log10(value)
            at = chart["top"] + chart["h"] * (1 - (value - chart["y0"])
                                              / (chart["y1"] - chart["y0"]))
            assert abs(at - line_y) < 0.02, (where, text, at, line_y)
            checked += 1
    return checked
