"""Where a run failed, as marks on its bird's-eye view and time series.

Every mark comes from the stored verdict: a failure's ``step`` is the trace row where
its criterion was violated (the metrics located it when they judged the run); an
error or timeout is marked at the last recorded row.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from reports.charts import fmt
from reports.metrics.catalogue import CATALOGUE
from reports.tables import RunEntry

# metric -> colour of its failure mark: the catalogue's ``mark`` role
MARK_COLOURS = {s.name: s.mark for s in CATALOGUE if s.mark}
DEFAULT_MARK_COLOUR = "#9333ea"
END_MARK_COLOUR = "#7c3aed"


@dataclass(frozen=True)
class Mark:
    """A labelled trace row drawn on the run's plots."""

    label: str
    row: int
    colour: str

    @property
    def name(self) -> str:
        """The label without its time ('min_ttc_s at t=3 s' -> 'min_ttc_s')."""
        return self.label.split(" at ", 1)[0]


def failure_marks(run: RunEntry) -> list[Mark]:
    """A mark per located failure (criteria order), then one for an error/timeout end."""
    rec = run.record
    n = len(rec.trace) if rec is not None else 0
    if rec is None or n == 0:
        return []
    marks = []
    for f in run.failures:
        if f.step is None or not 0 <= f.step < n:
            continue
        when = f.t_s if f.t_s is not None else math.nan
        marks.append(Mark(f"{f.metric} at t={fmt(when, 4)} s", f.step,
                          MARK_COLOURS.get(f.metric, DEFAULT_MARK_COLOUR)))
    if run.status in ("error", "timeout"):
        marks.append(Mark(f"{run.status} at t={fmt(rec.trace.t_s[-1], 4)} s", n - 1,
                          END_MARK_COLOUR))
    return marks
