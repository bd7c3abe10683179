"""Catalog key ``replay`` (recorded traffic): the spec it builds, its validation (bad
mode, missing or corrupt tracks file -> a CatalogError at ``replay.tracks``), sweeps
over ``replay.mode``; the handover rule and the neighbours' ``agent`` column without
SUMO (tests/test_replay_sumo.py runs them)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from replay_fixtures import cut_in_tracks, rear_end_tracks

from controllers.behaviour.types import Traffic
from reports.record import AGENT_SUMO, NeighbourColumns
from suite.catalog import CatalogError, ReplaySpec, SpecError, load_catalog
from suite.catalog.tracks import write_tracks
from suite.world.replay import HandoverEgo, handover_due

KNOWN = {"lane_keep", "two_loop"}
HEADER = """
[defaults]
controller = "lane_keep"
duration_s = 10.0
step_s = 0.02

[[scenario]]
name = "a"
net = "straight_3lane"
ego = { lane = 1, pos_m = 50.0, speed_mps = 25.0 }
"""


def _write(tmp_path: Path, body: str) -> Path:
    write_tracks(tmp_path / "t.tracks.parquet", rear_end_tracks())
    path = tmp_path / "c.toml"
    path.write_text(HEADER + body)
    return path


def _issues(tmp_path: Path, body: str) -> list[tuple[str, object]]:
    with pytest.raises(CatalogError) as exc:
        load_catalog(_write(tmp_path, body), known_controllers=KNOWN)
    return [(i.key, i.got) for i in exc.value.issues]


def test_replay_table_builds_its_spec(tmp_path: Path) -> None:
    cat = load_catalog(_write(tmp_path, 'replay = { tracks = "t.tracks.parquet", '
                              'mode = "reactive", handover_time_gap_s = 1.5 }\n'
                              "stalled = [ { lane = 0, pos_m = 300.0 } ]\n"),
                       known_controllers=KNOWN)
    sc = cat.get("a")
    assert sc.replay == ReplaySpec("t.tracks.parquet", "reactive", 1.5, "strategic",
                                   tracks_path=(tmp_path / "t.tracks.parquet").resolve())
    assert sc.replay.reactive and len(sc.stalled) == 1
    assert sc.as_dict()["replay"]["mode"] == "reactive"


def test_scenarios_without_replay_keep_their_dict(tmp_path: Path) -> None:
    sc = load_catalog(_write(tmp_path, ""), known_controllers=KNOWN).get("a")
    assert sc.replay is None and "replay" not in sc.as_dict()


def test_sweep_over_the_mode(tmp_path: Path) -> None:
    cat = load_catalog(_write(tmp_path, 'replay = { tracks = "t.tracks.parquet" }\n'
                              '[scenario.sweep]\n"replay.mode" = ["replay", "reactive"]\n'),
                       known_controllers=KNOWN)
    assert [s.replay.mode for s in cat if s.replay is not None] == ["replay", "reactive"]
    assert len(set(cat.names())) == 2


@pytest.mark.parametrize(("body", "key"), [
    ('replay = { tracks = "t.tracks.parquet", mode = "log" }', "scenario[0].replay.mode"),
    ('replay = { tracks = "t.tracks.parquet", handover_time_gap_s = 0.0 }',
     "scenario[0].replay.handover_time_gap_s"),
    ('replay = { tracks = "t.tracks.parquet", lane_changes = "some" }',
     "scenario[0].replay.lane_changes"),
    ('replay = { tracks = "t.tracks.parquet", speed = 1 }', "scenario[0].replay.speed"),
    ('replay = { mode = "replay" }', "scenario[0].replay.tracks"),
    ('replay = { tracks = "nowhere.tracks.parquet" }', "scenario[0].replay.tracks"),
    ('replay = "t.tracks.parquet"', "scenario[0].replay"),
])
def test_bad_replay_values_are_catalog_issues(tmp_path: Path, body: str, key: str) -> None:
    assert key in [k for k, _ in _issues(tmp_path, body + "\n")]


def test_a_corrupt_tracks_file_is_an_issue_at_replay_tracks(tmp_path: Path) -> None:
    (tmp_path / "bad.tracks.parquet").write_bytes(b"not parquet at all")
    issues = _issues(tmp_path, 'replay = { tracks = "bad.tracks.parquet" }\n')
    assert issues == [("scenario[0].replay.tracks", "bad.tracks.parquet")]


def test_a_tracks_file_without_a_column_is_an_issue_naming_the_file(tmp_path: Path) -> None:
    pq.write_table(pa.table({"track_id": ["rec_1"], "time_s": [0.0]}).replace_schema_metadata(
        {b"hwyeval.tracks.version": b"1", b"hwyeval.tracks.dt_s": b"0.1"}),
        tmp_path / "cols.tracks.parquet")
    with pytest.raises(CatalogError) as exc:
        load_catalog(_write(tmp_path, 'replay = { tracks = "cols.tracks.parquet" }\n'),
                     known_controllers=KNOWN)
    [issue] = exc.value.issues
    assert issue.key == "scenario[0].replay.tracks"
    assert str(tmp_path / "cols.tracks.parquet") in issue.expected


def test_replay_spec_validates_itself() -> None:
    with pytest.raises(SpecError):
        ReplaySpec("t.parquet", mode="log")
    with pytest.raises(SpecError):
        ReplaySpec("t.parquet", handover_time_gap_s=-1.0)
    assert ReplaySpec("t.parquet", lane_changes="none").lane_change_mode == 0


def _ego(x: float = 100.0, y: float = 0.0) -> HandoverEgo:
    return HandoverEgo(x, y, 0.0, 20.0, 4.8, 1.9, "e0", 1)


def _traffic(x: list[float], y: list[float], v: list[float], heading: list[float],
             lanes: list[int], road: str = "e0") -> Traffic:
    n = len(x)
    return Traffic(tuple(f"rec_{i}" for i in range(n)), np.array(x), np.array(y),
                   np.array(heading), np.array(v), np.full(n, 4.5), np.full(n, 1.8),
                   np.array(lanes), (road,) * n, np.zeros(n, bool))


def test_handover_rule() -> None:
    """Behind in the ego's lane: due at any distance; ahead: never; beside in the next
    lane: only when about to overlap laterally within the time gap and its bumper gap
    is below speed x gap."""
    tr = _traffic([0.0, 150.0, 60.0, 60.0, 90.0],
                  [0.0, 0.0, -3.5, -3.5, -3.5],
                  [20.0, 20.0, 25.0, 25.0, 25.0],
                  [0.0, 0.0, 0.0, math.atan2(2.0, 25.0), math.atan2(2.0, 25.0)],
                  [1, 1, 0, 0, 0])
    due = handover_due(_ego(), tr, 1.0).tolist()
    # 0: behind in lane; 1: ahead; 2: next lane, straight; 3: drifting in, but its gap
    # (35.35 m) above 25 m/s x 1 s; 4: drifting in, gap 5.35 m
    assert due == [True, False, False, False, True]
    on_next_road = _traffic([60.0], [0.3], [20.0], [0.0], [0], road="e_prev")
    # on another road the lane indices are not compared: its box overlaps the ego's
    # laterally, so it is behind in the ego's lane (rule 1), whatever its gap
    assert handover_due(_ego(), on_next_road, 1.0).tolist() == [True]


def test_old_neighbour_files_read_agent_zero(tmp_path: Path) -> None:
    """A neighbours.parquet written before the ``agent`` column reads as SUMO traffic."""
    import pandas as pd

    frame = pd.DataFrame({"step": [0, 1], "t_s": [0.02, 0.04], "id": ["v0", "rec_1"],
                          "x_m": [1.0, 2.0], "y_m": [0.0, 0.0], "heading_rad": [0.0, 0.0],
                          "speed_mps": [1.0, 1.0], "length_m": [4.5, 4.5],
                          "width_m": [1.8, 1.8], "lane_index": [0, 1],
                          "stalled": [False, False]})
    nb = NeighbourColumns.from_frame(frame)
    assert nb.agent.dtype == np.int8 and nb.agent.tolist() == [AGENT_SUMO] * 2
    again = NeighbourColumns.from_frame(nb.to_frame().assign(agent=[1, 2]))
    assert again.agent.tolist() == [1, 2]


def test_tracks_fixtures_are_valid(tmp_path: Path) -> None:
    write_tracks(tmp_path / "c.tracks.parquet", cut_in_tracks())
    assert load_catalog(_write(tmp_path, 'replay = { tracks = "c.tracks.parquet" }\n'),
                        known_controllers=KNOWN).get("a").replay is not None


def test_the_tracks_file_content_is_part_of_the_scenario_hash(tmp_path: Path) -> None:
    from suite.run.info import scenario_content_sha256

    body = 'replay = { tracks = "t.tracks.parquet" }\n'
    first = scenario_content_sha256(load_catalog(_write(tmp_path, body),
                                                 known_controllers=KNOWN).get("a"))
    same = scenario_content_sha256(load_catalog(_write(tmp_path, body),
                                                known_controllers=KNOWN).get("a"))
    write_tracks(tmp_path / "t.tracks.parquet", cut_in_tracks())  # same name, new content
    cat = load_catalog(tmp_path / "c.toml", known_controllers=KNOWN)
    assert first == same != scenario_content_sha256(cat.get("a"))
