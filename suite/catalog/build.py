"""One merged scenario dict (a sweep variant, or the scenario itself) checked field by
field and, if it has no problem, built into a :class:`Scenario`.

Every problem is reported through a :class:`~suite.catalog.report.Report`, in a fixed
order: scalars, criteria, controller, net, route, ego, stalled, traffic, ramp traffic,
actors, replay (its tracks file read and checked: :func:`suite.catalog.tracks.read_tracks`),
then the placements and the traffic on the network (only if the net and route are
usable).
"""

from __future__ import annotations

import difflib
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TypeVar

from suite.catalog.actors import RELATIVE_START, resolve_relative_start
from suite.catalog.controller_check import ControllerChecker
from suite.catalog.errors import MISSING, SpecError
from suite.catalog.network_checks import check_placements, resolve_net, resolve_route
from suite.catalog.report import Report
from suite.catalog.specs import (
    ActorEventSpec,
    ActorSpec,
    ControllerSpec,
    EgoSpec,
    RampTrafficSpec,
    ReplaySpec,
    Scenario,
    StalledSpec,
    TrafficSpec,
    XfailSpec,
    labels_problem,
    openscenario_problem,
    sumo_step_problem,
)
from suite.catalog.storyboard import Storyboard, StoryError, story_from_json
from suite.catalog.tracks import (
    TracksError,
    TrackSpan,
    ego_track_problem,
    read_tracks,
    track_spans,
)
from suite.catalog.traffic_checks import check_traffic

__all__ = ["build_variant"]

_Spec = TypeVar("_Spec", EgoSpec, StalledSpec, TrafficSpec, RampTrafficSpec, ActorSpec,
                ActorEventSpec, ReplaySpec, XfailSpec)

# resolved tracks file -> (size, mtime_ns, problem or None, its track spans): a catalog
# whose sweep expands one scenario many times reads its tracks file once (and keeps no
# samples: a spans table per file, not the tracks)
_TRACKS_CHECKED: dict[Path, tuple[int, int, TracksError | None, dict[str, TrackSpan]]] = {}

# Scalar keys of a scenario and their defaults (MISSING: required).
_SCALARS: tuple[tuple[str, Any], ...] = (
    ("duration_s", MISSING), ("step_s", MISSING), ("seed", 0), ("allow_shoulder", False),
    ("record_radius_m", 150.0), ("timeout_s", None), ("friction", 1.0), ("sumo_step_s", None),
)


def build_variant(d: dict[str, Any], report: Report, *, catalog_path: Path,
                  controllers: ControllerChecker, bundled: Sequence[str]) -> Scenario | None:
    """The scenario of the merged dict ``d``, or None if it has a problem (reported).
    ``report`` names the scenario and its family and holds the sweep values."""
    n_before = len(report.err.issues)
    scalars = _scalars(d, report)
    criteria = _criteria(d, report)
    controller = controllers.spec(d.get("controller", MISSING), report)
    net_path, network = resolve_net(d.get("net", MISSING), catalog_path, bundled, report)
    route = resolve_route(d.get("route", MISSING), network, report)
    ego = _spec(EgoSpec, d.get("ego", MISSING), "ego", report)
    stalled_raw = d.get("stalled", [])
    stalled = _stalled(stalled_raw, report)
    traffic = _traffic(d.get("traffic", MISSING), scalars, report)
    ramps = _ramps(d.get("ramp_traffic", []), report)
    actors_raw = _relative_starts(d.get("actors", []), d.get("ego"), report)
    actors = _actors(actors_raw, report)
    replay = _replay(d.get("replay", MISSING), catalog_path, report)
    xfail = _spec(XfailSpec, d.get("xfail", MISSING), "xfail", report)  # a known failure
    story = _storyboard(d.get("storyboard", MISSING), catalog_path, report)
    labels = _labels(d.get("labels", {}), report)
    _openscenario(d.get("openscenario", MISSING), report)
    _check_recorded_driver(controller, d.get("replay", MISSING), report)
    if network is not None and route is not None:
        check_placements(network, route, d.get("ego"), stalled_raw, traffic,
                         bool(scalars.get("allow_shoulder", False)), report,
                         actors_raw=actors_raw)
        check_traffic(network, route, traffic, ramps, report)

    if len(report.err.issues) != n_before:
        return None
    if (ego is None or controller is None or net_path is None or route is None
            or "duration_s" not in scalars or "step_s" not in scalars):
        return None  # a required key is missing (reported by the loader)
    try:
        return Scenario(
            name=report.name, family=report.family, catalog_path=catalog_path, net=d["net"],
            net_path=net_path, route=route, ego=ego,
            stalled=tuple(s for s in stalled if s is not None), traffic=traffic,
            controller=controller, duration_s=scalars["duration_s"],
            step_s=scalars["step_s"], seed=scalars["seed"],
            allow_shoulder=scalars["allow_shoulder"], criteria=criteria,
            sweep_values=report.swept, record_radius_m=scalars["record_radius_m"],
            timeout_s=scalars["timeout_s"], friction=scalars["friction"],
            ramp_traffic=tuple(r for r in ramps if r is not None),
            actors=tuple(a for a in actors if a is not None),
            sumo_step_s=scalars.get("sumo_step_s"), replay=replay, xfail=xfail,
            storyboard=None if story is None else str(d["storyboard"]), story=story,
            labels=labels)
    except SpecError as exc:  # pragma: no cover - the checks above mirror these
        report.add(exc.field, exc.expected, exc.got)
        return None


