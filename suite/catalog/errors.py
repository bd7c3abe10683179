"""Catalog problems: a bad spec field, one catalog issue, the error listing them all.

Also the ``MISSING`` sentinel ("no value given"), which an issue shows as no ``got``.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["MISSING", "CatalogError", "CatalogIssue", "IssueCollector", "SpecError",
           "dedupe", "type_name"]


class SpecError(ValueError):
    """A spec field is invalid: ``field`` names it, ``expected`` says what fits."""

    def __init__(self, field_name: str, expected: str, got: Any = None) -> None:
        self.field = field_name
        self.expected = expected
        self.got = got
        super().__init__(f"{field_name}: expected {expected}, got {got!r}")


class _Missing:
    def __repr__(self) -> str:
        return "<missing>"


MISSING: Any = _Missing()


def _short_repr(value: Any, limit: int = 120) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


@dataclass(frozen=True)
class CatalogIssue:
    """One problem: ``key`` is dotted from the catalog root, ``scenario`` its name/label."""

    key: str
    expected: str
    got: Any = None
    scenario: str | None = None
    note: str = ""

    def line(self, path: Path | str) -> str:
        where = f" (scenario {self.scenario!r})" if self.scenario else ""
        got = "" if self.got is MISSING else f", got {_short_repr(self.got)}"
        note = f" [{self.note}]" if self.note else ""
        return f"{path}: {self.key}{where}: expected {self.expected}{got}{note}"


class CatalogError(ValueError):
    """A catalog is unusable. ``issues`` lists every problem; the message has one a line."""

    def __init__(self, path: Path | str, issues: Sequence[CatalogIssue]) -> None:
        self.path = Path(path)
        self.issues = tuple(issues)
        lines = [issue.line(path) for issue in self.issues]
        head = f"{path}: {len(lines)} problem{'s' if len(lines) != 1 else ''} in scenario catalog"
        super().__init__("\n".join([head, *lines]))


class IssueCollector:
    """The issues of one catalog, in the order they were found."""

    def __init__(self) -> None:
        self.issues: list[CatalogIssue] = []

    def add(self, key: str, expected: str, got: Any = MISSING, scenario: str | None = None,
            note: str = "") -> None:
        self.issues.append(CatalogIssue(key, expected, got, scenario, note))


def type_name(value: Any) -> str:
    """The type of ``value`` as a problem names it (``list``, ``str``...)."""
    return type(value).__name__


def dedupe(issues: Sequence[CatalogIssue]) -> list[CatalogIssue]:
    """``issues`` without repeats (first occurrence kept, order unchanged)."""
    seen: set[str] = set()
    out = []
    for issue in issues:
        key = json.dumps([issue.key, issue.expected, repr(issue.got), issue.scenario,
                          issue.note])
        if key not in seen:
            seen.add(key)
            out.append(issue)
    return out
