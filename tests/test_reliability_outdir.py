"""The output directory (W2, W13) and ``--resume``: a non-empty ``--out`` needs ``--resume``
or ``--overwrite``; what is refused loses nothing; the reports cover exactly the runs of
the manifest; resume keeps only runs finished with the same scenario content and
hwyeval version."""

from __future__ import annotations

import dataclasses
import json
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

import tests.synthetic_runs as sr
from reports.record import RUN_JSON, load_run
from suite.catalog import load_catalog
from suite.exec.executors import RunJob
from suite.exec.outdir import (
    OutputDirError,
    check_out_dir,
    finished_record,
    prepare_out_dir,
    resume_plan,
)
from suite.run.info import scenario_content_sha256, scenario_info
from suite.run.runner import RunOptions
from tests.reliability_support import hwyeval, results, scenario_toml, write_catalog


def _snapshot(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file()}


def _tiny(tmp_path: Path, names: tuple[str, ...] = ("tiny_a",), duration_s: float = 1.0
          ) -> Path:
    return write_catalog(tmp_path / "cat" / "tiny.toml",
                         [scenario_toml(n, lane=i % 2) for i, n in enumerate(names)],
                         duration_s=duration_s)


@pytest.mark.slow
def test_run_into_an_earlier_output_is_refused_and_loses_nothing(tmp_path: Path) -> None:
    """W2: re-running into an existing --out mixed the earlier runs into every report."""
    out = sr.make_catalog(tmp_path / "earlier")
    (out / "manifest.json").write_text("{}")
    before = _snapshot(out)
    proc = hwyeval("run", str(_tiny(tmp_path)), "--out", str(out), "--no-log")
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "not empty" in proc.stderr and "--resume" in proc.stderr \
        and "--overwrite" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert _snapshot(out) == before


@pytest.mark.slow
@pytest.mark.sumo
def test_overwrite_reports_exactly_the_new_runs_and_the_exit_code_covers_them(
        tmp_path: Path) -> None:
    """W2: after --overwrite the reports, junit and the exit code cover the new run only."""
    out = sr.make_catalog(tmp_path / "earlier")  # runs that fail and error, other names
    assert len(list(out.iterdir())) > 3
    proc = hwyeval("run", str(_tiny(tmp_path)), "--out", str(out), "--no-log", "--overwrite")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert list(results(out).index) == ["tiny_a"]
    runs = sorted(p.name for p in out.iterdir() if (p / RUN_JSON).is_file())
    assert runs == ["tiny_a"]
    junit = ET.parse(out / "junit.xml").getroot()
    assert (junit.get("tests"), junit.get("failures"), junit.get("errors")) == ("1", "0", "0")
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["scenarios"] == ["tiny_a"]


@pytest.mark.slow
def test_overwrite_refuses_a_directory_that_is_not_an_hwyeval_output(tmp_path: Path) -> None:
    home = tmp_path / "home"
    (home / ".ssh").mkdir(parents=True)
    (home / ".ssh" / "id_rsa").write_text("secret")
    (home / "notes.txt").write_text("mine")
    before = _snapshot(home)
    proc = hwyeval("run", str(_tiny(tmp_path)), "--out", str(home), "--overwrite")
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "not an hwyeval output" in proc.stderr
    assert _snapshot(home) == before


@pytest.mark.slow
def test_resume_refuses_an_output_holding_runs_of_other_scenarios(tmp_path: Path) -> None:
    out = sr.make_catalog(tmp_path / "other")
    before = _snapshot(out)
    proc = hwyeval("run", str(_tiny(tmp_path)), "--out", str(out), "--resume")
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "not among the scenarios to run" in proc.stderr
    assert _snapshot(out) == before


