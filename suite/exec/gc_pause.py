"""The first module of the forkserver's preload (:data:`suite.exec.forkserver.PRELOAD`):
it pauses Python's cyclic garbage collector while the preload imports. Its gen-2 passes
over the growing heap (three of them, each walking up to ~200 000 objects) cost 0.1-0.5 s
of a ~2.3 s preload that every catalog waits for before its first run (median of 11
alternating pairs: 2.14 s against 2.28 s; docs/performance.md). The preload's
last module, :mod:`suite.exec.warmup`, freezes what the preload made and resumes the
collector, so scenario processes collect as usual, without walking the preload.

Imported anywhere else it pauses that process's collector until :mod:`suite.exec.warmup`
is imported: only the preload lists it.
"""

from __future__ import annotations

import gc

gc.disable()
