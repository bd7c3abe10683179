"""A night read from its output directory (:func:`read_night`): the manifest's facts and,
per run, its typed record (``RunInfo``, ``RunOutcome``, ``Verdict``: the run's row,
failures and facts), as the :class:`NightRecord` the history database stores
(:mod:`reports.history.store` adds it). Nothing is parsed back from text: results.csv is
not read, and the failure modes are the typed failures' metric names."""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from reports.collector import collector_paused
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
    setup_digests,
)
from reports.manifest import MANIFEST, read_manifest
from reports.metrics.catalogue import CRITERIA_METRICS
from reports.record import Failure, RunInfo, Verdict
from reports.record.meta import STATUSES
from reports.record.run import read_run_json
from reports.tables import RunEntry, collect_runs, results_frame


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
    """What the history keeps of a run beyond its results row, from its typed run.json
    (:func:`run_facts`): ``scenario_hash`` (the content hash, '' unknown), ``limits``
    (metric -> limit in force, in the metric's unit), the set-up digests
    (:class:`reports.identity.SetupDigests`), ``controller_code`` (its code hash) and
    ``controller_params`` (its resolved options, canonical JSON), the typed
    ``failures`` (``Verdict.failures``) and the known-failure mark."""

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

    metric_names: the metric columns (results.csv's, in its order); values_2d[i, j]: run
    i's value of metric j (NaN absent; ±inf as stored); limits_2d[i, j]: the limit in
    force on metric j for run i (NaN: none). failed_criteria[i]: run i's
    ``Verdict.failed_text`` (results.csv's column; '' without a verdict);
    failure_modes[i]: the metric names of its failures (``Verdict.failures``)."""

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


def run_facts(info: RunInfo, verdict: Verdict | None) -> RunFacts:
    """:class:`RunFacts` of a run from its typed run.json (``info`` and its verdict;
    without a verdict: no limits, no failures)."""
    spec = info.scenario_spec or {}
    criteria = verdict.criteria if verdict is not None else {}
    content = spec.get(CONTENT_KEY, "")
    params = info.controller_params or info.controller_options or {}
    limits = tuple((CRITERIA_METRICS[c][0], float(v)) for c, v in criteria.items()
                   if c in CRITERIA_METRICS and isinstance(v, int | float)
                   and not isinstance(v, bool))
    return RunFacts(scenario_hash=content if isinstance(content, str) else "", limits=limits,
                    digests=setup_digests(info, criteria),
                    controller_code=str(spec.get(CONTROLLER_KEY) or spec.get(CODE_KEY) or ""),
                    controller_params=json.dumps(params, sort_keys=True, allow_nan=True,
                                                 default=str),
                    failures=verdict.failures if verdict is not None else (),
                    xfail=xfail_of(spec))


def entry_facts(entry: RunEntry) -> RunFacts:
    """:func:`run_facts` of a run as the reports read it; a run directory they could not
    read (another file damaged: an 'error' run) has its run.json read alone
    (:func:`reports.record.run.read_run_json`); empty facts when that fails too."""
    if entry.record is not None:
        return run_facts(entry.record.info, entry.record.verdict)
    try:
        info, _, verdict = read_run_json(entry.run_dir)
    except (OSError, ValueError):  # RecordError is a ValueError
        return RunFacts()
    return run_facts(info, verdict)


def parse_started(text: str, where: str) -> _dt.datetime:
    """A manifest's ``started`` (ISO 8601) as an aware datetime (naive: UTC)."""
    try:
        t = _dt.datetime.fromisoformat(text)
    except ValueError as exc:
        raise HistoryError(f"{where}: key 'started': expected an ISO 8601 time, got "
                           f"{text!r}") from exc
    return t if t.tzinfo is not None else t.replace(tzinfo=_dt.UTC)


def _metric_matrix(frame: pd.DataFrame) -> tuple[tuple[str, ...], np.ndarray]:
    names = tuple(c for c in frame.columns if c not in NOT_METRICS)
    if not names:
        return (), np.zeros((len(frame), 0))
    values = frame[list(names)].apply(pd.to_numeric, errors="coerce")
    return names, values.to_numpy(dtype=np.float64, na_value=np.nan)


def read_night(out_dir: str | Path, night_id: str | None = None,
               catalog_name: str | None = None) -> NightRecord:
    """The night in ``out_dir``: its manifest and, per run directory (sorted by name),
    its typed record as the reports read it (:func:`reports.tables.collect_runs`,
    through :func:`reports.record.load_run`: a directory that cannot be read, a file
    changed or corrupt since the run wrote it, is an 'error' run). The metric columns
    and values are results.csv's (:func:`reports.tables.results_frame`, built from the
    verdicts, never read back from the file), ``failed_criteria`` is
    ``Verdict.failed_text``, the failure modes the failures' metric names, and each
    run's :class:`RunFacts` come from its ``RunInfo`` and ``Verdict``. ``night_id``
    defaults to ``<catalog name>@<started>``; ``catalog_name`` (``--catalog-name``)
    replaces the catalog's identity (the manifest's). Raises :class:`HistoryError` when
    ``out_dir`` is not a directory, has no readable manifest, has not finished, or
    holds no run."""
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
    with collector_paused():
        entries = collect_runs(out)
        if not entries:
            raise HistoryError(f"{out_dir}: holds no run directory (DIR/<scenario>/run.json)")
        facts = tuple(entry_facts(e) for e in entries)
        names, values = _metric_matrix(results_frame(entries))
    index = {m: j for j, m in enumerate(names)}
    limits = np.full(values.shape, np.nan)
    for i, k in enumerate(facts):
        for metric, limit in k.limits:
            if metric in index:
                limits[i, index[metric]] = limit
    scenarios = tuple(e.scenario for e in entries)
    controllers = tuple(e.controller for e in entries)
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
            statuses=tuple(e.status for e in entries),
            failed_criteria=tuple(e.verdict.failed_text if e.verdict is not None else ""
                                  for e in entries),
            failure_modes=tuple(tuple(f.metric for f in e.failures) for e in entries),
            run_dirs=tuple(str(e.run_dir) for e in entries), metric_names=names,
            values_2d=values, limits_2d=limits, facts=facts)
    except ValueError as exc:
        raise HistoryError(f"{out}: {exc}") from exc
