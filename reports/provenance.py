"""Where and with what a catalog ran: git revision, versions, host, CPU and load.

Collected once by ``hwyeval run`` (start and end) into ``manifest.json``
(:mod:`reports.manifest`); shown in report.html and compared by ``hwyeval compare``,
which warns when two outputs were produced by different code, versions or machines
(behaviour should not depend on those; timing does).

Load is the 1-minute load average divided by the number of logical cores (1.0: every
core busy on average), sampled when the run started and when it finished; timing
metrics measured under a load well above the other side's are not comparable.
"""

from __future__ import annotations

import importlib.metadata
import math
import os
import platform
import socket
import subprocess
from dataclasses import dataclass, fields, replace
from pathlib import Path

# The repository that holds this package (a git checkout in development installs).
SOURCE_ROOT = Path(__file__).resolve().parents[1]
# Distributions whose versions are recorded: name in the manifest -> distribution.
VERSIONED = (("hwyeval", "hwyeval"), ("sumo", "eclipse-sumo"), ("numba", "numba"),
             ("rerun", "rerun-sdk"), ("numpy", "numpy"))
# Fields whose difference ``compare`` reports (code and machine; not load or time).
COMPARED = ("git_sha", "git_dirty", "hwyeval_version", "sumo_version", "numba_version",
            "rerun_version", "numpy_version", "python_version", "host", "cpu_model",
            "cpu_count", "plugins")


@dataclass(frozen=True)
class Provenance:
    """git_sha: commit of the hwyeval checkout ('' when not a git checkout);
    git_dirty: uncommitted changes to tracked files (None: unknown); *_version:
    installed versions ('' when not installed); host, cpu_model, cpu_count: the
    machine; load_start / load_end: 1-min load average per logical core at the
    start / end of the run (NaN: unknown); plugins: controller plug-ins loaded
    ("name (module or distribution version)")."""

    git_sha: str = ""
    git_dirty: bool | None = None
    hwyeval_version: str = ""
    sumo_version: str = ""
    numba_version: str = ""
    rerun_version: str = ""
    numpy_version: str = ""
    python_version: str = ""
    host: str = ""
    cpu_model: str = ""
    cpu_count: int = 0
    load_start: float = math.nan
    load_end: float = math.nan
    plugins: tuple[str, ...] = ()

    @property
    def short_sha(self) -> str:
        """The first 10 hex digits and '+dirty' when there are uncommitted changes."""
        if not self.git_sha:
            return "unknown"
        return self.git_sha[:10] + ("+dirty" if self.git_dirty else "")

    @property
    def load(self) -> float:
        """The larger of the start and end load per core (NaN if neither is known)."""
        known = [v for v in (self.load_start, self.load_end) if math.isfinite(v)]
        return max(known) if known else math.nan

    def finished(self) -> Provenance:
        """This provenance with ``load_end`` sampled now."""
        return replace(self, load_end=load_per_core())


@dataclass(frozen=True)
class Difference:
    """A provenance field that differs between base and new."""

    field: str
    base: str
    new: str


def _git(*args: str) -> str | None:
    try:
        proc = subprocess.run(["git", "-C", str(SOURCE_ROOT), *args], capture_output=True,
                              text=True, timeout=10, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    return proc.stdout if proc.returncode == 0 else None


def git_revision() -> tuple[str, bool | None]:
    """(commit sha, dirty) of the hwyeval checkout; ('', None) outside a git checkout."""
    sha = _git("rev-parse", "HEAD")
    if sha is None:
        return "", None
    status = _git("status", "--porcelain", "--untracked-files=no")
    return sha.strip(), (bool(status.strip()) if status is not None else None)


def version_of(distribution: str) -> str:
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return ""


def cpu_model() -> str:
    """The CPU's model name (/proc/cpuinfo on Linux, else ``platform.processor()``)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def load_per_core() -> float:
    """The 1-minute load average over the logical cores (NaN where unavailable)."""
    try:
        return os.getloadavg()[0] / max(os.cpu_count() or 1, 1)
    except OSError:
        return math.nan


def collect(plugins: tuple[str, ...] = ()) -> Provenance:
    """The provenance of a run starting now (``load_end`` still NaN)."""
    sha, dirty = git_revision()
    versions = {name: version_of(dist) for name, dist in VERSIONED}
    return Provenance(git_sha=sha, git_dirty=dirty, hwyeval_version=versions["hwyeval"],
                      sumo_version=versions["sumo"], numba_version=versions["numba"],
                      rerun_version=versions["rerun"], numpy_version=versions["numpy"],
                      python_version=platform.python_version(), host=socket.gethostname(),
                      cpu_model=cpu_model(), cpu_count=os.cpu_count() or 0,
                      load_start=load_per_core(), plugins=tuple(plugins))


def _text(value: object) -> str:
    if isinstance(value, tuple):
        return ", ".join(str(v) for v in value) or "none"
    return "unknown" if value is None or value == "" else str(value)


def differences(base: Provenance, new: Provenance) -> list[Difference]:
    """The :data:`COMPARED` fields in which ``new`` differs from ``base``."""
    names = {f.name for f in fields(Provenance)}
    out = []
    for name in COMPARED:
        assert name in names
        b, n = getattr(base, name), getattr(new, name)
        if b != n:
            out.append(Difference(name, _text(b), _text(n)))
    return out
