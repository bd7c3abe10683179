"""Scripted vehicles of a scenario: :class:`ActorSpec`, its :class:`ActorEventSpec` and an
event's trigger :class:`ActorWhenSpec` (docs/catalog.md, ``actors``).

An actor starts at t = 0 at a route position (its front bumper, as ``ego.pos_m``) given
absolutely (``pos_m``) or relative to the ego's start (``ahead_of_ego_m``, resolved to
``pos_m`` when the catalog is read). Its events run in order: an event is armed once the
one before it has started, and starts at the first SUMO step at which it is due: at run
time ``t_s`` or later, and, with ``when``, once every condition of it has held for
``delay_s``. The conditions are the ego's view of the actor, in OpenSCENARIO's terms
(docs/openscenario.md), with the gap g the bumper-to-bumper distance along the route
from the ego's front to the actor's rear (the actor ahead; no condition holds while it
is not):

* ``ahead_gap_m``: g <= value [m] (RelativeDistance, longitudinal, freespace);
* ``time_headway_s``: g / v_ego <= value [s] (TimeHeadway, freespace);
* ``ttc_s``: g / (v_ego - v_actor) <= value [s], closing only (TimeToCollision);
* ``ego_pos_m``: the ego's front bumper has reached this route position [m]
  (ReachPosition along the route).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, ClassVar

from suite.catalog import rules
from suite.catalog.errors import SpecError
from suite.catalog.rules import Rule

__all__ = ["ActorEventSpec", "ActorSpec", "ActorWhenSpec"]

WHEN_CONDITIONS = ("ahead_gap_m", "time_headway_s", "ttc_s", "ego_pos_m")


@dataclass(frozen=True)
class ActorWhenSpec:
    """An event's trigger (module docstring): every condition given must hold at one SUMO
    step, and the event starts ``delay_s`` [s] after they first all did. At least one
    condition."""

    ahead_gap_m: float | None = None
    time_headway_s: float | None = None
    ttc_s: float | None = None
    ego_pos_m: float | None = None
    delay_s: float = 0.0

    _RULES: ClassVar[dict[str, Rule]] = {
        "ahead_gap_m": rules.num(0.0, optional=True),
        "time_headway_s": rules.num(0.0, strict=True, optional=True),
        "ttc_s": rules.num(0.0, strict=True, optional=True),
        "ego_pos_m": rules.num(0.0, optional=True),
        "delay_s": rules.num(0.0),
    }
    _REQUIRED: ClassVar[tuple[str, ...]] = ()

    def __post_init__(self) -> None:
        rules.check_fields(self)
        if all(getattr(self, name) is None for name in WHEN_CONDITIONS):
            raise SpecError("when", f"at least one condition of {list(WHEN_CONDITIONS)}", {})
        for name in (*WHEN_CONDITIONS, "delay_s"):
            if getattr(self, name) is not None:
                rules.as_float(self, name)

    def as_dict(self) -> dict[str, Any]:
        """The conditions given and the delay (what the catalog said)."""
        return {f.name: getattr(self, f.name) for f in fields(self)
                if getattr(self, f.name) is not None}


def _when_rule(v: Any) -> str | None:
    if v is None or isinstance(v, ActorWhenSpec):
        return None
    if not isinstance(v, dict):
        return f"a table with keys {list(ActorWhenSpec._RULES)}"
    for k, value in v.items():
        if k not in ActorWhenSpec._RULES:
            return f"a table with keys {list(ActorWhenSpec._RULES)} (not {k!r})"
        problem = ActorWhenSpec._RULES[k](value)
        if problem:
            return f"{k}: {problem}"
    if not any(k in v for k in WHEN_CONDITIONS):
        return f"at least one condition of {list(WHEN_CONDITIONS)}"
    return None


@dataclass(frozen=True)
class ActorEventSpec:
    """What a scripted vehicle does once due (module docstring): ``lane_change`` lanes to
    the left (> 0) or right (< 0) of the lane it is in then (SUMO's continuous lane change,
    without regard for other drivers: a cut-in is a cut-in); ``speed_mps`` a new speed
    [m/s], reached at ``accel_mps2`` [m/s²] (a linear ramp, up or down) and then held.
    At least one of the two. Due: at run time ``t_s`` [s] or later, and with ``when``
    once its conditions held for its delay; ``t_s`` is required without ``when``."""

    t_s: float | None = None
    lane_change: int = 0
    speed_mps: float | None = None
    accel_mps2: float = 2.0
    when: ActorWhenSpec | None = None

    _RULES: ClassVar[dict[str, Rule]] = {
        "t_s": rules.num(0.0, optional=True), "lane_change": rules.lane_change,
        "speed_mps": rules.num(0.0, optional=True),
        "accel_mps2": rules.num(0.0, strict=True), "when": _when_rule,
    }
    _REQUIRED: ClassVar[tuple[str, ...]] = ()

    def __post_init__(self) -> None:
        rules.check_fields(self)
        if isinstance(self.when, dict):
            try:
                object.__setattr__(self, "when", ActorWhenSpec(**self.when))
            except SpecError as exc:
                raise SpecError(f"when.{exc.field}", exc.expected, exc.got) from None
        if self.t_s is None and self.when is None:
            raise SpecError("t_s", "a run time t_s [s] or a when table (the event would "
                            "never start)", None)
        if self.lane_change == 0 and self.speed_mps is None:
            raise SpecError("lane_change", "a lane change (+/-1, ...) or a speed_mps in the "
                            "event (it does nothing)", self.lane_change)
        rules.as_float(self, "accel_mps2")
        for name in ("t_s", "speed_mps"):
            if getattr(self, name) is not None:
                rules.as_float(self, name)

    @property
    def earliest_s(self) -> float:
        """The earliest run time [s] it may start (``t_s``, else 0)."""
        return 0.0 if self.t_s is None else float(self.t_s)

    def as_dict(self) -> dict[str, Any]:
        """Its fields, ``when`` only when given (so that a catalog without triggers reads
        as it always did)."""
        out: dict[str, Any] = {"t_s": self.t_s, "lane_change": self.lane_change,
                               "speed_mps": self.speed_mps, "accel_mps2": self.accel_mps2}
        if self.when is not None:
            out["when"] = self.when.as_dict()
        return out


@dataclass(frozen=True)
class ActorSpec:
    """A scripted vehicle: starts at t = 0 in lane ``lane`` with its front bumper at route
    position ``pos_m`` [m] at ``speed_mps`` [m/s], holds that speed and its lane (it
    still brakes for what is ahead of it, the ego included) and does its ``events`` in
    order (module docstring). Its SUMO id is ``actor_<id>``. A catalog may give
    ``ahead_of_ego_m`` instead of ``pos_m`` (the loader resolves it:
    :func:`resolve_relative_start`)."""

    id: str
    lane: int
    pos_m: float
    speed_mps: float
    length_m: float = 4.5
    width_m: float = 1.8
    events: tuple[ActorEventSpec, ...] = ()

    _RULES: ClassVar[dict[str, Rule]] = {
        "id": rules.name_rule, "lane": rules.integer(0), "pos_m": rules.num(0.0),
        "speed_mps": rules.num(0.0), "length_m": rules.num(0.0, strict=True),
        "width_m": rules.num(0.0, strict=True), "events": rules.table_list,
    }
    _REQUIRED: ClassVar[tuple[str, ...]] = ("id", "lane", "pos_m", "speed_mps")

    def __post_init__(self) -> None:
        rules.check_fields(self)
        events = []
        for i, ev in enumerate(self.events):
            if isinstance(ev, ActorEventSpec):
                events.append(ev)
                continue
            try:
                events.append(ActorEventSpec(**ev))
            except SpecError as exc:
                raise SpecError(f"events.{i}.{exc.field}", exc.expected, exc.got) from None
            except TypeError:
                raise SpecError(f"events.{i}", "a table with keys "
                                f"{list(ActorEventSpec._RULES)}", ev) from None
        timed = [ev.t_s for ev in events if ev.t_s is not None]
        if timed != sorted(timed):
            raise SpecError("events", "events in time order (t_s ascending)", timed)
        object.__setattr__(self, "events", tuple(events))
        rules.as_float(self, "pos_m", "speed_mps", "length_m", "width_m")

    @property
    def sumo_id(self) -> str:
        return f"actor_{self.id}"

    def as_dict(self) -> dict[str, Any]:
        """Plain values (JSON-able), the events' as :meth:`ActorEventSpec.as_dict`."""
        out: dict[str, Any] = {f.name: getattr(self, f.name) for f in fields(self)}
        out["events"] = [ev.as_dict() for ev in self.events]
        return out


RELATIVE_START = "ahead_of_ego_m"


def resolve_relative_start(item: dict[str, Any], ego: Any) -> tuple[dict[str, Any], str | None]:
    """An actor table with ``ahead_of_ego_m`` [m] turned into one with ``pos_m`` = the
    ego's ``pos_m`` + that (front bumpers, along the route; negative: behind the ego, but
    not before the route's start); returns (the table, a problem or None). A table
    without it is returned as it is."""
    if RELATIVE_START not in item:
        return item, None
    ahead = item[RELATIVE_START]
    if "pos_m" in item:
        return item, "either pos_m or ahead_of_ego_m, not both"
    if not rules.is_number(ahead):
        return item, "a finite number [m] (negative: behind the ego)"
    ego_pos = ego.get("pos_m") if isinstance(ego, dict) else None
    if not isinstance(ego_pos, int | float) or not rules.is_number(ego_pos):
        return item, "an ego with a pos_m to be relative to"
    pos = float(ego_pos) + float(ahead)
    if pos < 0.0:
        return item, (f"a place on the route: the ego's pos_m + this must be >= 0 (it is "
                      f"{pos:g} m)")
    out = {k: v for k, v in item.items() if k != RELATIVE_START}
    out["pos_m"] = pos
    return out, None