def _scalars(d: dict[str, Any], report: Report) -> dict[str, Any]:
    """The valid scalar values (defaults filled in); a missing required one is left out."""
    scalars: dict[str, Any] = {}
    for key, default in _SCALARS:
        value = d.get(key, default)
        if value is MISSING:
            continue  # reported as missing already
        problem = Scenario._RULES[key](value)
        if problem:
            report.add(key, problem, value)
        else:
            scalars[key] = value
    if ("duration_s" in scalars and "step_s" in scalars
            and scalars["step_s"] > scalars["duration_s"]):
        report.add("step_s", f"a step <= duration_s ({scalars['duration_s']:g})",
                   scalars["step_s"])
    if scalars.get("sumo_step_s") is not None and "step_s" in scalars:
        problem = sumo_step_problem(scalars["sumo_step_s"], scalars["step_s"])
        if problem:
            report.add("sumo_step_s", problem, scalars["sumo_step_s"])
            del scalars["sumo_step_s"]
    return scalars


def _criteria(d: dict[str, Any], report: Report) -> dict[str, Any]:
    """The scenario's criteria table (names known to the metrics, values numbers or
    "off", which switches that criterion off)."""
    criteria = d.get("criteria", {})
    if not isinstance(criteria, dict):
        report.add("criteria", 'a table of name -> finite number or "off"', criteria)
        return {}
    from reports.metrics.criteria import Criteria, override_problem

    valid = Criteria.names()
    for k, v in criteria.items():
        if k not in valid:
            report.add(f"criteria.{k}", f"a known criterion, one of {', '.join(valid)}", k)
        elif v is None or override_problem(v) is not None:
            report.add(f"criteria.{k}", 'a finite number or "off"', v)
    return criteria


def _labels(raw: Any, report: Report) -> dict[str, str]:
    """The scenario's labels (:func:`suite.catalog.specs.labels_problem`), {} if invalid
    (reported)."""
    problem = labels_problem(raw)
    if problem is not None:
        report.add("labels", problem, raw)
        return {}
    return dict(raw)


def _openscenario(raw: Any, report: Report) -> None:
    """The ``openscenario`` table, checked as data only (the run does not read it;
    ``hwyeval search`` imports its template per point): problems at its key."""
    if raw is MISSING:
        return
    problem = openscenario_problem(raw)
    if problem is not None:
        report.add(*problem)


def _stalled(raw: Any, report: Report) -> list[StalledSpec | None]:
    if not isinstance(raw, list):
        report.add("stalled", "a list of tables [{lane = ..., pos_m = ...}, ...]", raw)
        return []
    return [_spec(StalledSpec, item, f"stalled.{i}", report) for i, item in enumerate(raw)]