def test_resume_and_overwrite_exclude_each_other(tmp_path: Path) -> None:
    proc = hwyeval("run", str(_tiny(tmp_path)), "--out", str(tmp_path / "o"), "--resume",
                   "--overwrite")
    assert proc.returncode == 2
    assert "not allowed with" in proc.stderr
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
@pytest.mark.parametrize("case", ["file", "under_a_file", "dangling_link"])
def test_out_that_is_or_lies_under_a_file_exits_2_before_writing(tmp_path: Path,
                                                                  case: str) -> None:
    """W13: --out an existing file or under one: a traceback, rc 1, manifest written."""
    blocker = tmp_path / "blocker"
    if case == "dangling_link":
        blocker.symlink_to(tmp_path / "nowhere")
        out = blocker
    else:
        blocker.write_text("a file")
        out = blocker if case == "file" else blocker / "sub" / "out"
    proc = hwyeval("run", str(_tiny(tmp_path)), "--out", str(out), "--no-log")
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr and "--out" in proc.stderr
    assert not (tmp_path / "nowhere").exists()
    if case != "dangling_link":
        assert blocker.read_text() == "a file"


@pytest.mark.slow
@pytest.mark.parametrize("name", ["report.html", "results.csv", "junit.xml", "report-runs"])
def test_a_report_target_that_is_not_a_file_exits_2(tmp_path: Path, name: str) -> None:
    """W13: report.html a directory: traceback, rc 1 (run --resume, and report)."""
    out = sr.make_catalog(tmp_path / "out")
    target = out / name
    if name == "report-runs":
        target.write_text("not a directory")
    else:
        target.mkdir()
    before = _snapshot(out)
    for args in (("report", str(out)),
                 ("run", str(_tiny(tmp_path)), "--out", str(out), "--resume")):
        proc = hwyeval(*args)
        assert proc.returncode == 2, proc.stdout + proc.stderr
        assert "Traceback" not in proc.stderr and name in proc.stderr
    assert _snapshot(out) == before


@pytest.mark.parametrize("jobs", ["-1", "0", "two"])
def test_bad_jobs_exit_2_without_writing(tmp_path: Path, jobs: str) -> None:
    """W13: --jobs -1 gave a traceback and rc 1 with manifest.json written."""
    out = tmp_path / "out"
    proc = hwyeval("run", str(_tiny(tmp_path)), "--out", str(out), "--jobs", jobs)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    assert not out.exists()


# ---------------------------------------------------------------- resume, unit level


def _jobs(tmp_path: Path, out: Path, duration_s: float = 1.0) -> list[RunJob]:
    catalog = load_catalog(_tiny(tmp_path, ("r_a", "r_b", "r_c"), duration_s))
    return [RunJob(sc, out, RunOptions(content_sha256=scenario_content_sha256(sc)))
            for sc in catalog.scenarios]


def _finished(job: RunJob, status_end: str = "ok", **info_changes: object) -> Path:
    """A judged record of ``job`` as the runner writes it (synthetic trace)."""
    from controllers.plant.vehicle_model import VehicleParams

    info = scenario_info(job.scenario, "tiny", VehicleParams(), {},
                         job.options.content_sha256)
    info = dataclasses.replace(info, **info_changes)  # type: ignore[arg-type]
    record = sr.make_record(sr.straight_trace(2.0), info=info)
    record.outcome = dataclasses.replace(record.outcome, end=status_end)
    return sr.write_judged(record, job.run_dir)


def test_resume_keeps_only_runs_finished_with_the_same_content_and_version(
        tmp_path: Path) -> None:
    out = tmp_path / "out"
    jobs = _jobs(tmp_path, out)
    a, b, c = jobs
    _finished(a)  # same content, same version: kept
    _finished(b, hwyeval_version="0.0.1")  # an older hwyeval wrote it
    _finished(c, scenario_spec={**a.scenario.as_dict(), "content_sha256": "0" * 64})
    (out / "r_a" / "keep_me").write_text("x")
    prepare_out_dir(check_out_dir(out, "resume", [j.name for j in jobs]))
    plan = resume_plan(jobs)
    assert [r.info.scenario for r in plan.kept] == ["r_a"]
    assert [j.name for j in plan.to_run] == ["r_b", "r_c"]
    assert not (out / "r_b").exists() and not (out / "r_c").exists()  # never inherited
    assert (out / "r_a" / "keep_me").exists()


