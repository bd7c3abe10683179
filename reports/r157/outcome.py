"""UN R157's acceptance logic over two sets of runs of one R157 pack: the system under
test's and the regulation's reference driver's (``r157_reference``, docs/baselines.md).

Annex 5's test scenarios are judged on three things (docs/r157.md):

* no collision caused by the system: the run's own criterion
  ``max_at_fault_collisions = 0`` (a failed criterion of the system's run);
* the minimum following time gap (§5.2.3.3, ``max_r157_gap_shortfall_s``): likewise a
  criterion of the system's run when the pack was imported with ``--r157``;
* every collision the reference driver avoids is avoided: a scenario in which the
  system collides (any contact, ``collisions`` > 0) and the reference driver, on the
  same test, does not.

The run's other criteria (comfort, tracking) are no part of the regulation's verdict:
its status (pass or fail by all its criteria) is shown beside it.

A scenario's row pairs the system's run with the reference driver's run of the same
test (:attr:`reports.identity.Setup.test`: the same scenario, net and storyboard, so a
reference run of another speed or another storyboard is never taken for it). The
scenario's section is its ``r157_section`` label (``hwyeval import openscenario
--r157``; "" when the scenario has none).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from reports.tables import RunEntry

__all__ = ["REFERENCE_CONTROLLER", "SECTION_LABEL", "SECTION_TITLES", "Acceptance",
           "PackRow", "RunOutcome", "SectionSummary", "pack_rows", "section_of",
           "summarise"]

REFERENCE_CONTROLLER = "r157_reference"
SECTION_LABEL = "r157_section"
# Annex 5's test sections (4.1 to 4.6), in our words.
SECTION_TITLES = {
    "4.1": "lane keeping",
    "4.2": "a road user or object blocking the lane",
    "4.3": "following a lead vehicle",
    "4.4": "another vehicle changing into the lane (cut-in)",
    "4.5": "a stationary obstacle after the lead vehicle's lane change (cut-out)",
    "4.6": "detection range",
}


@dataclass(frozen=True)
class RunOutcome:
    """One run as the regulation reads it: its status (pass | fail | error | timeout),
    its contacts (any, and those the ego caused), the largest ego speed change of a
    contact it caused [m/s], the smallest time to collision [s], the time below the
    R157 following gap beyond its allowance [s] (NaN when not measured), its failed
    criteria and its run directory's name."""

    status: str
    collisions: int
    at_fault_collisions: int
    at_fault_delta_v_mps: float
    min_ttc_s: float
    gap_shortfall_s: float
    failed: tuple[str, ...]
    run: str

    @property
    def collided(self) -> bool:
        return self.collisions > 0

    @property
    def judged(self) -> bool:
        """Whether it ran to a verdict (not error or timeout)."""
        return self.status in ("pass", "fail")


def _count(entry: RunEntry, name: str) -> int:
    v = entry.value(name)
    return int(v) if math.isfinite(v) else 0


def run_outcome(entry: RunEntry) -> RunOutcome:
    """The :class:`RunOutcome` of one run directory."""
    return RunOutcome(
        status=entry.status, collisions=_count(entry, "collisions"),
        at_fault_collisions=_count(entry, "at_fault_collisions"),
        at_fault_delta_v_mps=entry.value("max_at_fault_delta_v_mps"),
        min_ttc_s=entry.value("min_ttc_s"), gap_shortfall_s=entry.value("r157_gap_shortfall_s"),
        failed=tuple(sorted({f.criterion for f in entry.failures})), run=entry.run_id)


@dataclass(frozen=True)
class Acceptance:
    """Whether the system's run meets the acceptance logic (``met``), and each reason
    it does not (``reasons``, empty when met). ``preventable``: the system collides
    where the reference driver does not; ``unpreventable``: both collide (the reference
    model could not avoid it either)."""

    met: bool
    reasons: tuple[str, ...]
    preventable: bool = False
    unpreventable: bool = False


