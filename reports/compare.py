"""Compare two catalog outputs (base vs new): status changes, metric and timing regressions.

Only the stored verdicts are read (``run.json`` of each run directory): statuses,
metric values and typed failures; an unreadable run directory counts as 'error'.

Matching: runs are matched by (scenario, controller). When each directory holds exactly
one controller and they differ (comparing controller A against B), runs are matched by
scenario name alone. An unreadable run directory is matched by its directory name.
Unmatched runs are listed as ``missing`` (in base only; a regression unless
``missing_is_regression = false``) or ``new`` (in new only).

Regressions (exit code 1):
* ``new_failure``: base passed, new did not; ``worse_status``: fail → error/timeout;
  ``new_criterion``: both failed but new fails a criterion base did not;
* ``metric_regression``: a metric moved in its worse direction by more than
  max(abs, rel·|base|) (``MetricTolerance``); metrics of error/timeout runs are skipped;
* ``timing_regression``: new/base > ratio for a timing metric (base/new for
  ``realtime_factor``), ignored when both values are below ``timing_floor_ms``.
Improvements beyond tolerance and fixed runs are listed but never fail the comparison.

Tolerances TOML (``--tolerances FILE``), every key optional::

    missing_is_regression = true
    timing_floor_ms = 1.0
    [metrics.min_gap_m]          # merged into the default entry
    abs = 0.5
    rel = 0.1
    direction = "lower_is_worse"  # or "higher_is_worse"
    [timing]
    step_ms_p99 = 1.5            # max ratio new/base
"""

from __future__ import annotations

import csv
import datetime as _dt
import html
import math
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from reports.tables import RunEntry, collect_runs

HIGHER_IS_WORSE = "higher_is_worse"
LOWER_IS_WORSE = "lower_is_worse"
DIRECTIONS = (HIGHER_IS_WORSE, LOWER_IS_WORSE)
TIMING_LOWER_IS_WORSE = frozenset({"realtime_factor"})
STATUS_RANK = {"pass": 0, "fail": 1, "timeout": 2, "error": 2}
REGRESSION_KINDS = frozenset({"missing", "new_failure", "worse_status", "new_criterion",
                              "metric_regression", "timing_regression"})


@dataclass(frozen=True)
class MetricTolerance:
    """A change is beyond tolerance when |new − base| > max(abs, rel·|base|); ``direction``
    says which way is a regression."""

    abs: float = 0.0
    rel: float = 0.0
    direction: str = HIGHER_IS_WORSE

    def __post_init__(self) -> None:
        if self.direction not in DIRECTIONS:
            raise ValueError(f"direction must be one of {DIRECTIONS}, got {self.direction!r}")
        for name in ("abs", "rel"):
            value = getattr(self, name)
            if not isinstance(value, int | float) or isinstance(value, bool) or value < 0 \
                    or not math.isfinite(value):
                raise ValueError(f"tolerance {name} must be a finite number >= 0, got {value!r}")

    def threshold(self, base: float) -> float:
        """Allowed change for a base value."""
        if math.isfinite(base):
            return max(self.abs, self.rel * abs(base))
        return self.abs


def default_metric_tolerances() -> dict[str, MetricTolerance]:
    """Default per-metric tolerances."""
    h, lo = HIGHER_IS_WORSE, LOWER_IS_WORSE
    return {
        "collision": MetricTolerance(0.5, 0.0, h),
        "min_gap_m": MetricTolerance(0.25, 0.1, lo),
        "min_ttc_s": MetricTolerance(0.2, 0.1, lo),
        "min_ellipse_margin": MetricTolerance(0.1, 0.1, lo),
        "offroad_s": MetricTolerance(0.1, 0.0, h),
        "shoulder_s": MetricTolerance(0.5, 0.1, h),
        "progress_m": MetricTolerance(5.0, 0.05, lo),
        "progress_ratio": MetricTolerance(0.05, 0.0, lo),
        "rms_lat_dev_m": MetricTolerance(0.05, 0.1, h),
        "max_abs_lat_dev_m": MetricTolerance(0.1, 0.1, h),
        "mean_speed_mps": MetricTolerance(0.5, 0.05, lo),
        "min_long_acc_mps2": MetricTolerance(0.2, 0.1, lo),
        "max_long_acc_mps2": MetricTolerance(0.2, 0.1, h),
        "max_abs_lat_acc_mps2": MetricTolerance(0.2, 0.1, h),
        "max_abs_yaw_rate_radps": MetricTolerance(0.02, 0.1, h),
        "max_abs_yaw_acc_radps2": MetricTolerance(0.1, 0.1, h),
        "max_abs_long_jerk_mps3": MetricTolerance(0.3, 0.15, h),
        "max_abs_jerk_mps3": MetricTolerance(0.3, 0.15, h),
        "residual_max": MetricTolerance(1e-3, 1.0, h),
        "fallbacks": MetricTolerance(0.5, 0.0, h),
        "guards": MetricTolerance(2.0, 0.25, h),
        "deadline_misses": MetricTolerance(2.0, 0.5, h),
    }


