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
controller's own code, the plant's and the world's adapters, the recorder. The probe
also times each of the loop's stages whole, so the glue splits by stage
(:data:`GLUE_STAGES`, :meth:`FloorRun.glue_by_stage_s`): the controller's own Python is
its step's time less the kernel's, the world's adapters the world's step less SUMO's.
:func:`bound` takes a measured command (``hwyeval bench``'s ``commands`` part) and
subtracts every run's glue: the whole command's wall time with a loop that were all
compiled, and its real-time factor. The timers are wrappers (a few hundred ns a call, a
few thousand calls a run): they slow what they measure slightly, so the bound is a
little optimistic.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from suite.bench.floor_probe import STAGE_KEYS

ROOT = Path(__file__).resolve().parents[2]

# The measuring process, a script run in a fresh interpreter (its docstring says why not
# with ``python -m``).
PROBE = Path(__file__).resolve().with_name("floor_probe.py")

@dataclass(frozen=True)
class FloorRun:
    """One run's times [s]: the whole run, its loop, the C/GMRES kernel and SUMO's step
    inside the loop; ``glue_s`` the rest of the loop; ``steps`` its control steps; and
    the loop's stages each timed whole (NaN: not timed): the behaviour (its decisions
    and the last decision moved on between them), the controller's step (the kernel
    inside), the ego dynamics (the world's step inside), the world's step (SUMO's step
    inside), the safety monitor, the recorder; ``wall_s`` the run's results.csv
    ``wall_s`` (its build and loop; NaN: not recorded)."""

    scenario: str
    status: str
    run_s: float
    loop_s: float
    kernel_s: float
    sumo_s: float
    steps: int = 0
    behaviour_s: float = math.nan
    controller_s: float = math.nan
    dynamics_s: float = math.nan
    world_s: float = math.nan
    monitor_s: float = math.nan
    recorder_s: float = math.nan
    wall_s: float = math.nan

    def __post_init__(self) -> None:
        if min(self.run_s, self.loop_s, self.kernel_s, self.sumo_s) < 0:
            raise ValueError(f"{self.scenario}: negative time")
        if self.steps < 0:
            raise ValueError(f"{self.scenario}: steps must be >= 0, got {self.steps}")
        if self.loop_s > self.wall_s + 1e-9 or self.wall_s > self.run_s + 1e-9:
            raise ValueError(f"{self.scenario}: the loop ({self.loop_s} s) must fit in wall_s "
                             f"({self.wall_s} s), wall_s in the run ({self.run_s} s)")
        if self.kernel_s + self.sumo_s > self.loop_s + 1e-9 or self.loop_s > self.run_s + 1e-9:
            raise ValueError(f"{self.scenario}: kernel + SUMO ({self.kernel_s + self.sumo_s} s) "
                             f"must fit in the loop ({self.loop_s} s), the loop in the run "
                             f"({self.run_s} s)")
        if self.staged:
            self._check_nesting()

    def _check_nesting(self) -> None:
        """Each timer inside the one around it: the kernel in the controller's step,
        SUMO's step in the world's, the world's in the dynamics', every stage in the
        loop."""
        stages = (self.behaviour_s, self.controller_s, self.dynamics_s, self.monitor_s,
                  self.recorder_s)
        inside = ((self.kernel_s, self.controller_s, "the kernel", "the controller's step"),
                  (self.sumo_s, self.world_s, "SUMO's step", "the world's step"),
                  (self.world_s, self.dynamics_s, "the world's step", "the dynamics"),
                  (sum(stages), self.loop_s, "the stages", "the loop"))
        if min(stages) < 0 or self.world_s < 0:
            raise ValueError(f"{self.scenario}: negative stage time")
        for part, whole, part_name, whole_name in inside:
            if part > whole + 1e-9:
                raise ValueError(f"{self.scenario}: {part_name} ({part} s) must fit in "
                                 f"{whole_name} ({whole} s)")

    @property
    def staged(self) -> bool:
        """Whether the loop's stages were timed (every stage time finite)."""
        return all(math.isfinite(getattr(self, key)) for key in STAGE_KEYS)

    @property
    def glue_s(self) -> float:
        return self.loop_s - self.kernel_s - self.sumo_s

    @property
    def glue_per_step_us(self) -> float:
        """The Python between SUMO's step and the kernel per control step [us]."""
        return self.glue_s / self.steps * 1e6 if self.steps else float("nan")

    def glue_by_stage_s(self) -> tuple[float, ...]:
        """The glue split by :data:`GLUE_STAGES` [s], in its order; they add up to
        :attr:`glue_s` (NaN each when the stages were not timed)."""
        if not self.staged:
            return (math.nan,) * len(GLUE_STAGES)
        timed = (self.behaviour_s + self.controller_s + self.dynamics_s + self.monitor_s
                 + self.recorder_s)
        return (self.behaviour_s, self.controller_s - self.kernel_s,
                self.world_s - self.sumo_s, self.dynamics_s - self.world_s,
                self.monitor_s, self.recorder_s, self.loop_s - timed)


# The glue's parts (:meth:`FloorRun.glue_by_stage_s`), (name, what it is), in the loop's
# order. The timers' own cost (a few hundred ns a call) lands in the part around them,
# mostly the loop's own.
GLUE_STAGES: tuple[tuple[str, str], ...] = (
    ("behaviour", "the behaviour: its decision on each fresh scene, the last one moved on "
                  "between them"),
    ("controller", "the controller's own Python around the C/GMRES kernel"),
    ("world", "the world's adapters around SUMO's step: the ego's pose in, the scene read, "
              "traffic extrapolated between SUMO's steps"),
    ("plant", "the plant's step and the ego's projection on the path"),
    ("monitor", "the safety monitor's 2-D overlap check"),
    ("recorder", "the recorder's trace rows"),
    ("loop", "the loop's own: the observation, the stop rule, the timers"),
)


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
                     for r in runs],
            "glue_stages_s": [dict(zip([name for name, _ in GLUE_STAGES],
                                       r.glue_by_stage_s(), strict=True)) for r in runs]}


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
