"""A storyboard in SUMO (slow): the hand-written bend cut-in imported and run through
`hwyeval run`; the storyboard's own log and the recorded neighbours agree with the
known answers (a lane change across a 3.6 m lane at a mean lateral rate of 1.2 m/s
takes 3.0 s; the stalled van stays put)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from suite.cli import main

DATA = Path(__file__).resolve().parent / "data" / "openscenario"
pytestmark = pytest.mark.slow
SUMO_STEP_S = 0.1


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    tmp = tmp_path_factory.mktemp("osc_sumo")
    assert main(["import", "openscenario", str(DATA / "bend_cut_in.xosc"),
                 "--out", str(tmp / "cat")]) == 0
    assert main(["run", str(tmp / "cat" / "catalog.toml"), "--out", str(tmp / "runs"),
                 "--jobs", "1", "--no-log", "--no-fail"]) == 0
    with (tmp / "runs" / "results.csv").open() as f:
        (row,) = list(csv.DictReader(f))
    assert row["status"] in ("pass", "fail"), row
    return tmp / "runs" / "bend_cut_in"


def _transition(log: dict[str, object], name: str, what: str) -> float:
    rows = log["transitions"]
    assert isinstance(rows, list)
    return float(next(t for t, _, n, w in rows if n == name and w == what))


def test_the_lane_change_takes_width_over_rate(run: Path) -> None:
    log = json.loads((run / "sumo" / "storyboard.json").read_text())
    start = _transition(log, "CutInAction", "startTransition")
    end = _transition(log, "CutInAction", "endTransition")
    assert end - start == pytest.approx(3.6 / 1.2, abs=SUMO_STEP_S + 1e-6)
    assert start > 0.0  # the headway trigger fired during the run, not at its start


def test_the_entities_are_in_sumo_where_the_story_puts_them(run: Path) -> None:
    d = pq.read_table(run / "neighbours.parquet").to_pydict()
    lead = [i for i, v in enumerate(d["id"]) if v == "osc_Lead"]
    van = [i for i, v in enumerate(d["id"]) if v == "osc_Van"]
    assert lead and van
    assert d["lane_index"][lead[0]] == 0 and d["speed_mps"][lead[0]] == pytest.approx(20.0)
    assert {d["lane_index"][i] for i in lead} >= {0, 1}  # it cut into the Hero's lane
    assert max(d["speed_mps"][i] for i in van) == 0.0
    assert d["length_m"][lead[0]] == pytest.approx(4.2)
