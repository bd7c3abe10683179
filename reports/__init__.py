"""Reports of a catalog output directory (``DIR/<run>/run.json`` …), from stored verdicts.

``write_reports(out_dir)`` writes results.csv, summary.csv, junit.xml and report.html;
``compare_runs`` diffs two outputs. Sub-packages: ``reports.record`` (the run-directory
schema), ``reports.metrics`` (judges a record once, right after its run).

The renderers are imported on first use (PEP 562 ``__getattr__``), so that importing
``reports.record`` or ``reports.metrics`` (as the runner does in every scenario
process) does not load the HTML, JUnit and comparison code.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from reports.compare import CompareResult, MetricTolerance, Tolerances, compare_runs
    from reports.tables import RunEntry, collect_runs
    from reports.write import ReportPaths, write_reports

_LAZY = {
    "CompareResult": "reports.compare", "MetricTolerance": "reports.compare",
    "Tolerances": "reports.compare", "compare_runs": "reports.compare",
    "RunEntry": "reports.tables", "collect_runs": "reports.tables",
    "ReportPaths": "reports.write", "write_reports": "reports.write",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'reports' has no attribute {name!r}")
    return getattr(importlib.import_module(module), name)


__all__ = ["CompareResult", "MetricTolerance", "ReportPaths", "RunEntry", "Tolerances",
           "collect_runs", "compare_runs", "write_reports"]
