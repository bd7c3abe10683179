"""The history's catalog identity and what it says about a night: the same catalog from
two checkouts is one history (a v2 database keyed by absolute paths migrates into it);
another catalog of the same name is refused unless ``--catalog-name`` says otherwise;
per scenario and night which kind of change happened (test, limits, system under test);
the first failing night's failed criteria and what changed; the sparkline of the failing
criterion's metric; the links to each night's report and run page; known failures; and
``compare --history`` on the first night. Real git repositories and DuckDB files;
nights are synthetic run directories (tests/synthetic_runs.py) with a manifest."""

from __future__ import annotations

import dataclasses
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import duckdb
import pytest
import synthetic_runs as sr

from reports.history import CatalogClash, add_night, load_trends, read_night
from reports.history.page import history_html
from reports.history.schema import MIGRATIONS, V1_DDL
from reports.history.trends import trends_dict
from reports.identity import CONTROLLER_KEY, TEST_KEY
from reports.manifest import Manifest, catalog_identity, write_manifest
from reports.provenance import Provenance
from reports.record import RunRecord, write_run

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = "cruise_straight"


def git(*args: str, cwd: Path) -> None:
    subprocess.run(["git", *args], cwd=cwd, check=True, capture_output=True,
                   env={"GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t",
                        "GIT_COMMITTER_NAME": "t", "GIT_COMMITTER_EMAIL": "t@t",
                        "PATH": "/usr/bin:/bin", "HOME": str(cwd)})


def repository(path: Path, text: str = "[[scenario]]\n") -> Path:
    """A git repository holding ``catalogs/nightly.toml``, one commit."""
    (path / "catalogs").mkdir(parents=True)
    (path / "catalogs" / "nightly.toml").write_text(text)
    git("init", "-q", cwd=path)
    git("add", ".", cwd=path)
    git("commit", "-q", "-m", "catalog", cwd=path)
    return path / "catalogs" / "nightly.toml"


def clone(source: Path, path: Path) -> Path:
    git("clone", "-q", str(source), str(path), cwd=source.parent)
    return path / "catalogs" / "nightly.toml"


def run_of(controller: str = "ctrl_a", params: dict[str, Any] | None = None,
           trace_of: str = "cruise_straight__ctrl_a", xfail: dict[str, Any] | None = None
           ) -> RunRecord:
    """SCENARIO's run with the trajectory of the synthetic catalog's ``trace_of``."""
    record = dict(sr.catalog_records(("ctrl_a",)))[trace_of]
    params = params if params is not None else {"gain": 1.0}
    spec: dict[str, Any] = {TEST_KEY: "7" * 64, CONTROLLER_KEY: "c" * 64}
    if xfail is not None:
        spec["xfail"] = xfail
    record.info = dataclasses.replace(record.info, scenario=SCENARIO, family="cruise",
                                      controller=controller, controller_params=params,
                                      scenario_spec=spec)
    return record


def night(out: Path, catalog: Path, day: int, record: RunRecord,
          criteria: dict[str, object] | None = None, sha: str = "a" * 40) -> Path:
    """A finished night in ``out`` of ``catalog`` (as ``hwyeval run`` writes its
    manifest) started on November ``day``, SCENARIO's run ``record``."""
    write_run(sr.judge(record, criteria), out / SCENARIO)
    identity = catalog_identity(catalog)
    started = f"2026-11-{day:02d}T03:00:00+00:00"
    write_manifest(out, Manifest(catalog=str(catalog), catalog_name=catalog.stem,
                                 scenarios=(SCENARIO,), started=started, jobs=1,
                                 executor="local", finished=started,
                                 provenance=Provenance(git_sha=sha, git_dirty=False),
                                 catalog_id=identity.name, catalog_origin=identity.origin))
    return out


def hwyeval(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "suite", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=300)