def default_timing_ratios() -> dict[str, float]:
    """Default max timing ratios (new/base; base/new for realtime_factor)."""
    return {"step_ms_p50": 1.5, "step_ms_p99": 1.5, "outer_ms_p99": 1.5, "inner_ms_p99": 1.5,
            "realtime_factor": 1.5}


@dataclass(frozen=True)
class Tolerances:
    """Per-metric tolerances, timing ratios, and the treatment of missing runs."""

    metrics: Mapping[str, MetricTolerance] = field(default_factory=default_metric_tolerances)
    timing: Mapping[str, float] = field(default_factory=default_timing_ratios)
    timing_floor_ms: float = 1.0
    missing_is_regression: bool = True

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], base: Tolerances | None = None) -> Tolerances:
        """Defaults (or ``base``) updated from a dict shaped like the TOML file."""
        base = base if base is not None else cls()
        known = {"metrics", "timing", "timing_floor_ms", "missing_is_regression"}
        for key in data:
            if key not in known:
                raise ValueError(f"unknown tolerances key {key!r}; "
                                 f"valid: {', '.join(sorted(known))}")
        metrics = dict(base.metrics)
        for name, spec in (data.get("metrics") or {}).items():
            if not isinstance(spec, Mapping):
                raise ValueError(f"metrics.{name}: expected a table with abs/rel/direction")
            bad = set(spec) - {"abs", "rel", "direction"}
            if bad:
                raise ValueError(f"metrics.{name}: unknown keys {sorted(bad)}; "
                                 "valid: abs, rel, direction")
            current = metrics.get(name, MetricTolerance())
            try:
                kwargs: dict[str, Any] = {k: (float(v) if k != "direction" else v)
                                          for k, v in spec.items()}
                metrics[name] = replace(current, **kwargs)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"metrics.{name}: {exc}") from exc
        timing = dict(base.timing)
        for name, ratio in (data.get("timing") or {}).items():
            if isinstance(ratio, bool) or not isinstance(ratio, int | float) or ratio < 1.0:
                raise ValueError(f"timing.{name}: expected a ratio >= 1, got {ratio!r}")
            timing[name] = float(ratio)
        floor = data.get("timing_floor_ms", base.timing_floor_ms)
        if isinstance(floor, bool) or not isinstance(floor, int | float) or floor < 0:
            raise ValueError(f"timing_floor_ms: expected a number >= 0, got {floor!r}")
        missing = data.get("missing_is_regression", base.missing_is_regression)
        if not isinstance(missing, bool):
            raise ValueError(f"missing_is_regression: expected true/false, got {missing!r}")
        return cls(metrics=metrics, timing=timing, timing_floor_ms=float(floor),
                   missing_is_regression=missing)

    @classmethod
    def from_toml(cls, path: str | Path) -> Tolerances:
        """Defaults updated from a TOML file (see module doc)."""
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
        return cls.from_mapping(data)


@dataclass
class CompareRow:
    """One finding."""

    key: str
    scenario: str
    controller: str
    kind: str
    metric: str = ""
    base: float = math.nan
    new: float = math.nan
    delta: float = math.nan
    ratio: float = math.nan
    limit: float = math.nan
    note: str = ""

    @property
    def regression(self) -> bool:
        """Whether this finding makes the comparison fail."""
        return self.kind in REGRESSION_KINDS and not self.note.startswith("(ignored)")


CSV_COLUMNS = ("key", "scenario", "controller", "kind", "regression", "metric", "base", "new",
               "delta", "ratio", "limit", "note")


