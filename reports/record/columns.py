"""Column groups of the per-step tables: one dataclass of arrays per group.

Every group is a dataclass whose fields are numpy arrays of one row per step (or per
(step, vehicle) for :class:`NeighbourColumns`). The same class is the recorder's
columnar buffer (allocated once, filled by index), the schema of the parquet file
(field name = column name, ``metadata["unit"]``/``["doc"]`` describe it) and what the
reader returns, so a column the writer forgets or a consumer misspells is an
attribute error, not a silently missing key.

Field kinds: ``FloatColumn`` (float64, NaN = not available), ``IntColumn`` (int64),
``BoolColumn`` (bool), ``AgentColumn`` (int8, 0 when absent: :data:`AGENT_SUMO`) and
``TextColumn`` (object array of str).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, TypeVar

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:  # pandas is imported where frames are read or built (the writer,
    import pandas as pd  # reports.record.run.write_parquet, goes to pyarrow directly)

FloatColumn = npt.NDArray[np.float64]
IntColumn = npt.NDArray[np.int64]
BoolColumn = npt.NDArray[np.bool_]
TextColumn = npt.NDArray[np.object_]
AgentColumn = npt.NDArray[np.int8]

# What moves a neighbour (NeighbourColumns.agent): the simulator's traffic or a scripted
# actor, a vehicle replayed from a recording, a recorded vehicle handed over to the
# simulator's driver (reactive replay, suite.world.replay).
AGENT_SUMO = 0
AGENT_REPLAYED = 1
AGENT_REACTIVE = 2
AGENT_NAMES = {AGENT_SUMO: "sumo", AGENT_REPLAYED: "replayed", AGENT_REACTIVE: "reactive"}

G = TypeVar("G", bound="ColumnGroup")

# zero-length columns by class (:meth:`ColumnGroup.no_rows`)
_NO_ROWS: dict[type, dict[str, np.ndarray]] = {}

_KINDS = {"FloatColumn": (np.float64, math.nan), "IntColumn": (np.int64, -1),
          "BoolColumn": (np.bool_, False), "TextColumn": (np.object_, ""),
          "AgentColumn": (np.int8, AGENT_SUMO)}


def col(unit: str, doc: str) -> Any:
    """A column field: ``unit`` ('-' for dimensionless or flags) and meaning."""
    return field(metadata={"unit": unit, "doc": doc})


class ColumnGroup:
    """Mixin for the column dataclasses below (allocation, slicing, frames)."""

    __dataclass_fields__: ClassVar[dict[str, Any]]

    @classmethod
    def names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in dataclasses.fields(cls))  # type: ignore[arg-type]

    @classmethod
    def kinds(cls) -> dict[str, tuple[Any, Any]]:
        """Column name -> (numpy dtype, fill value)."""
        out = {}
        for f in dataclasses.fields(cls):  # type: ignore[arg-type]
            kind = f.type if isinstance(f.type, str) else getattr(f.type, "__name__", "")
            out[f.name] = _KINDS[kind]
        return out

    @classmethod
    def describe(cls) -> dict[str, tuple[str, str]]:
        """Column name -> (unit, meaning)."""
        return {f.name: (f.metadata.get("unit", ""), f.metadata.get("doc", ""))
                for f in dataclasses.fields(cls)}  # type: ignore[arg-type]

    @classmethod
    def allocate(cls: type[G], n: int) -> G:
        """n rows, each column at its fill value (NaN, -1, False or '')."""
        arrays = {}
        for name, (dtype, fill) in cls.kinds().items():
            arrays[name] = np.full(n, fill, dtype=dtype)
        return cls(**arrays)

    @classmethod
    def no_rows(cls: type[G]) -> G:
        """``allocate(0)`` over zero-length columns made once per class and shared (a
        zero-length array holds nothing to write into): 1-2 us, not 10-15, for the
        readers that skip a part of thousands of runs."""
        columns = _NO_ROWS.get(cls)
        if columns is None:
            columns = _NO_ROWS[cls] = dict(cls.allocate(0).columns())
        return cls(**columns)

    @classmethod
    def from_frame(cls: type[G], frame: pd.DataFrame) -> G:
        """Columns of ``frame`` (absent ones at their fill value, coerced to the kind)."""
        n = len(frame)
        arrays = {}
        for name, (dtype, fill) in cls.kinds().items():
            if name not in frame.columns:
                arrays[name] = np.full(n, fill, dtype=dtype)
                continue
            arrays[name] = _coerce(frame[name].to_numpy(), dtype, fill)
        return cls(**arrays)

    def columns(self) -> Iterator[tuple[str, np.ndarray]]:
        for name in self.names():
            yield name, getattr(self, name)

    def head(self: G, n: int) -> G:
        """The first ``n`` rows (views)."""
        return type(self)(**{name: arr[:n] for name, arr in self.columns()})

    def take(self: G, index: np.ndarray) -> G:
        """Rows at ``index`` (bool mask or integer positions)."""
        return type(self)(**{name: arr[index] for name, arr in self.columns()})

    def __len__(self) -> int:
        first = self.names()[0]
        return int(getattr(self, first).shape[0])


def _coerce(values: np.ndarray, dtype: Any, fill: Any) -> np.ndarray:
    import pandas as pd

    if dtype is np.object_:
        return np.array(["" if v is None or (isinstance(v, float) and math.isnan(v)) else str(v)
                         for v in values], dtype=object)
    if dtype is np.bool_:
        numeric = pd.to_numeric(pd.Series(values), errors="coerce").fillna(0.0).to_numpy()
        flags: np.ndarray = numeric.astype(np.float64) != 0.0
        return flags
    numeric = pd.to_numeric(pd.Series(values), errors="coerce").to_numpy(dtype=np.float64)
    if dtype is np.int64 or dtype is np.int8:
        return np.where(np.isfinite(numeric), numeric, fill).astype(dtype)
    return numeric.astype(np.float64)


# ============================================================================ trace groups
@dataclass
class EgoColumns(ColumnGroup):
    """The ego after each step (plant truth, or SUMO's ego for the SUMO driver)."""

    x_m: FloatColumn = col("m", "CG X")
    y_m: FloatColumn = col("m", "CG Y")
    psi_rad: FloatColumn = col("rad", "yaw, CCW from +X")
    u_mps: FloatColumn = col("m/s", "body longitudinal speed")
    v_mps: FloatColumn = col("m/s", "body lateral speed")
    r_radps: FloatColumn = col("rad/s", "yaw rate")
    speed_mps: FloatColumn = col("m/s", "speed magnitude")
    long_acc_mps2: FloatColumn = col("m/s^2", "body longitudinal acceleration u' - r v")
    lat_acc_mps2: FloatColumn = col("m/s^2", "body lateral acceleration v' + r u")
    steer_rad: FloatColumn = col("rad", "applied front-wheel angle (NaN: SUMO drives)")
    torque_nm: FloatColumn = col("N m", "applied drive torque, negative brakes")
    s_m: FloatColumn = col("m", "progress along the reference path")
    lat_dev_m: FloatColumn = col("m", "CG offset from the reference centreline, left +")
    heading_err_rad: FloatColumn = col("rad", "yaw minus the reference tangent angle")
    lane_index: IntColumn = col("-", "SUMO lane index under the ego (-1 off the net)")
    sumo_front_x_m: FloatColumn = col("m", "front bumper X as SUMO has it")
    sumo_front_y_m: FloatColumn = col("m", "front bumper Y as SUMO has it")
    sumo_heading_rad: FloatColumn = col("rad", "heading as SUMO has it, CCW from +X")


@dataclass
class DecisionColumns(ColumnGroup):
    """What the behaviour layer decided before the controller ran."""

    target_speed_mps: FloatColumn = col("m/s", "speed set-point given to the controller")
    side: IntColumn = col("-", "pass side: +1 left, -1 right, 0 keep, 2 follow "
                          "(controllers.behaviour.types.Side)")
    side_reason: TextColumn = col("-", "why that side")
    reason_code: TextColumn = col("-", "the kind of that reason: "
                                  "controllers.behaviour.types.Reason ('' in older records)")
    n_obstacles: IntColumn = col("-", "obstacle ellipses given to the controller")
    lat_ref_m: FloatColumn = col("m", "lateral reference given to the controller, left +")


@dataclass
class SafetyColumns(ColumnGroup):
    """Geometric and SUMO checks after each step."""

    min_gap_m: FloatColumn = col("m", "ego box to the nearest other box (0 on contact)")
    gap_vehicle: TextColumn = col("-", "id of that vehicle ('' if none)")
    geom_collision: BoolColumn = col("-", "ego box overlaps another box")
    sumo_collision: BoolColumn = col("-", "SUMO reported a collision of the ego this step")
    ssm_ttc_s: FloatColumn = col("s", "SUMO SSM device's TTC for the ego (NaN if none)")


@dataclass
class ControllerColumns(ColumnGroup):
    """Health and timing every controller reports (``StepDiagnostics`` of
    :mod:`controllers.protocol`); controller-specific diagnostics go to ``Trace.extra``."""

    residual: FloatColumn = col("-", "outer-loop residual E = ||F||inf (NaN if n/a)")
    fallback: BoolColumn = col("-", "a safe fallback replaced the plan this step")
    guard_fired: IntColumn = col("-", "barrier guard interventions this step")
    outer_s: FloatColumn = col("s", "outer-loop time this step (NaN if n/a)")
    inner_s: FloatColumn = col("s", "inner-loop time this step (NaN if n/a)")


@dataclass
class TimingColumns(ColumnGroup):
    """Wall-clock time of the loop's stages this step."""

    obstacles_s: FloatColumn = col("s", "behaviour: perception, side choice, obstacles")
    controller_s: FloatColumn = col("s", "behaviour plus controller step")
    sumo_s: FloatColumn = col("s", "ego dynamics and SUMO step")


TRACE_GROUPS: dict[str, type[ColumnGroup]] = {
    "ego": EgoColumns, "decision": DecisionColumns, "safety": SafetyColumns,
    "controller": ControllerColumns, "timing": TimingColumns,
}
TRACE_KEYS = ("step", "t_s")


def _check_unique() -> tuple[str, ...]:
    seen: dict[str, str] = {k: "key" for k in TRACE_KEYS}
    for group, cls in TRACE_GROUPS.items():
        for name in cls.names():
            if name in seen:
                raise RuntimeError(f"trace column {name!r} in {group} and {seen[name]}")
            seen[name] = group
    return tuple(seen)


CORE_TRACE_COLUMNS = _check_unique()


_NO_STEPS = np.zeros(0, dtype=np.int64)  # Trace.empty()'s step and t_s (zero-length, shared)
_NO_TIMES = np.zeros(0, dtype=np.float64)


@dataclass
class Trace:
    """One row per control step: keys, the column groups and the controller's extras.

    ``extra`` holds the controller-specific diagnostics (the fields of its diagnostics
    dataclass beyond ``StepDiagnostics``), one float array per field, in declaration
    order.
    """

    step: IntColumn
    t_s: FloatColumn
    ego: EgoColumns
    decision: DecisionColumns
    safety: SafetyColumns
    controller: ControllerColumns
    timing: TimingColumns
    extra: dict[str, FloatColumn] = field(default_factory=dict)

    @classmethod
    def allocate(cls, n: int, extra_names: tuple[str, ...] = ()) -> Trace:
        clash = set(extra_names) & set(CORE_TRACE_COLUMNS)
        if clash:
            raise ValueError(f"controller diagnostics clash with trace columns: {sorted(clash)}")
        groups = {name: g.allocate(n) for name, g in TRACE_GROUPS.items()}
        return cls(step=np.arange(n, dtype=np.int64), t_s=np.full(n, math.nan),
                   extra={k: np.full(n, math.nan) for k in extra_names},
                   **groups)  # type: ignore[arg-type]

    @classmethod
    def empty(cls) -> Trace:
        """A trace of no rows (``allocate(0)``), its groups' zero-length columns shared
        (:meth:`ColumnGroup.no_rows`): 5 us, not 50."""
        groups = {name: g.no_rows() for name, g in TRACE_GROUPS.items()}
        return cls(step=_NO_STEPS, t_s=_NO_TIMES, extra={}, **groups)  # type: ignore[arg-type]

    def __len__(self) -> int:
        return int(self.step.shape[0])

    def head(self, n: int) -> Trace:
        groups = {name: getattr(self, name).head(n) for name in TRACE_GROUPS}
        return Trace(step=self.step[:n], t_s=self.t_s[:n],
                     extra={k: v[:n] for k, v in self.extra.items()},
                     **groups)

    def table_columns(self) -> dict[str, np.ndarray]:
        """Every column of trace.parquet, in file order: step, t_s, the groups, extra."""
        data: dict[str, np.ndarray] = {"step": self.step, "t_s": self.t_s}
        for name in TRACE_GROUPS:
            data.update(dict(getattr(self, name).columns()))
        data.update(self.extra)
        return data

    def to_frame(self) -> pd.DataFrame:
        import pandas as pd

        return pd.DataFrame(self.table_columns())

    @classmethod
    def from_frame(cls, frame: pd.DataFrame) -> Trace:
        step = _coerce(frame["step"].to_numpy(), np.int64, -1) if "step" in frame.columns \
            else np.arange(len(frame), dtype=np.int64)
        t_s = _coerce(frame["t_s"].to_numpy(), np.float64, math.nan) if "t_s" in frame.columns \
            else np.full(len(frame), math.nan)
        groups = {name: g.from_frame(frame) for name, g in TRACE_GROUPS.items()}
        extra = {c: _coerce(frame[c].to_numpy(), np.float64, math.nan)
                 for c in frame.columns if c not in CORE_TRACE_COLUMNS}
        return cls(step=step, t_s=t_s, extra=extra, **groups)  # type: ignore[arg-type]

    def describe(self) -> dict[str, tuple[str, str]]:
        """Column name -> (unit, meaning) for the core columns."""
        out = {"step": ("-", "control step index"), "t_s": ("s", "simulation time")}
        for g in TRACE_GROUPS.values():
            out.update(g.describe())
        return out


# ============================================================================ neighbours
@dataclass
class NeighbourColumns(ColumnGroup):
    """One row per (step, other vehicle within the recording radius)."""

    step: IntColumn = col("-", "control step index")
    t_s: FloatColumn = col("s", "simulation time")
    id: TextColumn = col("-", "SUMO vehicle id")
    x_m: FloatColumn = col("m", "box centre X")
    y_m: FloatColumn = col("m", "box centre Y")
    heading_rad: FloatColumn = col("rad", "heading, CCW from +X")
    speed_mps: FloatColumn = col("m/s", "speed")
    length_m: FloatColumn = col("m", "box length")
    width_m: FloatColumn = col("m", "box width")
    lane_index: IntColumn = col("-", "SUMO lane index")
    stalled: BoolColumn = col("-", "a stalled vehicle of the scenario")
    agent: AgentColumn = col("-", "what moves it: 0 SUMO traffic or actor, 1 replayed from "
                             "a recording, 2 recorded and handed over to SUMO (reactive)")

    def to_frame(self) -> pd.DataFrame:
        import pandas as pd

        return pd.DataFrame(dict(self.columns()))


# ============================================================================ metric series
@dataclass
class SeriesColumns(ColumnGroup):
    """Per-step signals the metrics are extremes of (``series.parquet``), aligned with the
    trace rows: what the HTML report and the Rerun log plot, computed once."""

    long_acc_mps2: FloatColumn = col("m/s^2", "smoothed longitudinal acceleration")
    lat_acc_mps2: FloatColumn = col("m/s^2", "smoothed lateral acceleration")
    yaw_rate_radps: FloatColumn = col("rad/s", "smoothed yaw rate")
    yaw_acc_radps2: FloatColumn = col("rad/s^2", "yaw acceleration")
    long_jerk_mps3: FloatColumn = col("m/s^3", "longitudinal jerk")
    jerk_mps3: FloatColumn = col("m/s^3", "magnitude of the world-frame jerk vector")
    ttc_s: FloatColumn = col("s", "time to collision with vehicles ahead (inf: none)")
    ttc_rear_s: FloatColumn = col("s", "time to collision with vehicles behind (inf: none)")
    offroad_excess_m: FloatColumn = col("m", "largest ego corner excess beyond drivable lanes")
    ellipse_margin: FloatColumn = col("-", "min ellipse value of the ego CG (< 0 inside)")
    drac_mps2: FloatColumn = col("m/s^2", "deceleration to avoid a crash with the vehicle "
                                 "ahead in the ego's path (0: none or not closing)")

    def to_frame(self) -> pd.DataFrame:
        import pandas as pd

        return pd.DataFrame(dict(self.columns()))


def frame_columns(groups: Mapping[str, ColumnGroup]) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    for g in groups.values():
        out.update(dict(g.columns()))
    return out
