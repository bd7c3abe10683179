"""Headless Chromium for the report tests (Debian's chromium + chromedriver), and where
their screenshots go: ``tests/artifacts/`` (ignored by git, kept after the run)."""

from __future__ import annotations

import os
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
