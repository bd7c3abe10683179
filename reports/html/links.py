"""Where the report's files are and how they link to each other (relative links only,
so a copied or served report directory keeps working).

``DEST/report.html`` is the index; each run has a page ``DEST/report-runs/<run>.html``
(a directory name no scenario can take: scenario names are ``[a-z0-9_]+``); the
pages share ``DEST/report-runs/report.css``. A run's Rerun log stays in its run
directory (``OUT/<run>/run.rrd``), linked relative to the page.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from reports.record import RRD

RUN_PAGES = "report-runs"
STYLE = "report.css"


def _safe(name: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in name)


@dataclass(frozen=True)
class Links:
    """Paths of one report: ``dest`` holds report.html, ``out`` the run directories."""

    dest: Path

    @property
    def pages(self) -> Path:
        return self.dest / RUN_PAGES

    def page_file(self, run_id: str) -> Path:
        return self.pages / f"{_safe(run_id)}.html"

    def page_href(self, run_id: str) -> str:
        """A run's page, from the index."""
        return f"{RUN_PAGES}/{_safe(run_id)}.html"

    def rrd_href(self, run_dir: Path, from_page: bool) -> str:
        """A run's .rrd, from the index or from its page."""
        base = self.pages if from_page else self.dest
        return os.path.relpath(Path(run_dir).absolute() / RRD, base.absolute())

    def dir_href(self, run_dir: Path, from_page: bool) -> str:
        base = self.pages if from_page else self.dest
        return os.path.relpath(Path(run_dir).absolute(), base.absolute()) + "/"
