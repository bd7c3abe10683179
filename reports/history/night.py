"""A night read from its output directory (:func:`read_night`): the manifest's facts, each
run's facts and its results row, as the :class:`NightRecord` the history database stores
(:mod:`reports.history.store` adds it)."""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from reports.expectation import Xfail, xfail_of
from reports.history.schema import (
    METRIC_NAME,
    HistoryError,
)
from reports.identity import (
    CODE_KEY,
    CONTENT_KEY,
    CONTROLLER_KEY,
    SetupDigests,
    digests_of_run_json,
)
from reports.manifest import MANIFEST, read_manifest
from reports.metrics.catalogue import CRITERIA_METRICS
from reports.record import RUN_JSON, Failure, iter_run_dirs
from reports.record.codec import RecordError, decode_dataclass
from reports.record.meta import STATUSES
from reports.tables import collect_runs, results_frame

RESULTS_CSV = "results.csv"


@dataclass(frozen=True)
class NightInfo:
    """One row of ``nights``. started_at: when the run started (timezone-aware);
    git_revision: '' when unknown; git_dirty: None when unknown; catalog: the catalog
    file as the manifest names it; catalog_id / catalog_origin: its identity
    (:func:`reports.manifest.catalog_identity`: what nights are grouped by; '' only
    before a database is migrated); catalog_sha256: digest of the night's scenarios
    (name, controller, content hash; see :func:`catalog_digest`); out_dir: the output
    directory (absolute) the night was read from."""

    night_id: str
    started_at: _dt.datetime
    git_revision: str
    hwyeval_version: str
    host: str
    catalog: str
    catalog_sha256: str = ""
    out_dir: str = ""
    git_dirty: bool | None = None
    catalog_id: str = ""
    catalog_origin: str = ""

    def __post_init__(self) -> None:
        if not self.night_id:
            raise ValueError("NightInfo.night_id must not be empty")
        if self.started_at.tzinfo is None:
            raise ValueError(f"NightInfo.started_at must carry a timezone, got "
                             f"{self.started_at.isoformat()}")

    @property
    def short_revision(self) -> str:
        return self.git_revision[:10] if self.git_revision else "unknown"

    @property
    def catalog_key(self) -> str:
        """What the night's catalog is known by: its identity (its path before a
        database is migrated)."""
        return self.catalog_id or self.catalog

    @property
    def report(self) -> str:
        """The night's report.html ('' when its output directory is unknown)."""
        return str(Path(self.out_dir) / "report.html") if self.out_dir else ""


@dataclass(frozen=True)
class RunFacts:
    """What the history keeps of a run beyond results.csv, read from its run.json:
    ``scenario_hash`` (the content hash, '' unknown), ``limits`` (metric -> limit in
    force), the set-up digests (:class:`reports.identity.SetupDigests`),
    ``controller_code`` (its code hash) and ``controller_params`` (its resolved options,
    canonical JSON), the typed ``failures`` and the known-failure mark."""

    scenario_hash: str = ""
    limits: tuple[tuple[str, float], ...] = ()
    digests: SetupDigests = field(default_factory=lambda: SetupDigests("", "", "", ""))
    controller_code: str = ""
    controller_params: str = ""
    failures: tuple[Failure, ...] = ()
    xfail: Xfail | None = None


@dataclass(frozen=True)
class NightRecord:
    """A night as the database stores it: ``info`` and one entry per run, aligned.

    metric_names: the metric columns (results.csv's order); values_2d[i, j]: run i's
    value of metric j (NaN absent; ±inf as stored); limits_2d[i, j]: the limit in force
    on metric j for run i (NaN: none). failure_modes[i]: the metric names of run i's
    failed criteria."""

    info: NightInfo
    scenarios: tuple[str, ...]
    scenario_hashes: tuple[str, ...]
    controllers: tuple[str, ...]
    statuses: tuple[str, ...]
    failed_criteria: tuple[str, ...]
    failure_modes: tuple[tuple[str, ...], ...]
    run_dirs: tuple[str, ...]
    metric_names: tuple[str, ...]
    values_2d: np.ndarray = field(repr=False)
    limits_2d: np.ndarray = field(repr=False)
    facts: tuple[RunFacts, ...] = ()  # per run (empty: none known, e.g. built by hand)

    def __post_init__(self) -> None:
        n = len(self.scenarios)
        if not self.facts:
            object.__setattr__(self, "facts", (RunFacts(),) * n)
        for name in ("scenario_hashes", "controllers", "statuses", "failed_criteria",
                     "failure_modes", "run_dirs", "facts"):
            if len(getattr(self, name)) != n:
                raise ValueError(f"NightRecord.{name}: {len(getattr(self, name))} entries "
                                 f"for {n} scenarios")
        if len(set(zip(self.scenarios, self.controllers, strict=True))) != n:
            raise ValueError(f"NightRecord {self.info.night_id}: a (scenario, controller) "
                             "appears twice")
        bad = sorted(set(self.statuses) - set(STATUSES))
        if bad:
            raise ValueError(f"NightRecord.statuses: expected one of {STATUSES}, got {bad}")
        shape = (n, len(self.metric_names))
        for name in ("values_2d", "limits_2d"):
            arr = getattr(self, name)
            if arr.shape != shape:
                raise ValueError(f"NightRecord.{name}: shape {arr.shape}, expected {shape}")
        for m in self.metric_names:
            if not METRIC_NAME.match(m):
                raise ValueError(f"NightRecord.metric_names: {m!r} is not an identifier")

    @property
    def n_runs(self) -> int:
        return len(self.scenarios)

    @property
    def sha256(self) -> str:
        """Digest of the night's content (identity, statuses, hashes, values): two adds
        of the same night agree on it, a changed directory does not."""
        h = hashlib.sha256()
        i = self.info
        h.update("\x1f".join([i.night_id, i.started_at.isoformat(), i.git_revision,
                              i.catalog]).encode())
        for cols in (self.scenarios, self.scenario_hashes, self.controllers, self.statuses,
                     self.failed_criteria, self.metric_names):
            h.update("\x1e".join(cols).encode())
        marks = [f.xfail.text if f.xfail is not None else "" for f in self.facts]
        if any(marks):  # a night without marks keeps the digest it had before v3
            h.update("\x1e".join(marks).encode())
        h.update(np.ascontiguousarray(self.values_2d, dtype=np.float64).tobytes())
        return h.hexdigest()


