"""Selecting scenarios by name or family (the ``--filter`` of the command line)."""

from __future__ import annotations

import fnmatch
from collections.abc import Iterable

from suite.catalog.specs import Scenario

__all__ = ["expand_filter"]


def expand_filter(scenarios: Iterable[Scenario], glob: str | None) -> tuple[Scenario, ...]:
    """Scenarios whose name or family matches ``glob`` (fnmatch, case-sensitive; several
    patterns may be comma-separated). ``None``/``""``/``"*"`` keep everything."""
    items = tuple(scenarios)
    if not glob or glob.strip() == "*":
        return items
    patterns = [p.strip() for p in glob.split(",") if p.strip()]
    return tuple(s for s in items
                 if any(fnmatch.fnmatchcase(s.name, p) or fnmatch.fnmatchcase(s.family, p)
                        for p in patterns))
