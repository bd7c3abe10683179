"""The floor study's measuring process (:func:`suite.bench.floor.floor_study` runs it).

Run as a script in a fresh interpreter, from the repository root::

    python suite/bench/floor_probe.py CATALOG OUT

and prints one JSON line: ``third_party_import_s``, ``preload_s`` and ``runs`` (one
row per scenario: ``run_s``, ``wall_s`` (results.csv's: build and loop), ``loop_s``,
``kernel_s``, ``sumo_s``, the stage times, ``scenario``, ``status``, ``steps``), as
:mod:`suite.bench.floor`'s docstring describes.

It is run as a file, not with ``python -m``: ``-m`` would import ``suite`` and
``suite.bench`` (and numpy with them) before the third-party imports are timed. So this
module imports nothing but the standard library at its top; the third-party modules,
then the scenario processes' preparation (:func:`suite.exec.prepare.prepare_process`),
are done inside :func:`main`, timed.

The timers wrap, for the probe's process only, the calls they time
(:func:`install_timers`): the C/GMRES continuation kernel
(``CgmresOuter._continue``), SUMO's step with its collision query
(``SumoWorld._advance``), the runner's loop (``suite.run.runner.run_loop``) and, inside
it, each of the loop's stages (:func:`time_stages`: ``behaviour_s``, ``controller_s``,
``dynamics_s``, ``world_s``, ``monitor_s``, ``recorder_s``), so that the Python between
the kernel and SUMO's step can be told apart stage by stage.
"""

from __future__ import annotations

import importlib
import json
import os
import sys
import time

# Only what the ``python -c`` script imported before its first timer: typing, pathlib and
# collections.abc would otherwise be imported before the third-party modules are timed.
TYPE_CHECKING = False
if TYPE_CHECKING:
    from collections.abc import Callable
    from pathlib import Path
    from typing import Any

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.realpath(__file__))))

# what no change to this project's code removes (kept equal to suite.bench.floor's)
THIRD_PARTY = ("numpy", "numba", "libsumo", "rerun", "pyarrow.parquet", "scipy.linalg",
               "scipy.sparse", "scipy.ndimage", "scipy.spatial", "sumolib")


def _timed(fn: Callable[..., Any], acc: dict[str, float], key: str) -> Callable[..., Any]:
    """``fn`` adding its wall time of every call to ``acc[key]`` [s]."""
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        t = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            acc[key] += time.perf_counter() - t
    return wrapper


# the loop's stages each timed on its own (:func:`time_stages`), keys of ``acc``
STAGE_KEYS = ("behaviour_s", "controller_s", "dynamics_s", "world_s", "monitor_s",
              "recorder_s")


def _time_method(obj: Any, name: str, acc: dict[str, float], key: str) -> None:
    """``obj.name`` replaced, on this instance only, by the timed bound method."""
    setattr(obj, name, _timed(getattr(obj, name), acc, key))


def time_stages(stages: Any, acc: dict[str, float]) -> None:
    """Time each stage of one run's :class:`suite.run.loop.Stages` into ``acc``
    (:data:`STAGE_KEYS`), by wrapping the instances' own methods the loop calls: the
    behaviour's ``decide``, the controller's ``step``, the ego dynamics' ``start`` and
    ``advance``, the world's ``start`` and ``step`` inside them (when the dynamics have a
    world), the safety monitor's ``check`` and the recorder's ``record``. The last
    decision moved on between two decisions (``Decision.ahead``) is timed with the
    behaviour by :func:`install_timers`, on its class."""
    _time_method(stages.behaviour, "decide", acc, "behaviour_s")
    _time_method(stages.controller, "step", acc, "controller_s")
    for name in ("start", "advance"):
        _time_method(stages.dynamics, name, acc, "dynamics_s")
    world = getattr(stages.dynamics, "world", None)
    if world is not None:
        for name in ("start", "step"):
            _time_method(world, name, acc, "world_s")
    _time_method(stages.monitor, "check", acc, "monitor_s")
    _time_method(stages.recorder, "record", acc, "recorder_s")


def install_timers(acc: dict[str, float]) -> None:
    """Wrap the C/GMRES kernel calls, SUMO's step and the loop with timers into ``acc``,
    and every run's stages (:func:`time_stages`)."""
    import controllers.behaviour.types as behaviour_types
    import controllers.two_loop.outer.cgmres as cgmres
    import suite.run.runner as runner
    import suite.world.sumo as sumo

    cgmres.CgmresOuter._continue = _timed(  # type: ignore[method-assign]
        cgmres.CgmresOuter._continue, acc, "kernel_s")
    sumo.SumoWorld._advance = _timed(  # type: ignore[method-assign]
        sumo.SumoWorld._advance, acc, "sumo_s")
    behaviour_types.Decision.ahead = _timed(  # type: ignore[method-assign]
        behaviour_types.Decision.ahead, acc, "behaviour_s")
    loop = _timed(runner.run_loop, acc, "loop_s")  # type: ignore[attr-defined]

    def staged_loop(stages: Any, n_steps: int) -> str:
        time_stages(stages, acc)
        return str(loop(stages, n_steps))

    runner.run_loop = staged_loop  # type: ignore[attr-defined]


def _run_in_child(acc: dict[str, float], scenario: Any, out: Path) -> dict[str, Any]:
    """Run one scenario in a child forked from this process; its row, through a pipe."""
    import suite.run.runner as runner
    from suite.run.options import RunOptions

    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(read)
        t = time.perf_counter()
        record = runner.run_scenario(scenario, out, RunOptions())
        child_row = dict(acc, run_s=time.perf_counter() - t, scenario=scenario.name,
                         status=record.status, steps=record.outcome.steps,
                         wall_s=record.outcome.wall_s)
        os.write(write, json.dumps(child_row).encode())
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
    row: dict[str, Any] = json.loads(b"".join(chunks))
    return row


def main(catalog: str, out: str) -> dict[str, Any]:
    """The study (module docstring): import times, then every scenario of ``catalog``
    run into ``out``/k in a child with the timers."""
    t0 = time.perf_counter()
    for name in THIRD_PARTY:
        importlib.import_module(name)
    third_party_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    from suite.exec.prepare import prepare_process

    prepare_process()  # what the forkserver's preload does, collector frozen included
    preload_s = time.perf_counter() - t0
    from pathlib import Path

    from suite.catalog import load_catalog

    acc = dict.fromkeys(("kernel_s", "sumo_s", "loop_s", *STAGE_KEYS), 0.0)
    install_timers(acc)
    runs = [_run_in_child(acc, scenario, Path(out) / str(k))
            for k, scenario in enumerate(load_catalog(Path(catalog)).scenarios)]
    return {"third_party_import_s": third_party_s, "preload_s": preload_s, "runs": runs}


if __name__ == "__main__":
    # as ``python -c`` from the root did: the root first on the path, not this folder
    sys.path[0] = ROOT
    print(json.dumps(main(sys.argv[1], sys.argv[2])))