def _ramps(raw: Any, report: Report) -> list[RampTrafficSpec | None]:
    if not isinstance(raw, list):
        report.add("ramp_traffic", "a list of tables [{edge = ..., vehicles_per_hour = ...}, "
                   "...]", raw)
        return []
    return [_spec(RampTrafficSpec, item, f"ramp_traffic.{i}", report)
            for i, item in enumerate(raw)]


def _relative_starts(raw: Any, ego: Any, report: Report) -> Any:
    """The actor tables with ``ahead_of_ego_m`` resolved to ``pos_m``
    (:func:`suite.catalog.actors.resolve_relative_start`); a problem is reported at the
    actor's ``ahead_of_ego_m`` and that actor left out."""
    if not isinstance(raw, list):
        return raw  # reported by _actors
    out = []
    for i, item in enumerate(raw):
        if not isinstance(item, dict):
            out.append(item)
            continue
        resolved, problem = resolve_relative_start(item, ego)
        if problem is not None:
            report.add(f"actors.{i}.{RELATIVE_START}", problem, item.get(RELATIVE_START))
            continue
        out.append(resolved)
    return out


def _actors(raw: Any, report: Report) -> list[ActorSpec | None]:
    """The scripted vehicles, every bad field of them and of their events reported."""
    if not isinstance(raw, list):
        report.add("actors", "a list of tables [{id = ..., lane = ..., pos_m = ..., "
                   "speed_mps = ...}, ...]", raw)
        return []
    out: list[ActorSpec | None] = []
    seen: set[str] = set()
    for i, item in enumerate(raw):
        key = f"actors.{i}"
        if not isinstance(item, dict):
            report.add(key, f"a table with keys {list(ActorSpec._RULES)}", item)
            out.append(None)
            continue
        events_raw = item.get("events", [])
        events: list[ActorEventSpec | None] = []
        if isinstance(events_raw, list):
            events = [_spec(ActorEventSpec, ev, f"{key}.events.{j}", report)
                      for j, ev in enumerate(events_raw)]
        actor = _spec(ActorSpec, {**item, "events": []}, key, report) \
            if "events" not in item or isinstance(events_raw, list) else None
        if not isinstance(events_raw, list):
            report.add(f"{key}.events", "a list of tables [{t_s = ..., lane_change = ...}, "
                       "...]", events_raw)
        if actor is None or any(ev is None for ev in events):
            out.append(None)
            continue
        try:
            actor = ActorSpec(**{**item, "events": tuple(events)})
        except SpecError as exc:
            report.add(f"{key}.{exc.field}", exc.expected, exc.got)
            out.append(None)
            continue
        if actor.id in seen:
            report.add(f"{key}.id", "an id no other actor of the scenario has", actor.id)
            out.append(None)
            continue
        seen.add(actor.id)
        out.append(actor)
    return out


def _replay(raw: Any, catalog_path: Path, report: Report) -> ReplaySpec | None:
    """The ``replay`` table with its tracks file resolved (relative to the catalog) and
    read; a missing or unusable file is reported at ``replay.tracks``."""
    spec = _spec(ReplaySpec, raw, "replay", report)
    if spec is None:
        return None
    path = Path(spec.tracks).expanduser()
    if not path.is_absolute():
        path = catalog_path.parent / path
    if not path.is_file():
        report.add("replay.tracks", f"an existing tracks file (Parquet, relative to "
                   f"{catalog_path.parent}; not found: {path})", spec.tracks)
        return None
    path = path.resolve()
    problem, spans = _tracks_problem(path)
    if problem is not None:
        report.add("replay.tracks", f"a valid tracks file: {problem.path}: {problem.key}: "
                   f"expected {problem.expected}", spec.tracks)
        return None
    if spec.ego_track is not None:
        ego_problem = ego_track_problem(spans, spec.ego_track)
        if ego_problem is not None:
            report.add("replay.ego_track", f"{ego_problem} in {path}", spec.ego_track)
            return None
    return ReplaySpec(tracks=spec.tracks, mode=spec.mode,
                      handover_time_gap_s=spec.handover_time_gap_s,
                      lane_changes=spec.lane_changes, tracks_path=path,
                      ego_track=spec.ego_track)


