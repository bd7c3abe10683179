"""One run's page (``report-runs/<run>.html``): why it failed, where, and its plots.

Header: status, scenario, controller variant, back to the index, the run's ``.rrd``
and directory and the command that opens the log. Then its failures (each criterion
with value vs limit and where, ``id="failures"``), the error text of an error run, the
collisions on which SUMO's report and the 2-D boxes disagree
(``id="collision-disagreements"``, when there are any), the metrics table (units,
limits), the bird's-eye views (whole run and zoomed at the first failure or the closest
approach) and the time series (:mod:`reports.html.runs`). A run with recorded traffic
has a line ``id="replay"`` after the failures: its tracks file and mode, how many
recorded vehicles it had, how many of them were handed over to SUMO (reactive) and when
the first was, and the collisions of replayed cars driving into the ego (not at fault).
"""

from __future__ import annotations

from reports.charts import esc, fmt
from reports.html.birdseye import birdseye_svg
from reports.html.failures import badge, failure_detail, log_link, value_vs_limit, when
from reports.html.links import STYLE, Links
from reports.html.marks import Mark, failure_marks
from reports.html.runs import collision_disagreements, metrics_table, time_series
from reports.tables import RunEntry


def zoom_focus(run: RunEntry, marks: list[Mark]) -> tuple[int, str] | None:
    """Where to zoom the bird's-eye view: the first mark, else the closest approach."""
    if marks:
        return marks[0].row, marks[0].name
    gap = run.verdict.metric("min_gap_m") if run.verdict is not None else None
    if gap is None or gap.worst_step is None:
        return None
    return gap.worst_step, f"closest approach ({fmt(gap.value, 3)} m)"


def _failures(run: RunEntry) -> str:
    if run.status == "pass":
        return '<section id="failures"><p class="allpass">passed every criterion</p></section>'
    items = []
    for f in run.failures:
        step = f", step {f.step}" if f.step is not None else ""
        detail = failure_detail(f, run.metrics)
        where = f"<br><span class=\"meta\">{esc(detail)}</span>" if detail else ""
        items.append(f"<li><b>{esc(f.criterion)}</b>: {esc(f.metric)} = {value_vs_limit(f)} "
                     f"({esc(when(f))}{step}){where}</li>")
    err = f'<pre class="err">{esc(run.error)}</pre>' if run.error else ""
    return (f'<section id="failures"><h2>Why it did not pass</h2><ul>{"".join(items)}</ul>'
            f"{err}</section>")


def xfail_line(run: RunEntry) -> str:
    """The known-failure mark of a run page ('' without one, reports.expectation)."""
    mark = run.xfail
    if mark is None:
        return ""
    did = {"xfail": "failed as expected", "xpass": "passed: fixed, remove the xfail"}.get(
        run.expectation, f"ended {run.status}: not the expected failure")
    return (f'<p id="xfail" class="meta">{badge(run.expectation or run.status)} known failure '
            f"({esc(mark.text)}): {esc(did)}</p>")


def replay_line(run: RunEntry) -> str:
    """The recorded-traffic line of a run page ('' without recorded traffic)."""
    rec = run.record
    rp = rec.outcome.replay if rec is not None else None
    if rp is None:
        return ""
    hand = rp.handovers
    first = f" (first at t = {fmt(hand[0].t_s, 3)} s, {esc(hand[0].track_id)})" if hand else ""
    into = run.verdict.metric("collisions_replayed_into_ego") if run.verdict is not None \
        else None
    hits = (f" · {fmt(into.value)} collision(s) of replayed cars driving into the ego "
            "(not at fault)") if into is not None and into.value and into.value > 0 else ""
    return (f'<p id="replay" class="meta">recorded traffic <code>{esc(rp.tracks)}</code>, '
            f"mode {esc(rp.mode)}: {rp.vehicles} recorded vehicle(s), "
            f"{len(hand)} handed over to SUMO{first}{hits}</p>")


def render_run_page(run: RunEntry, links: Links, index_title: str) -> str:
    """The page of one run (module doc)."""
    marks = failure_marks(run)
    run_dir = links.dir_href(run.run_dir, from_page=True)
    info = run.info
    seed = info.seed if info is not None else "–"
    views = [birdseye_svg(run.record, run.verdict, marks)]
    # the zoomed view where it failed (a passing run's page stays small: its closest
    # approach is in the Rerun log and the whole-run view)
    focus = zoom_focus(run, marks) if run.status != "pass" else None
    if focus is not None:
        views.append(birdseye_svg(run.record, run.verdict, marks, zoom=focus))
    mark_line = ("<p class=\"marks\">" + " · ".join(
        f'<span style="color:{m.colour}">✖ {esc(m.label)}</span>' for m in marks) + "</p>"
        if marks else "")
    return "".join([
        '<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">'
        f'<link rel="icon" href="data:,"><link rel="stylesheet" href="{STYLE}">'
        f"<title>{esc(run.scenario)} — {esc(run.status)}</title></head><body>",
        f'<header><h1>{badge(run.status)} {esc(run.scenario)}</h1><div class="counts">'
        f"<span>{esc(run.label)}</span><span>family {esc(run.family)}</span>"
        f"<span>seed {esc(seed)}</span><span>sim {fmt(run.sim_time_s)} s · wall "
        f"{fmt(run.wall_s, 3)} s</span></div><nav><a href=\"../report.html\">← "
        f"{esc(index_title)}</a> · {log_link(run, links, from_page=True)} · "
        f"<a href=\"{esc(run_dir)}\">run directory</a> · <code>hwyeval view "
        f"{esc(run.run_dir.parent.name)}/{esc(run.run_dir.name)}</code></nav></header><main>",
        _failures(run), xfail_line(run), replay_line(run), collision_disagreements(run),
        mark_line, "".join(views),
        time_series(run, marks), metrics_table(run),
        "</main></body></html>"])
