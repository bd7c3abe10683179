"""How a problem of one scenario (variant) becomes a :class:`CatalogIssue`.

The key is prefixed with ``scenario[i]``; the note says where the bad value came from:
``value from scenario[i].sweep."<key>"`` (under the variant's name) for a swept value,
``all sweep variants`` (under the family name, once: the loader dedupes) for a problem a
sweep did not cause, ``value from [defaults]`` for an inherited value.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Set
from typing import Any

from suite.catalog.errors import MISSING, IssueCollector

__all__ = ["Report"]


class Report:
    """Adds the problems of the scenario ``name`` (of ``family``) from ``scenario[index]``."""

    def __init__(self, err: IssueCollector, index: int, name: str, family: str,
                 swept: Mapping[str, Any], own_keys: Set[str], *,
                 name_reported: bool = False) -> None:
        self.err = err
        self.where = f"scenario[{index}]"
        self.name = name
        self.family = family
        self.swept = swept
        self.own_keys = own_keys
        # The loader reported a missing or invalid name already: the label standing in
        # for it ('scenario[i]') is not a second problem.
        self.name_reported = name_reported

    def add(self, key: str, expected: str, got: Any = MISSING) -> None:
        """One problem at ``key`` (dotted within the scenario; ``""`` = the scenario)."""
        if key in ("name", "family") and self.name_reported:
            return
        where = self.where
        full = f"{where}.{key}" if key else where
        from_sweep = [sk for sk in self.swept if key == sk or key.startswith(sk + ".")]
        if from_sweep:
            note = f"value from {where}.sweep.{json.dumps(from_sweep[0])}"
            self.err.add(full, expected, got, self.name, note)
        elif self.swept:  # not caused by the sweep: reported once per family (dedupe)
            self.err.add(full, expected, got, self.family, "all sweep variants")
        else:
            top = key.split(".", 1)[0]
            note = "value from [defaults]" if top and top not in self.own_keys else ""
            self.err.add(full, expected, got, self.name, note)
