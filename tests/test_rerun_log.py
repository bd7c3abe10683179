"""Rerun logs: written from synthetic run directories, read back with Rerun's own reader."""

from __future__ import annotations

import dataclasses
import os
import sys
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rerun as rr
from rerun.chunk import RrdReader
from rerun_fixtures import (
    EXTRA,
    make_error_dir,
    make_run_dir,
    read_chunks,
    render_birdseye,
    rows_at_step,
)

from reports.record import Failure, load_run, write_run_json
from suite.rerun.blueprint import ViewGeometry, default_blueprint
from suite.rerun.log import ENTITY_PATHS, application_id_for, lane_edges, write_rrd
from suite.rerun.viewer import failed_runs, open_logs, resolve_logs, view_command

WORLD_PATHS = [
    "/world/road/lanes", "/world/road/shoulders", "/world/road/centrelines",
    "/world/reference_path", "/world/ego/box", "/world/ego/frame", "/world/vehicles",
    "/world/stalled", "/world/ellipses", "/world/plan", "/world/preview",
    "/world/preview_error", "/world/detection",
]
SCALAR_PATHS = [
    "/safety/ttc_s", "/safety/min_gap_m", "/comfort/accel_mps2/long", "/comfort/accel_mps2/lat",
    "/comfort/jerk_mps3/long", "/comfort/jerk_mps3/total", "/controller/speed_mps/actual",
    "/controller/speed_mps/target", "/controller/lat_dev_m", "/controller/steer_deg/total",
    "/controller/steer_deg/outer", "/controller/steer_deg/correction",
    "/controller/torque_nm/total", "/controller/torque_nm/outer",
    "/controller/torque_nm/correction", "/controller/residual", "/timing/step_ms/outer",
    "/timing/step_ms/inner", "/timing/step_ms/controller", "/timing/step_ms/sumo",
    "/controller/preview_err_m/t", "/controller/preview_err_m/n", "/safety/ttc_s/ahead",
    "/comfort/accel_mps2/long_smoothed", "/comfort/yaw_rate_radps",
]
STATIC_ONLY = ["/world/road/lanes", "/world/road/shoulders", "/world/road/centrelines",
               "/world/reference_path", "/world/stalled", "/docs/scenario", "/docs/controller"]


@pytest.fixture(autouse=True)
def _strict_rerun() -> Any:
    rr.set_strict_mode(True)  # a bad column raises instead of warning
    yield


@pytest.fixture(scope="module")
def collision_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("runs")
    # a lateral-acceleration limit the lane change exceeds, besides the collision
    run_dir = make_run_dir(root, collision=True, steps=300, n_traffic=2,
                           criteria={"max_abs_lat_acc_mps2": 1.0})
    return run_dir, write_rrd(run_dir)


def _rows(chunks: list[Any]) -> dict[tuple[str, bool], int]:
    out: dict[tuple[str, bool], int] = defaultdict(int)
    for c in chunks:
        out[(c.entity_path, c.is_static)] += c.num_rows
    return out


def _events(chunks: list[Any]) -> list[tuple[int, str, str]]:
    ev = []
    for c in chunks:
        if c.entity_path != "/events" or c.is_static:
            continue
        rb = c.to_record_batch()
        for s, lv, tx in zip(rb.column("step").to_pylist(), rb.column("TextLog:level").to_pylist(),
                             rb.column("TextLog:text").to_pylist(), strict=True):
            ev.append((s, lv[0], tx[0]))
    return sorted(ev, key=lambda e: e[0])  # stable: keeps logging order within a step


def test_entity_paths_present(collision_run: tuple[Path, Path]) -> None:
    _, rrd = collision_run
    assert rrd.name == "run.rrd" and rrd.is_file()
    paths = {c.entity_path for c in read_chunks(rrd)}
    missing = [p for p in WORLD_PATHS + SCALAR_PATHS + ["/events", "/docs/scenario",
                                                        "/docs/controller"] if p not in paths]
    assert not missing, missing
    assert set(ENTITY_PATHS.values()) <= paths | {"/world/ego/driven_path"}


def test_one_ego_pose_per_step(collision_run: tuple[Path, Path]) -> None:
    _, rrd = collision_run
    steps: list[int] = []
    frame_steps: list[int] = []
    for c in read_chunks(rrd):
        if c.is_static:
            continue
        rb = c.to_record_batch()
        if c.entity_path == "/world/ego/box":
            assert "LineStrips2D:strips" in rb.schema.names
            steps += rb.column("step").to_pylist()
            for strip_batch in rb.column("LineStrips2D:strips").to_pylist():
                assert len(strip_batch) == 1 and len(strip_batch[0]) == 5  # closed box
        elif c.entity_path == "/world/ego/frame":
            frame_steps += rb.column("step").to_pylist()
    assert sorted(steps) == list(range(300))
    assert sorted(frame_steps) == list(range(300))


