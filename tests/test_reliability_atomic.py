"""Atomic run directories: written under a staging name and renamed when complete; an
older run is replaced whole, never mixed with the new one; a symbolic link in its
place is replaced, never followed out of ``--out``; what a killed writer leaves is
hidden from readers and removed."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

import tests.synthetic_runs as sr
from reports.record import RUN_JSON, RunRecord, iter_run_dirs, load_run
from reports.record import run as record_run
from reports.record.run import (
    discard_staging,
    publish_run_dir,
    staging_dir,
    write_run_atomic,
)
from suite.catalog import load_catalog
from suite.run.runner import RunOptions, run_scenario
from tests.reliability_support import scenario_toml, write_catalog


def _record(name: str, wall_s: float = 5.0) -> RunRecord:
    record = sr.make_record(sr.straight_trace(2.0), name=name)
    record.outcome = dataclasses.replace(record.outcome, wall_s=wall_s)
    return sr.judge(record)


def test_publishing_replaces_an_older_run_whole(tmp_path: Path) -> None:
    final = tmp_path / "out" / "r"
    write_run_atomic(_record("r", wall_s=1.0), final)
    (final / "traceback.txt").write_text("from the old run")
    write_run_atomic(_record("r", wall_s=2.0), final)
    assert not (final / "traceback.txt").exists()
    assert load_run(final).outcome.wall_s == 2.0
    assert [p.name for p in (tmp_path / "out").iterdir()] == ["r"]  # nothing left beside


def test_a_symlink_in_the_run_directorys_place_is_replaced_not_followed(tmp_path: Path) -> None:
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / RUN_JSON).write_text("precious")
    out = tmp_path / "out"
    out.mkdir()
    (out / "r").symlink_to(elsewhere, target_is_directory=True)
    write_run_atomic(_record("r"), out / "r")
    assert not (out / "r").is_symlink() and (out / "r" / RUN_JSON).is_file()
    assert (elsewhere / RUN_JSON).read_text() == "precious"
    assert sorted(p.name for p in elsewhere.iterdir()) == [RUN_JSON]


def test_a_writer_that_fails_half_way_leaves_the_older_run_untouched(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    final = tmp_path / "out" / "r"
    write_run_atomic(_record("r", wall_s=1.0), final)
    before = {p.name: p.read_bytes() for p in final.iterdir()}

    def half(record: object, run_dir: Path, *, run_json: bool = True) -> None:
        (run_dir / "road.json").write_text("{")
        raise OSError("disk full")

    monkeypatch.setattr(record_run, "write_run", half)
    with pytest.raises(OSError, match="disk full"):
        write_run_atomic(_record("r", wall_s=2.0), final)
    assert {p.name: p.read_bytes() for p in final.iterdir()} == before
    assert [p.name for p in (tmp_path / "out").iterdir()] == ["r"]


def test_staging_directories_are_not_runs_and_are_cleaned_by_name(tmp_path: Path) -> None:
    out = tmp_path / "out"
    write_run_atomic(_record("a"), out / "a")
    stage_a = staging_dir(out, "a")
    stage_b = staging_dir(out, "b")
    (stage_a / RUN_JSON).write_text((out / "a" / RUN_JSON).read_text())  # as if killed late
    assert [p.name for p in iter_run_dirs(out)] == ["a"]
    assert discard_staging(out, "a") == [stage_a]
    assert stage_b.exists()
    assert discard_staging(out) == [stage_b]
    publish_run_dir(staging_dir(out, "c"), out / "c")
    assert (out / "c").is_dir()


@pytest.mark.sumo
def test_a_run_over_a_symlinked_directory_writes_inside_out_only(tmp_path: Path) -> None:
    """A scenario directory that was a symlink was followed out of --out."""
    scenario = load_catalog(write_catalog(tmp_path / "c.toml", [scenario_toml("linked")])
                            ).scenarios[0]
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "keep.txt").write_text("not yours")
    out = tmp_path / "out"
    out.mkdir()
    (out / "linked").symlink_to(outside, target_is_directory=True)
    record = run_scenario(scenario, out, RunOptions(write_rrd=False))
    assert record.status == "pass" and record.run_dir == out / "linked"
    assert not (out / "linked").is_symlink()
    assert (out / "linked" / "trace.parquet").is_file()
    assert sorted(p.name for p in outside.iterdir()) == ["keep.txt"]
    assert sorted(p.name for p in out.iterdir()) == ["linked"]
