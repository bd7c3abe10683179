"""The Recorder role: every step's records into columnar buffers, handed over once.

The trace is allocated for the whole run (:meth:`reports.record.Trace.allocate`) and
filled by row index. The neighbours (one row per step and vehicle within the recording
radius) and the obstacle ellipses (one row per step and obstacle) go into growable
column buffers (:class:`_Columns`: capacity doubled when full, so a step writes slices
into existing arrays and allocates nothing in the common case); the ellipses are turned
into the world frame once, at :meth:`TraceRecorder.finish`, for all steps at once. The
controller's plan and preview arrays are kept by reference and stacked at the end.
Columns are the fields of the record schema's column groups and of the controller's
declared diagnostics dataclass, so a field the controller declares always reaches
``trace.parquet``.
"""

from __future__ import annotations

import dataclasses
import math
import operator
from dataclasses import dataclass
from typing import Protocol

import numba
import numpy as np

from controllers.behaviour.types import Decision, Traffic
from controllers.path.frenet import FrenetPath
from controllers.protocol import Command, StepDiagnostics
from reports.record import ControllerArrays, ControllerColumns, NeighbourColumns, Trace
from suite.run.ego import EgoState
from suite.run.safety import SafetySample

BASE_DIAGNOSTICS = tuple(f.name for f in dataclasses.fields(StepDiagnostics))
if set(BASE_DIAGNOSTICS) != set(ControllerColumns.names()):  # schema and protocol agree
    raise RuntimeError(f"StepDiagnostics fields {BASE_DIAGNOSTICS} differ from the trace's "
                       f"controller columns {ControllerColumns.names()}")


@dataclass(frozen=True)
class StepTiming:
    """Wall time of this step's stages [s]: behaviour, behaviour + controller, dynamics."""

    behaviour_s: float
    controller_s: float
    dynamics_s: float


class Recorder(Protocol):
    def record(self, step: int, t_s: float, ego: EgoState, decision: Decision, command: Command,
               safety: SafetySample, timing: StepTiming, traffic: Traffic) -> None: ...


def extra_diagnostics(diagnostics_type: type[StepDiagnostics]) -> tuple[str, ...]:
    """The controller-specific diagnostic fields (beyond :class:`StepDiagnostics`)."""
    return tuple(f.name for f in dataclasses.fields(diagnostics_type)
                 if f.name not in BASE_DIAGNOSTICS)


class _Columns:
    """Growable columns of one dtype each, filled by appending slices of ``n`` rows.

    ``columns``: name -> dtype; rows are written at ``[size, size + n)`` after growing
    every column to twice its capacity when needed (amortised O(1) per row)."""

    def __init__(self, columns: dict[str, type | np.dtype], capacity: int) -> None:
        if capacity < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity}")
        self.size = 0
        self.data = {name: np.empty(capacity, dtype=dtype) for name, dtype in columns.items()}

    def reserve(self, n: int) -> int:
        """Room for ``n`` more rows; returns the first row index to write."""
        start = self.size
        need = start + n
        cap = next(iter(self.data.values())).shape[0]
        if need > cap:
            new_cap = max(need, 2 * cap)
            for name, arr in self.data.items():
                grown = np.empty(new_cap, dtype=arr.dtype)
                grown[:start] = arr[:start]
                self.data[name] = grown
        self.size = need
        return start

    def trim(self, size: int) -> None:
        """Keep the first ``size`` rows (of those reserved): the rest are not filled."""
        if not 0 <= size <= self.size:
            raise ValueError(f"cannot trim {self.size} rows to {size}")
        self.size = size

    def head(self, name: str) -> np.ndarray:
        """The filled rows of column ``name`` (a copy, owned by the caller)."""
        return self.data[name][: self.size].copy()


_NEIGHBOUR_NUMERIC = {"step": np.int64, "t_s": np.float64, "x_m": np.float64,
                      "y_m": np.float64, "heading_rad": np.float64, "speed_mps": np.float64,
                      "length_m": np.float64, "width_m": np.float64, "lane_index": np.int64,
                      "stalled": np.bool_, "agent": np.int8}


