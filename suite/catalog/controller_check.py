"""Controllers of a catalog: the ``controller`` value (a name, or a table with ``name`` and
options) becomes a :class:`ControllerSpec` once the name is registered and the registry
builds the controller with those options (once per distinct name and options)."""

from __future__ import annotations

import copy
import difflib
import json
from collections.abc import Iterable
from typing import Any

from suite.catalog import rules
from suite.catalog.errors import MISSING
from suite.catalog.report import Report
from suite.catalog.specs import ControllerSpec

__all__ = ["ControllerChecker"]


class ControllerChecker:
    """Checks controller names and options; caches per distinct (name, options)."""

    def __init__(self, known: Iterable[str] | None) -> None:
        self.explicit = known is not None
        self._cache: dict[str, list[tuple[str, str, Any]]] = {}
        self.registry_error: str | None = None
        if known is not None:
            self.known: list[str] = sorted(set(known))
        else:
            try:
                from controllers import registry
                self.known = list(registry.names())
            except Exception as exc:  # registry or builtins broken
                self.known = []
                self.registry_error = f"{type(exc).__name__}: {exc}"

    def check(self, name: str, options: dict[str, Any]) -> list[tuple[str, str, Any]]:
        """[] if fine, else every problem as (sub-key, expected, got)."""
        if name not in self.known:
            # A name near a built-in one is as likely a plug-in not loaded ("acc_keep"
            # is two edits from "lane_keep"): the --plugin hint always comes first.
            close = difflib.get_close_matches(name, self.known, n=1)
            hint = ("; a plug-in controller needs --plugin FILE.py (or MODULE) or an "
                    "installed entry point: forgot --plugin?"
                    + (f" Or did you mean {close[0]!r}?" if close else ""))
            return [("name", f"a registered controller, one of {self.known}{hint}", name)]
        cache_key = json.dumps([name, options], sort_keys=True, default=repr)
        if cache_key in self._cache:
            return self._cache[cache_key]
        result = self._build(name, options)
        self._cache[cache_key] = result
        return result

    def _build(self, name: str, options: dict[str, Any]) -> list[tuple[str, str, Any]]:
        try:
            from controllers import registry
            from controllers.protocol import ConfigError
        except Exception:
            return []  # only reachable with explicit known_controllers
        if self.explicit:
            try:
                available = registry.names()
            except Exception:
                return []  # registry unavailable: explicit known_controllers only
            if name not in available:
                return []
        try:
            registry.make(name, copy.deepcopy(options))
        except ConfigError as exc:
            return [(_sub_key(e.key), e.expected, e.got) for e in exc.all]
        except Exception as exc:
            return [("name", f"a controller that can be built ({type(exc).__name__}: {exc})",
                     name)]
        return []


    def spec(self, raw: Any, report: Report) -> ControllerSpec | None:
        """The checked spec of a scenario's ``controller`` value; None (reported) if bad."""
        if raw is MISSING:
            return None
        parsed = _name_and_options(raw, report)
        if parsed is None:
            return None
        name, options = parsed
        if not self.known and self.registry_error:
            return ControllerSpec(name, options)  # registry problem reported once
        problems = self.check(name, options)
        for sub, expected, got in problems:
            report.add(f"controller.{sub}" if sub else "controller", expected, got)
        if problems:
            return None
        return ControllerSpec(name, options)


def _name_and_options(raw: Any, report: Report) -> tuple[str, dict[str, Any]] | None:
    """(name, options) of a ``controller`` value (a name, or a table with ``name`` and
    options); None (reported) unless it is one, the name a controller name and every
    option JSON-able."""
    options: dict[str, Any]
    if isinstance(raw, str):
        name, options = raw, {}
    elif isinstance(raw, dict):
        if "name" not in raw:
            report.add("controller.name", "a controller name in the controller table")
            return None
        name = raw["name"]
        options = {k: v for k, v in raw.items() if k != "name"}
    else:
        report.add("controller", "a controller name or a table {name = ..., <options>}",
                   raw)
        return None
    if not isinstance(name, str) or rules.name_rule(name):
        report.add("controller.name", "a controller name matching [a-z0-9_]+", name)
        return None
    bad = rules.non_json_path(options)
    if bad is not None:
        report.add(f"controller.{bad[0]}", "a JSON-able value (string, number, bool, "
                   "list, table)", bad[1])
        return None
    return name, options


def _sub_key(key: str) -> str:
    """A ConfigError's dotted key below the scenario's ``controller``."""
    if key == "controller":
        return ""
    return key[len("controller."):] if key.startswith("controller.") else key