@dataclass
class CompareResult:
    """Outcome of :func:`compare_runs`."""

    rows: list[CompareRow]
    matched: int
    base_dir: Path
    new_dir: Path
    csv_path: Path | None = None
    html_path: Path | None = None

    def of_kind(self, *kinds: str) -> list[CompareRow]:
        """Rows of the given kinds."""
        return [r for r in self.rows if r.kind in kinds]

    @property
    def regressions(self) -> list[CompareRow]:
        """Rows that are regressions."""
        return [r for r in self.rows if r.regression]

    @property
    def new_failures(self) -> list[str]:
        """Keys of runs that passed in base and not in new."""
        return [r.key for r in self.of_kind("new_failure")]

    @property
    def fixed(self) -> list[str]:
        """Keys of runs that failed in base and pass in new."""
        return [r.key for r in self.of_kind("fixed")]

    @property
    def missing(self) -> list[str]:
        """Keys only in base."""
        return [r.key for r in self.of_kind("missing")]

    @property
    def added(self) -> list[str]:
        """Keys only in new."""
        return [r.key for r in self.of_kind("new")]

    @property
    def exit_code(self) -> int:
        """1 on any regression, else 0."""
        return 1 if self.regressions else 0

    def summary_text(self) -> str:
        """A few lines for the terminal."""
        lines = [f"compared {self.matched} matched runs: {len(self.regressions)} regression(s), "
                 f"{len(self.fixed)} fixed, {len(self.missing)} missing, {len(self.added)} new"]
        for row in self.regressions:
            lines.append(f"  REGRESSION {row.key}: {row.kind} {row.metric} {row.note}".rstrip())
        return "\n".join(lines)


def _match_keys(base: Sequence[RunEntry], new: Sequence[RunEntry]
                ) -> tuple[dict[str, RunEntry], dict[str, RunEntry]]:
    base_ctrls = {r.controller for r in base if r.record is not None}
    new_ctrls = {r.controller for r in new if r.record is not None}
    by_scenario = len(base_ctrls) == 1 and len(new_ctrls) == 1 and base_ctrls != new_ctrls

    def key(r: RunEntry) -> str:
        return r.scenario if by_scenario else f"{r.scenario} [{r.controller}]"

    def keyed(runs: Sequence[RunEntry], other: Sequence[RunEntry]) -> dict[str, RunEntry]:
        # an unreadable run directory knows only its name: it takes the key of the
        # other side's run in the directory of that name
        by_dir = {r.run_id: key(r) for r in other if r.record is not None}
        return {(by_dir.get(r.run_id, key(r)) if r.record is None else key(r)): r
                for r in runs}

    return keyed(base, new), keyed(new, base)


def _status_rows(key: str, b: RunEntry, n: RunEntry) -> list[CompareRow]:
    rows = []
    common: dict[str, Any] = {"key": key, "scenario": n.scenario, "controller": n.controller}
    rb, rn = STATUS_RANK.get(b.status, 2), STATUS_RANK.get(n.status, 2)
    note = f"{b.status} → {n.status}"
    if n.failures and n.status != "pass":
        note += ": " + "; ".join(f.text for f in n.failures)
    elif n.error and n.status in ("error", "timeout"):
        lines = n.error.strip().splitlines()
        note += ": " + (lines[-1] if lines else n.status)
    if b.status == "pass" and n.status != "pass":
        rows.append(CompareRow(kind="new_failure", note=note, **common))
    elif n.status == "pass" and b.status != "pass":
        rows.append(CompareRow(kind="fixed", note=note, **common))
    elif rn > rb:
        rows.append(CompareRow(kind="worse_status", note=note, **common))
    elif b.status != n.status:
        rows.append(CompareRow(kind="status_change", note=note, **common))
    if b.status == "fail" and n.status == "fail":
        base_criteria = {f.criterion for f in b.failures}
        for failure in n.failures:
            if failure.criterion not in base_criteria:
                rows.append(CompareRow(kind="new_criterion", metric=failure.metric,
                                       note=failure.text, **common))
    return rows


