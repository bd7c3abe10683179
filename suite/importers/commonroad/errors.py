"""The importer's errors: :class:`ImportFailure` (which file, which element: lanelet /
obstacle id, XML tag, and what was wrong) and :class:`OutputRefused` (the command as a
whole: the output folder or the inputs' names; nothing was written)."""

from __future__ import annotations

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


class OutputRefused(ValueError):
    """The import would overwrite what it did not write, or two inputs would write the
    same outputs (:mod:`~suite.importers.commonroad.out_guard`): refused before any file
    is written (the CLI exits 2 with this message)."""