@dataclass(frozen=True)
class PackRow:
    """One concrete scenario of the pack: its section and name, the ego's set speed
    [km/h], the system's controller, its run and the reference driver's run of the same
    test (None when the pack was not run with the reference driver)."""

    section: str
    scenario: str
    ego_speed_kmh: float
    controller: str
    system: RunOutcome
    reference: RunOutcome | None

    @property
    def acceptance(self) -> Acceptance:
        """The regulation's acceptance logic (module docstring) for this scenario."""
        s, ref = self.system, self.reference
        reasons: list[str] = []
        if not s.judged:
            reasons.append(f"the run ended {s.status}")
        if s.at_fault_collisions > 0:
            reasons.append("a collision caused by the system")
        if s.gap_shortfall_s > 0.0:
            reasons.append(f"below the R157 following gap for {s.gap_shortfall_s:.2f} s")
        preventable = s.collided and ref is not None and ref.judged and not ref.collided
        if preventable:
            reasons.append("a collision the reference driver avoids")
        both = s.collided and ref is not None and ref.collided
        return Acceptance(met=not reasons, reasons=tuple(reasons), preventable=preventable,
                          unpreventable=both)


def section_of(entry: RunEntry) -> str:
    """The scenario's R157 section label ("" without one)."""
    info = entry.info
    labels = (info.scenario_spec.get("labels") if info is not None else None) or {}
    return str(labels.get(SECTION_LABEL, ""))


def _test_of(entry: RunEntry) -> str:
    setup = entry.setup
    return setup.test or setup.test_spec if setup is not None else ""


def pack_rows(runs: Sequence[RunEntry]) -> list[PackRow]:
    """One row per run of a system under test (any controller but the reference
    driver), paired with the reference driver's run of the same test when there is one;
    sorted by section, scenario and controller. Only scenarios with an R157 section label
    are rows (a pack imported without ``--r157`` has none)."""
    reference = {_test_of(e): e for e in runs
                 if e.controller == REFERENCE_CONTROLLER and section_of(e)}
    rows = []
    for e in runs:
        section = section_of(e)
        if e.controller == REFERENCE_CONTROLLER or not section:
            continue
        ref = reference.get(_test_of(e))
        speed = e.info.target_speed_mps * 3.6 if e.info is not None else math.nan
        rows.append(PackRow(section, e.scenario, speed, e.controller, run_outcome(e),
                            None if ref is None else run_outcome(ref)))
    return sorted(rows, key=lambda r: (r.section, r.scenario, r.controller))


@dataclass(frozen=True)
class SectionSummary:
    """Counts of one section for one controller: scenarios, acceptance met, passes,
    collisions (runs with contact), those caused by the system, the collisions the
    reference avoids, and the reference driver's passes and collisions (of the rows that
    have a reference run, ``with_reference``)."""

    section: str
    controller: str
    scenarios: int
    met: int
    passed: int
    collided: int
    at_fault: int
    preventable: int
    with_reference: int
    reference_passed: int
    reference_collided: int


def summarise(rows: Sequence[PackRow]) -> list[SectionSummary]:
    """One :class:`SectionSummary` per (section, controller), and one per controller
    for all sections (section "all")."""
    keys = sorted({(r.section, r.controller) for r in rows})
    keys += sorted({("all", r.controller) for r in rows})
    out = []
    for section, controller in keys:
        mine = [r for r in rows if r.controller == controller
                and (section == "all" or r.section == section)]
        refs = [r.reference for r in mine if r.reference is not None]
        out.append(SectionSummary(
            section=section, controller=controller, scenarios=len(mine),
            met=sum(r.acceptance.met for r in mine),
            passed=sum(r.system.status == "pass" for r in mine),
            collided=sum(r.system.collided for r in mine),
            at_fault=sum(r.system.at_fault_collisions > 0 for r in mine),
            preventable=sum(r.acceptance.preventable for r in mine),
            with_reference=len(refs), reference_passed=sum(x.status == "pass" for x in refs),
            reference_collided=sum(x.collided for x in refs)))
    return out
