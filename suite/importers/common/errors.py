"""The error of the import as a whole, before anything is written."""

from __future__ import annotations

__all__ = ["OutputRefused"]


class OutputRefused(ValueError):
    """The import would overwrite what it did not write, or two inputs would write the
    same outputs (:mod:`~suite.importers.common.out_guard`): refused before any file
    is written (the CLI exits 2 with this message)."""
