"""The workers' forkserver starts before the catalog is read (suite/exec/catalog_run.py,
``EarlyWarmUp``): a command that ends before it runs anything (a catalog error, an
output directory refused, a resume with nothing left to run) leaves no process behind,
and one that runs still runs and reports as before."""

from __future__ import annotations

import time
import uuid
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.reliability_support import (
    hwyeval,
    marked_env,
    marked_pids,
    scenario_toml,
    write_catalog,
)

pytestmark = [pytest.mark.sumo, pytest.mark.slow]


def _gone_within(marker: str, seconds: float) -> list[int]:
    deadline = time.monotonic() + seconds
    while marked_pids(marker) and time.monotonic() < deadline:
        time.sleep(0.1)
    return marked_pids(marker)


def _run(marker: str, *args: str) -> tuple[int, str]:
    res = hwyeval("run", *args, env=marked_env(marker), timeout_s=300)
    return res.returncode, res.stdout + res.stderr


Case = Callable[[Path], list[str]]


def _bad_key(tmp: Path) -> list[str]:
    cat = write_catalog(tmp / "bad.toml", [scenario_toml("a", extra="bogus_key = 1\n")])
    return [str(cat), "--out", str(tmp / "out"), "--no-log"]


def _refused_out(tmp: Path) -> list[str]:
    cat = write_catalog(tmp / "ok.toml", [scenario_toml("a")])
    out = tmp / "out"
    out.mkdir()
    (out / "something.txt").write_text("not ours")
    return [str(cat), "--out", str(out), "--no-log"]


@pytest.mark.parametrize("case", [_bad_key, _refused_out], ids=["bad key", "refused --out"])
def test_an_input_error_leaves_no_forkserver(tmp_path: Path, case: Case) -> None:
    marker = uuid.uuid4().hex
    code, text = _run(marker, *case(tmp_path))
    assert code == 2, text
    assert "Traceback" not in text, text
    assert _gone_within(marker, 0.5) == []


def test_a_resume_with_nothing_to_run_leaves_no_forkserver(tmp_path: Path) -> None:
    cat = write_catalog(tmp_path / "ok.toml", [scenario_toml("a"), scenario_toml("b", lane=1)])
    out = tmp_path / "out"
    first = uuid.uuid4().hex
    code, text = _run(first, str(cat), "--out", str(out), "--no-log")
    assert code == 0, text
    assert (out / "results.csv").is_file() and "[2/2]" in text
    again = uuid.uuid4().hex
    code, text = _run(again, str(cat), "--out", str(out), "--no-log", "--resume")
    assert code == 0, text
    assert sum(" kept: pass" in line for line in text.splitlines()) == 2 and "[1/" not in text
    assert _gone_within(again, 0.5) == []
