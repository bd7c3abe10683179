"""A damaged search journal and searches whose runs have no verdict (issue 35).

``search --resume`` of a journal holding a garbage line, random bytes, something that
is not an Optuna operation, or cut inside a batch's asks was a traceback with exit 1
(which for ``search`` means "a failure was found") or a resume that ran a batch the
uninterrupted search never ran; it is now exit 2 naming the file and the line, with the
output left as it was. A search whose runs ended in error or timeout exited 0 with an
empty found.toml; it now says so and exits 3 (1 when a failure was found anyway)."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from suite.search.journal import JournalError
from suite.search.journal_check import check_journal
from suite.search.loop import FamilyResult, TrialResult
from suite.search.outcome import SearchOutput, verdict_lines
from suite.search.space import Family, load_search_catalog
from tests.reliability_support import ROOT
from tests.test_search_loop import CATALOG, _search

BUDGET, JOBS = 6, 2


@pytest.fixture(scope="module")
def searched(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Family, bytes]:
    """A search catalog, its family and the journal of a finished 6-run search (batches
    of 2) on the fake objective."""
    tmp = tmp_path_factory.mktemp("journal")
    catalog = tmp / "fake.toml"
    catalog.write_text(CATALOG)
    family = load_search_catalog(catalog).families[0]
    journal = tmp / "search.journal"
    _search(family, journal, "tpe", 0, BUDGET, jobs=JOBS)
    return catalog, family, journal.read_bytes()


def _ops(data: bytes) -> list[dict[str, Any]]:
    return [json.loads(line) for line in data.splitlines()]


def _first(ops: list[dict[str, Any]], op_code: int, key: str | None = None) -> int:
    """The 1-based line of the first operation ``op_code`` (whose user_attr has ``key``)."""
    for number, op in enumerate(ops, start=1):
        if op["op_code"] == op_code and (key is None or key in op.get("user_attr", {})):
            return number
    raise AssertionError(f"no operation {op_code}")


# The damages that insert one line: kind -> (the line, how many journal lines precede
# it); the error must name the inserted line.
_INSERTED_LINES: dict[str, tuple[bytes, int]] = {
    "garbage_line": (b"hello world\n", 5),
    "not_an_operation": (b"[1, 2, 3]\n", 4),
    "missing_fields": (b'{"op_code": 5, "worker_id": "w"}\n', 4),
    "unknown_trial": (json.dumps({"op_code": 8, "worker_id": "w", "trial_id": 999,
                                  "user_attr": {"batch": 0}}).encode() + b"\n", 4),
}


def _damaged(kind: str, data: bytes) -> tuple[bytes, int]:
    """The journal damaged as ``kind`` and the line the error must name."""
    lines = data.splitlines(keepends=True)
    ops = _ops(data)
    create, batch = _first(ops, 4), _first(ops, 8, "batch")
    if kind in _INSERTED_LINES:
        inserted, before = _INSERTED_LINES[kind]
        return b"".join(lines[:before]) + inserted + b"".join(lines[before:]), before + 1
    if kind == "random_bytes":
        return bytes(range(256)) * 4 + b"\n", 1
    if kind == "cut_inside_an_ask":  # the first trial created, one parameter set
        return b"".join(lines[:create + 1]), create
    # cut between the batch's two asks: the first trial complete, its batch never marked
    return b"".join(lines[:batch]), batch


def _out(tmp_path: Path, catalog: Path, journal: bytes) -> Path:
    """A search output to --resume: its settings, manifest and ``journal``."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "search.json").write_text(json.dumps({
        "catalog": str(catalog.resolve()), "sampler": "tpe", "seed": 0, "jobs": JOBS,
        "budget": BUDGET}))
    (out / "manifest.json").write_text("{}")
    (out / "search.journal").write_bytes(journal)
    return out


def _snapshot(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file()}


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["garbage_line", "random_bytes", "not_an_operation",
                                  "missing_fields", "unknown_trial", "cut_inside_an_ask",
                                  "cut_between_asks"])
def test_resuming_a_damaged_journal_exits_2_naming_file_and_line(
        tmp_path: Path, searched: tuple[Path, Family, bytes], kind: str) -> None:
    catalog, _, data = searched
    damaged, line = _damaged(kind, data)
    out = _out(tmp_path, catalog, damaged)
    before = _snapshot(out)
    proc = subprocess.run([sys.executable, "-m", "suite", "search", str(catalog), "--out",
                           str(out), "--budget", str(BUDGET), "--jobs", str(JOBS), "--resume",
                           "--no-log"], cwd=ROOT, capture_output=True, text=True,
                          timeout=300, env={**os.environ})
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert f"{out / 'search.journal'}:{line}:" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert _snapshot(out) == before


def test_an_interrupted_batch_and_a_torn_last_line_still_resume(
        tmp_path: Path, searched: tuple[Path, Family, bytes]) -> None:
    """What --resume is for passes the check, which writes nothing: a journal cut after
    a batch's asks were marked, inside its tells, or in the middle of its last line."""
    _, family, data = searched
    lines = data.splitlines(keepends=True)
    marked = _first(_ops(data), 2, "hwyeval_asked_0")
    for keep in (marked, marked + 1, marked + 2, len(lines)):
        path = tmp_path / f"j{keep}.journal"
        body = b"".join(lines[:keep]) + b'{"op_code": 8, "wor'  # a torn last line
        path.write_bytes(body)
        check_journal(path, [family])
        assert path.read_bytes() == body
    with pytest.raises(JournalError):
        path.write_bytes(b"".join(lines[:_first(_ops(data), 4) + 1]))
        check_journal(path, [family])


def _trial(status: str, number: int) -> TrialResult:
    rob = {"pass": 0.5, "fail": -0.5}.get(status, math.nan)
    return TrialResult("fam", number, f"fam__t{number:04d}", (1.0,), status, rob)


def test_a_search_says_when_runs_had_no_verdict_and_exits_3(
        searched: tuple[Path, Family, bytes], tmp_path: Path) -> None:
    _, family, _ = searched
    cases = [(("pass", "pass"), 0), (("pass", "error"), 3), (("timeout", "error"), 3),
             (("fail", "error"), 1), (("fail", "pass"), 1)]
    for statuses, expected in cases:
        res = SearchOutput(results=[FamilyResult(family, [_trial(s, i) for i, s in
                                                          enumerate(statuses)])])
        code, lines = verdict_lines(res, tmp_path)
        assert code == expected
        assert f"exit {code}" in lines[-1]
        named = [t.run for t in res.results[0].trials if t.status in ("error", "timeout")]
        assert all(any(run in line for line in lines) for run in named)


@pytest.mark.slow
@pytest.mark.sumo
def test_a_search_whose_every_run_errors_exits_3_not_0(tmp_path: Path) -> None:
    """Every run of the family crashes (a controller raising at its 50th step): the
    search found nothing because it judged nothing; it says so and exits 3."""
    catalog = tmp_path / "crash.toml"
    catalog.write_text(CATALOG.replace('controller = "lane_keep"',
                                       'controller = "crash_at_step_50"'))
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "suite", "search", str(catalog), "--out",
                           str(out), "--budget", "2", "--no-log", "--plugin",
                           str(ROOT / "tests" / "crash_plugin.py")], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 3, proc.stdout + proc.stderr
    assert "fake__t0000" in proc.stdout.split("NOT JUDGED", 1)[-1]
    assert (out / "found.toml").is_file()