@numba.njit(cache=True)
def _append_within(step: int, t_s: float, ex: float, ey: float, radius2: float,
                   x: np.ndarray, y: np.ndarray, heading: np.ndarray, speed: np.ndarray,
                   length: np.ndarray, width: np.ndarray, lane: np.ndarray, stalled: np.ndarray,
                   agent: np.ndarray, a: int, o_step: np.ndarray, o_t: np.ndarray,
                   o_x: np.ndarray, o_y: np.ndarray, o_heading: np.ndarray,
                   o_speed: np.ndarray, o_length: np.ndarray, o_width: np.ndarray,
                   o_lane: np.ndarray, o_stalled: np.ndarray, o_agent: np.ndarray,
                   picked: np.ndarray) -> int:
    """Rows ``a, a+1, ...`` of the ``o_*`` neighbour columns from the vehicles (n,) whose
    CG is within ``radius2`` [m²] of the ego's CG (ex, ey) [m], in traffic order
    (``(x - ex)² + (y - ey)² <= radius2``, evaluated as numpy does); ``picked`` gets
    their traffic indices. Returns how many."""
    n = 0
    for k in range(x.shape[0]):
        dx = x[k] - ex
        dy = y[k] - ey
        if dx * dx + dy * dy <= radius2:
            r = a + n
            o_step[r] = step
            o_t[r] = t_s
            o_x[r] = x[k]
            o_y[r] = y[k]
            o_heading[r] = heading[k]
            o_speed[r] = speed[k]
            o_length[r] = length[k]
            o_width[r] = width[k]
            o_lane[r] = lane[k]
            o_stalled[r] = stalled[k]
            o_agent[r] = agent[k]
            picked[n] = k
            n += 1
    return n


def load_kernels() -> None:
    """Load (or compile once) this module's kernel on a tiny input: the forkserver's
    warm-up calls it, so scenario processes inherit the compiled code."""
    f, i, b = np.zeros(1), np.zeros(1, dtype=np.int64), np.zeros(1, dtype=np.bool_)
    g = np.zeros(1, dtype=np.int8)
    _append_within(0, 0.0, 0.0, 0.0, 1.0, f, f, f, f, f, f, i, b, g, 0, i.copy(), f.copy(),
                   f.copy(), f.copy(), f.copy(), f.copy(), f.copy(), f.copy(), i.copy(),
                   b.copy(), g.copy(), i.copy())


def _as(values: object, dtype: type) -> np.ndarray:
    """``values`` as a contiguous 1-D array of ``dtype`` (itself when it is one)."""
    return np.ascontiguousarray(values, dtype=dtype)


_ELLIPSE = {"step": np.int64, "s_m": np.float64, "y_m": np.float64, "semi_a_m": np.float64,
            "semi_b_m": np.float64}


