"""The benchmark's fixed catalogs (TOML text, written to a temporary folder per bench run).

* :data:`TARGET_CATALOG`: issue 11's target, ``two_loop`` on the 3-lane road with
  2400 veh/h and a stalled car in the ego's lane, 4 runs (traffic seeds) of 40 s;
  :func:`dense_catalog` makes it with any number of runs and duration (issue 25's
  dense catalogs: the one-run figures over N seeds, the whole command over 24 runs).
* :data:`MATRIX_CATALOG`: 2 and 3 lanes x 0, 1200 and 2400 veh/h x ``two_loop`` and
  ``lane_keep`` (12 runs of 20 s; ``two_loop`` meets a stalled car in its lane,
  ``lane_keep`` drives free), for per-scenario real-time factors and peak memory.

Both use SUMO's default step (``sumo_step_s`` unset: 0.1 s for the 0.02 s control step);
:func:`with_defaults` injects extra ``[defaults]`` keys (e.g. ``sumo_step_s = 0.02`` for
the 50 Hz comparison).
"""

from __future__ import annotations

_DENSE = """
[defaults]
controller = "two_loop"
duration_s = {duration_s!r}
step_s = 0.02
seed = 7

[[scenario]]
name = "target_stall_3lane_2400"
net = "straight_3lane"
ego = {{ lane = 1, pos_m = 100.0, speed_mps = 25.0 }}
stalled = [ {{ lane = 1, pos_m = 500.0 }} ]
traffic = {{ vehicles_per_hour = 2400, seed = 3 }}
[scenario.sweep]
"traffic.seed" = [{seeds}]
"""


def dense_catalog(runs: int, duration_s: float = 40.0) -> str:
    """The dense target (issue 25's: two_loop, 3 lanes, 2400 veh/h, a stalled car in the
    ego's lane) as ``runs`` runs of ``duration_s``, traffic seeds 3, 4, ..."""
    if runs < 1:
        raise ValueError(f"runs must be >= 1, got {runs}")
    if not duration_s > 0:
        raise ValueError(f"duration_s must be > 0, got {duration_s}")
    seeds = ", ".join(str(3 + k) for k in range(runs))
    return _DENSE.format(duration_s=float(duration_s), seeds=seeds)


TARGET_CATALOG = dense_catalog(4, 40.0)

_MATRIX_HEAD = """
[defaults]
duration_s = 20.0
step_s = 0.02
seed = 5
"""

_MATRIX_SCENARIO = """
[[scenario]]
name = "{name}"
net = "{net}"
controller = "{controller}"
ego = {{ lane = {lane}, pos_m = 100.0, speed_mps = 25.0 }}
{stalled}{traffic}"""


def _matrix() -> str:
    parts = [_MATRIX_HEAD]
    for lanes, net in ((2, "straight_2lane"), (3, "straight_3lane")):
        for vph in (0, 1200, 2400):
            for controller in ("two_loop", "lane_keep"):
                lane = lanes - 2  # the 2-lane road: lane 0; the 3-lane road: lane 1
                stalled = (f"stalled = [ {{ lane = {lane}, pos_m = 350.0 }} ]\n"
                           if controller == "two_loop" else "")
                traffic = (f"traffic = {{ vehicles_per_hour = {vph}, seed = 4 }}\n"
                           if vph else "")
                parts.append(_MATRIX_SCENARIO.format(
                    name=f"m{lanes}lane_{vph}vph_{controller}", net=net, controller=controller,
                    lane=lane, stalled=stalled, traffic=traffic))
    return "".join(parts)


MATRIX_CATALOG = _matrix()


def with_defaults(catalog: str, **keys: float) -> str:
    """``catalog`` with ``keys`` added to its ``[defaults]`` table (numbers only)."""
    if "[defaults]\n" not in catalog:
        raise ValueError("the catalog has no [defaults] table")
    lines = "".join(f"{k} = {float(v)!r}\n" for k, v in keys.items())
    return catalog.replace("[defaults]\n", "[defaults]\n" + lines, 1)
