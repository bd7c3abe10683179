"""compare by the three kinds of change (reports.identity): a run whose test is unchanged
gates whatever happened to the system under test (a controller swapped or its options
changed in the catalog); a changed test, a changed limit and a waiver are labelled and do
not gate; older run directories without the split digests still compare; known failures
(xfail, strict and not); compare.html's charts are drawn, not painted black. Synthetic
runs (tests/synthetic_runs.py) written as the runner writes them."""

from __future__ import annotations

import dataclasses
import json
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import synthetic_runs as sr
from browser import chromium, needs_chromium, screenshot

from reports.compare import compare_runs
from reports.expectation import XFAIL_KEY
from reports.identity import CONTROLLER_KEY, TEST_KEY
from reports.junit import junit_tree
from reports.record import RunRecord, write_run
from reports.tables import collect_runs

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = "cruise_straight"
TEST = "7" * 64  # the test digest both nights' runs of SCENARIO share


def _record(trace_of: str, controller: str, params: dict[str, Any], code: str,
            test: str = TEST, xfail: dict[str, Any] | None = None) -> RunRecord:
    """SCENARIO run by ``controller`` with ``params``, its trajectory that of the
    synthetic catalog's ``trace_of`` run (``rear_end__ctrl_a``: an at-fault collision)."""
    record = dict(sr.catalog_records(("ctrl_a",)))[trace_of]
    spec: dict[str, Any] = {"controller": {"name": controller, "options": params},
                            TEST_KEY: test, CONTROLLER_KEY: code}
    if xfail is not None:
        spec[XFAIL_KEY] = xfail
    record.info = dataclasses.replace(record.info, scenario=SCENARIO, family="cruise",
                                      controller=controller, controller_params=params,
                                      scenario_spec=spec)
    return record


def _night(path: Path, record: RunRecord, criteria: dict[str, object] | None = None) -> Path:
    """A night of SCENARIO's run ``record`` (judged with the catalog's ``criteria``) and
    the synthetic catalog's passing cruise on a curve, which nothing changes."""
    write_run(sr.judge(record, criteria), path / SCENARIO)
    other = dict(sr.catalog_records(("ctrl_a",)))["lane_change_left__ctrl_a"]
    write_run(sr.judge(other, criteria), path / "lane_change_left")
    return path


def _base(tmp_path: Path) -> Path:
    return _night(tmp_path / "base", _record(f"{SCENARIO}__ctrl_a", "ctrl_a", {"gain": 1.0},
                                             "c" * 64))


def _rows(result: Any, category: str) -> list[Any]:
    return [r for r in result.rows if r.scenario == SCENARIO and r.category == category]


def test_a_controller_swapped_in_the_catalog_gates_a_new_at_fault_collision(
        tmp_path: Path) -> None:
    base = _base(tmp_path)
    new = _night(tmp_path / "new", _record("rear_end__ctrl_a", "ctrl_b", {"gain": 1.0},
                                           "d" * 64))
    result = compare_runs(base, new, tmp_path / "cmp")
    assert result.exit_code == 1
    (gate,) = [r for r in result.regressions if r.kind == "new_failure"]
    assert gate.category == "behaviour_regression"
    (run,) = [r for r in collect_runs(new) if r.scenario == SCENARIO]
    assert "at_fault_collisions" in {f.metric for f in run.failures}
    assert "system under test changed" in gate.note  # what the gate reports, as asked
    (sut,) = _rows(result, "sut_changed")
    assert "ctrl_a" in sut.note and "ctrl_b" in sut.note
    assert not _rows(result, "test_changed")


