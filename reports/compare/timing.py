"""The timing side of a comparison, catalog-wide: one line per timing metric.

Per-run timing ratios are noisy (a neighbour's compile job doubles one run's p99);
a real slowdown of the code moves the whole catalog. For each timing metric with a
ratio limit, over the matched runs where both sides measured it (above the floor):
the median ratio r̃ = median(new/base) (base/new where higher is better), its range,
and how many runs exceeded the limit. The machine's load per core on each side
(``manifest.json``) says whether the two sides are comparable at all: a side that ran
above :data:`BUSY_LOAD` or loads that differ by more than :data:`LOAD_GAP` make every
timing finding "machine noise likely".
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence
from dataclasses import dataclass

from reports.compare.findings import timing_ratio
from reports.compare.tolerances import Tolerances
from reports.provenance import Provenance
from reports.tables import RunEntry

BUSY_LOAD = 0.8  # load per core above which timing is not trusted
LOAD_GAP = 0.3  # a difference of load per core beyond which two sides are not comparable


@dataclass(frozen=True)
class TimingLine:
    """One timing metric over the matched runs: ratios > 1 are slower."""

    metric: str
    unit: str
    runs: int
    median_ratio: float
    min_ratio: float
    max_ratio: float
    over_limit: int
    limit: float
    gate: bool

    @property
    def slower(self) -> bool:
        """The catalog as a whole is slower beyond the limit (the median run)."""
        return self.median_ratio > self.limit


def timing_lines(pairs: Sequence[tuple[RunEntry, RunEntry]], tol: Tolerances
                 ) -> list[TimingLine]:
    """A :class:`TimingLine` per metric of ``tol.timing`` measured in some pair."""
    out = []
    for metric, limit in tol.timing.items():
        ratios: list[float] = []
        unit = ""
        for b, n in pairs:
            if b.status not in ("pass", "fail") or n.status not in ("pass", "fail"):
                continue
            mb = b.verdict.metric(metric) if b.verdict is not None else None
            mn = n.verdict.metric(metric) if n.verdict is not None else None
            if mb is None or mn is None:
                continue
            if mn.unit == "ms" and max(mb.value, mn.value) < tol.timing_floor_ms:
                continue
            ratio = timing_ratio(mb, mn)
            if math.isfinite(ratio):
                ratios.append(ratio)
                unit = mn.unit
        if not ratios:
            continue
        median = statistics.median(ratios)
        out.append(TimingLine(metric, unit, len(ratios), median, min(ratios), max(ratios),
                              sum(r > limit for r in ratios), limit,
                              tol.timing_gate and median > limit))
    return out


def load_note(base: Provenance | None, new: Provenance | None) -> str:
    """Why timing of these two sides may not be comparable ('' when it looks fine)."""
    if base is None or new is None:
        return "load unknown (no manifest.json on one side)"
    lb, ln = base.load, new.load
    if not (math.isfinite(lb) and math.isfinite(ln)):
        return "load unknown"
    notes = []
    if max(lb, ln) > BUSY_LOAD:
        notes.append(f"busy machine (load per core: base {lb:.2f}, new {ln:.2f})")
    elif abs(lb - ln) > LOAD_GAP:
        notes.append(f"load per core differs: base {lb:.2f}, new {ln:.2f}")
    if base.host != new.host or base.cpu_model != new.cpu_model:
        notes.append(f"different machines ({base.host}: {base.cpu_model or '?'} vs "
                     f"{new.host}: {new.cpu_model or '?'})")
    return "; ".join(notes)