@pytest.mark.slow  # git init, commit and clone in subprocesses
def test_the_same_catalog_from_two_checkouts_is_one_history(tmp_path: Path) -> None:
    first = repository(tmp_path / "ws1")
    second = clone(tmp_path / "ws1", tmp_path / "ws2")
    assert catalog_identity(first) == catalog_identity(second)
    assert catalog_identity(first).name == "catalogs/nightly.toml"
    db = tmp_path / "h.duckdb"
    add_night(db, read_night(night(tmp_path / "n1", first, 1, run_of())))
    add_night(db, read_night(night(tmp_path / "n2", second, 2, run_of())))
    trends = load_trends(db)
    assert trends.catalog == "catalogs/nightly.toml" and len(trends.nights) == 2
    # another repository's catalogs/nightly.toml is another catalog: refused
    other = repository(tmp_path / "elsewhere", "# another project\n")
    with pytest.raises(CatalogClash):
        add_night(db, read_night(night(tmp_path / "n3", other, 3, run_of())))
    # unless the catalog is named
    add_night(db, read_night(tmp_path / "n3", catalog_name="elsewhere-nightly"), named=True)
    assert len(load_trends(db, catalog="elsewhere-nightly").nights) == 1
    assert len(load_trends(db, catalog="catalogs/nightly.toml").nights) == 2


@pytest.mark.slow  # the CLI in subprocesses
def test_another_catalog_of_the_same_name_exits_2_unless_named(tmp_path: Path) -> None:
    db = tmp_path / "h.duckdb"
    mine = night(tmp_path / "n1", repository(tmp_path / "ws"), 1, run_of())
    theirs = night(tmp_path / "n2", repository(tmp_path / "elsewhere", "# another\n"), 2,
                   run_of())
    assert hwyeval("history", "add", str(db), str(mine)).returncode == 0
    assert hwyeval("history", "add", str(db), str(theirs)).returncode == 2
    assert hwyeval("history", "add", str(db), str(theirs), "--catalog-name",
                   "elsewhere-nightly").returncode == 0
    assert len(load_trends(db, catalog="catalogs/nightly.toml").nights) == 1


def test_a_declared_name_is_the_identity_wherever_the_file_is(tmp_path: Path) -> None:
    a = repository(tmp_path / "a", '[catalog]\nname = "nightly"\n')
    moved = tmp_path / "a" / "moved.toml"
    shutil.copy(a, moved)
    assert catalog_identity(a) == catalog_identity(moved)
    assert catalog_identity(a).name == "nightly"
    loose = tmp_path / "loose" / "nightly.toml"
    loose.parent.mkdir()
    loose.write_text("")
    assert catalog_identity(loose).name == "nightly.toml"  # no git, no name: its file name


def _v2_database(db: Path, catalog: Path, out_dir: Path) -> None:
    """A schema-v2 file holding one night of ``catalog`` (keyed by its absolute path)."""
    with duckdb.connect(str(db)) as con:
        for sql in (*V1_DDL, *MIGRATIONS[2]):
            con.execute(sql)
        con.execute("INSERT INTO nights (night_id, started_at, git_revision, hwyeval_version, "
                    "host, catalog, out_dir) VALUES ('old', '2026-10-31 03:00:00+00', 'a', "
                    "'0.1.0', 'ci', ?, ?)", [str(catalog), str(out_dir)])
        con.execute("INSERT INTO runs (night_id, scenario, scenario_hash, controller, status, "
                    "failed_criteria, failure_modes, run_dir) VALUES ('old', ?, '', 'ctrl_a', "
                    "'pass', '', [], '')", [SCENARIO])


def test_a_v2_database_keyed_by_absolute_paths_migrates_into_one_history(tmp_path: Path
                                                                         ) -> None:
    first = repository(tmp_path / "ws1")
    second = clone(tmp_path / "ws1", tmp_path / "ws2")
    db = tmp_path / "h.duckdb"
    _v2_database(db, first, tmp_path / "gone")
    result = add_night(db, read_night(night(tmp_path / "n2", second, 2, run_of())))
    assert result.migrated_from == 2
    assert [n.info.night_id for n in load_trends(db).nights][0] == "old"
    # a checkout since removed: its nights join the catalog whose path they end with
    db2 = tmp_path / "h2.duckdb"
    _v2_database(db2, tmp_path / "removed" / "catalogs" / "nightly.toml", tmp_path / "gone")
    add_night(db2, read_night(night(tmp_path / "n3", second, 3, run_of())))
    assert len(load_trends(db2).nights) == 2


