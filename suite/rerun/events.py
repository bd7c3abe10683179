"""The text of a recording: the event log (``/events``) and the two documents.

Events, each at the step it happens: start; collisions (geometric overlap onsets and
SUMO-reported episodes, ERROR); fallback onsets (WARN); pass-side changes (INFO); each
failed criterion at the trace row its verdict located it (WARN; aggregates such as
progress at the end); the final status (INFO when it passed, else ERROR).

``/docs/scenario``: status and failures, the scenario's parameters, the criteria and
metrics of the verdict (with units), stalled cars, SUMO collisions, SSM, run.json.
``/docs/controller``: the controller's options and parameters.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import numpy as np
import rerun as rr

from reports.record import SumoCollision
from reports.record.codec import to_plain
from suite.rerun.paths import ENTITY_PATHS
from suite.rerun.stream import RunLog, time_columns
from suite.rerun.world import SIDE_NAME


@dataclass(frozen=True)
class Event:
    """A line of the event log at a trace row."""

    row: int
    level: str
    text: str


def _rising(flag: np.ndarray) -> np.ndarray:
    prev = np.concatenate([[False], flag[:-1]])
    return np.flatnonzero(flag & ~prev)


def collision_episodes(log: RunLog, collisions: tuple[SumoCollision, ...]
                       ) -> list[tuple[int, SumoCollision, int]]:
    """SUMO reports a lasting collision every step: one (row, first report, count) per
    run of reports of the same pair on consecutive steps."""
    end = max(log.n - 1, 0)
    dt = log.record.info.step_s if log.record.info.step_s > 0 else (
        float(np.median(np.diff(log.t))) if log.n > 1 else 0.1)
    episodes: list[tuple[int, SumoCollision, int]] = []
    last: dict[tuple[str, str, str], tuple[int, float]] = {}  # pair -> (episode, t)
    for c in sorted(collisions, key=lambda c: c.t_s):
        pair = (c.collider, c.victim, c.type)
        prev = last.get(pair)
        if prev is not None and c.t_s - prev[1] <= 1.5 * dt + 1e-9:
            row, first, count = episodes[prev[0]]
            episodes[prev[0]] = (row, first, count + 1)
            last[pair] = (prev[0], c.t_s)
            continue
        row = int(np.clip(np.searchsorted(log.t, c.t_s - 1e-9), 0, end)) if log.n else 0
        episodes.append((row, c, 1))
        last[pair] = (len(episodes) - 1, c.t_s)
    return episodes


def _collision_events(log: RunLog) -> list[Event]:
    safety = log.record.trace.safety
    out = []
    for i in _rising(safety.geom_collision):
        who = f" with {safety.gap_vehicle[i]}" if safety.gap_vehicle[i] else ""
        out.append(Event(int(i), "ERROR", f"COLLISION (geometry){who} at t={log.t[i]:.2f} s"))
    reported = log.record.outcome.sumo_collisions
    for i, c, count in collision_episodes(log, reported):
        more = f" (reported on {count} steps)" if count > 1 else ""
        out.append(Event(i, "ERROR", f"COLLISION (SUMO, {c.type}): {c.collider} -> "
                                     f"{c.victim} at t={c.t_s:.2f} s{more}"))
    if not reported:
        for i in _rising(safety.sumo_collision):
            out.append(Event(int(i), "ERROR", f"COLLISION (SUMO) at t={log.t[i]:.2f} s"))
    return out


def _behaviour_events(log: RunLog) -> list[Event]:
    trace = log.record.trace
    out = []
    fallback = trace.controller.fallback
    for i in _rising(fallback):
        run_len = int(np.argmin(np.append(fallback[i:], False)))
        out.append(Event(int(i), "WARN", f"fallback: safe fallback replaced the plan "
                                         f"({run_len} step{'s' if run_len != 1 else ''})"))
    side = np.asarray(trace.decision.side, dtype=np.int64)
    prev = 0
    for i in range(log.n):
        if side[i] != prev:
            reason = trace.decision.side_reason[i]
            why = f" ({reason})" if reason else ""
            out.append(Event(i, "INFO", f"side: {SIDE_NAME.get(prev, str(prev))} -> "
                                        f"{SIDE_NAME.get(int(side[i]), str(side[i]))}{why}"))
            prev = int(side[i])
    return out


def _verdict_events(log: RunLog) -> list[Event]:
    record = log.record
    end = max(log.n - 1, 0)
    failures = record.verdict.failures if record.verdict is not None else ()
    out = []
    for f in failures:
        if f.step is not None and 0 <= f.step < log.n:
            out.append(Event(f.step, "WARN", f"criterion violated: {f.text} "
                                             f"(at t={log.t[f.step]:.2f} s)"))
        else:
            out.append(Event(end, "WARN", f"criterion violated: {f.text} "
                                          "(whole run, logged at the end)"))
    status = record.status
    text = f"status: {status.upper()}"
    if failures:
        text += " — failed: " + ", ".join(f.text for f in failures)
    if record.outcome.error:
        text += " — error: " + record.outcome.error.strip().splitlines()[-1]
    out.append(Event(end, "INFO" if status == "pass" else "ERROR", text))
    return out


def collect_events(log: RunLog) -> list[Event]:
    """Every event of the run (see the module doc), in row order (stable)."""
    info = log.record.info
    events = [Event(0, "INFO", f"start: {info.scenario} — controller {info.controller}, "
                               f"seed {info.seed}")]
    if log.n:
        events += _collision_events(log) + _behaviour_events(log)
    events += _verdict_events(log)
    return sorted(events, key=lambda e: e.row)


def log_events(log: RunLog, events: list[Event]) -> None:
    rows = np.array([e.row for e in events], dtype=np.int64)
    if log.n:
        steps, t = log.steps[rows], log.t[rows]
    else:
        steps, t = np.zeros(len(rows), np.int64), np.zeros(len(rows))
    log.send(ENTITY_PATHS["events"],
             rr.TextLog.columns(text=[e.text for e in events], level=[e.level for e in events]),
             idx=time_columns(steps, t))


def _md_json(obj: Any) -> str:
    return "```json\n" + json.dumps(to_plain(obj), indent=2, sort_keys=True, default=str) \
        + "\n```\n"


def _metrics_table(log: RunLog) -> list[str]:
    verdict = log.record.verdict
    if verdict is None:
        return ["(not judged)", ""]
    failed = {f.metric for f in verdict.failures}
    rows = ["| metric | value | unit | kind |", "|---|---|---|---|"]
    rows += [f"| {'**' + m.name + '**' if m.name in failed else m.name} | {m.value:.6g} | "
             f"{m.unit} | {m.kind} |" for m in verdict.metrics]
    return rows + [""]


def scenario_markdown(log: RunLog) -> str:
    record = log.record
    info, outcome, verdict = record.info, record.outcome, record.verdict
    failures = verdict.failures if verdict is not None else ()
    head = [f"# {info.scenario}", "",
            f"**status: {record.status.upper()}**"
            + (f" — failed: {', '.join(f.text for f in failures)}" if failures else ""), ""]
    if outcome.error:
        head += ["```", outcome.error.strip().splitlines()[-1], "```", ""]
    facts = [("controller", info.controller), ("catalog", info.catalog), ("seed", info.seed),
             ("net", info.net), ("duration_s", info.duration_s), ("step_s", info.step_s),
             ("target_speed_mps", info.target_speed_mps), ("sim_time_s", outcome.sim_time_s),
             ("wall_s", outcome.wall_s), ("stop_reason", outcome.stop_reason)]
    head += ["| parameter | value |", "|---|---|"] + [f"| {k} | {v} |" for k, v in facts]
    body = ["", "## Criteria", _md_json(verdict.criteria if verdict is not None else {}),
            "## Metrics", *_metrics_table(log),
            "## Stalled vehicles", _md_json(outcome.stalled),
            "## SUMO collisions", _md_json(outcome.sumo_collisions),
            "## SSM", _md_json(outcome.ssm),
            "## run.json", _md_json({"info": info, "outcome": {
                k: v for k, v in to_plain(outcome).items() if k != "error"}})]
    return "\n".join(head + body)


def log_docs(log: RunLog) -> None:
    info = log.record.info
    log.static(ENTITY_PATHS["scenario_doc"], rr.TextDocument(
        scenario_markdown(log), media_type=rr.MediaType.MARKDOWN))
    ctrl = ["# Controller: " + info.controller, "",
            "## Options", _md_json(info.controller_options),
            "## Parameters", _md_json(info.controller_params)]
    log.static(ENTITY_PATHS["controller_doc"], rr.TextDocument(
        "\n".join(ctrl), media_type=rr.MediaType.MARKDOWN))
