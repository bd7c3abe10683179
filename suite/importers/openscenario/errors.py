"""The OpenSCENARIO importer's one error: which file, which element, which line, why."""

from __future__ import annotations

from typing import Any

__all__ = ["OscImportError", "fail_at"]


class OscImportError(ValueError):
    """A file that cannot be imported: ``path``, ``element`` (an XML tag, a parameter),
    ``line`` (the element's source line, 0 unknown) and ``reason``. The CLI exits 2 with
    this message."""

    def __init__(self, path: str, element: str, reason: str, line: int = 0) -> None:
        self.path = str(path)
        self.element = element
        self.reason = reason
        self.line = int(line or 0)
        where = f"{path}:{self.line}" if self.line else str(path)
        super().__init__(f"{where}: <{element}>: {reason}" if not element.startswith("parameter")
                         else f"{where}: {element}: {reason}")


def fail_at(el: Any, reason: str) -> OscImportError:
    """The error for lxml element ``el`` (file from its document, its tag and line;
    None: an element not known)."""
    if el is None:
        return OscImportError("?", "?", reason)
    doc = el.getroottree().docinfo.URL if hasattr(el, "getroottree") else ""
    return OscImportError(doc or "?", str(el.tag), reason, int(el.sourceline or 0))