def _metric_rows(key: str, b: RunEntry, n: RunEntry, tol: Tolerances) -> list[CompareRow]:
    rows = []
    common: dict[str, Any] = {"key": key, "scenario": n.scenario, "controller": n.controller}
    for metric, mt in tol.metrics.items():
        vb, vn = b.value(metric), n.value(metric)
        if math.isnan(vb) and math.isnan(vn):
            continue
        if math.isnan(vb) or math.isnan(vn):
            rows.append(CompareRow(kind="metric_nan", metric=metric, base=vb, new=vn,
                                   note="only measured in one run", **common))
            continue
        if vb == vn:
            continue
        worse = (vn - vb) if mt.direction == HIGHER_IS_WORSE else (vb - vn)
        limit = mt.threshold(vb)
        delta = vn - vb
        if worse > limit:
            rows.append(CompareRow(kind="metric_regression", metric=metric, base=vb, new=vn,
                                   delta=delta, limit=limit,
                                   note=f"{mt.direction.replace('_', ' ')}; tolerance "
                                        f"{limit:.4g}", **common))
        elif worse < -limit:
            rows.append(CompareRow(kind="metric_improvement", metric=metric, base=vb, new=vn,
                                   delta=delta, limit=limit, **common))
    for metric, max_ratio in tol.timing.items():
        vb, vn = b.value(metric), n.value(metric)
        if not (math.isfinite(vb) and math.isfinite(vn)) or vb <= 0 or vn <= 0:
            continue
        lower_worse = metric in TIMING_LOWER_IS_WORSE
        ratio = vb / vn if lower_worse else vn / vb
        if "_ms_" in metric and max(vb, vn) < tol.timing_floor_ms:
            continue
        if ratio > max_ratio:
            rows.append(CompareRow(kind="timing_regression", metric=metric, base=vb, new=vn,
                                   delta=vn - vb, ratio=ratio, limit=max_ratio,
                                   note=f"ratio {ratio:.2f} > {max_ratio:g}", **common))
        elif ratio < 1.0 / max_ratio:
            rows.append(CompareRow(kind="timing_improvement", metric=metric, base=vb, new=vn,
                                   delta=vn - vb, ratio=ratio, limit=max_ratio, **common))
    return rows


def compare_evaluated(base: Sequence[RunEntry], new: Sequence[RunEntry],
                      tolerances: Tolerances | None = None) -> tuple[list[CompareRow], int]:
    """Findings for two lists of evaluated runs, and the number of matched runs."""
    tol = tolerances or Tolerances()
    base_map, new_map = _match_keys(base, new)
    rows: list[CompareRow] = []
    matched = 0
    for key in sorted(set(base_map) | set(new_map)):
        b, n = base_map.get(key), new_map.get(key)
        if n is None and b is not None:
            note = "in base only" if tol.missing_is_regression else "(ignored) in base only"
            rows.append(CompareRow(key, b.scenario, b.controller, "missing", note=note))
            continue
        if b is None and n is not None:
            rows.append(CompareRow(key, n.scenario, n.controller, "new",
                                   note=f"in new only ({n.status})"))
            continue
        assert b is not None and n is not None
        matched += 1
        rows.extend(_status_rows(key, b, n))
        if b.status in ("pass", "fail") and n.status in ("pass", "fail"):
            rows.extend(_metric_rows(key, b, n, tol))
    return rows, matched


def compare_runs(base_dir: str | Path, new_dir: str | Path, out_dir: str | Path,
                 tolerances: Tolerances | None = None) -> CompareResult:
    """Compare two catalog outputs; writes ``compare.csv`` and ``compare.html`` into
    ``out_dir``. ``result.exit_code`` is 1 on any regression, else 0."""
    base_dir, new_dir, out = Path(base_dir), Path(new_dir), Path(out_dir)
    for d in (base_dir, new_dir):
        if not d.is_dir():
            raise FileNotFoundError(f"{d}: not a directory")
    base = collect_runs(base_dir)
    new = collect_runs(new_dir)
    rows, matched = compare_evaluated(base, new, tolerances)
    result = CompareResult(rows, matched, base_dir, new_dir)
    out.mkdir(parents=True, exist_ok=True)
    result.csv_path = write_compare_csv(result, out / "compare.csv")
    result.html_path = write_compare_html(result, out / "compare.html", base, new)
    return result


def write_compare_csv(result: CompareResult, path: Path) -> Path:
    """compare.csv: one row per finding (columns ``CSV_COLUMNS``)."""
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(CSV_COLUMNS)
        for r in result.rows:
            writer.writerow([r.key, r.scenario, r.controller, r.kind, int(r.regression), r.metric,
                             _num(r.base), _num(r.new), _num(r.delta), _num(r.ratio),
                             _num(r.limit), r.note])
    return path


def _num(value: float) -> str:
    if math.isnan(value):
        return ""
    return repr(float(value)) if math.isfinite(value) else ("inf" if value > 0 else "-inf")


def _fmt(value: float) -> str:
    if math.isnan(value):
        return "–"
    if math.isinf(value):
        return "∞" if value > 0 else "−∞"
    return f"{value:.4g}"


