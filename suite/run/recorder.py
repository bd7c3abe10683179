"""The Recorder role: every step's records into columnar buffers, handed over once.

The trace is allocated for the whole run (:meth:`reports.record.Trace.allocate`) and
filled by row index; neighbours and per-step controller arrays are collected as arrays
and joined at the end. Columns are the fields of the record schema's column groups and
of the controller's declared diagnostics dataclass, so a field the controller declares
always reaches ``trace.parquet``.
"""

from __future__ import annotations

import dataclasses
import math
import operator
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from controllers.behaviour.ellipses import ellipses_in_world
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


class TraceRecorder:
    """Columnar buffers for ``n_steps`` steps of one run."""

    def __init__(self, n_steps: int, diagnostics_type: type[StepDiagnostics], path: FrenetPath,
                 record_radius_m: float) -> None:
        self.diagnostics_type = diagnostics_type
        self._extra = extra_diagnostics(diagnostics_type)
        self._get_extra = operator.attrgetter(*self._extra) if self._extra else None
        self.trace = Trace.allocate(n_steps, self._extra)
        self.path = path
        self.record_radius_m = record_radius_m
        self.rows = 0
        self._nb: list[NeighbourColumns] = []
        self._plans: list[np.ndarray | None] = []
        self._previews: list[np.ndarray | None] = []
        self._ellipses: list[np.ndarray] = []

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
        self._ellipses.append(ellipses_in_world(self.path, decision.obstacles))
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
            for name, value in zip(self._extra, values, strict=True):
                self.trace.extra[name][i] = float(value)

    def _neighbours(self, step: int, t_s: float, ego: EgoState, traffic: Traffic) -> None:
        if traffic.count == 0:
            return
        keep = np.hypot(traffic.x_m - ego.state[0], traffic.y_m - ego.state[1]) \
            <= self.record_radius_m
        if not np.any(keep):
            return
        tr = traffic.take(keep)
        n = tr.count
        self._nb.append(NeighbourColumns(
            step=np.full(n, step, dtype=np.int64), t_s=np.full(n, t_s),
            id=np.array(tr.ids, dtype=object), x_m=tr.x_m, y_m=tr.y_m,
            heading_rad=tr.heading_rad, speed_mps=tr.speed_mps, length_m=tr.length_m,
            width_m=tr.width_m, lane_index=tr.lane_index, stalled=tr.stalled))

    def finish(self, detection_radius_m: float) -> tuple[Trace, NeighbourColumns,
                                                         ControllerArrays]:
        """The recorded rows (the trace cut to the steps run)."""
        trace = self.trace.head(self.rows)
        if self._nb:
            names = NeighbourColumns.names()
            nb = NeighbourColumns(**{name: np.concatenate([getattr(c, name) for c in self._nb])
                                     for name in names})
        else:
            nb = NeighbourColumns.allocate(0)
        arrays = ControllerArrays(plan_xy_m=_stack(self._plans, 2),
                                  preview_xy_m=_stack(self._previews, 2),
                                  ellipses=_stack(list(self._ellipses), 6),
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
