""":func:`settle_pyarrow_without_pandas`: pyarrow settles whether pandas is there without
importing pandas, so that scenario processes never import it (0.25-0.3 s of a preload
every catalog waits for; nothing in a run uses pandas: the run's files go to pyarrow
directly, the reports read them in the parent). Called by
:func:`suite.exec.prepare.prepare_process` in the process scenario processes are forked
from; importing this module does nothing.

Why it is needed: pyarrow imports pandas, when it is installed, the first time
``pa.array`` is given a numpy array (its check whether the array is a pandas object),
and Rerun's logging makes that call. :func:`settle_pyarrow_without_pandas` makes that
first call with the import of pandas refused (an :class:`ImportError`, which pyarrow
catches), so later numpy conversions go straight on. A Python object (``pa.scalar``,
``pa.array`` of a list) still tries ``import pandas`` every time until it succeeds: what
scenario processes log goes as numpy arrays (``suite.rerun.log._text``), and
``tests/test_warmup_coverage.py`` fails if a run imports pandas. Nothing is lost: code in
the same process that imports pandas itself afterwards (a user's plugin, say) still
converts both ways (``Table.to_pandas``, ``pa.array`` of a Series;
``tests/test_arrow_without_pandas.py``).
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import sys
from collections.abc import Sequence
from types import ModuleType

import numpy as np
import pyarrow as pa

__all__ = ["settle_pyarrow_without_pandas"]


class _RefusePandas(importlib.abc.MetaPathFinder):
    """A finder that refuses ``import pandas`` (and nothing else)."""

    def find_spec(self, fullname: str, path: Sequence[str] | None,
                  target: ModuleType | None = None) -> importlib.machinery.ModuleSpec | None:
        if fullname == "pandas":
            raise ImportError("pandas is not imported in scenario processes "
                              "(suite.exec.arrow_without_pandas)")
        return None


def settle_pyarrow_without_pandas() -> None:
    """Make pyarrow's first pandas check with ``import pandas`` refused; a no-op where
    pandas is imported already."""
    if "pandas" in sys.modules:
        return
    finder = _RefusePandas()
    sys.meta_path.insert(0, finder)
    try:
        pa.array(np.zeros(1))
    finally:
        sys.meta_path.remove(finder)