_CSS = """
body{font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:0;
background:#f1f5f9;color:#0f172a}
header{padding:14px 24px;color:#fff}header.bad{background:#b91c1c}header.ok{background:#15803d}
header h1{margin:0 0 4px;font-size:19px}main{padding:8px 24px 40px;max-width:1400px}
table{border-collapse:collapse;background:#fff;margin:6px 0 14px}
th,td{border:1px solid #e2e8f0;padding:3px 8px;font-size:13px;text-align:left}
th{background:#f8fafc}td.num{text-align:right;font-variant-numeric:tabular-nums}
tr.reg td{background:#fef2f2}tr.good td{background:#f0fdf4}h2{font-size:16px;margin:22px 0 6px}
.none{color:#94a3b8;font-style:italic}
"""


def _table(rows: Sequence[CompareRow], title: str, show_kind: bool = True) -> str:
    esc = html.escape
    if not rows:
        return f"<h2>{esc(title)}</h2><p class=\"none\">none</p>"
    head = ("<tr><th>run</th>" + ("<th>kind</th>" if show_kind else "") +
            "<th>metric</th><th>base</th><th>new</th><th>Δ</th><th>ratio</th><th>limit</th>"
            "<th>note</th></tr>")
    body = []
    for r in rows:
        cls = "reg" if r.regression else ("good" if r.kind in ("fixed", "metric_improvement",
                                                                "timing_improvement") else "")
        body.append(f'<tr class="{cls}"><td>{esc(r.key)}</td>'
                    + (f"<td>{esc(r.kind)}</td>" if show_kind else "")
                    + f"<td>{esc(r.metric)}</td><td class=\"num\">{_fmt(r.base)}</td>"
                    f"<td class=\"num\">{_fmt(r.new)}</td><td class=\"num\">{_fmt(r.delta)}</td>"
                    f"<td class=\"num\">{_fmt(r.ratio)}</td><td class=\"num\">{_fmt(r.limit)}</td>"
                    f"<td>{esc(r.note)}</td></tr>")
    return f"<h2>{esc(title)} ({len(rows)})</h2><table>{head}{''.join(body)}</table>"


def _status_counts(runs: Sequence[RunEntry]) -> dict[str, dict[str, int]]:
    out: dict[str, dict[str, int]] = {}
    for r in runs:
        out.setdefault(r.controller, {}).setdefault(r.status, 0)
        out[r.controller][r.status] += 1
    return out


def write_compare_html(result: CompareResult, path: Path, base: Sequence[RunEntry] = (),
                       new: Sequence[RunEntry] = ()) -> Path:
    """compare.html: one self-contained page (inline CSS, no scripts, no network)."""
    esc = html.escape
    bad = result.exit_code != 0
    verdict = (f"REGRESSION: {len(result.regressions)} finding(s)" if bad else
               "no regression")
    counts_b, counts_n = _status_counts(base), _status_counts(new)
    ctrl_rows = []
    for ctrl in sorted(set(counts_b) | set(counts_n)):
        cells = []
        for counts in (counts_b, counts_n):
            c = counts.get(ctrl, {})
            cells.append(" / ".join(f"{c.get(s, 0)} {s}" for s in ("pass", "fail", "error",
                                                                   "timeout")))
        ctrl_rows.append(f"<tr><td>{esc(ctrl)}</td><td>{esc(cells[0])}</td>"
                         f"<td>{esc(cells[1])}</td></tr>")
    now = _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
    parts = [
        '<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">'
        '<link rel="icon" href="data:,">'
        f"<title>hwyeval compare</title><style>{_CSS}</style></head><body>",
        f'<header class="{"bad" if bad else "ok"}"><h1>hwyeval compare — {esc(verdict)}</h1>'
        f"<div>base <code>{esc(str(result.base_dir))}</code> · new "
        f"<code>{esc(str(result.new_dir))}</code> · {result.matched} matched · "
        f"{len(result.new_failures)} new failures · {len(result.fixed)} fixed · "
        f"{len(result.missing)} missing · {len(result.added)} new · generated {esc(now)}</div>"
        "</header><main>",
        "<h2>Status per controller</h2><table><tr><th>controller</th><th>base</th><th>new</th>"
        f"</tr>{''.join(ctrl_rows)}</table>",
        _table(result.regressions, "Regressions"),
        _table(result.of_kind("fixed"), "Fixed", show_kind=False),
        _table(result.of_kind("missing", "new"), "Missing / new runs"),
        _table(result.of_kind("status_change", "metric_nan"), "Other status / metric changes"),
        _table(result.of_kind("metric_improvement", "timing_improvement"), "Improvements"),
        "</main></body></html>",
    ]
    path.write_text("\n".join(parts), encoding="utf-8")
    return path