@pytest.mark.slow  # the CLI in a subprocess
def test_a_controller_option_changed_in_the_catalog_gates_a_new_at_fault_collision(
        tmp_path: Path) -> None:
    base = _base(tmp_path)
    new = _night(tmp_path / "new", _record("rear_end__ctrl_a", "ctrl_a", {"gain": 3.0},
                                           "c" * 64))
    proc = subprocess.run([sys.executable, "-m", "suite", "compare", str(base), str(new),
                           "--json"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1, proc.stderr
    doc = json.loads(proc.stdout)
    gates = [r for r in doc["regressions"] if r["scenario"] == SCENARIO]
    assert {r["kind"] for r in gates} == {"behaviour_regression"}
    assert any("system under test changed" in r["note"] and "gain" in r["note"] for r in gates)
    assert [r["finding"] for r in doc["rows"] if r["kind"] == "sut_changed"] == ["sut_changed"]


def test_a_changed_test_is_labelled_and_does_not_gate(tmp_path: Path) -> None:
    base = _base(tmp_path)
    new = _night(tmp_path / "new", _record("rear_end__ctrl_a", "ctrl_b", {"gain": 1.0},
                                           "d" * 64, test="8" * 64))
    result = compare_runs(base, new, tmp_path / "cmp")
    assert result.exit_code == 0 and not result.regressions
    assert any(r.kind == "new_failure" for r in _rows(result, "test_changed"))


def test_a_criterion_edit_and_a_waiver_are_labelled_and_do_not_gate(tmp_path: Path) -> None:
    base = _base(tmp_path)
    same = _record(f"{SCENARIO}__ctrl_a", "ctrl_a", {"gain": 1.0}, "c" * 64)
    tight = _night(tmp_path / "tight", same, {"min_progress_fraction": 0.999})
    result = compare_runs(base, tight, tmp_path / "cmp1")
    assert result.exit_code == 0 and _rows(result, "limits_changed")
    waived = _night(tmp_path / "waived", _record(f"{SCENARIO}__ctrl_a", "ctrl_a",
                                                 {"gain": 1.0}, "c" * 64),
                    {"max_abs_jerk_mps3": "off"})
    result = compare_runs(base, waived, tmp_path / "cmp2")
    assert result.exit_code == 0 and result.fixed == []
    assert [r.kind for r in _rows(result, "waived")] == ["criterion_off"]


def test_older_run_directories_without_the_split_digests_still_compare(tmp_path: Path
                                                                        ) -> None:
    base = _base(tmp_path)
    for run_json in base.glob("*/run.json"):  # as an older hwyeval wrote them
        data = json.loads(run_json.read_text())
        data["info"]["scenario_spec"] = {}
        data["info"]["controller_params"] = {}
        run_json.write_text(json.dumps(data))
    new = _night(tmp_path / "new", _record("rear_end__ctrl_a", "ctrl_b", {"gain": 1.0},
                                           "d" * 64))
    result = compare_runs(base, new, tmp_path / "cmp")
    # the test is compared by the recorded fields (here RunInfo's own): unchanged, so
    # the new collision gates
    assert result.exit_code == 1 and not _rows(result, "test_changed")


@pytest.mark.parametrize("strict", [True, False])
def test_a_known_failure(tmp_path: Path, strict: bool) -> None:
    mark = {"reason": "issue 41", "strict": strict}
    base = _night(tmp_path / "base", _record("rear_end__ctrl_a", "ctrl_a", {"gain": 1.0},
                                             "c" * 64, xfail=mark))
    runs = collect_runs(base)
    (known,) = [r for r in runs if r.scenario == SCENARIO]
    assert known.expectation == "xfail" and not known.fails_night
    case = junit_tree(runs).getroot().find(f".//testcase[@name='{SCENARIO}']")
    assert case is not None and case.find("skipped") is not None and case.find("failure") is None
    # still failing the same way: listed, does not gate
    again = _night(tmp_path / "again", _record("rear_end__ctrl_a", "ctrl_a", {"gain": 1.0},
                                               "c" * 64, xfail=mark))
    result = compare_runs(base, again, tmp_path / "cmp1")
    assert result.exit_code == 0 and [r.kind for r in _rows(result, "known_failure")] == [
        "xfailed"]
    # it passes: "fixed: remove the xfail", gating only when strict
    fixed = _night(tmp_path / "fixed", _record(f"{SCENARIO}__ctrl_a", "ctrl_a",
                                               {"gain": 1.0}, "c" * 64, xfail=mark))
    result = compare_runs(base, fixed, tmp_path / "cmp2")
    (xpass,) = [r for r in _rows(result, "known_failure") if r.kind == "xpass"]
    assert xpass.gate is strict and result.exit_code == int(strict)
    assert result.fixed == [xpass.key]
    (passed,) = [r for r in collect_runs(fixed) if r.scenario == SCENARIO]
    assert passed.expectation == "xpass" and passed.fails_night is strict
    case = junit_tree(collect_runs(fixed)).getroot().find(f".//testcase[@name='{SCENARIO}']")
    assert case is not None and (case.find("failure") is not None) is strict


def _plot_area(png: Path, box: tuple[int, int, int, int]) -> tuple[int, float]:
    """(how many distinct colours, the luminance in [0, 1] of the commonest one) of the
    plot area ``box`` (left, top, right, bottom, px) of a chart's screenshot."""
    image = pytest.importorskip("PIL.Image")
    with image.open(png) as im:
        colours = im.convert("RGB").crop(box).getcolors(maxcolors=1 << 24) or []
    _, (r, g, b) = max(colours)
    return len(colours), (0.2126 * r + 0.7152 * g + 0.0722 * b) / 255.0


@pytest.mark.slow
@needs_chromium[0]
@needs_chromium[1]
def test_compare_html_charts_are_drawn_not_one_colour(tmp_path: Path) -> None:
    base = _base(tmp_path)
    new = Path(shutil.copytree(base, tmp_path / "new"))
    worse = _record(f"{SCENARIO}__ctrl_a", "ctrl_a", {"gain": 1.0}, "c" * 64)
    worse.trace.ego.lat_dev_m[:] = 0.3 + 0.2 * worse.trace.t_s / worse.trace.t_s[-1]
    shutil.rmtree(new / SCENARIO)
    sr.write_judged(worse, new / SCENARIO)
    compare_runs(base, new, tmp_path / "cmp")
    driver_gen = chromium()
    driver = next(driver_gen)
    try:
        driver.get((tmp_path / "cmp" / "compare.html").as_uri())
        charts = driver.find_elements("css selector", ".overlay svg.chart")
        assert charts, "compare.html drew no overlay chart"
        png = tmp_path / "chart.png"
        png.write_bytes(charts[0].screenshot_as_png)
        screenshot(driver, "compare_overlay")
        frame = charts[0].find_element("css selector", "rect.frame")
        x, y, w, h = (float(frame.get_attribute(k)) for k in ("x", "y", "width", "height"))
        n, light = _plot_area(png, (int(x) + 2, int(y) + 2, int(x + w) - 2, int(y + h) - 2))
        # the curves, the limit and the gridlines on the chart's light background, not
        # lines on a block of SVG's default black fill
        assert n > 2 and light > 0.8
    finally:
        driver_gen.close()