def test_static_road_logged_once(collision_run: tuple[Path, Path]) -> None:
    _, rrd = collision_run
    rows = _rows(read_chunks(rrd))
    for path in STATIC_ONLY:
        assert rows[(path, True)] == 1, path
        assert rows.get((path, False), 0) == 0, path
    # per-step scalars are batched: one row per step, never static data rows
    assert rows[("/safety/min_gap_m", False)] == 300
    assert rows[("/controller/speed_mps/actual", False)] == 300


def test_road_geometry(collision_run: tuple[Path, Path]) -> None:
    _, rrd = collision_run
    chunks = read_chunks(rrd)
    lanes = rows_at_step(chunks, "/world/road/lanes", 0, "LineStrips2D:strips")
    shoulders = rows_at_step(chunks, "/world/road/shoulders", 0, "LineStrips2D:strips")
    assert len(lanes) == 6 and len(shoulders) == 2  # 3 driving lanes + 1 shoulder, 2 edges each
    ys = sorted({round(s[0][1], 3) for s in lanes})
    assert ys == [-1.75, 1.75, 5.25, 8.75]
    left, right = lane_edges(np.array([[0.0, 0.0], [10.0, 10.0]]), 2.0)
    assert np.allclose(np.linalg.norm(left - right, axis=1), 2.0)


def test_vehicles_and_stalled(collision_run: tuple[Path, Path]) -> None:
    run_dir, rrd = collision_run
    chunks = read_chunks(rrd)
    labels = rows_at_step(chunks, "/world/vehicles", 0, "LineStrips2D:labels")
    assert labels and set(labels) <= {"veh0", "veh1"}
    stalled = rows_at_step(chunks, "/world/stalled", 0, "LineStrips2D:labels")
    assert stalled == ["stalled0 (stalled)"]
    # obstacle ellipse only while the stalled car is within detection range ahead
    assert rows_at_step(chunks, "/world/ellipses", 60, "LineStrips2D:strips")
    assert not rows_at_step(chunks, "/world/ellipses", 5, "LineStrips2D:strips")
    assert rows_at_step(chunks, "/world/ego/velocity", 60, "Arrows2D:labels") == [
        "pass left: left lane free"]
    assert not rows_at_step(chunks, "/world/ego/velocity", 5, "Arrows2D:labels")


def test_recording_ids_are_unique_per_run_and_the_application_groups_a_scenario(
        tmp_path: Path) -> None:
    a = write_rrd(make_run_dir(tmp_path / "a", seed=7, steps=40))
    recordings = [RrdReader(a).recordings()[0]]
    b = write_rrd(make_run_dir(tmp_path / "b", seed=7, steps=40))
    again = write_rrd(a.parent)  # the same run directory logged again: a new recording
    other = write_rrd(make_run_dir(tmp_path / "c", scenario="other_case", seed=7, steps=40))
    recordings += [RrdReader(p).recordings()[0] for p in (b, again, other)]
    ids = [r.recording_id for r in recordings]
    assert len(set(ids)) == 4, "two nights of one scenario must never merge"
    apps = [r.application_id for r in recordings]
    assert apps[0] == apps[1] == apps[2] == application_id_for("smoke", "stalled_pass") \
        == "hwyeval:smoke:stalled_pass"
    assert apps[3] == "hwyeval:smoke:other_case"
    assert application_id_for("catalogs/smoke.toml", "stalled_pass") == apps[0]
    write_rrd(make_run_dir(tmp_path / "d", seed=7, steps=40), catalog_name="x")
    assert RrdReader(tmp_path / "d" / "stalled_pass" / "run.rrd").recordings()[0] \
        .application_id == "hwyeval:x:stalled_pass"
    assert RrdReader(a).blueprints(), "default blueprint must be embedded"


