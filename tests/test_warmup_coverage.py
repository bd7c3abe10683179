"""The forkserver's preload (suite.exec.prepare.prepare_process, with the kernels of
suite.exec.warmup) leaves nothing for a scenario process to load: after it, running
scenarios loads no numba kernel from the on-disk cache (each load is 5-25 ms of every
run: ``_gamma_many`` alone was 20 ms of each run until the warm-up called it) and imports
no heavy module; and the processes it forks find the
preload's objects frozen for the garbage collector.

Run in a fresh interpreter (this test process has loaded kernels already), on real
SUMO: a two-loop run with traffic and a stalled car, logs on, and a lane-keeping run.
"""

from __future__ import annotations

import json
import multiprocessing as mp
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import pytest

from suite.exec.forkserver import PRELOAD

pytestmark = pytest.mark.sumo

ROOT = Path(__file__).resolve().parents[1]

CATALOG = """
[defaults]
duration_s = 2.0
step_s = 0.02

[[scenario]]
name = "two_loop_stall"
net = "straight_3lane"
controller = "two_loop"
ego = { lane = 1, pos_m = 100.0, speed_mps = 25.0 }
stalled = [ { lane = 1, pos_m = 160.0 } ]
traffic = { vehicles_per_hour = 2400, seed = 3 }

[[scenario]]
name = "lane_keep_free"
net = "straight_2lane"
controller = "lane_keep"
ego = { lane = 0, pos_m = 100.0, speed_mps = 25.0 }
traffic = { vehicles_per_hour = 1200, seed = 4 }
"""

SCRIPT = """
import json, sys
from pathlib import Path
from suite.exec.prepare import prepare_process
prepare_process()
import numba.core.caching as caching
from suite.catalog import load_catalog
from suite.run.runner import RunOptions, run_scenario

loads = []
original = caching.Cache.load_overload

def counting(self, sig, target_context):
    loads.append(getattr(self, "_name", str(self)))
    return original(self, sig, target_context)

caching.Cache.load_overload = counting
before = set(sys.modules)
statuses = []
for scenario in load_catalog(Path({catalog!r})).scenarios:
    statuses.append(run_scenario(scenario, Path({out!r}), RunOptions()).status)
print(json.dumps({{"loads": loads, "statuses": statuses,
                   "modules": sorted(set(sys.modules) - before)}}))
"""


@pytest.mark.slow
def test_a_scenario_after_the_preload_loads_no_kernel(tmp_path: Path) -> None:
    catalog = tmp_path / "c.toml"
    catalog.write_text(CATALOG)
    script = SCRIPT.format(catalog=str(catalog), out=str(tmp_path / "o"))
    res = subprocess.run([sys.executable, "-c", textwrap.dedent(script)], cwd=ROOT,
                         capture_output=True, text=True, timeout=300, check=False)
    assert res.returncode == 0, res.stderr[-3000:]
    got = json.loads(res.stdout.strip().splitlines()[-1])
    assert got["statuses"] == ["pass", "pass"]
    assert got["loads"] == [], f"kernels the warm-up does not load: {got['loads']}"
    heavy = [m for m in got["modules"] if m.split(".")[0] in
             {"scipy", "pandas", "rerun", "numba", "libsumo", "pyarrow", "sumolib"}
             and m not in {"pyarrow.pandas_compat", "pyarrow.vendored.version"}]
    assert heavy == [], f"modules every run imports on its own: {heavy}"


def _freeze_count(conn: Any) -> None:
    import gc

    conn.send((gc.get_freeze_count(), gc.isenabled()))
    conn.close()


def test_scenario_processes_inherit_a_frozen_preload() -> None:
    """A process forked by a forkserver with the preload finds the preload's objects
    frozen (its collections skip them: a gen-2 pass over them was ~190 ms of every 40 s
    run) and the collector running (paused while the preload imported)."""
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(list(PRELOAD))
    ours, theirs = ctx.Pipe()
    proc = ctx.Process(target=_freeze_count, args=(theirs,))
    proc.start()
    frozen, enabled = ours.recv()
    proc.join(60)
    assert proc.exitcode == 0
    assert frozen > 50_000, f"only {frozen} objects frozen"
    assert enabled  # paused while prepare_process() imported, resumed after
