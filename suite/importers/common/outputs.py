"""What one importer writes into its output folder: the description that the shared
guards (:mod:`~suite.importers.common.out_guard`) and the catalog writer
(:mod:`~suite.importers.common.catalog`) are parametrised by."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Outputs"]


@dataclass(frozen=True)
class Outputs:
    """``command``: the format's name (``hwyeval import <command>``); ``input_suffix``:
    its inputs' (an input ``<stem><input_suffix>``); ``per_input``: the suffixes of the
    files an input ``<stem>`` writes (``<stem>`` + each, moved into the folder in that
    order: the scenario file last); ``shared``: the suffixes of the files several inputs
    may share (OpenSCENARIO's road, ``<road>`` + each); ``doc``: the page that explains
    the import; ``header``: the first lines of ``catalog.toml``'s comment;
    ``fallback_name``: the scenario name of a stem without a letter or digit;
    ``requires``: a scenario table lacking this key is not listed in the catalog."""

    command: str
    input_suffix: str
    per_input: tuple[str, ...]
    doc: str
    header: tuple[str, ...]
    fallback_name: str
    shared: tuple[str, ...] = ()
    requires: str | None = None

    @property
    def own_suffixes(self) -> tuple[str, ...]:
        """Every suffix of a file the import writes (besides ``catalog.toml``)."""
        return (*self.per_input, *self.shared)
