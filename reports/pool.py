"""Per-step times pooled over many runs in fixed memory: log-spaced histograms.

A report of thousands of runs cannot keep every run's trace; it streams them and adds
each run's per-step times [s] to a :class:`TimePool` per group and loop. Bins are
log-spaced, :data:`BINS_PER_DECADE` per decade from :data:`LO_S` to :data:`HI_S` (one
underflow and one overflow bin), so a percentile read back is within a factor
10^(1/BINS_PER_DECADE) ≈ 1.2 % of the exact one; it is the geometric centre of the bin
holding it. Memory: a few kB per pool, whatever the number of runs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

LO_S = 1e-7
HI_S = 1e2
BINS_PER_DECADE = 200
N_BINS = int(round(math.log10(HI_S / LO_S) * BINS_PER_DECADE))
EDGES_S = LO_S * 10 ** (np.arange(N_BINS + 1) / BINS_PER_DECADE)
CENTRES_S = np.sqrt(EDGES_S[:-1] * EDGES_S[1:])


def _counts() -> np.ndarray:
    return np.zeros(N_BINS + 2, dtype=np.int64)


@dataclass
class TimePool:
    """Counts of per-step times [s] in log bins (index 0: below LO_S, last: above HI_S)."""

    counts: np.ndarray = field(default_factory=_counts)

    @property
    def n(self) -> int:
        return int(self.counts.sum())

    def add(self, times_s: np.ndarray) -> None:
        """Add finite samples [s]."""
        t = np.asarray(times_s, dtype=np.float64)
        t = t[np.isfinite(t)]
        if t.size:
            idx = np.searchsorted(EDGES_S, t, side="right")
            self.counts += np.bincount(idx, minlength=N_BINS + 2)

    def percentile(self, q: float) -> float:
        """The q-th percentile [s] (NaN when empty), to the bin (module doc)."""
        total = self.n
        if total == 0:
            return math.nan
        rank = q / 100.0 * (total - 1)
        k = int(np.searchsorted(np.cumsum(self.counts), rank, side="right"))
        if k == 0:
            return LO_S
        if k > N_BINS:
            return HI_S
        return float(CENTRES_S[k - 1])

    def cdf(self) -> tuple[np.ndarray, np.ndarray]:
        """(time [s], fraction ≤ it) at the occupied bins' upper edges."""
        occupied = np.flatnonzero(self.counts[1:-1])
        if occupied.size == 0 or self.n == 0:
            return np.zeros(0), np.zeros(0)
        cum = np.cumsum(self.counts)[1:-1]
        return EDGES_S[occupied + 1], cum[occupied] / self.n
