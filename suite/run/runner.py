"""Run one scenario: build the loop's stages, run them, judge the record, write it once.

``run_scenario`` never raises: a crash is recorded as ``error`` with its traceback, an
exceeded wall-clock budget as ``timeout``, and what was recorded until then is kept
(its trace and series), while the verdict of such a run carries NaN metric values and
no failures (:func:`void_metrics`): a run that did not finish is never counted as, say,
collision-free. The verdict is computed once, here, by :func:`reports.metrics.evaluate`;
the run directory (:mod:`reports.record.run`) is written once, into a staging directory
(run.json last) that is renamed to ``OUT/<scenario>`` when complete.
"""

from __future__ import annotations

import math
import resource
import time
import traceback
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from controllers import registry
from controllers.baselines.recorded_driver import RecordedDriverModel
from controllers.behaviour.decision import EgoShape, LaneBehaviour
from controllers.behaviour.protocol import Behaviour, CruiseBehaviour
from controllers.path.frenet import FrenetPath
from controllers.plant.vehicle_model import SingleTrackPlant, VehicleParams
from controllers.protocol import (
    Controller,
    ScenarioContext,
    SumoDriverModel,
)
from reports.record import (
    RRD,
    ControllerArrays,
    NeighbourColumns,
    RoadRecord,
    RunInfo,
    RunOutcome,
    RunRecord,
    Trace,
    write_run,
    write_run_json,
)
from reports.record.run import publish_run_dir, remove_path, staging_dir
from reports.record.verdict import Verdict
from suite.catalog import Scenario
from suite.catalog.specs import EgoSpec
from suite.road.lane_pose import lane_frame
from suite.road.lanes import LaneContextMap
from suite.road.network import RoadNetwork
from suite.road.record import route_lane_records
from suite.road.route_reference import RouteReference, build_reference
from suite.run.dynamics import DrivenEgoStage, EgoDynamics, PlantDynamics, SumoDrivenDynamics
from suite.run.ego import EgoProjector
from suite.run.info import scenario_info
from suite.run.loop import Stages, run_loop
from suite.run.options import RunOptions
from suite.run.recorded import (
    RecordedDrivesEgo,
    RecordedDynamics,
    RecordedPath,
    recorded_track,
    recorded_vehicle,
)
from suite.run.recorder import TraceRecorder
from suite.run.safety import SafetyMonitor
from suite.run.stop import ScenarioTimeout, StandardStop, StopRule, StoryboardStop
from suite.world.protocol import WorldSummary
from suite.world.sumo import SumoWorld


class SumoDrivesEgo(DrivenEgoStage):
    """The loop's controller stage when SUMO's driver model drives: commands nothing."""

    def __init__(self, model: SumoDriverModel) -> None:
        super().__init__("sumo", dict(model.parameters()))
        self.model = model


@dataclass
class _Run:
    """A run's stages and what surrounds them."""

    stages: Stages
    world: SumoWorld
    recorder: TraceRecorder
    info: RunInfo
    road: RoadRecord
    detection_m: float
    n_steps: int


def identity_of(options: RunOptions) -> dict[str, str]:
    """The code hashes of ``options`` by their run.json key (:mod:`suite.run.code_identity`)."""
    from suite.run.code_identity import CODE_KEY, CONTROLLER_KEY

    return {CODE_KEY: options.code_sha256, CONTROLLER_KEY: options.controller_sha256}


def initial_state(network: RoadNetwork, route: tuple[str, ...], ego: EgoSpec,
                  path: FrenetPath, vehicle: VehicleParams, s_hint_m: float) -> np.ndarray:
    """(6,) plant state at t = 0: the front bumper's centre on lane ``ego.lane`` at route
    position ``ego.pos_m``, where SUMO has that lane position (the lane frame of
    :func:`suite.road.lane_pose.lane_frame`: the point of the net's own lane shape, not
    of the smoothed reference), ``ego.lateral_offset_m`` to the left of it; heading
    ``ego.heading_rad`` from the lane's direction when the catalog gives a start pose,
    else the reference path's heading where the bumper projects onto it (found near
    ``s_hint_m``; the lane polyline's own direction steps at every vertex). The CG is
    ``cg_to_front_bumper_m`` behind the bumper along the heading; speed ``ego.speed_mps``
    along it, no side slip or yaw rate.

    Why the lane and not the reference: the reference cuts a digitising kink's corner by
    up to ``TubeParams.kink_tube_max_m``, and a position measured along it, offset to the
    lane along its normal, lands up to ~0.1 m along the lane from where SUMO would put
    ``pos_m`` (tests/test_placement.py)."""
    frame = lane_frame(network, route, ego.pos_m, ego.lane)
    if ego.start_pose is not None:
        fx, fy, psi = frame.place(*ego.start_pose)
    else:
        fx, fy, _ = frame.place(0.0, 0.0)
        s, _ = path.project(fx, fy, s_hint=s_hint_m)
        psi = float(path.gamma(float(np.asarray(s).reshape(-1)[0])))
    d = vehicle.cg_to_front_bumper_m
    return np.array([fx - d * math.cos(psi), fy - d * math.sin(psi), psi, ego.speed_mps,
                     0.0, 0.0])


