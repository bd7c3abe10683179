"""SUMO's SSM device output for the ego: per-time TTC and a summary."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import numpy.typing as npt

from reports.record import SsmSummary

FloatArray = npt.NDArray[np.float64]


def parse_ssm(path: Path) -> tuple[FloatArray, FloatArray, SsmSummary]:
    """Read SUMO's SSM log of the ego: per-time minimum TTC over its conflicts.

    Returns (times_s (n,), ttc_s (n,), summary). TTC is only defined while a conflict is
    tracked; an absent or empty file gives empty arrays and zero conflicts.
    """
    if not path.is_file() or path.stat().st_size == 0:
        return np.zeros(0), np.zeros(0), SsmSummary()
    root = ET.parse(path).getroot()
    per_time: dict[float, float] = {}
    min_ttc = math.inf
    max_drac = -math.inf
    n = 0
    for conflict in root.iter("conflict"):
        n += 1
        _collect_ttc_span(conflict, per_time)
        min_ttc = min(min_ttc, _value(conflict, "minTTC", nonneg=True, default=math.inf))
        max_drac = max(max_drac, _value(conflict, "maxDRAC", nonneg=False, default=-math.inf))
    times = np.array(sorted(per_time))
    ttc = np.array([per_time[t] for t in times]) if per_time else np.zeros(0)
    summary = SsmSummary(conflicts=n, min_ttc_s=min_ttc if math.isfinite(min_ttc) else None,
                         max_drac_mps2=max_drac if math.isfinite(max_drac) else None)
    return times, ttc, summary


def _collect_ttc_span(conflict: ET.Element, per_time: dict[float, float]) -> None:
    span = conflict.find("timeSpan")
    ttc_span = conflict.find("TTCSpan")
    if span is None or ttc_span is None:
        return
    times = span.get("values", "").split()
    ttcs = ttc_span.get("values", "").split()
    for t_txt, v_txt in zip(times, ttcs, strict=False):
        try:
            t, v = float(t_txt), float(v_txt)
        except ValueError:
            continue
        if v >= 0:
            per_time[t] = min(per_time.get(t, math.inf), v)


def _value(conflict: ET.Element, tag: str, *, nonneg: bool, default: float) -> float:
    el = conflict.find(tag)
    if el is None:
        return default
    try:
        value = float(el.get("value", "nan"))
    except ValueError:
        return default
    if not math.isfinite(value) or (nonneg and value < 0):
        return default
    return value
