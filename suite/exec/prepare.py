"""Make this process the warm image scenario processes are forked from: one explicit call,
:func:`prepare_process`.

A scenario process is a fork of a process that has already imported what a run needs and
loaded the numba kernels, so that a catalog pays those costs once, not once per run
(docs/performance.md §3.3). Two kinds of process are prepared that way:

* the local executor's forkserver (:mod:`suite.exec.forkserver`), whose preload is the
  one module :mod:`suite.exec.forkserver_preload` calling :func:`prepare_process`;
* a Ray actor (:mod:`suite.exec.ray.actor`), and the bench's probes that time or profile
  runs in one process (:mod:`suite.bench.floor_probe`, :mod:`suite.bench.profile`), which
  call it themselves.

Importing this module does nothing but import the standard library (and
:mod:`suite.exec.quick_exit`, which imports nothing else): everything happens
in :func:`prepare_process`, and none of the modules it uses (:mod:`suite.exec.warmup`,
:mod:`suite.exec.arrow_without_pandas`) acts when imported.
"""

from __future__ import annotations

import atexit
import gc
import importlib
import os
import sys
from types import FrameType

from suite.exec.quick_exit import exit_without_teardown  # the standard library only

__all__ = ["IMPORTS", "in_forkserver", "is_prepared", "prepare_process"]

# What a run imports that the warm-up's own imports (suite.exec.warmup) do not reach
# first; imported in this order, each on its own (an ImportError is skipped, as the
# forkserver's preload always did: the scenario then fails and says why).
IMPORTS = ("numba", "libsumo", "suite.run.runner", "suite.catalog", "controllers.builtin")

_prepared = False  # inherited by forks: a prepared process's children are prepared


def is_prepared() -> bool:
    """Whether :func:`prepare_process` has run in this process (or in the one it was
    forked from)."""
    return _prepared


def prepare_process() -> None:
    """Import what a run needs and load its kernels, for the processes forked from this one.

    Idempotent: only the first call in a process (or in the process it was forked from)
    does anything. In this order:

    1. **Pause the cyclic garbage collector** (``gc.disable``). Its gen-2 passes over the
       heap that the imports grow (three of them, each walking up to ~200 000 objects)
       cost 0.1-0.5 s of a ~2.3 s preload that every catalog waits for before its first
       run (docs/performance.md). It is resumed in step 6 whatever happens in between.
    2. **Settle pyarrow without pandas**
       (:func:`suite.exec.arrow_without_pandas.settle_pyarrow_without_pandas`, which
       imports numpy and pyarrow): pyarrow's first conversion of a numpy array asks
       whether it is a pandas object and imports pandas to know; made now with that
       import refused, no scenario process imports pandas (0.25-0.3 s). First, so
       that nothing imported later makes that conversion with pandas allowed.
    3. **Import** :data:`IMPORTS`: numba, libsumo, the runner, the catalog and the built-in
       controllers, each on its own; one that is missing is skipped.
    4. **Warm up** (:mod:`suite.exec.warmup`): import the heavy modules a run imports
       lazily (Rerun, ``pyarrow.parquet``, the network reader's XML parser, the bundled
       nets, the eclipse-sumo package) and load every numba kernel from the on-disk cache
       (compiling it once) by running the lane behaviour and the controllers a few
       steps on a tiny problem. A failed warm-up is ignored: the scenario will raise
       and be reported with its traceback.
    5. **Freeze** what steps 2-4 made (``gc.freeze``: ~200 000 objects moved to the
       collector's permanent generation, which forked processes inherit): their
       collections no longer walk it, which was ~190 ms of every 40 s run, nor write to
       those objects' headers, which copied this process's pages into each child. In
       multiprocessing's forkserver (:func:`in_forkserver`) also register a quick exit
       (:func:`suite.exec.quick_exit.exit_without_teardown`): the server ends by
       ``SystemExit`` once its parent is gone, and the interpreter's teardown of all this
       took 0.55 s while it still held the command's stdout and stderr.
    6. **Resume the collector** (``gc.enable``), so forked processes collect as usual.
    """
    global _prepared
    if _prepared:
        return
    _prepared = True
    gc.disable()
    try:
        _settle_pyarrow()
        for name in IMPORTS:
            try:
                importlib.import_module(name)
            except ImportError:
                pass
        _warm_up()
        if in_forkserver():
            atexit.register(_exit_without_teardown)
        gc.freeze()
    finally:
        gc.enable()


def _settle_pyarrow() -> None:
    try:
        from suite.exec.arrow_without_pandas import settle_pyarrow_without_pandas
    except ImportError:
        return
    settle_pyarrow_without_pandas()


def _warm_up() -> None:
    try:
        from suite.exec import warmup

        warmup.warm_up()
    except Exception:  # noqa: BLE001 - a failed warm-up must not take the forkserver down;
        pass  # the scenario itself will then raise and be reported with its traceback.


def in_forkserver() -> bool:
    """Whether this runs in multiprocessing's forkserver preload (its ``main`` is on the
    call stack)."""
    frame: FrameType | None = sys._getframe()
    target = os.path.join("multiprocessing", "forkserver.py")
    while frame is not None:
        if frame.f_code.co_name == "main" and frame.f_code.co_filename.endswith(target):
            return True
        frame = frame.f_back
    return False


def _exit_without_teardown() -> None:
    atexit.unregister(_exit_without_teardown)  # the other handlers run, not this again
    exit_without_teardown(0)
