"""``run.json``: what was run (:class:`RunInfo`) and how it went (:class:`RunOutcome`).

Both are frozen dataclasses written once, at the end of a run (or by the executor for a
run that never finished); :mod:`reports.record.codec` reads them back with every field
checked. Units are in the field names.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

STATUSES = ("pass", "fail", "error", "timeout")
# How a run ended before metrics judged it: the loop finished, or it did not.
END_OK = "ok"


@dataclass(frozen=True)
class EgoBox:
    """The ego's body box relative to its CG [m]; ``cg_to_rear_axle_m``: the rear axle
    behind the CG (NaN in files written before it was recorded)."""

    length_m: float
    width_m: float
    cg_to_front_bumper_m: float
    cg_to_box_centre_m: float
    cg_to_rear_axle_m: float = math.nan


@dataclass(frozen=True)
class RunInfo:
    """The run's identity and set-up, known before the first step."""

    scenario: str
    family: str
    controller: str
    catalog: str
    catalog_name: str
    seed: int
    net: str
    net_name: str
    duration_s: float
    step_s: float
    target_speed_mps: float
    allow_shoulder: bool
    ego: EgoBox
    controller_options: dict[str, Any] = field(default_factory=dict)
    controller_params: dict[str, Any] = field(default_factory=dict)
    criteria: dict[str, Any] = field(default_factory=dict)
    scenario_spec: dict[str, Any] = field(default_factory=dict)
    record_radius_m: float = 150.0
    hwyeval_version: str = ""
    friction: float = 1.0  # tyre-road friction coefficient mu of the plant [-]


@dataclass(frozen=True)
class StalledVehicle:
    """A stalled car of the scenario as SUMO placed it (box centre, heading)."""

    id: str
    x_m: float
    y_m: float
    heading_rad: float
    length_m: float
    width_m: float
    lane_index: int


@dataclass(frozen=True)
class SumoCollision:
    """A collision SUMO reported with the ego as collider or victim."""

    t_s: float
    collider: str
    victim: str
    type: str


@dataclass(frozen=True)
class SsmSummary:
    """SUMO's SSM device for the ego: conflicts seen, minimum TTC [s], maximum DRAC [m/s²]."""

    conflicts: int = 0
    min_ttc_s: float | None = None
    max_drac_mps2: float | None = None
    error: str | None = None


@dataclass(frozen=True)
class ReplayHandover:
    """A recorded vehicle handed over to SUMO's driver (reactive replay): its id
    (``rec_<id>``) and the run time [s] of its last replayed pose; SUMO drives it from
    the next SUMO step on."""

    track_id: str
    t_s: float


@dataclass(frozen=True)
class ReplaySummary:
    """The run's recorded traffic (docs/replay.md): the tracks file as the catalog names
    it, the mode (``"replay"``/``"reactive"``), how many recorded vehicles were in the
    simulation (``vehicles``) and every handover, in time order."""

    tracks: str = ""
    mode: str = ""
    vehicles: int = 0
    handovers: tuple[ReplayHandover, ...] = ()


@dataclass(frozen=True)
class FileDigest:
    """A file of a run directory as run.json lists it when written: ``name`` (in the
    run directory), ``size_bytes`` and ``sha256`` (hex) of its content. A directory
    counts as complete only when every listed file is there with that size (the
    reports) and, for ``--resume``, that content."""

    name: str
    size_bytes: int
    sha256: str

    def __post_init__(self) -> None:
        if not self.name or "/" in self.name or self.name.startswith("."):
            raise ValueError(f"FileDigest.name must be a plain file name, got {self.name!r}")
        if self.size_bytes < 0:
            raise ValueError(f"FileDigest.size_bytes must be >= 0, got {self.size_bytes!r}")
        if len(self.sha256) != 64 or any(c not in "0123456789abcdef" for c in self.sha256):
            raise ValueError(f"FileDigest.sha256 must be 64 hex digits, got {self.sha256!r}")


@dataclass(frozen=True)
class RunOutcome:
    """How the run went. ``end`` is 'ok' when the loop completed its stop rules, else
    'error' or 'timeout'; the final status (pass/fail/error/timeout) is the verdict's."""

    end: str = END_OK
    error: str | None = None
    stop_reason: str = ""
    wall_s: float = math.nan
    sim_time_s: float = 0.0
    steps: int = 0
    peak_rss_mb: float = math.nan
    sumo_t_origin_s: float = 0.0
    stalled: tuple[StalledVehicle, ...] = ()
    sumo_collisions: tuple[SumoCollision, ...] = ()
    ssm: SsmSummary = field(default_factory=SsmSummary)
    log_s: float = math.nan
    log_error: str | None = None
    replay: ReplaySummary | None = None  # recorded traffic; None: the run had none

    def __post_init__(self) -> None:
        if self.end not in (END_OK, "error", "timeout"):
            raise ValueError(f"RunOutcome.end must be 'ok', 'error' or 'timeout', got {self.end!r}")
