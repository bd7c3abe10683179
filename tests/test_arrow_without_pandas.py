"""suite.exec.arrow_without_pandas: after ``settle_pyarrow_without_pandas()`` (which
``prepare_process()`` calls), pyarrow converts numpy arrays without importing pandas, and
code that imports pandas itself still converts both ways; importing the module alone
changes nothing.

Each check runs in a fresh interpreter (this test process may have pandas loaded)."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SCRIPT = """
import sys
import numpy as np
import pyarrow as pa
from suite.exec.arrow_without_pandas import settle_pyarrow_without_pandas
settle_pyarrow_without_pandas()
settle_pyarrow_without_pandas()  # again: a no-op
assert "pandas" not in sys.modules, "settling imported pandas"
a = pa.array(np.arange(3.0))
s = pa.array(np.array(["x", "yz"], dtype=np.str_))
assert (a.type, s.type) == (pa.float64(), pa.string())
assert "pandas" not in sys.modules, "a numpy conversion imported pandas"
import pandas as pd
frame = pa.table({"v": a}).to_pandas()
assert frame["v"].tolist() == [0.0, 1.0, 2.0]
assert pa.array(pd.Series([1.5, None])).to_pylist() == [1.5, None]
print("ok")
"""


def _run(script: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", textwrap.dedent(script)], cwd=ROOT,
                          capture_output=True, text=True, timeout=120, check=False)


def test_numpy_conversions_skip_pandas_and_pandas_still_converts() -> None:
    res = _run(SCRIPT)
    assert res.returncode == 0 and res.stdout.strip() == "ok", res.stderr[-2000:]


def test_a_python_string_would_import_pandas() -> None:
    """Why the Rerun log passes numpy strings: pyarrow imports pandas for a Python
    object (``pa.scalar``), whatever this module did; if this ever stops being true the
    workaround in suite.rerun.log can go."""
    res = _run("""
        import sys
        import pyarrow as pa
        from suite.exec.arrow_without_pandas import settle_pyarrow_without_pandas
        settle_pyarrow_without_pandas()
        pa.scalar("x")
        print("pandas" in sys.modules)
    """)
    assert res.returncode == 0, res.stderr[-2000:]
    assert res.stdout.strip() == "True"


def test_importing_the_module_settles_nothing() -> None:
    """Only the call settles pyarrow: after a bare import, pyarrow's first numpy
    conversion still imports pandas as it would without hwyeval."""
    res = _run("""
        import sys
        import numpy as np
        import pyarrow as pa
        import suite.exec.arrow_without_pandas  # noqa: F401
        assert "pandas" not in sys.modules
        pa.array(np.zeros(1))
        print("pandas" in sys.modules)
    """)
    assert res.returncode == 0, res.stderr[-2000:]
    assert res.stdout.strip() == "True"
