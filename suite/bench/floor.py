"""The floor under the 50x target: how fast the target command could be if the loop's
Python between the compiled parts took no time at all.

Measured in one fresh interpreter (:func:`floor_study` runs
:mod:`suite.bench.floor_probe` there), as the command's processes do it:

* ``third_party_import_s``: importing the third-party modules the scenario processes need
  (numpy, numba, libsumo, Rerun, pyarrow's parquet, the parts of scipy used, sumolib)
  before anything else: what no change to this project's code removes;
* then the scenario processes' preload (:func:`suite.exec.prepare.prepare_process`, the
  collector frozen as in the forkserver; ``preload_s``, after the third-party imports)
  and each run of the catalog in a child forked from it, with three timers: ``loop_s``
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
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]

# The measuring process, a script run in a fresh interpreter (its docstring says why not
# with ``python -m``).
PROBE = Path(__file__).resolve().with_name("floor_probe.py")

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
    proc = subprocess.run([sys.executable, str(PROBE), str(catalog), str(out)], cwd=ROOT,
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