def catalog_digest(scenarios: Sequence[str], controllers: Sequence[str],
                   hashes: Sequence[str]) -> str:
    """sha256 of the sorted ``scenario controller content-hash`` lines: the same for
    two nights that ran the same scenarios with the same content."""
    lines = sorted(f"{s}\t{c}\t{h}" for s, c, h in zip(scenarios, controllers, hashes,
                                                      strict=True))
    return hashlib.sha256("\n".join(lines).encode()).hexdigest()


# results.csv columns that are not metrics (every other column is one, as a DOUBLE)
NOT_METRICS = ("scenario", "controller", "variant", "status", "failed_criteria", "family",
               "run", "robustness_criterion")


def _failures(raw: Any, path: Path) -> tuple[Failure, ...]:
    if not isinstance(raw, list):
        return ()
    try:
        return tuple(decode_dataclass(Failure, f, path, "verdict.failures") for f in raw)
    except RecordError:
        return ()


def run_facts(run_dir: Path) -> RunFacts:
    """:class:`RunFacts` of a run directory, read from its run.json directly (these
    fields only: the typed reader takes ~20 ms a run, this well under 1 ms); an
    unreadable file gives empty facts (results.csv already reports that run as
    'error')."""
    path = run_dir / RUN_JSON
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        info = data["info"]
        spec = info.get("scenario_spec") or {}
        verdict = data.get("verdict") or {}
        criteria = verdict.get("criteria") or {}
        content = spec.get(CONTENT_KEY, "")
        params = info.get("controller_params") or info.get("controller_options") or {}
        code = spec.get(CONTROLLER_KEY) or spec.get(CODE_KEY) or ""
        digests = digests_of_run_json(info, criteria)
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return RunFacts()
    limits = tuple((CRITERIA_METRICS[c][0], float(v)) for c, v in criteria.items()
                   if c in CRITERIA_METRICS and isinstance(v, int | float)
                   and not isinstance(v, bool))
    return RunFacts(scenario_hash=content if isinstance(content, str) else "", limits=limits,
                    digests=digests, controller_code=str(code),
                    controller_params=json.dumps(params, sort_keys=True, allow_nan=True,
                                                 default=str),
                    failures=_failures(verdict.get("failures"), path),
                    xfail=xfail_of(spec if isinstance(spec, dict) else None))


def failure_modes_of(failed_criteria: str) -> tuple[str, ...]:
    """The metric names of results.csv's ``failed_criteria`` (``metric=value>limit;…``)."""
    return tuple(re.split(r"[=<>]", f, maxsplit=1)[0] for f in failed_criteria.split(";")
                 if f)


def parse_started(text: str, where: str) -> _dt.datetime:
    """A manifest's ``started`` (ISO 8601) as an aware datetime (naive: UTC)."""
    try:
        t = _dt.datetime.fromisoformat(text)
    except ValueError as exc:
        raise HistoryError(f"{where}: key 'started': expected an ISO 8601 time, got "
                           f"{text!r}") from exc
    return t if t.tzinfo is not None else t.replace(tzinfo=_dt.UTC)


