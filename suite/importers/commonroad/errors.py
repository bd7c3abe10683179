"""The importer's errors: :class:`ImportFailure` (which file, which element: lanelet /
obstacle id, XML tag, and what was wrong) and :class:`OutputRefused` (the command as a
whole: the output folder or the inputs' names; nothing was written), shared by every
importer (:mod:`suite.importers.common.errors`)."""

from __future__ import annotations

from suite.importers.common.errors import OutputRefused

__all__ = ["ImportFailure", "OutputRefused"]


class ImportFailure(ValueError):
    """A CommonRoad file cannot be imported. ``path`` names the file, ``element`` the
    element of it (``lanelet 12``, ``obstacle 301``, ``planningProblem``, ``XML line 7``)
    and ``reason`` what was wrong (the CLI exits 2 with this message)."""

    def __init__(self, path: str, element: str, reason: str) -> None:
        self.path = str(path)
        self.element = element
        self.reason = reason
        super().__init__(f"{path}: {element}: {reason}")
