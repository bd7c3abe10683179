"""Many nights in one embedded DuckDB database: trends, flaky scenarios, the night a
scenario broke (docs/history.md).

Modules: :mod:`~reports.history.schema` (versions and migrations),
:mod:`~reports.history.store` (reading a night, adding it under a lock, queries,
baselines), :mod:`~reports.history.trends` (first failing night, flaky; pure),
:mod:`~reports.history.page` (the trend page).
"""

from __future__ import annotations

from reports.history.page import write_history_page
from reports.history.schema import SCHEMA_VERSION, HistoryError, ensure_schema
from reports.history.store import (
    BASELINES,
    DEFAULT_WAIT_S,
    AddResult,
    Baseline,
    CatalogClash,
    HistoryLocked,
    NightConflict,
    NightInfo,
    NightRecord,
    NoBaseline,
    QueryResult,
    add_night,
    baseline_night,
    read_night,
    run_sql,
)
from reports.history.trends import (
    DEFAULT_METRIC,
    FLAKY_ALTERNATIONS,
    ScenarioTrend,
    Trends,
    load_trends,
    scenario_trend,
    trends_json,
)

__all__ = ["BASELINES", "DEFAULT_METRIC", "DEFAULT_WAIT_S", "FLAKY_ALTERNATIONS",
           "SCHEMA_VERSION", "AddResult", "Baseline", "CatalogClash", "HistoryError",
           "HistoryLocked", "NightConflict", "NightInfo", "NightRecord", "NoBaseline",
           "QueryResult", "ScenarioTrend", "Trends", "add_night", "baseline_night",
           "ensure_schema", "load_trends", "read_night", "run_sql", "scenario_trend",
           "trends_json", "write_history_page"]
