"""The run-record schema: what a run directory holds, as typed dataclasses.

Written by the runner (``suite``), read by the metrics, the Rerun log and the reports.
This package imports nothing of hwyeval.
"""

from reports.record.codec import RecordError
from reports.record.columns import (
    AGENT_NAMES,
    AGENT_REACTIVE,
    AGENT_REPLAYED,
    AGENT_SUMO,
    ControllerColumns,
    DecisionColumns,
    EgoColumns,
    NeighbourColumns,
    SafetyColumns,
    SeriesColumns,
    TimingColumns,
    Trace,
)
from reports.record.meta import (
    EgoBox,
    ReplayHandover,
    ReplaySummary,
    RunInfo,
    RunOutcome,
    SsmSummary,
    StalledVehicle,
    SumoCollision,
)
from reports.record.road import LaneRecord, RoadRecord
from reports.record.run import (
    CONTROLLER_ARRAYS,
    NEIGHBOURS,
    ROAD_JSON,
    RRD,
    RUN_FILES,
    RUN_JSON,
    SERIES,
    TRACE,
    TRACEBACK,
    ControllerArrays,
    DamagedRun,
    RunRecord,
    check_run_files,
    incomplete_files,
    iter_run_dirs,
    load_run,
    write_run,
    write_run_json,
)
from reports.record.verdict import Failure, MetricValue, Verdict

__all__ = [
    "AGENT_NAMES", "AGENT_REACTIVE", "AGENT_REPLAYED", "AGENT_SUMO", "CONTROLLER_ARRAYS",
    "NEIGHBOURS", "ROAD_JSON", "RRD", "RUN_FILES", "RUN_JSON", "SERIES",
    "TRACE", "TRACEBACK", "ControllerArrays", "ControllerColumns", "DamagedRun",
    "DecisionColumns", "EgoBox",
    "EgoColumns", "Failure", "LaneRecord", "MetricValue", "NeighbourColumns", "RecordError",
    "ReplayHandover", "ReplaySummary", "RoadRecord", "RunInfo", "RunOutcome", "RunRecord",
    "SafetyColumns", "SeriesColumns",
    "SsmSummary", "StalledVehicle", "SumoCollision", "TimingColumns", "Trace", "Verdict",
    "check_run_files", "incomplete_files", "iter_run_dirs", "load_run", "write_run",
    "write_run_json",
]