def ego_start_state(network: RoadNetwork, scenario: Scenario, vehicle: VehicleParams
                    ) -> np.ndarray:
    """(6,) the plant state at t = 0 exactly as a run of ``scenario`` starts it (the
    reference and its Frenet path built as :func:`_build` builds them): for checks of the
    placement against the net file (tests/placement_check.py)."""
    ref = _reference(network, scenario)
    path = FrenetPath.cached(np.asarray(ref.points_xy_m, dtype=np.float64),
                             smoothing_m=REFERENCE_SMOOTHING_M)
    return initial_state(network, tuple(scenario.route), scenario.ego, path, vehicle,
                         ref.path_s(scenario.ego.pos_m))


REFERENCE_SMOOTHING_M = 0.5  # the reference is already smooth (suite.road.reference)
WINDOW_BEHIND_M = 150.0  # the reference covers this much route behind the ego's start ...
WINDOW_AHEAD_M = 500.0  # ... and this much beyond what it can reach in the run


def road_record(network: RoadNetwork, route: tuple[str, ...], reference: np.ndarray,
                path: FrenetPath) -> RoadRecord:
    """Every lane of every route edge and the internal junction lanes between consecutive
    route edges (:func:`suite.road.record.route_lane_records`: the drivable area is
    built from them), and the reference."""
    return RoadRecord(lanes=route_lane_records(network, route),
                      reference_xy_m=np.asarray(reference, dtype=np.float64),
                      reference_length_m=float(path.length_m), route=route)


def _reference(network: RoadNetwork, scenario: Scenario) -> RouteReference:
    """The run's reference: the through lane the ego starts in, over the stretch it can use."""
    ego = scenario.ego
    reach = max(ego.speed_mps, ego.target_speed_mps, 1.0) * scenario.duration_s
    window = (ego.pos_m - WINDOW_BEHIND_M, ego.pos_m + reach + WINDOW_AHEAD_M)
    return build_reference(network, tuple(scenario.route), ego.pos_m, ego.lane,
                           window_m=window)


