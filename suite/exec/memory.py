"""The memory cap of a scenario process, so that one run cannot take the machine.

Every scenario process limits its own address space (``RLIMIT_AS``) before it runs its
scenario. A run that needs more gets a ``MemoryError`` where it allocates (numpy,
Python, SUMO's ``std::bad_alloc``) instead of growing until the kernel's OOM killer
ends some process, perhaps another run, the command, or another user's work. The run
is then that run's ``error``, its message saying it ran out of memory under its cap
(:func:`memory_note`); the other runs go on.

The cap (:class:`MemoryCap`) is ``--max-memory-mb MB`` if given, else the environment
variable :data:`ENV`, else the default: :data:`DEFAULT_FRACTION` of the memory of the
machine that runs the scenario (its physical memory, or its cgroup's limit when lower;
a Ray node resolves it itself), but at least :data:`MIN_CAP_MIB`. ``0`` means no cap.

Why the floor: the cap counts address space, not resident memory, and a scenario
process maps far more than it fills: numba's and Arrow's reservations, a 64 MiB malloc
arena per thread, Rerun's encoder threads. Measured here (lane_keep and two_loop on
straight roads, 8 s): 2.9 GiB of address space without a Rerun log and 4.3 GiB with
one, for a resident peak of 185 MiB. A cap much below 8 GiB would fail healthy runs.
"""

from __future__ import annotations

import os
import resource
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

__all__ = ["DEFAULT_FRACTION", "ENV", "MIN_CAP_MIB", "MemoryCap", "apply_memory_cap",
           "machine_memory_bytes", "memory_cap_from", "memory_note", "ran_out_of_memory"]

ENV = "HWYEVAL_MAX_MEMORY_MB"
DEFAULT_FRACTION = 0.5  # of the machine's memory, per scenario process [-]
MIN_CAP_MIB = 8192  # the default is never below this address space [MiB]
MIB = 1024 * 1024  # [bytes]

# Where a cgroup's memory limit is read (v2 of this process's group, v2 root, v1).
_CGROUP_FILES = ("memory.max", "memory/memory.limit_in_bytes")


@dataclass(frozen=True)
class MemoryCap:
    """A scenario process's address-space cap. ``mib`` [MiB]: the cap; None: the default
    (module doc), resolved on the machine that runs the scenario; 0: no cap."""

    mib: int | None = None

    def __post_init__(self) -> None:
        if self.mib is not None and (isinstance(self.mib, bool) or not isinstance(self.mib, int)
                                     or self.mib < 0):
            raise ValueError(f"MemoryCap.mib: expected a whole number of MiB >= 0 or None, "
                             f"got {self.mib!r}")

    def limit_bytes(self) -> int | None:
        """The cap [bytes] on this machine; None: no cap."""
        if self.mib is not None:
            return self.mib * MIB if self.mib > 0 else None
        memory = machine_memory_bytes()
        fraction = int(DEFAULT_FRACTION * memory) if memory is not None else 0
        return max(fraction, MIN_CAP_MIB * MIB)


def _cgroup_limit() -> int | None:
    """The lowest memory limit [bytes] of this process's cgroup, None when unlimited."""
    root = Path("/sys/fs/cgroup")
    group = ""
    try:
        for line in Path("/proc/self/cgroup").read_text().splitlines():
            if line.startswith("0::"):
                group = line[3:].strip().lstrip("/")
    except OSError:
        pass
    limits = []
    for name in (f"{group}/memory.max" if group else "", *_CGROUP_FILES):
        try:
            text = (root / name).read_text().strip() if name else ""
        except OSError:
            continue
        if text.isdigit():
            limits.append(int(text))
    return min(limits) if limits else None


def machine_memory_bytes() -> int | None:
    """This machine's memory [bytes]: its physical memory, or its cgroup's limit when
    lower; None when neither can be read."""
    try:
        physical: int | None = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (OSError, ValueError):
        physical = None
    group = _cgroup_limit()
    known = [m for m in (physical, group) if m is not None and m > 0]
    return min(known) if known else None


def memory_cap_from(option_mib: int | None, environ: Mapping[str, str]) -> MemoryCap:
    """The cap of a command: ``--max-memory-mb`` if given, else :data:`ENV` from
    ``environ``, else the default. ValueError naming the variable for a value that is
    not a whole number of MiB >= 0."""
    if option_mib is not None:
        return MemoryCap(option_mib)
    text = environ.get(ENV, "").strip()
    if not text:
        return MemoryCap()
    try:
        value = int(text)
    except ValueError:
        raise ValueError(f"{ENV}={text!r}: expected a whole number of MiB >= 0 "
                         "(0: no cap)") from None
    if value < 0:
        raise ValueError(f"{ENV}={text!r}: expected a whole number of MiB >= 0 (0: no cap)")
    return MemoryCap(value)


def apply_memory_cap(limit: int | None) -> None:
    """Limit this process's address space to ``limit`` [bytes] (None: leave it); a lower
    limit already in force is kept."""
    if limit is None:
        return
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    if hard != resource.RLIM_INFINITY:
        limit = min(limit, hard)
    if soft != resource.RLIM_INFINITY:
        limit = min(limit, soft)
    resource.setrlimit(resource.RLIMIT_AS, (limit, hard))


def ran_out_of_memory(error: str | None) -> bool:
    """Whether a run's error text ends in an allocation that failed: Python's
    ``MemoryError`` or a subclass (numpy's ``numpy._core._exceptions._ArrayMemoryError``)
    or C++'s ``std::bad_alloc`` passed up by SUMO."""
    lines = [line for line in (error or "").splitlines() if line.strip()]
    if not lines:
        return False
    last = lines[-1].strip()
    exception = last.split(":", 1)[0].strip().rsplit(".", 1)[-1]
    return exception.endswith("MemoryError") or "bad_alloc" in last


def memory_note(limit: int | None) -> str:
    """The first line of the error of a run that ran out of memory under ``limit``."""
    cap = f"{limit / MIB:.0f} MiB" if limit is not None else "no cap"
    return (f"out of memory: the scenario process needed more than its memory cap of {cap} "
            f"of address space (--max-memory-mb MB or {ENV} sets it, 0: no cap; default "
            f"{DEFAULT_FRACTION:.0%} of the machine's memory, at least {MIN_CAP_MIB} MiB)")