class TraceRecorder:
    """Columnar buffers for ``n_steps`` steps of one run."""

    def __init__(self, n_steps: int, diagnostics_type: type[StepDiagnostics], path: FrenetPath,
                 record_radius_m: float) -> None:
        self.diagnostics_type = diagnostics_type
        self._extra = extra_diagnostics(diagnostics_type)
        self._get_extra = operator.attrgetter(*self._extra) if self._extra else None
        self.trace = Trace.allocate(n_steps, self._extra)
        # the extras row by row (one array write a step), into trace.extra at finish
        self._extra_rows = np.full((n_steps, len(self._extra)), np.nan)
        self.path = path
        self.record_radius_m = record_radius_m
        self._radius2 = float(record_radius_m) ** 2
        self.rows = 0
        self._nb = _Columns(dict(_NEIGHBOUR_NUMERIC), max(64 * n_steps, 64))
        self._nb_ids: list[str] = []
        self._picked = np.empty(64, dtype=np.int64)  # traffic indices of one step's rows
        self._ell = _Columns(dict(_ELLIPSE), max(4 * n_steps, 16))
        self._ell_ids: list[str] = []  # the vehicle behind each ellipse row ('' unknown)
        self._plans: list[np.ndarray | None] = []
        self._previews: list[np.ndarray | None] = []

    def record(self, step: int, t_s: float, ego: EgoState, decision: Decision, command: Command,
               safety: SafetySample, timing: StepTiming, traffic: Traffic) -> None:
        i = self.rows
        tr = self.trace
        tr.step[i] = step
        tr.t_s[i] = t_s
        self._ego(i, ego)
        d = tr.decision
        d.target_speed_mps[i] = decision.target_speed_mps
        d.side[i] = decision.side
        d.side_reason[i] = decision.reason
        d.reason_code[i] = decision.reason_code.value
        d.n_obstacles[i] = decision.obstacles.count
        d.lat_ref_m[i] = decision.lateral_reference_m
        sa = tr.safety
        sa.min_gap_m[i] = safety.min_gap_m
        sa.gap_vehicle[i] = safety.gap_vehicle
        sa.geom_collision[i] = safety.geom_collision
        sa.sumo_collision[i] = safety.sumo_collision
        self._diagnostics(i, command.diagnostics)
        tm = tr.timing
        tm.obstacles_s[i] = timing.behaviour_s
        tm.controller_s[i] = timing.controller_s
        tm.sumo_s[i] = timing.dynamics_s
        self._neighbours(step, t_s, ego, traffic)
        self._plans.append(command.plan_xy_m)
        self._previews.append(command.preview_xy_m)
        self._obstacles(i, decision)
        self.rows += 1

    def _ego(self, i: int, ego: EgoState) -> None:
        e = self.trace.ego
        st = ego.state
        e.x_m[i], e.y_m[i], e.psi_rad[i] = st[0], st[1], st[2]
        e.u_mps[i], e.v_mps[i], e.r_radps[i] = st[3], st[4], st[5]
        e.speed_mps[i] = ego.speed_mps
        e.long_acc_mps2[i] = ego.long_acc_mps2
        e.lat_acc_mps2[i] = ego.lat_acc_mps2
        e.steer_rad[i] = ego.steer_rad
        e.torque_nm[i] = ego.torque_nm
        e.s_m[i], e.lat_dev_m[i], e.heading_err_rad[i] = ego.s_m, ego.lat_m, ego.heading_err_rad
        w = ego.world
        e.lane_index[i] = w.lane_index if w is not None else -1
        e.sumo_front_x_m[i] = w.front_x_m if w is not None else math.nan
        e.sumo_front_y_m[i] = w.front_y_m if w is not None else math.nan
        e.sumo_heading_rad[i] = w.heading_rad if w is not None else math.nan

    def _diagnostics(self, i: int, diag: StepDiagnostics) -> None:
        if type(diag) is not self.diagnostics_type:
            raise TypeError(f"the controller declared diagnostics {self.diagnostics_type.__name__}"
                            f" but returned {type(diag).__name__}")
        c = self.trace.controller
        c.residual[i] = diag.residual
        c.fallback[i] = diag.fallback
        c.guard_fired[i] = diag.guard_fired
        c.outer_s[i] = diag.outer_s
        c.inner_s[i] = diag.inner_s
        if self._get_extra is not None:
            values = self._get_extra(diag)
            if len(self._extra) == 1:
                values = (values,)
            # float() of each, as a column per field would store them
            self._extra_rows[i] = [float(v) for v in values]

    def _neighbours(self, step: int, t_s: float, ego: EgoState, traffic: Traffic) -> None:
        """Rows of the vehicles within the recording radius of the ego's CG, in one
        compiled pass (:func:`_append_within`) instead of ~20 numpy calls a step."""
        count = traffic.count
        if count == 0:
            return
        if self._picked.shape[0] < count:
            self._picked = np.empty(2 * count, dtype=np.int64)
        a = self._nb.reserve(count)
        c = self._nb.data
        f8, i8 = np.float64, np.int64  # the kernel's types (no copy when they are so)
        n = _append_within(step, t_s, float(ego.state[0]), float(ego.state[1]),
                           self._radius2, _as(traffic.x_m, f8), _as(traffic.y_m, f8),
                           _as(traffic.heading_rad, f8), _as(traffic.speed_mps, f8),
                           _as(traffic.length_m, f8), _as(traffic.width_m, f8),
                           _as(traffic.lane_index, i8), _as(traffic.stalled, np.bool_),
                           _as(traffic.agent, np.int8), a, c["step"], c["t_s"],
                           c["x_m"], c["y_m"], c["heading_rad"], c["speed_mps"], c["length_m"],
                           c["width_m"], c["lane_index"], c["stalled"], c["agent"],
                           self._picked)
        self._nb.trim(a + n)
        ids = traffic.ids
        self._nb_ids.extend(ids if n == count else [ids[k] for k in self._picked[:n].tolist()])

    def _obstacles(self, i: int, decision: Decision) -> None:
        """The step's obstacle ellipses in the Frenet frame (world frame at finish)."""
        ob = decision.obstacles
        n = ob.count
        if n == 0:
            return
        a = self._ell.reserve(n)
        b = a + n
        cols = self._ell.data
        cols["step"][a:b] = i
        cols["s_m"][a:b] = ob.s_m
        cols["y_m"][a:b] = ob.y_m
        cols["semi_a_m"][a:b] = ob.semi_a_m
        cols["semi_b_m"][a:b] = ob.semi_b_m
        self._ell_ids.extend(ob.vehicle_ids if ob.vehicle_ids else [""] * n)

    def _ellipses(self) -> tuple[np.ndarray, np.ndarray]:
        """(T, max obstacles, 6) [cx_m, cy_m, heading_rad, semi_a_m, semi_b_m, active],
        NaN-padded: each step's ellipses in the world frame, axes along the path tangent
        at their centre (``controllers.behaviour.ellipses.ellipses_in_world`` for every
        step, in one vectorised pass); and (T, max obstacles) the vehicle id of each
        ('' padding or unknown)."""
        e = self._ell
        counts = np.bincount(e.data["step"][: e.size], minlength=self.rows)[: self.rows]
        width = int(counts.max()) if counts.size else 0
        out = np.full((self.rows, width, 6), np.nan)
        if e.size == 0:
            return out, np.full((self.rows, width), "", dtype=str)
        rows = e.head("step")
        s, y = e.head("s_m"), e.head("y_m")
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        slot = np.arange(e.size) - starts[rows]
        names = np.asarray(self._ell_ids[: e.size], dtype=str)
        ids = np.full((self.rows, width), "", dtype=names.dtype if names.size else str)
        ids[rows, slot] = names
        x_w, y_w = self.path.to_global(s, y)
        out[rows, slot, 0] = x_w
        out[rows, slot, 1] = y_w
        out[rows, slot, 2] = self.path.gamma(s)
        out[rows, slot, 3] = e.head("semi_a_m")
        out[rows, slot, 4] = e.head("semi_b_m")
        out[rows, slot, 5] = 1.0
        return out, ids

    def finish(self, detection_radius_m: float) -> tuple[Trace, NeighbourColumns,
                                                         ControllerArrays]:
        """The recorded rows (the trace cut to the steps run)."""
        for k, name in enumerate(self._extra):
            self.trace.extra[name][: self.rows] = self._extra_rows[: self.rows, k]
        trace = self.trace.head(self.rows)
        if self._nb.size:
            nb = NeighbourColumns(id=np.array(self._nb_ids, dtype=object),
                                  **{name: self._nb.head(name) for name in _NEIGHBOUR_NUMERIC})
        else:
            nb = NeighbourColumns.allocate(0)
        ellipses, ellipse_ids = self._ellipses()
        arrays = ControllerArrays(plan_xy_m=_stack(self._plans, 2),
                                  preview_xy_m=_stack(self._previews, 2),
                                  ellipses=ellipses, ellipse_ids=ellipse_ids,
                                  detection_radius_m=detection_radius_m)
        return trace, nb, arrays


def _stack(items: list[np.ndarray | None], width: int) -> np.ndarray:
    """(T, max rows, width) NaN-padded stack of per-step arrays (None: all NaN)."""
    sizes = [a.shape[0] for a in items if a is not None]
    rows = max(sizes) if sizes else 0
    out = np.full((len(items), rows, width), np.nan)
    for i, a in enumerate(items):
        if a is not None and a.size:
            out[i, : a.shape[0]] = a
    return out