def _storyboard(raw: Any, catalog_path: Path, report: Report) -> Storyboard | None:
    """The ``storyboard`` file (relative to the catalog) read and checked
    (:func:`suite.catalog.storyboard.story_from_json`); problems at ``storyboard``."""
    if raw is MISSING or raw is None:
        return None
    if not isinstance(raw, str) or not raw:
        report.add("storyboard", "a storyboard file path (.story.json), relative to the "
                   "catalog", raw)
        return None
    path = Path(raw).expanduser()
    path = path if path.is_absolute() else catalog_path.parent / path
    try:
        return story_from_json(path.read_text(encoding="utf-8"))
    except OSError as exc:
        report.add("storyboard", f"a readable storyboard file ({exc})", raw)
    except StoryError as exc:
        report.add("storyboard", f"a valid storyboard ({exc})", raw)
    return None


RECORDED_DRIVER = "recorded"  # controllers.baselines.recorded_driver.NAME


def _check_recorded_driver(controller: ControllerSpec | None, raw_replay: Any,
                           report: Report) -> None:
    """The ``recorded`` controller drives the ego's recorded track: the scenario must
    name one (``replay.ego_track``); a bad one is reported at that key already."""
    if controller is None or controller.name != RECORDED_DRIVER:
        return
    if isinstance(raw_replay, dict) and raw_replay.get("ego_track") is not None:
        return
    report.add("controller", "a controller the scenario can run: 'recorded' drives the "
               "ego along its recorded track, and this scenario names none (replay.ego_track"
               "; hwyeval import commonroad --ego-obstacle ID makes a recorded vehicle the "
               "ego)", controller.name)


def _tracks_problem(path: Path) -> tuple[TracksError | None, dict[str, TrackSpan]]:
    """Why the tracks file at ``path`` is unusable (None: it is usable) and its tracks'
    spans (empty when unusable), cached by its size and modification time."""
    st = path.stat()
    cached = _TRACKS_CHECKED.get(path)
    if cached is not None and cached[:2] == (st.st_size, st.st_mtime_ns):
        return cached[2], cached[3]
    spans: dict[str, TrackSpan] = {}
    try:
        spans = track_spans(read_tracks(path))
        problem = None
    except TracksError as exc:
        problem = exc
    _TRACKS_CHECKED[path] = (st.st_size, st.st_mtime_ns, problem, spans)
    return problem, spans


def _traffic(raw: Any, scalars: dict[str, Any], report: Report) -> TrafficSpec | None:
    """The traffic spec; its ``seed`` defaults to the scenario's."""
    if raw is MISSING:
        return None
    if isinstance(raw, dict) and "seed" not in raw:
        raw = {**raw, "seed": scalars.get("seed", 0)}
    return _spec(TrafficSpec, raw, "traffic", report)


def _spec(cls: type[_Spec], raw: Any, key: str, report: Report) -> _Spec | None:
    """``cls(**raw)`` for a spec table at ``key``, after reporting every bad field."""
    if raw is MISSING:
        return None  # a missing required table is reported by the required-key check
    if not isinstance(raw, dict):
        report.add(key, f"a table with keys {list(cls._RULES)}", raw)
        return None
    ok = True
    for k, v in raw.items():
        if k not in cls._RULES:
            close = difflib.get_close_matches(str(k), list(cls._RULES), n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            report.add(f"{key}.{k}", f"one of the keys {list(cls._RULES)}{hint}", k)
            ok = False
        else:
            problem = cls._RULES[k](v)
            if problem:
                report.add(f"{key}.{k}", problem, v)
                ok = False
    for k in cls._REQUIRED:
        if k not in raw:
            report.add(f"{key}.{k}", "this required key")
            ok = False
    if not ok:
        return None
    try:
        return cls(**raw)
    except SpecError as exc:
        report.add(f"{key}.{exc.field}", exc.expected, exc.got)
        return None
