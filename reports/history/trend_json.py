"""The trends as JSON for the history page (:func:`trends_dict`, :func:`trends_json`)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from reports.history.trend_model import FLAKY_ALTERNATIONS, ScenarioTrend, Trends
from reports.identity import CHANGE_KINDS

# ----------------------------------------------------------------------- JSON


def _num(x: float) -> float | str | None:
    if math.isnan(x):
        return None
    return x if math.isfinite(x) else ("inf" if x > 0 else "-inf")


def run_page(run_dir: str) -> str:
    """The report page of a run (its night's ``report-runs/<run>.html``; '' absent)."""
    if not run_dir:
        return ""
    path = Path(run_dir)
    return str(path.parent / "report-runs" / f"{path.name}.html")


def _run_name(t: ScenarioTrend) -> str | None:
    """The run directory's name when every night's is the same (the run page of night
    j is then ``<nights[j].out_dir>/report-runs/<run>.html``), else None."""
    names = {Path(d).name for d in t.run_dirs if d}
    return names.pop() if len(names) == 1 else None


def _scenario_dict(t: ScenarioTrend) -> dict[str, Any]:
    mark = t.marks[-1] if t.marks else None
    run = _run_name(t)
    out: dict[str, Any] = {
        "scenario": t.scenario, "status_now": t.status_now, "failing_now": t.failing_now,
        "known_failure": t.known_failure,
        "xfail": {"reason": mark.reason, "strict": mark.strict} if mark is not None else None,
        "xfail_nights": [j for j, m in enumerate(t.marks) if m is not None],
        "first_failing_night": t.first_failing_night,
        "first_failing_revision": t.first_failing_revision,
        "first_failures": [{"criterion": f.criterion, "metric": f.metric,
                            "value": _num(f.value), "limit": _num(f.limit), "bound": f.bound,
                            "unit": f.unit} for f in t.first_failures],
        "first_changes": list(t.first_changes),
        "last_good_night": t.last_good_night, "last_good_revision": t.last_good_revision,
        "flaky": t.flaky, "flaky_reasons": list(t.flaky_reasons),
        "alternations": t.alternations, "statuses": list(t.statuses),
        # one string per night: the kinds that changed, joined by '+' ('' none)
        "changes": ["+".join(c) for c in t.changes], "run": run,
        "metric": t.metric, "metric_values": [_num(v) for v in t.values],
        "metric_limit": _num(t.limit)}
    if run is None:  # the run directory's name varies: each night's page spelt out
        out["run_pages"] = [run_page(d) or None for d in t.run_dirs]
    return out


def trends_dict(trends: Trends) -> dict[str, Any]:
    """The trends as plain JSON data (``hwyeval history DB --json``; docs/history.md)."""
    return {
        "db": trends.db, "catalog": trends.catalog, "metric": trends.metric,
        "flaky_rule": {"same_hash_and_revision": True,
                       "min_alternations": FLAKY_ALTERNATIONS},
        "change_kinds": list(CHANGE_KINDS),
        "nights": [{"night_id": s.info.night_id, "started_at": s.info.started_at.isoformat(),
                    "git_revision": s.info.git_revision, "git_dirty": s.info.git_dirty,
                    "hwyeval_version": s.info.hwyeval_version, "host": s.info.host,
                    "catalog_sha256": s.info.catalog_sha256, "out_dir": s.info.out_dir,
                    "report": s.info.report or None, "runs": s.runs, "passed": s.passed,
                    "expected_failures": s.expected, "pass_rate": _num(s.pass_rate)}
                   for s in trends.nights],
        "scenarios": [_scenario_dict(t) for t in trends.scenarios],
    }


def trends_json(trends: Trends) -> str:
    return json.dumps(trends_dict(trends), indent=1)
