"""The wall-clock budget of one scenario run, so that no catalog can hang a night.

Every run gets one (``RunOptions.timeout_s``): the ``--timeout`` of the command line if
given, else the scenario's ``timeout_s`` from the catalog, else the default derived from
its simulated duration: :data:`STARTUP_S` for building the road, starting SUMO and the
controller, plus :data:`WALL_PER_SIM_S` wall seconds per simulated second, at most
:data:`MAX_DEFAULT_S`. The runner stops itself when its budget is spent (``timeout``,
what ran is kept); the executor kills a process that is still alive
``KILL_GRACE_S`` later (stuck outside the loop, e.g. inside SUMO).
"""

from __future__ import annotations

import math

__all__ = ["MAX_DEFAULT_S", "STARTUP_S", "WALL_PER_SIM_S", "default_budget_s", "run_budget_s"]

STARTUP_S = 60.0  # road, reference, SUMO start, controller set-up [s]
WALL_PER_SIM_S = 10.0  # wall seconds allowed per simulated second [s/s]
MAX_DEFAULT_S = 3600.0  # a default budget never exceeds an hour [s]


def _positive_seconds(value: float, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) \
            or not math.isfinite(value) or value <= 0:
        raise ValueError(f"{what}: expected a finite number of seconds > 0, got {value!r}")
    return float(value)


def default_budget_s(duration_s: float) -> float:
    """The default wall-clock budget [s] of a run simulating ``duration_s`` [s]."""
    duration = _positive_seconds(duration_s, "duration_s")
    return min(STARTUP_S + WALL_PER_SIM_S * duration, MAX_DEFAULT_S)


def run_budget_s(duration_s: float, catalog_timeout_s: float | None = None,
                 cli_timeout_s: float | None = None) -> float:
    """The budget [s] a run gets: ``--timeout``, else the catalog's ``timeout_s``, else
    :func:`default_budget_s`."""
    if cli_timeout_s is not None:
        return _positive_seconds(cli_timeout_s, "--timeout")
    if catalog_timeout_s is not None:
        return _positive_seconds(catalog_timeout_s, "timeout_s")
    return default_budget_s(duration_s)