def test_the_history_says_why_a_scenario_broke(tmp_path: Path) -> None:
    catalog = repository(tmp_path / "ws")
    db = tmp_path / "h.duckdb"
    nights = [
        night(tmp_path / "n1", catalog, 1, run_of()),
        night(tmp_path / "n2", catalog, 2, run_of(), {"min_ttc_s": 1.5}),  # a limit
        night(tmp_path / "n3", catalog, 3, run_of(params={"gain": 3.0},  # the SUT breaks
                                                  trace_of="rear_end__ctrl_a"),
              {"min_ttc_s": 1.5}, sha="b" * 40),
    ]
    for out in nights:
        add_night(db, read_night(out))
    trends = load_trends(db)
    (t,) = trends.scenarios
    assert t.changes == ((), ("limits",), ("sut",))
    assert t.failing_now and t.first_failing_night == trends.nights[2].info.night_id
    assert "at_fault_collisions" in {f.metric for f in t.first_failures}
    assert any("gain" in c for c in t.first_changes)  # the options diff
    assert any("revision" in c for c in t.first_changes)  # and the code revision
    assert t.metric in {f.metric for f in t.first_failures}  # the failing criterion's
    doc = json.loads(json.dumps(trends_dict(trends)))
    (s,) = doc["scenarios"]
    assert s["changes"] == ["", "limits", "sut"] and s["first_failures"]
    assert s["run"] == SCENARIO  # each night's page: <out_dir>/report-runs/<run>.html
    assert all(Path(n["out_dir"], "report-runs", f"{s['run']}.html").parent.parent
               == Path(n["report"]).parent for n in doc["nights"])
    page = history_html(trends, tmp_path / "trends")
    hrefs = set(re.findall(r'href="([^"]+)"', page))
    assert {f"../n{k}/report-runs/{SCENARIO}.html" for k in (1, 2, 3)} <= hrefs
    assert {f"../n{k}/report.html" for k in (1, 2, 3)} <= hrefs


@pytest.mark.parametrize("strict", [True, False])
def test_known_failures_in_the_history(tmp_path: Path, strict: bool) -> None:
    catalog = repository(tmp_path / "ws")
    db = tmp_path / "h.duckdb"
    mark = {"reason": "issue 41", "strict": strict}
    add_night(db, read_night(night(tmp_path / "n1", catalog, 1,
                                   run_of(trace_of="rear_end__ctrl_a", xfail=mark))))
    (t,) = load_trends(db).scenarios
    assert t.status_now == "xfail" and not t.failing_now and t.known_failure
    add_night(db, read_night(night(tmp_path / "n2", catalog, 2, run_of(xfail=mark))))
    trends = load_trends(db)
    (t,) = trends.scenarios
    assert t.status_now == "xpass" and t.failing_now is strict
    assert "remove the xfail" in history_html(trends)


@pytest.mark.slow  # the CLI in subprocesses
def test_compare_history_on_the_first_night_says_so_and_exits_0(tmp_path: Path) -> None:
    catalog = repository(tmp_path / "ws")
    db = tmp_path / "h.duckdb"
    first = night(tmp_path / "n1", catalog, 1, run_of())
    assert hwyeval("history", "add", str(db), str(first)).returncode == 0
    proc = hwyeval("compare", "--history", str(db), str(first))
    assert proc.returncode == 0, proc.stderr
    assert not (tmp_path / "n1.compare").exists()  # nothing was compared
    second = night(tmp_path / "n2", catalog, 2, run_of(trace_of="rear_end__ctrl_a"))
    assert hwyeval("history", "add", str(db), str(second)).returncode == 0
    assert hwyeval("compare", "--history", str(db), str(second)).returncode == 1
