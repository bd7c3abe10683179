"""The history at scale on synthetic rows: 2 000 scenarios x 100 nights with about as
many metric columns as results.csv. The test checks correctness and the page's size;
the speed figures (adding a night, building the page, a query) are measured, not
asserted, by running this file: ``.venv/bin/python tests/test_history_scale.py``.

Pattern: scenario i fails from night 61 on when i % 50 == 0 (a regression at
revision r61, nights 61-65), alternates pass/fail every 10 nights when i % 97 == 1 and not the
former (flaky by alternations), and passes otherwise; the revision changes every 5 nights."""

from __future__ import annotations

import datetime as dt
import json
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from reports.history import (
    NightInfo,
    NightRecord,
    add_night,
    load_trends,
    run_sql,
    trends_json,
    write_history_page,
)

T0 = dt.datetime(2026, 1, 1, 2, 0, tzinfo=dt.UTC)
N_SCENARIOS, N_NIGHTS, N_METRICS = 2000, 100, 90
REGRESSION_NIGHT = 61  # the first night of a new revision


def revision(k: int) -> str:
    return f"{(k - 1) // 5:02x}" * 20


def status(i: int, k: int) -> str:
    if i % 50 == 0 and k >= REGRESSION_NIGHT:
        return "fail"
    if i % 97 == 1 and i % 50 != 0 and (k // 10) % 2 == 1:
        return "fail"
    return "pass"


def night(k: int, n_scenarios: int = N_SCENARIOS, n_metrics: int = N_METRICS,
          seed: int = 0) -> NightRecord:
    rng = np.random.default_rng(seed + k)
    names = ("min_ttc_s", *(f"metric_{j:02d}" for j in range(1, n_metrics)))
    statuses = tuple(status(i, k) for i in range(n_scenarios))
    values = rng.normal(3.0, 0.5, size=(n_scenarios, n_metrics))
    limits = np.full_like(values, np.nan)
    limits[:, 0] = 0.95
    info = NightInfo(night_id=f"night-{k:03d}", started_at=T0 + dt.timedelta(days=k),
                     git_revision=revision(k), hwyeval_version="0.1.0", host="ci",
                     catalog="/ci/catalogs/big.toml", out_dir=f"/runs/{k}", git_dirty=False,
                     catalog_id="big.toml")  # as read_night names a catalog outside git
    return NightRecord(
        info=info, scenarios=tuple(f"scenario_{i:04d}" for i in range(n_scenarios)),
        scenario_hashes=("h" * 64,) * n_scenarios, controllers=("two_loop",) * n_scenarios,
        statuses=statuses,
        failed_criteria=tuple("" if s == "pass" else "min_ttc_s=0.5<0.95" for s in statuses),
        failure_modes=tuple(() if s == "pass" else ("min_ttc_s",) for s in statuses),
        run_dirs=tuple(f"/runs/{k}/scenario_{i:04d}" for i in range(n_scenarios)),
        metric_names=names, values_2d=values, limits_2d=limits)


def build(db: Path, n_nights: int = N_NIGHTS, n_scenarios: int = N_SCENARIOS
          ) -> list[float]:
    """Add the nights; returns each add's wall time [s] (the database write only)."""
    times = []
    for k in range(1, n_nights + 1):
        rec = night(k, n_scenarios)
        t0 = time.perf_counter()
        add_night(db, rec)
        times.append(time.perf_counter() - t0)
    return times


@pytest.mark.slow
def test_two_thousand_scenarios_by_a_hundred_nights(tmp_path: Path) -> None:
    db = tmp_path / "big.duckdb"
    build(db)
    rows = run_sql(db, "SELECT count(*), count(DISTINCT night_id) FROM runs").rows
    assert rows == ((N_SCENARIOS * N_NIGHTS, N_NIGHTS),)
    trends = load_trends(db)
    page = write_history_page(trends, tmp_path / "page")
    assert page.stat().st_size <= 5 * 1024 * 1024
    by = {t.scenario: t for t in trends.scenarios}
    regressed = [f"scenario_{i:04d}" for i in range(0, N_SCENARIOS, 50)]
    flaky = [f"scenario_{i:04d}" for i in range(N_SCENARIOS) if i % 97 == 1 and i % 50]
    assert [t.scenario for t in trends.failing] == sorted(
        regressed + [s for s in flaky if status(int(s[-4:]), N_NIGHTS) == "fail"])
    for name in regressed:
        t = by[name]
        assert t.first_failing_night == f"night-{REGRESSION_NIGHT:03d}"
        assert t.last_good_revision == revision(REGRESSION_NIGHT - 1)
        assert not t.flaky
    assert sorted(t.scenario for t in trends.flaky) == flaky
    data = json.loads(trends_json(trends))
    assert len(data["nights"]) == N_NIGHTS and len(data["scenarios"]) == N_SCENARIOS


def night_directory(out: Path, k: int) -> Path:
    """Night ``k`` as an output directory: a manifest, results.csv and per run a
    run.json of a real one's size (~25 kB: the verdict's metric entries, the criteria,
    the content hash). :func:`reports.history.read_night` reads the run.json files as
    typed records (the results.csv is there as a run writes one; it is not read)."""
    import dataclasses

    import pandas as pd

    import tests.synthetic_runs as sr
    from reports.manifest import Manifest, write_manifest
    from reports.provenance import Provenance
    from reports.record.codec import to_plain

    rec = night(k)
    out.mkdir(parents=True)
    started = rec.info.started_at.isoformat()
    write_manifest(out, Manifest(catalog=rec.info.catalog, catalog_name="big",
                                 scenarios=rec.scenarios, started=started, jobs=2,
                                 executor="local", finished=started,
                                 provenance=Provenance(git_sha=rec.info.git_revision,
                                                       git_dirty=False)))
    for i, name in enumerate(rec.scenarios):
        (out / name).mkdir()
        metrics = [{"name": m, "value": float(v), "unit": "s", "kind": "safety",
                    "better": "higher", "worst_step": 17, "series": "ttc_ahead_s"}
                   for m, v in zip(rec.metric_names, rec.values_2d[i], strict=True)]
        # every key the typed reader needs (read_night reads each run through it)
        info = to_plain(dataclasses.replace(
            sr.base_info(name, "two_loop"), scenario_spec={
                "content_sha256": rec.scenario_hashes[i]}))
        (out / name / "run.json").write_text(json.dumps({
            "schema": 2, "info": info, "outcome": {},
            "verdict": {"status": rec.statuses[i], "metrics": metrics,
                        "criteria": {"min_ttc_s": 0.95, "max_collision": None}}}))
    frame = pd.DataFrame(rec.values_2d, columns=list(rec.metric_names))
    frame.insert(0, "scenario", rec.scenarios)
    frame.insert(1, "controller", rec.controllers)
    frame.insert(2, "variant", rec.controllers)
    frame.insert(3, "status", rec.statuses)
    frame["failed_criteria"] = rec.failed_criteria
    frame["family"] = "big"
    frame["run"] = rec.scenarios
    frame.to_csv(out / "results.csv", index=False)
    return out


def main() -> None:
    import tempfile

    from reports.history import read_night

    with tempfile.TemporaryDirectory() as tmp:
        db = Path(tmp) / "big.duckdb"
        times = build(db, N_NIGHTS - 1)
        directory = night_directory(Path(tmp) / "night100", N_NIGHTS)
        t0 = time.perf_counter()
        rec = read_night(directory)
        t1 = time.perf_counter()
        add_night(db, rec)
        t2 = time.perf_counter()
        print(f"night {N_NIGHTS} from its directory ({rec.n_runs} runs): read {t1 - t0:.2f} s "
              f"+ add {t2 - t1:.2f} s = {t2 - t0:.2f} s")
        print(f"add a night ({N_SCENARIOS} runs x {N_METRICS} metrics): median "
              f"{np.median(times):.3f} s, max {max(times):.3f} s, last {times[-1]:.3f} s "
              f"(database {db.stat().st_size / 1e6:.1f} MB after {N_NIGHTS} nights)")
        t0 = time.perf_counter()
        trends = load_trends(db)
        t1 = time.perf_counter()
        page = write_history_page(trends, Path(tmp) / "page")
        t2 = time.perf_counter()
        text = trends_json(trends)
        t3 = time.perf_counter()
        print(f"page: trends {t1 - t0:.2f} s + HTML {t2 - t1:.2f} s = {t2 - t0:.2f} s, "
              f"{page.stat().st_size / 1e6:.2f} MB; JSON {t3 - t2:.2f} s, "
              f"{len(text) / 1e6:.2f} MB")
        for sql in ("SELECT night_id, avg((status = 'pass')::INT) FROM runs GROUP BY night_id "
                    "ORDER BY night_id",
                    "SELECT night_id, status, min_ttc_s FROM runs WHERE scenario = "
                    "'scenario_0050' ORDER BY night_id",
                    "SELECT scenario, count(*) FILTER (WHERE status <> 'pass') AS fails FROM "
                    "runs GROUP BY scenario ORDER BY fails DESC LIMIT 10"):
            t0 = time.perf_counter()
            result = run_sql(db, sql)
            print(f"query {time.perf_counter() - t0:.3f} s ({len(result.rows)} rows): {sql}")


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    main()