def test_the_run_identity_is_a_recording_property(tmp_path: Path) -> None:
    """The viewer's recording list shows each run's catalog, scenario, seed, controller,
    status and version, as one-element string columns of ``/__properties/run``."""
    run_dir = make_run_dir(tmp_path, seed=7, steps=40)
    rrd = write_rrd(run_dir, catalog_name="nightly")
    record = load_run(run_dir)
    chunks = [c for c in read_chunks(rrd) if c.entity_path == "/__properties/run"]
    assert len(chunks) == 1 and chunks[0].is_static
    rb = chunks[0].to_record_batch()
    got = {name: rb.column(name).to_pylist()[0] for name in rb.schema.names
           if not name.startswith("rerun.")}
    assert got == {"catalog": ["nightly"], "scenario": ["stalled_pass"], "seed": ["7"],
                   "controller": [record.info.controller], "status": [record.status],
                   "hwyeval_version": [record.info.hwyeval_version]}


def test_verdict_ttc_and_criteria_limits_are_logged(tmp_path: Path) -> None:
    run_dir = make_run_dir(tmp_path, seed=3, steps=120, criteria={"min_gap_m": 2.0})
    chunks = read_chunks(write_rrd(run_dir))
    verdict = load_run(run_dir, trace=False, neighbours=False, arrays=False,
                       series=False).verdict
    assert verdict is not None

    def values(entity: str) -> list[float]:
        out: list[float] = []
        for c in chunks:
            if c.entity_path == entity and not c.is_static:
                rb = c.to_record_batch()
                name = next(n for n in rb.schema.names if n.endswith("Scalars:scalars"))
                out += [v[0] for v in rb.column(name).to_pylist()]
        return out

    ttc = values("/safety/ttc_s/ahead")
    assert ttc and max(ttc) <= 10.0  # +inf drawn at the cap: the panel is never empty
    min_ttc = verdict.value("min_ttc_s")
    assert values("/safety/ttc_s/verdict_min") == pytest.approx([min(min_ttc, 10.0)] * 2)
    assert values("/safety/ttc_s/limit") == pytest.approx([0.95, 0.95])
    assert values("/safety/min_gap_m/limit") == pytest.approx([2.0, 2.0])
    assert values("/comfort/accel_mps2/lat_limit_pos") == pytest.approx([4.89, 4.89])
    assert values("/comfort/accel_mps2/lat_limit_neg") == pytest.approx([-4.89, -4.89])
    assert values("/comfort/accel_mps2/limit_min") == pytest.approx([-4.05, -4.05])
    assert not values("/safety/ellipse_margin/limit")  # off by default: not drawn


def test_events_for_collision(collision_run: tuple[Path, Path]) -> None:
    _, rrd = collision_run
    ev = _events(read_chunks(rrd))
    by_text = {t: (s, lv) for s, lv, t in ev}
    geom = [(s, lv) for s, lv, t in ev if t.startswith("COLLISION (geometry)")]
    assert geom == [(100, "ERROR")]
    sumo = [(s, lv) for s, lv, t in ev if t.startswith("COLLISION (SUMO")]
    assert sumo == [(101, "ERROR")]
    crit = [(s, t) for s, lv, t in ev
            if t.startswith("criterion violated: at_fault_collisions")]
    assert crit and crit[0][0] == 100
    assert any(t.startswith("criterion violated: max_abs_lat_acc") for _, _, t in ev)
    # every stored failure is logged at the step its verdict located it
    record = load_run(collision_run[0])
    assert record.verdict is not None and len(record.verdict.failures) == 2
    for f in record.verdict.failures:
        assert f.step is not None
        assert (int(record.trace.step[f.step]), "WARN",
                f"criterion violated: {f.text} (at t={f.t_s:.2f} s)") in ev
    assert any(t.startswith("fallback") and s == 60 and lv == "WARN" for s, lv, t in ev)
    assert any("pass left" in t and lv == "INFO" for _, lv, t in ev)
    final = [(s, lv, t) for s, lv, t in ev if t.startswith("status:")]
    assert final == [(299, "ERROR", final[0][2])] and "FAIL" in final[0][2]
    assert by_text  # sanity


def test_pass_run_and_error_run(tmp_path: Path) -> None:
    ok = write_rrd(make_run_dir(tmp_path, scenario="ok", steps=30))
    ev = _events(read_chunks(ok))
    assert ev[-1][1] == "INFO" and "PASS" in ev[-1][2]
    assert not any("COLLISION" in t or "criterion" in t for _, _, t in ev)

    rrd = write_rrd(make_error_dir(tmp_path))
    ev = _events(read_chunks(rrd))
    assert ev[-1][1] == "ERROR" and "ERROR" in ev[-1][2] and "SUMO died" in ev[-1][2]
    # nothing recorded: the steps criterion, an aggregate, is logged at the end
    assert any(t.startswith("criterion violated: steps=0<1 (whole run") for _, _, t in ev)


