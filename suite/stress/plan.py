"""What each stress scenario will be, drawn before any net exists (:func:`plan_scenarios`).

Feature schedule, in blocks of ``BLOCK`` (8) consecutive scenarios: feature f of share p
is on for floor((b + 1) B p + phase_f) - floor(b B p + phase_f) scenarios of block b
(B = 8), at positions drawn at random within the block; the phases come from
``default_rng(S)`` and are drawn so that the first block holds every feature of a share
> 0 at least once. So any catalog of 8 or more scenarios covers every feature, and n
scenarios hold n p of each, to within one. Within a block: on-ramps go to generated nets
first (a real motorway may have no ramp ahead of the ego), slower traffic in the passing
lane never to a free road (it needs traffic), and the other features independently.
Lane counts cycle over ``config.lanes`` and the shoulder alternates at its share over
the generated (not real) scenarios, so every (lanes, shoulder) pair recurs every six of
them; the number of stalled cars cycles over ``config.stalled_count`` over the scenarios
without several stalled cars, from a seed-dependent start.

Determinism: the schedule of block b comes from ``default_rng([S, BLOCK_STREAM, b])``,
scenario i draws from ``default_rng([S, i])`` alone, and the cycles count in scenario
order, so the first k scenarios of ``--n 300`` are those of ``--n k``.

Lanes and positions that depend on the net are kept as fractions (``*_u`` in [0, 1)) and
resolved on the built network (:mod:`suite.stress.scenarios`): lane ``floor(u n)`` of the
n through lanes at that position (0 = the rightmost through lane, whatever SUMO's index
there), positions as gaps [m] from the ego's front bumper to the stalled car's rear.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from suite.stress.config import StressConfig
from suite.stress.netgen import ACCEL_LENGTH_M, NetLayout

__all__ = ["BLOCK", "RampPlan", "ScenarioPlan", "StalledPlan", "plan_scenarios"]

BLOCK = 8
BLOCK_STREAM = 1_000_003  # the schedule's random stream, apart from the scenarios'
SCHEDULED = ("real", "merge", "free", "slow", "close", "several", "wet")
"""Features on the block schedule, in the order their phases are drawn and placed."""
STRAIGHT_MARGIN_M = 30.0  # the acceleration edge keeps this far from the curve
STALLED_LENGTH_M = 4.8  # StalledSpec's default length


@dataclass(frozen=True)
class StalledPlan:
    """A stalled car ``gap_m`` ahead of the ego (front bumper to its rear) in through lane
    ``floor(lane_u n)``."""

    gap_m: float
    lane_u: float


@dataclass(frozen=True)
class RampPlan:
    """On-ramp traffic: flow [veh/h], speed [m/s]; on a generated net the ramp joins
    ``ahead_m`` ahead of the ego, on a real one ``pick_u`` picks among its on-ramps ahead."""

    vehicles_per_hour: float
    speed_mps: float
    ahead_m: float
    pick_u: float


@dataclass(frozen=True)
class ScenarioPlan:
    """One scenario before its net is built (module doc). ``layout`` for a generated net,
    ``real_net`` (file name) for a real one."""

    index: int
    seed: int
    layout: NetLayout | None
    real_net: str | None
    ego_pos_m: float  # generated: route position; real: unused (see ego_pos_u)
    ego_pos_u: float
    ego_lane_u: float
    ego_speed_mps: float
    stalled: tuple[StalledPlan, ...]
    close_stall: bool
    traffic_vph: float
    slow_lane_speed_mps: float | None
    ramp: RampPlan | None
    friction: float

    @property
    def name(self) -> str:
        """``st<i>_<net>[_<feature>...]``: g<lanes>[s] for a generated net (s: shoulder),
        the motorway for a real one."""
        if self.layout is not None:
            net = f"g{self.layout.lanes}{'s' if self.layout.shoulder else ''}"
        else:
            net = (self.real_net or "real").split("_", 1)[0]
        tags = [tag for tag, on in (
            ("merge", self.ramp is not None), ("slow", self.slow_lane_speed_mps is not None),
            ("close", self.close_stall), ("many", len(self.stalled) - int(self.close_stall) > 3),
            ("free", self.traffic_vph == 0), ("wet", self.friction < 1.0)) if on]
        return "_".join([f"st{self.index:04d}", net, *tags])


def stratified_count(k: int, share: float, phase: float) -> int:
    """How many of the k-th group of a stratified schedule carry a feature of ``share``
    (per member) and ``phase``: floor((k + 1) share + phase) - floor(k share + phase)."""
    return math.floor((k + 1) * share + phase) - math.floor(k * share + phase)


def _u(rng: np.random.Generator, lo_hi: tuple[float, float]) -> float:
    return float(rng.uniform(lo_hi[0], lo_hi[1]))


def _gaps(rng: np.random.Generator, n: int, lo: float, hi: float, spacing: float
          ) -> list[float]:
    """n gaps in [lo, hi], any two at least ``spacing`` apart, uniformly (spacings)."""
    free = hi - lo - (n - 1) * spacing
    u = np.sort(rng.uniform(0.0, free, n))
    return [float(lo + u[k] + k * spacing) for k in range(n)]


def _close_gap(rng: np.random.Generator, cfg: StressConfig, speed: float) -> float:
    """A gap the ego can stop in: reaction distance plus a stop at the configured
    deceleration, within ``close_stall_ahead_m``."""
    need = speed * cfg.close_stall_reaction_s + speed * speed / (2.0 * cfg.close_stall_decel_mps2)
    lo, hi = cfg.close_stall_ahead_m
    return float(rng.uniform(min(max(lo, need), hi), hi))


def _layout(rng: np.random.Generator, cfg: StressConfig, name: str, lanes: int,
            shoulder: bool, ego_pos: float, speed: float, merge_ahead: float | None
            ) -> NetLayout:
    radius, angle = _u(rng, cfg.curve_radius_m), _u(rng, cfg.curve_angle_deg)
    angle *= 1.0 if rng.uniform() < 0.5 else -1.0
    lead_in = ego_pos + _u(rng, cfg.curve_ahead_m)
    curve_end = lead_in + radius * math.radians(abs(angle))
    reach = speed * cfg.duration_s
    end = ego_pos + max(cfg.stalled_ahead_m[1] + 300.0, reach + 600.0, 1800.0)
    merge_at = None
    if merge_ahead is not None:
        merge_at = ego_pos + merge_ahead
        before = lead_in - ACCEL_LENGTH_M - STRAIGHT_MARGIN_M  # the latest start before it
        if before < merge_at < curve_end + STRAIGHT_MARGIN_M:  # it would overlap the curve:
            # move it before the curve if that keeps it ahead of the ego, else after it
            merge_at = before if before >= ego_pos + 50.0 else curve_end + STRAIGHT_MARGIN_M
        end = max(end, merge_at + ACCEL_LENGTH_M + 300.0)
    lead_out = max(end - curve_end, 300.0)
    return NetLayout(name=name, lanes=lanes, shoulder=shoulder, lead_in_m=lead_in,
                     radius_m=radius, angle_deg=angle, lead_out_m=lead_out,
                     merge_at_m=merge_at)


@dataclass(frozen=True)
class _Flags:
    real: bool
    merge: bool
    slow: bool
    close: bool
    several: bool
    free: bool
    wet: bool
    shoulder: bool
    lanes: int
    stalled: int  # the number of stalled cars (besides a close one); 0: several


def _phases(cfg: StressConfig, seed: int, real_share: float) -> dict[str, float]:
    """Per feature, a phase in [max(0, 1 - B p), 1): the first block holds it."""
    master = np.random.default_rng(seed)
    out = {}
    for name in SCHEDULED:
        share = _share(cfg, name, real_share)
        lo = max(0.0, 1.0 - BLOCK * share) if share > 0 else 0.0
        out[name] = float(master.uniform(lo, 1.0))
    return out


def _share(cfg: StressConfig, name: str, real_share: float) -> float:
    return {"real": real_share, "merge": cfg.merge_share, "free": cfg.free_road_share,
            "slow": cfg.slow_passing_share, "close": cfg.close_stall_share,
            "several": cfg.several_stalled_share, "wet": cfg.wet_share}[name]


def _block(cfg: StressConfig, seed: int, b: int, phases: dict[str, float],
           real_share: float) -> dict[str, set[int]]:
    """Positions (0..BLOCK-1) of each scheduled feature in block b (module doc)."""
    rng = np.random.default_rng([seed, BLOCK_STREAM, b])
    on: dict[str, set[int]] = {}
    for name in SCHEDULED:
        count = stratified_count(b, BLOCK * _share(cfg, name, real_share), phases[name])
        order = [int(x) for x in rng.permutation(BLOCK)]
        if name == "merge":  # generated nets first
            order = [x for x in order if x not in on["real"]] + \
                [x for x in order if x in on["real"]]
        elif name == "slow":  # never on a free road
            order = [x for x in order if x not in on["free"]]
        on[name] = set(order[:count])
    return on


def _plan_one(cfg: StressConfig, seed: int, i: int, flags: _Flags) -> ScenarioPlan:
    rng = np.random.default_rng([seed, i])
    scenario_seed = int(rng.integers(0, 2**31 - 1))
    speed = _u(rng, cfg.close_stall_speed_mps if flags.close else cfg.ego_speed_mps)
    if flags.several:
        lo_n, hi_n = cfg.several_stalled_count
        count = int(rng.integers(lo_n, hi_n + 1))
    else:
        count = flags.stalled
    gaps = _gaps(rng, count, *cfg.stalled_ahead_m, cfg.stalled_spacing_m)
    stalled = [StalledPlan(g, float(rng.uniform())) for g in gaps]
    ego_lane_u = float(rng.uniform())
    if flags.close:  # in the ego's own lane, close ahead
        stalled.insert(0, StalledPlan(_close_gap(rng, cfg, speed), ego_lane_u))
    if flags.free:
        vph = 0.0
    else:
        lo_q = cfg.slow_passing_min_vph if flags.slow else cfg.traffic_vph[0]
        vph = float(round(rng.uniform(lo_q, cfg.traffic_vph[1]), -1))
    slow = None
    if flags.slow:
        slow = round(max(cfg.slow_passing_min_mps, speed - _u(rng, cfg.slow_passing_below_mps)),
                     2)
    ramp = None
    if flags.merge:
        ramp = RampPlan(float(round(rng.uniform(*cfg.ramp_vph), -1)),
                        round(_u(rng, cfg.ramp_speed_mps), 2), _u(rng, cfg.merge_ahead_m),
                        float(rng.uniform()))
    friction = round(_u(rng, cfg.wet_friction), 2) if flags.wet else 1.0
    ego_pos = round(_u(rng, cfg.ego_start_m), 1)
    ego_pos_u = float(rng.uniform())
    layout = None
    if not flags.real:
        layout = _layout(rng, cfg, f"stress_{i:04d}", flags.lanes, flags.shoulder, ego_pos,
                         speed, ramp.ahead_m if ramp is not None else None)
    return ScenarioPlan(
        index=i, seed=scenario_seed, layout=layout, real_net=None, ego_pos_m=ego_pos,
        ego_pos_u=ego_pos_u, ego_lane_u=ego_lane_u, ego_speed_mps=round(speed, 2),
        stalled=tuple(stalled), close_stall=flags.close, traffic_vph=vph,
        slow_lane_speed_mps=slow, ramp=ramp, friction=friction)


def plan_scenarios(cfg: StressConfig, seed: int, n: int, real_nets: tuple[str, ...] = ()
                   ) -> list[ScenarioPlan]:
    """The plans of scenarios 0..n-1 (module doc). ``real_nets``: the real net files
    available (none: no real scenarios, whatever ``real_share`` says); real scenarios
    cycle over them."""
    if n < 0:
        raise ValueError(f"n must be >= 0, got {n}")
    real_share = cfg.real_share if real_nets else 0.0
    phases = _phases(cfg, seed, real_share)
    shoulder_phase = float(np.random.default_rng([seed, BLOCK_STREAM + 1]).uniform())
    counts = list(range(cfg.stalled_count[0], cfg.stalled_count[1] + 1))
    count_start = int(np.random.default_rng([seed, BLOCK_STREAM + 2]).integers(len(counts)))
    plans: list[ScenarioPlan] = []
    generated = real = plain = 0
    schedule: dict[str, set[int]] = {}
    for i in range(n):
        if i % BLOCK == 0:
            schedule = _block(cfg, seed, i // BLOCK, phases, real_share)
        slot = i % BLOCK
        on = {name: slot in schedule[name] for name in SCHEDULED}
        several = on["several"]
        flags = _Flags(
            real=on["real"], merge=on["merge"], slow=on["slow"], close=on["close"],
            several=several, free=on["free"], wet=on["wet"],
            shoulder=stratified_count(generated, cfg.shoulder_share, shoulder_phase) > 0,
            lanes=cfg.lanes[generated % len(cfg.lanes)],
            stalled=0 if several else counts[(count_start + plain) % len(counts)])
        plain += int(not several)
        plan = _plan_one(cfg, seed, i, flags)
        if flags.real:
            plan = _as_real(plan, real_nets[real % len(real_nets)])
            real += 1
        else:
            generated += 1
        plans.append(plan)
    return plans


def _as_real(plan: ScenarioPlan, net: str) -> ScenarioPlan:
    from dataclasses import replace

    return replace(plan, layout=None, real_net=net)
