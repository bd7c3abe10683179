"""suite.exec.prepare: importing the preparation's modules does nothing; only
``prepare_process()`` acts (the collector paused while it imports, then frozen and
resumed; pyarrow settled without pandas; the run's modules and kernels loaded), and only
once per process.

Each check runs in a fresh interpreter: this test process has imported and collected
whatever other tests did."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(script: str) -> dict[str, object]:
    res = subprocess.run([sys.executable, "-c", textwrap.dedent(script)], cwd=ROOT,
                         capture_output=True, text=True, timeout=300, check=False)
    assert res.returncode == 0, res.stderr[-3000:]
    got: dict[str, object] = json.loads(res.stdout.strip().splitlines()[-1])
    return got


@pytest.mark.slow
def test_importing_the_preparation_modules_does_nothing() -> None:
    got = _run("""
        import gc, json, sys
        import numpy as np
        import pyarrow as pa
        import suite.exec.arrow_without_pandas
        import suite.exec.forkserver
        import suite.exec.prepare
        import suite.exec.warmup
        import suite.exec.worker
        state = {"gc_enabled": gc.isenabled(), "frozen": gc.get_freeze_count(),
                 "prepared": suite.exec.prepare.is_prepared()}
        pa.array(np.zeros(1))  # unsettled: pyarrow's pandas check imports pandas
        state["pandas"] = "pandas" in sys.modules
        print(json.dumps(state))
    """)
    assert got == {"gc_enabled": True, "frozen": 0, "prepared": False, "pandas": True}


@pytest.mark.slow
def test_prepare_process_prepares_once() -> None:
    got = _run("""
        import gc, json, sys
        from suite.exec.prepare import IMPORTS, is_prepared, prepare_process

        collections = []
        gc.callbacks.append(lambda phase, info: collections.append(info["generation"])
                            if phase == "start" else None)
        prepare_process()
        during = list(collections)
        first = {"gc_enabled": gc.isenabled(), "frozen": gc.get_freeze_count(),
                 "prepared": is_prepared(), "collections": len(during),
                 "loaded": all(name in sys.modules for name in
                               (*IMPORTS, "suite.exec.warmup", "pyarrow.parquet"))}
        modules = set(sys.modules)
        prepare_process()  # a no-op
        second = {"frozen": gc.get_freeze_count(), "gc_enabled": gc.isenabled(),
                  "new_modules": sorted(set(sys.modules) - modules)}
        import numpy as np
        import pyarrow as pa
        pa.array(np.zeros(3))  # settled: no pandas
        print(json.dumps({"first": first, "second": second,
                          "pandas": "pandas" in sys.modules}))
    """)
    first = got["first"]
    assert isinstance(first, dict)
    assert first["gc_enabled"] and first["prepared"] and first["loaded"], first
    assert first["collections"] == 0, "the collector ran while the preparation imported"
    assert first["frozen"] > 50_000, f"only {first['frozen']} objects frozen"
    assert got["second"] == {"frozen": first["frozen"], "gc_enabled": True,
                             "new_modules": []}
    assert got["pandas"] is False
