"""Replay fidelity on the real recordings: the three shared CommonRoad files imported
(hwyeval import commonroad), run in replay mode with real libsumo, read back from the
trace: every recorded vehicle within 0.05 m and 0.1 m/s of the file at every recorded
sample of the run, and present exactly when the file says."""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from reports.record import AGENT_REPLAYED, load_run
from suite.catalog.toml_write import dumps_catalog
from suite.catalog.tracks import read_tracks

pytestmark = [pytest.mark.sumo, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "commonroad"
SUMO_STEP_S = 0.1  # the catalog's SUMO step for step_s = 0.02
POS_TOL_M = 0.05
SPEED_TOL_MPS = 0.1


def _hwyeval(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "suite", *args], cwd=ROOT, text=True,
                          capture_output=True, timeout=900)


@pytest.fixture(scope="module")
def imported(tmp_path_factory: pytest.TempPathFactory) -> Path:
    files = sorted(SHARED.glob("*.xml"))
    if not files:
        pytest.skip(f"no CommonRoad files in {SHARED}")
    pytest.importorskip("commonroad.common.reader.file_reader_xml")
    base = tmp_path_factory.mktemp("cr")
    proc = _hwyeval("import", "commonroad", *map(str, files), "--out", str(base / "imp"))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    doc = tomllib.loads((base / "imp" / "catalog.toml").read_text())
    scenarios = [dict(sc, controller="lane_keep", record_radius_m=5000.0)
                 for sc in doc["scenario"]]
    catalog = base / "imp" / "fidelity.toml"
    catalog.write_text(dumps_catalog("replay fidelity", {}, scenarios))
    out = base / "out"
    proc = _hwyeval("run", str(catalog), "--out", str(out), "--no-log", "--jobs", "1")
    assert proc.returncode in (0, 1), proc.stdout + proc.stderr
    return base


def _names(imported: Path) -> list[str]:
    doc = tomllib.loads((imported / "imp" / "catalog.toml").read_text())
    return [sc["name"] for sc in doc["scenario"]]


def test_every_recorded_sample_is_where_the_file_says(imported: Path) -> None:
    doc = {sc["name"]: sc for sc in
           tomllib.loads((imported / "imp" / "catalog.toml").read_text())["scenario"]}
    checked = 0
    for name in _names(imported):
        rec = load_run(imported / "out" / name)
        tracks = read_tracks(imported / "imp" / doc[name]["replay"]["tracks"])
        nb = rec.neighbours
        end_s = float(rec.trace.t_s[-1])
        for track in tracks.tracks:
            mine = (nb.id == track.track_id) & (nb.agent == AGENT_REPLAYED)
            for k, t in enumerate(track.time_s):
                if t < 0.0 or t > end_s + 1e-9:
                    continue
                row = np.flatnonzero(mine & (np.abs(nb.t_s - t) < 1e-6))
                if not row.size:  # before the first trace row (run time 0)
                    assert t < float(rec.trace.t_s[0]) + 1e-9, (name, track.track_id, t)
                    continue
                j = int(row[0])
                assert np.hypot(nb.x_m[j] - track.x_m[k], nb.y_m[j] - track.y_m[k]) \
                    <= POS_TOL_M, (name, track.track_id, t)
                assert abs(nb.speed_mps[j] - track.speed_mps[k]) <= SPEED_TOL_MPS
                checked += 1
    assert checked > 200


def test_a_recorded_vehicle_is_present_exactly_when_the_file_says(imported: Path) -> None:
    doc = {sc["name"]: sc for sc in
           tomllib.loads((imported / "imp" / "catalog.toml").read_text())["scenario"]}
    for name in _names(imported):
        rec = load_run(imported / "out" / name)
        tracks = read_tracks(imported / "imp" / doc[name]["replay"]["tracks"])
        nb = rec.neighbours
        steps = rec.trace.t_s[np.abs(rec.trace.t_s / SUMO_STEP_S
                                     - np.round(rec.trace.t_s / SUMO_STEP_S)) < 1e-6]
        for track in tracks.tracks:
            seen = {round(float(t), 6) for t in nb.t_s[nb.id == track.track_id]}
            for t in steps:
                expected = track.start_s - 1e-9 <= t <= track.end_s + 1e-9
                assert (round(float(t), 6) in seen) == expected, (name, track.track_id, t)