def _build(scenario: Scenario, run_dir: Path, vehicle: VehicleParams, options: RunOptions,
           wall0: float) -> _Run:
    network = RoadNetwork.load(scenario.net_path)
    route = tuple(scenario.route)
    driver = registry.make(scenario.controller.name, scenario.controller.options_dict())
    controller: Controller = (
        SumoDrivesEgo(driver) if isinstance(driver, SumoDriverModel)
        else RecordedDrivesEgo(driver, recorded_track(scenario))
        if isinstance(driver, RecordedDriverModel) else driver)
    track = controller.track if isinstance(controller, RecordedDrivesEgo) else None
    if track is not None:  # the recorded ego has the recorded vehicle's box
        vehicle = recorded_vehicle(vehicle, track.length_m, track.width_m)
    info = scenario_info(scenario, options.catalog_name, vehicle, controller.parameters(),
                         options.content_sha256, identity_of(options))
    ref = _reference(network, scenario)
    reference = ref.points_xy_m
    start_edge, _ = network.locate(route, scenario.ego.pos_m)
    lane_width = network.lane_width_m(start_edge, scenario.ego.lane)
    dt = float(scenario.step_s)
    target = float(scenario.ego.target_speed_mps)
    context = ScenarioContext(reference, lane_width, target, dt, vehicle,
                              np.zeros(6), reference_smoothing_m=REFERENCE_SMOOTHING_M)
    path = context.reference_path()
    lanes = LaneContextMap(network, route, ref, path)
    state0 = initial_state(network, route, scenario.ego, path, vehicle,
                           ref.path_s(scenario.ego.pos_m))
    controller.reset(replace(context, initial_state=state0))
    plant_driven = not isinstance(driver, SumoDriverModel)
    world = SumoWorld(scenario, network, vehicle, run_dir / "sumo", externally_driven=plant_driven)
    projector = EgoProjector(path)
    dynamics: EgoDynamics = (
        RecordedDynamics(RecordedPath.from_track(track, dt), world, projector, vehicle)
        if track is not None else
        PlantDynamics(SingleTrackPlant(vehicle, state0), world, projector, dt)
        if plant_driven else SumoDrivenDynamics(world, projector, vehicle, dt, state0))
    policy = controller.obstacle_policy
    behaviour: Behaviour = CruiseBehaviour() if policy is None else LaneBehaviour(
        path, policy, EgoShape(vehicle.length_m, vehicle.width_m, scenario.allow_shoulder),
        lane_width)
    n_steps = int(round(scenario.duration_s / dt))
    recorder = TraceRecorder(n_steps, controller.diagnostics_type, path,
                             float(scenario.record_radius_m))
    stages = Stages(dynamics=dynamics, behaviour=behaviour,
                    lanes=lanes,
                    controller=controller, monitor=SafetyMonitor(vehicle), recorder=recorder,
                    stop=_stop_rule(scenario, world, StandardStop(path.length_m,
                                                                  options.timeout_s, wall0)),
                    set_speed_mps=target, step_s=dt)
    return _Run(stages, world, recorder, info, road_record(network, route, reference, path),
                float(policy.detection_distance_m) if policy is not None else 0.0, n_steps)


def _stop_rule(scenario: Scenario, world: SumoWorld, standard: StandardStop) -> StopRule:
    """The standard stop rule; with a storyboard, its stop trigger ends the run too."""
    if scenario.story is None:
        return standard
    return StoryboardStop(standard, world.storyboard_stopped_at_s)


def run_scenario(scenario: Scenario, out_dir: Path, options: RunOptions | None = None
                 ) -> RunRecord:
    """Run one scenario into ``out_dir/<name>/`` and return its record (never raises).

    The run is written into a staging directory and renamed to ``out_dir/<name>`` when
    complete, replacing an older run there (:func:`reports.record.run.publish_run_dir`);
    if even that fails, the record is returned with the reason and ``run_dir`` None."""
    options = options or RunOptions()
    final = Path(out_dir) / scenario.name
    vehicle = VehicleParams(friction_coeff=scenario.friction)  # the road's mu
    wall0 = time.perf_counter()
    try:
        stage = staging_dir(Path(out_dir), scenario.name)
    except OSError:
        record = _record(_recording(scenario, options, vehicle, None), WorldSummary(),
                         "error", "cannot create the run directory:\n"
                         + traceback.format_exc(), "", wall0)
        return judge_record(record)
    end, error, reason = "ok", None, ""
    run: _Run | None = None
    summary = WorldSummary()
    try:
        run = _build(scenario, stage, vehicle, options, wall0)
        reason = run_loop(run.stages, run.n_steps)
    except ScenarioTimeout as exc:
        end, error = "timeout", str(exc)
    except Exception:  # noqa: BLE001 - one scenario's crash must not stop the catalog
        end, error = "error", traceback.format_exc()
    finally:
        if run is not None:
            try:
                summary = run.world.close()
            except Exception:  # noqa: BLE001 - SUMO failing to close is the run's error
                end, error = "error", (error or "") + traceback.format_exc()
    record = _record(_recording(scenario, options, vehicle, run), summary, end, error, reason,
                     wall0)
    try:
        record = _judge_and_write(record, stage, options)
        publish_run_dir(stage, final)
        record.run_dir = final
    except Exception:  # noqa: BLE001 - a full disk, a vanished --out: reported, not raised
        remove_path(stage)
        record.run_dir = None
        record.outcome = replace(record.outcome, end="error", error=(
            (record.outcome.error or "") + f"\nwhile writing the run to {final}:\n"
            + traceback.format_exc()))
        if record.verdict is not None:
            record.verdict = void_metrics(record.verdict)
    return record


