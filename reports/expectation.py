"""Known failures: a scenario's ``xfail`` (docs/catalog.md) as the reports read it.

A catalog marks a scenario ``xfail = { reason = "...", strict = true }`` with pytest's
meaning: the scenario is expected to fail (its verdict ``fail``: a criterion not met).

* it fails: an **expected failure** (:data:`XFAILED`): reported apart (JUnit
  ``<skipped>`` with the reason, its own section of report.html, its own colour in the
  history) and it does not fail the night;
* it passes: an **unexpected pass** (:data:`XPASSED`), "fixed: remove the xfail";
  with ``strict = true`` it fails the night (``run``'s exit 1, a gating ``compare``
  finding), without it is reported and does not;
* it ends ``error`` or ``timeout``: not the failure that was expected, an error as
  any other.

The mark is recorded in the run's ``run.json`` (``info.scenario_spec.xfail``, the
resolved scenario), so every reader of a run directory sees the expectation it ran
under.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

__all__ = ["XFAILED", "XFAIL_KEY", "XPASSED", "Xfail", "expectation", "fails_night",
           "xfail_of"]

XFAIL_KEY = "xfail"  # the Scenario field (and scenario_spec key)
XFAILED = "xfail"  # an expected failure
XPASSED = "xpass"  # an unexpected pass


@dataclass(frozen=True)
class Xfail:
    """A known failure: why it is expected (non-empty), and whether an unexpected pass
    fails the night (``strict``)."""

    reason: str
    strict: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.reason, str) or not self.reason.strip():
            raise ValueError(f"Xfail.reason: expected a non-empty string, got {self.reason!r}")
        if not isinstance(self.strict, bool):
            raise ValueError(f"Xfail.strict: expected a bool, got {self.strict!r}")

    @property
    def text(self) -> str:
        return f"xfail{' (strict)' if self.strict else ''}: {self.reason}"


def xfail_of(spec: Mapping[str, Any] | None) -> Xfail | None:
    """The mark of a recorded scenario (``RunInfo.scenario_spec``), None when it has
    none or it cannot be read (a hand-edited file: the run is then judged as any)."""
    raw = (spec or {}).get(XFAIL_KEY)
    if not isinstance(raw, Mapping):
        return None
    try:
        return Xfail(reason=raw.get("reason", ""), strict=raw.get("strict", False))
    except ValueError:
        return None


def expectation(status: str, xfail: Xfail | None) -> str:
    """:data:`XFAILED`, :data:`XPASSED` or '' (no mark, or an error/timeout)."""
    if xfail is None:
        return ""
    return {"fail": XFAILED, "pass": XPASSED}.get(status, "")


def fails_night(status: str, xfail: Xfail | None) -> bool:
    """Whether this run makes the night fail: a run that did not pass, unless it is the
    expected failure; a strict mark's unexpected pass."""
    seen = expectation(status, xfail)
    if seen == XFAILED:
        return False
    if seen == XPASSED:
        return xfail is not None and xfail.strict
    return status != "pass"
