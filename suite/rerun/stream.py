"""The run being logged and the recording stream it goes to, with columnar send helpers.

Everything per step is sent with one ``send_columns`` call per entity (a handful of
batches per run, not one call per step) on two timelines: ``step`` (sequence, the
trace's ``step``) and ``sim_time`` (duration, the trace's ``t_s``; NaN times are
replaced by step × ``info.step_s``). Trace *rows* (what ``Failure.step`` and
``MetricValue.worst_step`` index) map to timeline steps through ``trace.step``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
import pyarrow as pa
import rerun as rr

from reports.record import RunRecord

Colour = tuple[int, int, int, int]


class FlatStrips(NamedTuple):
    """Line strips stored end to end: ``points`` (M, 2) [m], strip k is the next
    ``counts[k]`` of them (sum(counts) = M)."""

    points: np.ndarray
    counts: np.ndarray


def strip_array(strips: np.ndarray | list[np.ndarray] | FlatStrips) -> Any:
    """Line strips as Rerun's arrow type, built in one go: a list of (n_k, 2) arrays (or
    :class:`FlatStrips`) -> ``list<fixed_size_list<float32>[2]>`` with offsets from the
    n_k. Rerun's own conversion of a list goes strip by strip (4000 small conversions for
    a 40 s run's plan, preview and ellipses, a third of the log's time). Anything else is
    handed to Rerun as it is."""
    if isinstance(strips, FlatStrips):
        counts = np.asarray(strips.counts, dtype=np.int64)
        flat = np.asarray(strips.points, dtype=np.float64).astype(np.float32).ravel()
    elif isinstance(strips, list) and all(
            isinstance(x, np.ndarray) and x.ndim == 2 and x.shape[1] == 2 for x in strips):
        counts = np.fromiter((len(x) for x in strips), dtype=np.int64, count=len(strips))
        flat = (np.concatenate(strips).astype(np.float32).ravel() if strips
                else np.zeros(0, np.float32))
    else:
        return strips
    datatype = rr.components.LineStrip2DBatch._ARROW_DATATYPE
    offsets = np.zeros(len(counts) + 1, dtype=np.int32)
    np.cumsum(counts, out=offsets[1:])
    inner = pa.FixedSizeListArray.from_arrays(pa.array(flat, type=pa.float32()),
                                              type=datatype.value_type)
    return pa.ListArray.from_arrays(pa.array(offsets, type=pa.int32()), inner, type=datatype)


def time_columns(steps: np.ndarray, t_s: np.ndarray) -> list[rr.TimeColumn]:
    """The two timelines for rows with these steps and times [s]."""
    return [rr.TimeColumn("step", sequence=np.asarray(steps, dtype=np.int64)),
            rr.TimeColumn("sim_time", duration=np.asarray(t_s, dtype=np.float64))]


class RunLog:
    """One record being written to one recording stream."""

    def __init__(self, rec: rr.RecordingStream, record: RunRecord) -> None:
        self.rec = rec
        self.record = record
        trace = record.trace
        self.n = len(trace)
        self.steps = np.asarray(trace.step, dtype=np.int64)
        t = np.asarray(trace.t_s, dtype=np.float64)
        if self.n and not np.all(np.isfinite(t)):
            dt = record.info.step_s if record.info.step_s > 0 else 0.1
            t = np.where(np.isfinite(t), t, self.steps * dt)
        self.t = t
        self.idx = time_columns(self.steps, self.t)

    def rows_of_steps(self, steps: np.ndarray) -> np.ndarray:
        """Trace row of each given step (-1 where the step is not a trace step)."""
        if self.n == 0:
            return np.full(len(steps), -1, dtype=np.int64)
        order = np.argsort(self.steps, kind="stable")
        pos = np.clip(np.searchsorted(self.steps[order], steps), 0, self.n - 1)
        rows = order[pos]
        out: np.ndarray = np.where(self.steps[rows] == steps, rows, -1).astype(np.int64)
        return out

    def send(self, path: str, columns: Any, idx: Sequence[rr.TimeColumn] | None = None) -> None:
        self.rec.send_columns(path, indexes=self.idx if idx is None else idx, columns=columns)

    def static(self, path: str, *archetypes: Any) -> None:
        self.rec.log(path, *archetypes, static=True)

    def strips_per_step(self, path: str, strips: np.ndarray | list[np.ndarray] | FlatStrips,
                        lengths: np.ndarray, labels: list[str] | None = None,
                        label_lengths: np.ndarray | None = None,
                        colors: np.ndarray | None = None) -> None:
        """Per-step LineStrips2D: row i holds lengths[i] strips (0 clears the entity)."""
        lengths = np.asarray(lengths, dtype=np.int64)
        cols = list(rr.LineStrips2D.columns(strips=strip_array(strips)).partition(lengths))
        if labels is not None:
            ll = lengths if label_lengths is None else np.asarray(label_lengths, np.int64)
            cols += list(rr.LineStrips2D.columns(labels=labels).partition(ll))
        if colors is not None:
            cols += list(rr.LineStrips2D.columns(colors=colors).partition(lengths))
        self.send(path, cols)

    def scalar(self, path: str, values: np.ndarray, name: str,
               color: Colour | None = None) -> None:
        """A per-step scalar series (non-finite samples left out; nothing if none)."""
        values = np.asarray(values, dtype=np.float64)
        ok = np.isfinite(values)
        if not ok.any():
            return
        self.static(path, rr.SeriesLines(names=[name],
                                         colors=[color] if color is not None else None))
        self.send(path, rr.Scalars.columns(scalars=values[ok]),
                  idx=time_columns(self.steps[ok], self.t[ok]))
