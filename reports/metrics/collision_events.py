"""What the collision judgement finds (:mod:`reports.metrics.collisions`): its constants,
the collision classes, the episodes (ours and SUMO's) and the judgement."""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

from reports.record.verdict import CollisionDisagreement

STOPPED_SPEED_MPS = 0.05


BEHIND_ANGLE_RAD = math.radians(150.0)


EPISODE_GAP_S = 1.0


SUMO_MATCH_S = 1.0


EGO_ID = "ego"


JUMP_EXCESS_MPS = 10.0
"""A recorded vehicle *jumps* between two samples when its displacement differs from the
one its speeds and headings allow by more than this speed [m/s] times the interval
(1 m over 0.1 s). The three development recordings stay below 1.8 m/s."""


JUMP_AFTER_S = 0.5  # [s] a contact this long after a jump is still the jump's


JUMP_MAX_GAP_S = 0.5  # [s] rows further apart than this are not judged (absent between)


# How a collision episode's first contact was found (CollisionEvent.evidence)
OVERLAP = "overlap"  # the recorded boxes overlap at the row


SWEPT = "swept"  # they touch between the previous row and this one


MONITOR = "monitor"  # only the in-loop monitor's overlap flag


EVIDENCE = (OVERLAP, SWEPT, MONITOR)


class CollisionClass(StrEnum):
    """nuPlan's CollisionType, plus what a record cannot classify and a replayed
    (recorded, blind) vehicle driving into the ego."""

    STOPPED_EGO = "stopped_ego"
    STOPPED_TRACK = "stopped_track"
    ACTIVE_REAR = "active_rear"
    ACTIVE_FRONT = "active_front"
    ACTIVE_LATERAL = "active_lateral"
    UNCLASSIFIED = "unclassified"
    REPLAYED_INTO_EGO = "replayed_into_ego"


@dataclass(frozen=True)
class CollisionEvent:
    """One collision episode (2-D contact), judged at its first contact (module doc).

    ``row``/``t_s``: trace row and time [s] where the episode is located (its earliest
    evidence); ``contact_row``: the first contact, where it was classified (speeds [m/s]
    and ``ego_within_one_lane`` are taken there; for a swept contact at the row before,
    the last sample before the boxes touched); ``last_row``: its last contact;
    ``evidence``: how that first contact was found (:data:`OVERLAP`, :data:`SWEPT`,
    :data:`MONITOR`); ``sumo_reports``: SUMO's reports agreeing with it (0: SUMO did not
    report it); ``sumo_role``: the ego's role in the first ('collider', 'victim' or '')."""

    row: int
    contact_row: int
    last_row: int
    t_s: float
    other_id: str
    kind: CollisionClass
    at_fault: bool
    ego_speed_mps: float
    other_speed_mps: float
    other_stalled: bool
    ego_within_one_lane: bool
    delta_v_mps: float
    evidence: str
    sumo_role: str = ""
    sumo_type: str = ""
    sumo_reports: int = 0

    def __post_init__(self) -> None:
        if self.evidence not in EVIDENCE:
            raise ValueError(f"CollisionEvent.evidence must be one of {EVIDENCE}, "
                             f"got {self.evidence!r}")
        if not 0 <= self.row <= self.contact_row <= self.last_row:
            raise ValueError("CollisionEvent: rows must satisfy 0 <= row <= contact_row <= "
                             f"last_row, got {self.row}, {self.contact_row}, {self.last_row}")

    @property
    def geometric(self) -> bool:
        """The recorded boxes touched (sampled or swept), not only the monitor's flag."""
        return self.evidence != MONITOR


@dataclass(frozen=True)
class SumoEpisode:
    """SUMO's reports of the ego with one other vehicle, each within ``EPISODE_GAP_S`` of
    the previous: first/last trace row and time [s], the number of reports, the ego's
    role ('collider', 'victim'; '' for a flag without its report) and SUMO's type in the
    first. ``other_id`` '' when no vehicle is named."""

    other_id: str
    row: int
    last_row: int
    t_s: float
    last_t_s: float
    reports: int
    role: str
    type: str


@dataclass(frozen=True)
class CollisionJudgement:
    """Everything :func:`judge_collisions` finds: the collision episodes (what the
    verdict counts), SUMO's episodes (beside them) and where the two disagree, each in
    time order."""

    events: tuple[CollisionEvent, ...] = ()
    sumo: tuple[SumoEpisode, ...] = ()
    disagreements: tuple[CollisionDisagreement, ...] = ()