@dataclass(frozen=True)
class _Recording:
    """What a run recorded (empty for a run that never started): its info, road, trace,
    neighbour columns and controller arrays."""

    info: RunInfo
    road: RoadRecord
    trace: Trace
    neighbours: NeighbourColumns
    arrays: ControllerArrays


def _recording(scenario: Scenario, options: RunOptions, vehicle: VehicleParams,
               run: _Run | None) -> _Recording:
    """The recording of ``run`` (its recorder finished), or, with no run, an empty one
    with the info known before a run starts."""
    if run is not None:
        trace, neighbours, arrays = run.recorder.finish(run.detection_m)
        return _Recording(run.info, run.road, trace, neighbours, arrays)
    trace, neighbours, arrays = Trace.empty(), NeighbourColumns.allocate(0), ControllerArrays()
    info = scenario_info(scenario, options.catalog_name, vehicle,
                         content_sha256=options.content_sha256,
                         identity=identity_of(options))
    return _Recording(info, RoadRecord(), trace, neighbours, arrays)


def _record(recording: _Recording, summary: WorldSummary, end: str, error: str | None,
            reason: str, wall0: float) -> RunRecord:
    """The run's record: ``recording`` and its outcome (``end``, ``error``, the stop
    ``reason``, the wall time since ``wall0`` [s, perf_counter], SUMO's ``summary``)."""
    trace = recording.trace
    trace.safety.ssm_ttc_s[:] = summary.ssm_ttc_at(trace.t_s)
    outcome = RunOutcome(
        end=end, error=error, stop_reason=reason, wall_s=time.perf_counter() - wall0,
        sim_time_s=float(trace.t_s[-1]) if len(trace) else 0.0, steps=len(trace),
        # Linux reports ru_maxrss in KiB: the scenario process's peak memory.
        peak_rss_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        sumo_t_origin_s=summary.t_origin_s, stalled=summary.stalled,
        sumo_collisions=summary.collisions, ssm=summary.ssm, replay=summary.replay)
    return RunRecord(info=recording.info, outcome=outcome, road=recording.road, trace=trace,
                     neighbours=recording.neighbours, arrays=recording.arrays, run_dir=None)


def void_metrics(verdict: Verdict) -> Verdict:
    """The verdict of a run that did not finish ('error' or 'timeout'): every metric
    NaN (not measured: what ran is in the trace, but it says nothing of the whole run)
    and no failures; names, units and criteria kept."""
    metrics = tuple(replace(m, value=math.nan, worst_step=None) for m in verdict.metrics)
    return replace(verdict, metrics=metrics, failures=())


def judge_record(record: RunRecord) -> RunRecord:
    """Evaluate once (metrics NaN for a run that did not end 'ok'); a metric bug is
    recorded as the run's error, never raised."""
    from reports.metrics import evaluate

    try:
        evaluation = evaluate(record)
        record.verdict, record.series = evaluation.verdict, evaluation.series
    except Exception:  # noqa: BLE001 - a metric bug must not lose the run
        record.outcome = replace(record.outcome, end="error", error=(
            (record.outcome.error or "") + "\nwhile evaluating metrics:\n"
            + traceback.format_exc()))
    if record.verdict is not None and record.outcome.end != "ok":
        record.verdict = void_metrics(record.verdict)
    return record


def _judge_and_write(record: RunRecord, run_dir: Path, options: RunOptions) -> RunRecord:
    """Evaluate once, write the run's files, log it to Rerun from memory, then run.json
    (once, last: a reader never sees a run.json whose files are not all there)."""
    record = judge_record(record)
    record.run_dir = run_dir
    try:
        write_run(record, run_dir, run_json=False)
    except Exception:  # noqa: BLE001
        record.outcome = replace(record.outcome, end="error", error=(
            (record.outcome.error or "") + "\nwhile writing the run:\n" + traceback.format_exc()))
        if record.verdict is not None:
            record.verdict = void_metrics(record.verdict)
    if options.write_rrd:
        t0 = time.perf_counter()
        try:
            from suite.rerun.log import log_record

            log_record(record, run_dir / RRD, catalog_name=options.catalog_name or None)
            record.outcome = replace(record.outcome, log_s=time.perf_counter() - t0)
        except Exception:  # noqa: BLE001 - a broken log must not lose the verdict
            (run_dir / RRD).unlink(missing_ok=True)
            record.outcome = replace(record.outcome, log_error=traceback.format_exc())
    write_run_json(record, run_dir)
    return record