def test_failure_events_come_from_the_stored_verdict(tmp_path: Path) -> None:
    """The log reads the verdict the runner stored: a failure the trace would not give
    appears at its stored step; nothing is re-evaluated or re-located."""
    run_dir = make_run_dir(tmp_path, steps=80)
    record = load_run(run_dir)
    assert record.verdict is not None and record.verdict.status == "pass"
    stored = Failure(criterion="max_abs_yaw_rate_radps", metric="max_abs_yaw_rate_radps",
                     value=2.5, limit=0.95, bound="max", unit="rad/s", step=42,
                     t_s=float(record.trace.t_s[42]))
    record.verdict = dataclasses.replace(record.verdict, status="fail", failures=(stored,))
    write_run_json(record, run_dir)
    ev = _events(read_chunks(write_rrd(run_dir)))
    assert (42, "WARN", "criterion violated: max_abs_yaw_rate_radps=2.5>0.95 (at t=4.30 s)") \
        in ev
    assert ev[-1][1] == "ERROR" and "FAIL" in ev[-1][2]


def _scalars(chunks: list[Any], entity: str) -> dict[int, float]:
    """step -> value of a Scalars entity."""
    out: dict[int, float] = {}
    for c in chunks:
        if c.entity_path != entity or c.is_static:
            continue
        rb = c.to_record_batch()
        for step, value in zip(rb.column("step").to_pylist(),
                               rb.column("Scalars:scalars").to_pylist(), strict=True):
            out[int(step)] = float(value[0])
    return out


def test_every_controller_diagnostic_is_logged(collision_run: tuple[Path, Path]) -> None:
    run_dir, rrd = collision_run
    record = load_run(run_dir)
    assert tuple(record.trace.extra) == EXTRA
    chunks = read_chunks(rrd)
    for name, values in record.trace.extra.items():
        logged = _scalars(chunks, f"/controller/{name}")
        assert sorted(logged) == list(range(300)), name
        np.testing.assert_allclose([logged[k] for k in range(300)], values, err_msg=name)
    # the preview-error scalars are the recorded components
    np.testing.assert_allclose(
        [_scalars(chunks, "/controller/preview_err_m/t")[k] for k in range(300)],
        record.trace.extra["preview_err_t_m"])


def test_preview_error_arrow_from_the_recorded_components(
        collision_run: tuple[Path, Path]) -> None:
    run_dir, rrd = collision_run
    record = load_run(run_dir)
    chunks = read_chunks(rrd)
    for step in (10, 60, 150):
        prev = record.arrays.preview_xy_m[step]
        d = (prev[-1] - prev[-2]) / np.hypot(*(prev[-1] - prev[-2]))
        expected = (record.trace.extra["preview_err_t_m"][step] * d
                    + record.trace.extra["preview_err_n_m"][step] * np.array([-d[1], d[0]]))
        (origin,) = rows_at_step(chunks, "/world/preview_error", step, "Arrows2D:origins")
        (vector,) = rows_at_step(chunks, "/world/preview_error", step, "Arrows2D:vectors")
        np.testing.assert_allclose(origin, prev[-1], rtol=1e-6)
        np.testing.assert_allclose(vector, expected, rtol=1e-5, atol=1e-6)


def test_verdict_series_are_logged(collision_run: tuple[Path, Path]) -> None:
    run_dir, rrd = collision_run
    record = load_run(run_dir)
    assert record.series is not None
    chunks = read_chunks(rrd)
    jerk = _scalars(chunks, "/comfort/jerk_mps3/total")
    np.testing.assert_allclose([jerk[k] for k in range(300)], record.series.jerk_mps3,
                               rtol=1e-6)
    ttc = _scalars(chunks, "/safety/ttc_s/ahead")  # +inf (no conflict) drawn at the cap
    assert sorted(ttc) == list(range(300))
    expected = np.minimum(np.nan_to_num(record.series.ttc_s, posinf=10.0), 10.0)
    np.testing.assert_allclose([ttc[k] for k in range(300)], expected, rtol=1e-6)


def _views(container: object, out: list[tuple[str, str]]) -> list[tuple[str, str]]:
    """(name, origin) of every view below a blueprint container."""
    origin = getattr(container, "origin", None)
    kids = getattr(container, "contents", None)
    if not isinstance(origin, str) and isinstance(kids, (list, tuple)):
        for kid in kids:
            _views(kid, out)
    else:
        out.append((str(getattr(container, "name", "")), str(origin)))
    return out