def results_of(out: Path, run_dirs: Sequence[Path]) -> pd.DataFrame:
    """The night's results.csv rows, one per run directory. Every run directory is
    read with the reports' reader (:func:`reports.tables.collect_runs`, through
    :func:`reports.record.load_run`: a directory that cannot be read, a file changed
    or corrupt since the run wrote it, is an 'error' run). When every one can be read,
    the file the run wrote is used if it covers exactly these run directories and is
    newer than every run.json; otherwise the rows are rebuilt from the entries
    (:func:`reports.tables.results_frame`, as ``hwyeval report``)."""
    entries = collect_runs(out)
    frame = _written_results(out, run_dirs)
    if frame is not None and not any(e.unreadable for e in entries):
        return frame
    return results_frame(entries)


def _written_results(out: Path, run_dirs: Sequence[Path]) -> pd.DataFrame | None:
    """results.csv as the run wrote it, when it covers exactly ``run_dirs`` and is newer
    than every run.json (None otherwise)."""
    path = out / RESULTS_CSV
    if not path.is_file():
        return None
    try:
        # only an empty cell is missing: a scenario named "NA" stays a name
        frame = pd.read_csv(path, keep_default_na=False, na_values=[""])
    except (OSError, ValueError, pd.errors.ParserError):
        return None
    if "run" not in frame.columns:
        return None
    newest = max((d / RUN_JSON).stat().st_mtime for d in run_dirs)
    if (sorted(frame["run"].astype(str)) == sorted(d.name for d in run_dirs)
            and path.stat().st_mtime >= newest):
        return frame
    return None


def _metric_matrix(frame: pd.DataFrame) -> tuple[tuple[str, ...], np.ndarray]:
    names = tuple(c for c in frame.columns if c not in NOT_METRICS)
    if not names:
        return (), np.zeros((len(frame), 0))
    values = frame[list(names)].apply(pd.to_numeric, errors="coerce")
    return names, values.to_numpy(dtype=np.float64, na_value=np.nan)


def read_night(out_dir: str | Path, night_id: str | None = None,
               catalog_name: str | None = None) -> NightRecord:
    """The night in ``out_dir``: its manifest, its results.csv rows (see
    :func:`results_of`) and each run's :class:`RunFacts`. ``night_id`` defaults to
    ``<catalog name>@<started>``; ``catalog_name`` (``--catalog-name``) replaces the
    catalog's identity (the manifest's). Raises :class:`HistoryError` when ``out_dir``
    is not a directory, has no readable manifest, has not finished, or holds no run."""
    out = Path(out_dir).resolve()
    if not out.is_dir():
        raise HistoryError(f"{out_dir}: no such output directory")
    manifest = read_manifest(out)
    if manifest is None:
        raise HistoryError(f"{out / MANIFEST}: missing or unreadable (expected the manifest "
                           "hwyeval run writes)")
    if not manifest.finished:
        raise HistoryError(f"{out / MANIFEST}: key 'finished' is empty: the run has not "
                           "finished (or was interrupted); add it once it has")
    run_dirs = iter_run_dirs(out)
    if not run_dirs:
        raise HistoryError(f"{out_dir}: holds no run directory (DIR/<scenario>/run.json)")
    frame = results_of(out, run_dirs)
    by_name = {d.name: d for d in run_dirs}
    dirs = [by_name[str(r)] for r in frame["run"]]
    facts = tuple(run_facts(d) for d in dirs)
    names, values = _metric_matrix(frame)
    index = {m: j for j, m in enumerate(names)}
    limits = np.full(values.shape, np.nan)
    for i, k in enumerate(facts):
        for metric, limit in k.limits:
            if metric in index:
                limits[i, index[metric]] = limit
    failed = tuple("" if pd.isna(f) else str(f) for f in frame["failed_criteria"])
    scenarios = tuple(str(s) for s in frame["scenario"])
    controllers = tuple(str(c) for c in frame["controller"])
    hashes = tuple(k.scenario_hash for k in facts)
    prov = manifest.provenance
    identity = manifest.identity()
    info = NightInfo(
        night_id=night_id or f"{manifest.catalog_name}@{manifest.started}",
        started_at=parse_started(manifest.started, str(out / MANIFEST)),
        git_revision=prov.git_sha, git_dirty=prov.git_dirty,
        hwyeval_version=prov.hwyeval_version, host=prov.host, catalog=manifest.catalog,
        catalog_sha256=catalog_digest(scenarios, controllers, hashes), out_dir=str(out),
        catalog_id=catalog_name or identity.name, catalog_origin=identity.origin)
    try:
        return NightRecord(
            info=info, scenarios=scenarios, scenario_hashes=hashes, controllers=controllers,
            statuses=tuple(str(s) for s in frame["status"]), failed_criteria=failed,
            failure_modes=tuple(failure_modes_of(f) for f in failed),
            run_dirs=tuple(str(d) for d in dirs), metric_names=names, values_2d=values,
            limits_2d=limits, facts=facts)
    except ValueError as exc:
        raise HistoryError(f"{out / RESULTS_CSV}: {exc}") from exc
