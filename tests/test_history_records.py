"""The history reads a night from the typed run records (issue #37): the night equals the
one read before from results.csv's text and the raw run.json (the oracle below keeps
that reading), results.csv is never read back, a damaged run directory keeps the facts
of its run.json, and an older run.json without the failures' phases is read as before."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
import synthetic_runs as sr

from reports import write_reports
from reports.history import add_night, read_night, run_sql
from reports.history.night import NOT_METRICS, NightRecord
from reports.identity import (
    _INFO_TEST_FIELDS,
    CODE_KEY,
    CONTENT_KEY,
    CONTROLLER_KEY,
    SUT_KEY,
    TEST_KEY,
    SetupDigests,
    _test_fields,
    digest,
    limits_sha256,
    sut_sha256,
)
from reports.manifest import Manifest, write_manifest
from reports.metrics.catalogue import CRITERIA_METRICS
from reports.provenance import Provenance
from reports.record import TRACE

pytestmark = pytest.mark.slow  # each judges and writes a 12-run night (1.5-4 s)

STARTED = "2026-11-02T03:00:00+00:00"


def night_dir(path: Path) -> Path:
    """A finished synthetic night (pass, fail, error and timeout runs, two controllers)
    with the results.csv the run writes."""
    out = sr.make_catalog(path)
    names = tuple(sorted(p.name for p in out.iterdir() if p.is_dir()))
    write_manifest(out, Manifest(catalog="/ci/catalogs/nightly.toml", catalog_name="nightly",
                                 scenarios=names, started=STARTED, jobs=1, executor="local",
                                 finished=STARTED,
                                 provenance=Provenance(git_sha="b" * 40, git_dirty=False,
                                                       hwyeval_version="0.1.0", host="ci")))
    write_reports(out)
    return out


def digests_of_run_json(info: dict[str, Any], criteria: dict[str, Any]) -> SetupDigests:
    """The set-up digests as the history worked them out before, straight from a parsed
    run.json (the recorded digests as they are; an older run's from its fields)."""
    spec = info.get("scenario_spec") or {}
    test = str(spec.get(TEST_KEY) or "")
    test_spec = ""
    if not test:
        fields = _test_fields(spec)
        test_spec = digest(fields if fields else {k: info.get(k) for k in _INFO_TEST_FIELDS})
    sut = str(spec.get(SUT_KEY) or "")
    if not sut:
        params = info.get("controller_params") or info.get("controller_options") or {}
        sut = sut_sha256(str(info.get("controller", "")), params,
                         str(spec.get(CONTROLLER_KEY) or spec.get(CODE_KEY) or ""))
    return SetupDigests(test, test_spec, limits_sha256(criteria) if criteria else "", sut)


def _raw_facts(run_dir: Path) -> dict[str, Any]:
    """What the history read of a run.json before, straight from its JSON."""
    data = json.loads((run_dir / "run.json").read_text())
    info = data["info"]
    spec = info.get("scenario_spec") or {}
    verdict = data.get("verdict") or {}
    criteria = verdict.get("criteria") or {}
    params = info.get("controller_params") or info.get("controller_options") or {}
    return {
        "scenario_hash": spec.get(CONTENT_KEY, ""),
        "limits": tuple((CRITERIA_METRICS[c][0], float(v)) for c, v in criteria.items()
                        if c in CRITERIA_METRICS and isinstance(v, int | float)
                        and not isinstance(v, bool)),
        "digests": digests_of_run_json(info, criteria),
        "controller_code": str(spec.get(CONTROLLER_KEY) or spec.get(CODE_KEY) or ""),
        "controller_params": json.dumps(params, sort_keys=True, allow_nan=True, default=str),
        "failures": [(f["criterion"], f["metric"], f["value"], f["limit"], f["bound"],
                      f["unit"]) for f in verdict.get("failures") or []],
    }


def _csv_rows(out: Path) -> pd.DataFrame:
    """results.csv as the history read it back before."""
    return pd.read_csv(out / "results.csv", keep_default_na=False, na_values=[""])


def _assert_as_read_before(night: NightRecord, out: Path) -> None:
    frame = _csv_rows(out)
    names = tuple(c for c in frame.columns if c not in NOT_METRICS)
    assert night.metric_names == names
    values = frame[list(names)].apply(pd.to_numeric, errors="coerce").to_numpy(
        dtype=np.float64, na_value=np.nan)
    np.testing.assert_array_equal(night.values_2d, values)  # bit for bit, NaN where NaN
    failed = tuple("" if pd.isna(f) else str(f) for f in frame["failed_criteria"])
    assert night.failed_criteria == failed
    # the regex the history parsed failed_criteria with
    assert night.failure_modes == tuple(
        tuple(re.split(r"[=<>]", f, maxsplit=1)[0] for f in text.split(";") if f)
        for text in failed)
    assert night.scenarios == tuple(str(s) for s in frame["scenario"])
    assert night.controllers == tuple(str(c) for c in frame["controller"])
    assert night.statuses == tuple(str(s) for s in frame["status"])
    assert night.run_dirs == tuple(str(out.resolve() / str(r)) for r in frame["run"])
    for run_dir, facts in zip(night.run_dirs, night.facts, strict=True):
        raw = _raw_facts(Path(run_dir))
        assert facts.scenario_hash == raw["scenario_hash"]
        assert facts.limits == raw["limits"]
        assert facts.digests == raw["digests"]
        assert (facts.controller_code, facts.controller_params) == (
            raw["controller_code"], raw["controller_params"])
        assert [(f.criterion, f.metric, f.value, f.limit, f.bound, f.unit)
                for f in facts.failures] == raw["failures"]


def test_the_night_from_records_is_the_night_read_from_results_csv(tmp_path: Path) -> None:
    out = night_dir(tmp_path / "night")
    night = read_night(out)
    assert {"pass", "fail", "error", "timeout"} <= set(night.statuses)
    assert any(night.failure_modes)
    _assert_as_read_before(night, out)
    db = tmp_path / "h.duckdb"
    assert add_night(db, night).added
    stored = run_sql(db, "SELECT scenario, controller, failed_criteria, failure_modes "
                         "FROM runs ORDER BY scenario, controller").rows
    expected = sorted(zip(night.scenarios, night.controllers, night.failed_criteria,
                          night.failure_modes, strict=True))
    assert [(s, c, f, tuple(m)) for s, c, f, m in stored] == expected


def test_results_csv_is_not_read_back(tmp_path: Path) -> None:
    out = night_dir(tmp_path / "night")
    night = read_night(out)
    frame = _csv_rows(out)
    frame["min_gap_m"] = 1e6  # a results.csv newer than every run.json, and wrong
    frame["failed_criteria"] = "min_gap_m=1e+06>0"
    frame.to_csv(out / "results.csv", index=False)
    later = max(p.stat().st_mtime for p in out.glob("*/run.json")) + 10
    os.utime(out / "results.csv", (later, later))
    assert read_night(out).sha256 == night.sha256
    (out / "results.csv").unlink()
    again = read_night(out)
    assert again.sha256 == night.sha256 and again.facts == night.facts


def test_a_damaged_run_directory_keeps_the_facts_of_its_run_json(tmp_path: Path) -> None:
    out = night_dir(tmp_path / "night")
    damaged = out / "rear_end__ctrl_a"
    with (damaged / TRACE).open("ab") as fh:
        fh.write(b"changed after the run")
    night = read_night(out)
    i = night.run_dirs.index(str(damaged.resolve()))
    assert night.statuses[i] == "error"  # the reports' reader refuses the directory
    assert night.failed_criteria[i] == "" and night.failure_modes[i] == ()
    raw = _raw_facts(damaged)
    facts = night.facts[i]
    assert facts.scenario_hash == raw["scenario_hash"] and facts.digests == raw["digests"]
    assert facts.limits == raw["limits"] and len(facts.failures) == len(raw["failures"]) > 0


def test_an_older_run_json_without_phases_is_read_as_before(tmp_path: Path) -> None:
    out = night_dir(tmp_path / "night")
    before = read_night(out)
    for run_json in out.glob("*/run.json"):
        doc = json.loads(run_json.read_text())
        for f in (doc.get("verdict") or {}).get("failures") or []:
            f.pop("phase", None)
            f.pop("fell_back", None)
        run_json.write_text(json.dumps(doc))
    after = read_night(out)
    assert after.sha256 == before.sha256
    assert after.failure_modes == before.failure_modes
    assert all(f.phase == "" and f.fell_back is None
               for facts in after.facts for f in facts.failures)