def test_the_blueprint_has_the_views_a_run_needs() -> None:
    """Both bird's-eye views of /world, the verdict's safety series, and a view per
    controller diagnostic exactly when the run has it."""
    geometry = {"ego_start_xy": (0.0, 0.0), "ego_heading_rad": np.pi,
                "road_bounds": (0.0, 100.0, -5.0, 5.0)}
    with_diag = _views(default_blueprint(ViewGeometry(**geometry,  # type: ignore[arg-type]
                                                      diagnostics=("preview_err_t_m",))
                                         ).root_container, [])
    without = _views(default_blueprint(ViewGeometry(**geometry)  # type: ignore[arg-type]
                                       ).root_container, [])
    origins = {o for _, o in with_diag}
    assert [n for n, o in with_diag if o == "/world"] == ["Follow ego", "Whole road"]
    assert {"/safety/ttc_s", "/safety/min_gap_m", "/safety/collision",
            "/safety/offroad_excess_m", "/comfort/jerk_mps3"} <= origins
    assert "/controller/preview_err_t_m" in origins
    assert "/controller/preview_err_t_m" not in {o for _, o in without}
    assert set(without) < set(with_diag)
    assert _views(default_blueprint().root_container, [])  # defaults build too


def test_write_cost_1500_steps_30_neighbours(tmp_path: Path) -> None:
    run_dir = make_run_dir(tmp_path, steps=1500, n_traffic=30, neighbour_radius_m=None)
    t0 = time.perf_counter()
    rrd = write_rrd(run_dir)
    elapsed = time.perf_counter() - t0
    size_mb = rrd.stat().st_size / 1e6
    print(f"\nwrite_rrd 1500 steps x 31 vehicles: {elapsed:.3f} s, {size_mb:.1f} MB")
    rows = _rows(read_chunks(rrd))
    assert rows[("/world/ego/box", False)] == 1500
    assert rows[("/world/vehicles", False)] == 1500


def test_birdseye_png_from_rrd(collision_run: tuple[Path, Path]) -> None:
    _, rrd = collision_run
    out = render_birdseye(rrd, 70, Path("/tmp/rerun_birdseye.png"))
    from PIL import Image

    with Image.open(out) as img:
        assert img.size[0] > 500
        pixels = np.asarray(img.convert("RGB")).reshape(-1, 3)
        assert len(np.unique(pixels, axis=0)) > 5  # something was drawn


# ------------------------------------------------------------------ viewer


def test_view_command_is_portable(tmp_path: Path) -> None:
    cmd = view_command([Path("a/run.rrd"), tmp_path / "b" / "run.rrd"], cwd=tmp_path)
    # the viewer by its name and paths relative to the current directory: nothing of
    # this host (interpreter, absolute paths) in a command meant for another machine
    assert cmd == ["rerun", os.path.relpath(Path("a/run.rrd").absolute(), tmp_path),
                   "b/run.rrd"]
    assert sys.executable not in " ".join(cmd)


def test_failed_runs_and_open_logs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    make_run_dir(tmp_path, scenario="good", steps=20)
    # approaching the stalled car (TTC > 3 s) fails a 5 s TTC limit
    bad = make_run_dir(tmp_path, scenario="bad", steps=60, criteria={"min_ttc_s": 5.0})
    assert load_run(bad).status == "fail"
    err = make_error_dir(tmp_path, "err")
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "run.json").write_text("{")
    assert failed_runs(tmp_path) == [bad, broken, err]

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert open_logs([], failed_only_from=tmp_path) == 0
    captured = capsys.readouterr()
    out = captured.out
    rel = os.path.relpath(tmp_path)
    assert "rerun " in out and f"{rel}/bad/run.rrd" in out and f"{rel}/err/run.rrd" in out
    assert sys.executable not in out  # portable: not this host's interpreter
    monkeypatch.chdir(tmp_path)
    assert open_logs([], failed_only_from=tmp_path) == 0
    out = capsys.readouterr().out
    assert "  rerun bad/run.rrd err/run.rrd\n" in out and str(tmp_path) not in out
    assert (bad / "run.rrd").is_file()  # written on demand from the recorded arrays
    assert "good" not in out
    assert "broken: cannot write run.rrd" in captured.err  # reported, the others open

    assert resolve_logs([tmp_path / "good"]) == [tmp_path / "good" / "run.rrd"]
    assert len(resolve_logs([tmp_path])) == 3
    assert open_logs([tmp_path / "nothing_here"]) == 1
