"""The floor under the 50x target: how fast the target command could be if the loop's
Python between the compiled parts took no time at all.

Measured in one fresh interpreter (:func:`floor_study`), as the command's processes do
it:

* ``third_party_import_s``: importing the third-party modules the scenario processes need
  (numpy, numba, libsumo, Rerun, pyarrow's parquet, the parts of scipy used, sumolib)
  before anything else: what no change to this project's code removes;
* then the scenario processes' preload (:data:`suite.exec.forkserver.PRELOAD`, frozen as
  the forkserver freezes it; ``preload_s``, after the third-party imports) and each run
  of the catalog in a child forked from it, with three timers: ``loop_s``
  (:func:`suite.run.loop.run_loop`), ``kernel_s`` (inside the C/GMRES continuation
  kernel calls, ``CgmresOuter._continue``) and ``sumo_s`` (SUMO's own step with its
  collision query, ``SumoWorld._advance``), and ``run_s`` (the whole
  :func:`suite.run.runner.run_scenario`: build, loop, judging, files, Rerun log).

``glue_s = loop_s - kernel_s - sumo_s`` is the Python between them (per control step:
``glue_per_step_us``, issue 25's target): the behaviour, the
controller's own code, the plant's and the world's adapters, the recorder.
:func:`bound` takes a measured command (``hwyeval bench``'s ``commands`` part) and
subtracts every run's glue: the whole command's wall time with a loop that were all
compiled, and its real-time factor. The timers are wrappers (a few hundred ns a call, a
few thousand calls a run): they slow what they measure slightly, so the bound is a
little optimistic.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]

THIRD_PARTY = ("numpy", "numba", "libsumo", "rerun", "pyarrow.parquet", "scipy.linalg",
               "scipy.sparse", "scipy.ndimage", "scipy.spatial", "sumolib")

_SCRIPT = """
import importlib, json, os, time
t0 = time.perf_counter()
for name in {third_party!r}:
    importlib.import_module(name)
third_party_s = time.perf_counter() - t0
import gc
t0 = time.perf_counter()
from suite.exec.forkserver import PRELOAD
for name in PRELOAD:
    importlib.import_module(name)
gc.freeze()
preload_s = time.perf_counter() - t0
from pathlib import Path
import controllers.two_loop.outer.cgmres as cgmres
import suite.run.runner as runner
import suite.world.sumo as sumo
from suite.catalog import load_catalog

acc = {{"kernel_s": 0.0, "sumo_s": 0.0, "loop_s": 0.0}}

def timed(fn, key):
    def wrapper(*args, **kwargs):
        t = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            acc[key] += time.perf_counter() - t
    return wrapper

cgmres.CgmresOuter._continue = timed(cgmres.CgmresOuter._continue, "kernel_s")
sumo.SumoWorld._advance = timed(sumo.SumoWorld._advance, "sumo_s")
runner.run_loop = timed(runner.run_loop, "loop_s")
runs = []
for k, scenario in enumerate(load_catalog(Path({catalog!r})).scenarios):
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(read)
        t = time.perf_counter()
        record = runner.run_scenario(scenario, Path({out!r}) / str(k), runner.RunOptions())
        row = dict(acc, run_s=time.perf_counter() - t, scenario=scenario.name,
                   status=record.status, steps=record.outcome.steps)
        os.write(write, json.dumps(row).encode())
        os._exit(0)
    os.close(write)
    chunks = []
    while True:
        chunk = os.read(read, 65536)
        if not chunk:
            break
        chunks.append(chunk)
    os.close(read)
    os.waitpid(pid, 0)
    runs.append(json.loads(b"".join(chunks)))
print(json.dumps({{"third_party_import_s": third_party_s, "preload_s": preload_s,
                  "runs": runs}}))
"""


@dataclass(frozen=True)
class FloorRun:
    """One run's times [s]: the whole run, its loop, the C/GMRES kernel and SUMO's step
    inside the loop; ``glue_s`` the rest of the loop; ``steps`` its control steps."""

    scenario: str
    status: str
    run_s: float
    loop_s: float
    kernel_s: float
    sumo_s: float
    steps: int = 0

    def __post_init__(self) -> None:
        if min(self.run_s, self.loop_s, self.kernel_s, self.sumo_s) < 0:
            raise ValueError(f"{self.scenario}: negative time")
        if self.steps < 0:
            raise ValueError(f"{self.scenario}: steps must be >= 0, got {self.steps}")
        if self.kernel_s + self.sumo_s > self.loop_s + 1e-9 or self.loop_s > self.run_s + 1e-9:
            raise ValueError(f"{self.scenario}: kernel + SUMO ({self.kernel_s + self.sumo_s} s) "
                             f"must fit in the loop ({self.loop_s} s), the loop in the run "
                             f"({self.run_s} s)")

    @property
    def glue_s(self) -> float:
        return self.loop_s - self.kernel_s - self.sumo_s

    @property
    def glue_per_step_us(self) -> float:
        """The Python between SUMO's step and the kernel per control step [us]."""
        return self.glue_s / self.steps * 1e6 if self.steps else float("nan")


def glue_per_step_us(runs: list[FloorRun]) -> float:
    """The runs' glue over their steps [us per control step] (NaN without steps)."""
    steps = sum(r.steps for r in runs)
    return sum(r.glue_s for r in runs) / steps * 1e6 if steps else float("nan")


def floor_study(catalog: Path, out: Path) -> dict[str, Any]:
    """Run ``catalog`` as described in the module docstring, into ``out`` (fresh)."""
    if out.exists():
        raise FileExistsError(f"{out} exists: the floor study runs into a fresh folder")
    script = _SCRIPT.format(third_party=THIRD_PARTY, catalog=str(catalog), out=str(out))
    proc = subprocess.run([sys.executable, "-c", textwrap.dedent(script)], cwd=ROOT,
                          capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"the floor study failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    doc = json.loads(proc.stdout.strip().splitlines()[-1])
    runs = [FloorRun(**row) for row in doc["runs"]]
    return {"third_party_import_s": float(doc["third_party_import_s"]),
            "preload_s": float(doc["preload_s"]),
            "glue_per_step_us": glue_per_step_us(runs),
            "runs": [{**r.__dict__, "glue_s": r.glue_s, "glue_per_step_us": r.glue_per_step_us}
                     for r in runs]}


def bound(floor: dict[str, Any], command: dict[str, Any]) -> dict[str, float]:
    """The measured ``command`` (a ``CommandTiming.as_dict()`` of the same catalog) with
    every run's glue taken out (the floor study's mean glue per run times the command's
    runs): ``wall_s`` [s], ``realtime_factor``, and the ``glue_share`` of the command."""
    runs = floor["runs"]
    if not runs or not command["runs"]:
        raise ValueError("no runs to bound")
    glue = sum(r["glue_s"] for r in runs) / len(runs) * len(command["runs"])
    wall = command["wall_s"] - glue
    if wall <= 0:
        raise ValueError(f"the glue ({glue:.2f} s) exceeds the command ({command['wall_s']} s)")
    return {"wall_s": wall, "realtime_factor": command["sim_s"] / wall,
            "glue_share": glue / command["wall_s"]}
