"""The stress table: what a catalog run of a stress catalog says, per controller.

    python -m suite.stress.summary RUNS [--json]

For every controller (the ``__<controller>`` suffix of the sweep variants, else the run
info's controller) over the run directories in RUNS: the number of runs and their
statuses; runs with an at-fault collision and with any collision (nuPlan's
classification, ``reports.metrics.collisions``); the comfort pass rate (runs judged pass
or fail with no failed comfort criterion), over all runs and split by the scenario-name
tags of :mod:`suite.stress` (``close``, ``merge``, ``slow``, ``many``, ``free``, ``wet``,
the real nets); the share of control steps the fallback drove; and, from the traces,
the distribution of the outer solver's residual E (percentiles over every finite step).
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from reports.record import RunRecord, iter_run_dirs, load_run

TAGS = ("close", "merge", "slow", "many", "free", "wet", "a2", "a36", "a391")
E_PERCENTILES = (50.0, 90.0, 99.0, 99.9, 100.0)
JUDGED = ("pass", "fail")


@dataclass(frozen=True)
class ShareCount:
    """``passed`` of ``runs`` runs (a rate in percent, NaN for none)."""

    passed: int
    runs: int

    @property
    def percent(self) -> float:
        return 100.0 * self.passed / self.runs if self.runs else math.nan


@dataclass
class ControllerSummary:
    """One controller's stress table (module docstring); counts are runs, E unitless."""

    controller: str
    runs: int = 0
    statuses: dict[str, int] = field(default_factory=dict)
    at_fault: list[str] = field(default_factory=list)
    collided: list[str] = field(default_factory=list)
    comfort: dict[str, ShareCount] = field(default_factory=dict)
    fallback_steps: int = 0
    steps: int = 0
    residual_percentiles: dict[str, float] = field(default_factory=dict)
    residual_above: dict[str, float] = field(default_factory=dict)

    @property
    def fallback_percent(self) -> float:
        return 100.0 * self.fallback_steps / self.steps if self.steps else math.nan

    def as_dict(self) -> dict[str, object]:
        out = asdict(self)
        out["comfort"] = {k: {"passed": v.passed, "runs": v.runs, "percent": v.percent}
                          for k, v in self.comfort.items()}
        out["fallback_percent"] = self.fallback_percent
        return out


def _controller_of(rec: RunRecord, run_dir: Path) -> str:
    name = run_dir.name
    return name.rsplit("__", 1)[1] if "__" in name else rec.info.controller


def _tags(name: str) -> list[str]:
    base = name.split("__", 1)[0]
    parts = base.split("_")[1:]  # st<i>, then the net and the features
    return [t for t in TAGS if t in parts]


def _comfort_ok(rec: RunRecord) -> bool | None:
    """True/False for a judged run (no failed comfort criterion?), None otherwise."""
    v = rec.verdict
    if v is None or v.status not in JUDGED:
        return None
    kinds = {m.name: m.kind for m in v.metrics}
    return not any(kinds.get(f.metric) == "comfort" for f in v.failures)


def _value(rec: RunRecord, name: str) -> float:
    return rec.verdict.value(name) if rec.verdict is not None else math.nan


def _count(table: dict[str, ShareCount], key: str, ok: bool) -> None:
    old = table.get(key, ShareCount(0, 0))
    table[key] = ShareCount(old.passed + int(ok), old.runs + 1)


def summarise(run_dirs: Iterable[Path]) -> list[ControllerSummary]:
    """The stress table of the given run directories, one entry per controller."""
    by: dict[str, ControllerSummary] = {}
    residuals: dict[str, list[np.ndarray]] = {}
    for d in run_dirs:
        rec = load_run(d, neighbours=False, arrays=False, series=False)
        ctrl = _controller_of(rec, d)
        s = by.setdefault(ctrl, ControllerSummary(ctrl))
        s.runs += 1
        status = rec.verdict.status if rec.verdict is not None else rec.outcome.end
        s.statuses[status] = s.statuses.get(status, 0) + 1
        if _value(rec, "at_fault_collisions") > 0:
            s.at_fault.append(d.name)
        if _value(rec, "collisions") > 0:
            s.collided.append(d.name)
        ok = _comfort_ok(rec)
        if ok is not None:
            _count(s.comfort, "all", ok)
            tags = _tags(d.name)
            _count(s.comfort, "not close" if "close" not in tags else "close", ok)
            for tag in tags:
                if tag != "close":
                    _count(s.comfort, tag, ok)
        trace = rec.trace
        s.steps += len(trace.t_s)
        s.fallback_steps += int(np.count_nonzero(trace.controller.fallback))
        e = np.asarray(trace.controller.residual, dtype=np.float64)
        residuals.setdefault(ctrl, []).append(e[np.isfinite(e)])
    for ctrl, s in by.items():
        e = np.concatenate(residuals[ctrl]) if residuals[ctrl] else np.zeros(0)
        if e.size:
            s.residual_percentiles = {f"p{p:g}": float(np.percentile(e, p))
                                      for p in E_PERCENTILES}
            s.residual_above = {f"{b:g}": float(100.0 * np.mean(e > b))
                                for b in (1.0, 10.0, 40.0)}
    return [by[k] for k in sorted(by)]


def lines(table: Sequence[ControllerSummary]) -> list[str]:
    """The table as text, one block per controller."""
    out: list[str] = []
    for s in table:
        st = ", ".join(f"{k} {v}" for k, v in sorted(s.statuses.items()))
        out.append(f"{s.controller}: {s.runs} runs ({st})")
        out.append(f"  at-fault collisions: {len(s.at_fault)} runs "
                   f"({100.0 * len(s.at_fault) / max(s.runs, 1):.2f} %) {s.at_fault[:8]}")
        out.append(f"  any collision: {len(s.collided)} runs {s.collided[:8]}")
        comfort = "; ".join(f"{k} {v.passed}/{v.runs} = {v.percent:.1f} %"
                            for k, v in s.comfort.items())
        out.append(f"  comfort pass: {comfort}")
        out.append(f"  fallback steps: {s.fallback_steps}/{s.steps} = "
                   f"{s.fallback_percent:.3f} % of all steps")
        if s.residual_percentiles:
            e = ", ".join(f"{k} {v:.3g}" for k, v in s.residual_percentiles.items())
            above = ", ".join(f"E > {k}: {v:.3f} %" for k, v in s.residual_above.items())
            out.append(f"  residual E: {e}; {above}")
    return out


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m suite.stress.summary",
                                 description="The stress table of a catalog run.")
    ap.add_argument("runs", type=Path, help="the --out directory of hwyeval run")
    ap.add_argument("--json", action="store_true", help="print JSON instead of text")
    args = ap.parse_args(argv)
    dirs = iter_run_dirs(args.runs)
    if not dirs:
        print(f"{args.runs}: no run directories")
        return 2
    table = summarise(dirs)
    if args.json:
        print(json.dumps([s.as_dict() for s in table], indent=2))
    else:
        print("\n".join(lines(table)))
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