def test_resume_runs_again_what_ended_in_error_or_timeout(tmp_path: Path) -> None:
    out = tmp_path / "out"
    jobs = _jobs(tmp_path, out)
    _finished(jobs[0], status_end="error")
    _finished(jobs[1], status_end="timeout")
    assert finished_record(jobs[0])[0] is None and finished_record(jobs[1])[0] is None
    assert [j.name for j in resume_plan(jobs).to_run] == ["r_a", "r_b", "r_c"]


def test_resume_unlinks_a_symlinked_run_directory_without_following_it(tmp_path: Path) -> None:
    out = tmp_path / "out"
    jobs = _jobs(tmp_path, out)
    elsewhere = tmp_path / "elsewhere"
    _finished(RunJob(jobs[0].scenario, elsewhere, jobs[0].options))
    out.mkdir()
    (out / "r_a").symlink_to(elsewhere / "r_a", target_is_directory=True)
    before = _snapshot(elsewhere)
    plan = resume_plan(jobs)
    assert "r_a" in [j.name for j in plan.to_run]
    assert not (out / "r_a").is_symlink() and not (out / "r_a").exists()
    assert _snapshot(elsewhere) == before


def test_the_content_hash_follows_what_is_simulated_not_where_it_is(tmp_path: Path) -> None:
    one = load_catalog(_tiny(tmp_path / "x", ("h",))).scenarios[0]
    moved = load_catalog(_tiny(tmp_path / "elsewhere" / "y", ("h",))).scenarios[0]
    longer = load_catalog(_tiny(tmp_path / "z", ("h",), duration_s=2.0)).scenarios[0]
    assert one.catalog_path != moved.catalog_path
    assert scenario_content_sha256(one) == scenario_content_sha256(moved)
    assert scenario_content_sha256(one) != scenario_content_sha256(longer)
    assert scenario_content_sha256(one, "0" * 64) != scenario_content_sha256(one)  # the net


def test_check_out_dir_writes_nothing(tmp_path: Path) -> None:
    out = tmp_path / "new" / "out"
    plan = check_out_dir(out, "fresh", ["a"])
    assert not (tmp_path / "new").exists()
    prepare_out_dir(plan)
    assert out.is_dir()
    with pytest.raises(OutputDirError):
        check_out_dir(tmp_path, "fresh", ["a"])


@pytest.mark.slow
@pytest.mark.sumo
def test_resume_after_a_catalog_change_reruns_only_the_changed_scenario(tmp_path: Path) -> None:
    out = tmp_path / "out"
    catalog = _tiny(tmp_path, ("c_a", "c_b"))
    first = hwyeval("run", str(catalog), "--out", str(out), "--no-log")
    assert first.returncode == 0, first.stdout + first.stderr
    wall_a = load_run(out / "c_a", trace=False, neighbours=False, arrays=False,
                      series=False).outcome.wall_s
    catalog.write_text(catalog.read_text().replace(
        'name = "c_b"\nnet = "straight_2lane"\n', 'name = "c_b"\nnet = "straight_2lane"\n'
        'seed = 4\n'))
    again = hwyeval("run", str(catalog), "--out", str(out), "--no-log", "--resume")
    assert again.returncode == 0, again.stdout + again.stderr
    assert "[1/1] PASS    c_b" in again.stdout  # one run to run: c_a kept
    kept = load_run(out / "c_a", trace=False, neighbours=False, arrays=False, series=False)
    assert kept.outcome.wall_s == wall_a
    assert load_run(out / "c_b", trace=False).info.seed == 4
    assert sorted(results(out).index) == ["c_a", "c_b"]
