"""How a scenario is run (:class:`RunOptions`): light on purpose, so that the command
that builds the jobs (``hwyeval run``'s parent process) need not import the runner and
the simulation stack behind it."""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["RunOptions"]


@dataclass(frozen=True)
class RunOptions:
    """How to run: Rerun log on/off, the catalog's name (for logs), the wall-clock budget
    ``timeout_s`` [s] (None: none), and what produced the result, to record for
    ``--resume``: the scenario's content hash
    (:func:`suite.run.info.scenario_content_sha256`), the hash of hwyeval's sources and
    of a plug-in controller's (:mod:`suite.run.code_identity`); '' where not computed."""

    write_rrd: bool = True
    catalog_name: str = ""
    timeout_s: float | None = None
    content_sha256: str = ""
    code_sha256: str = ""
    controller_sha256: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.write_rrd, bool):
            raise TypeError(f"RunOptions.write_rrd: expected a bool, got {self.write_rrd!r}")
        if self.timeout_s is not None and (
                isinstance(self.timeout_s, bool) or not isinstance(self.timeout_s, int | float)
                or not math.isfinite(self.timeout_s) or self.timeout_s <= 0):
            raise ValueError(f"RunOptions.timeout_s: expected a finite number of seconds > 0 "
                             f"or None, got {self.timeout_s!r}")
