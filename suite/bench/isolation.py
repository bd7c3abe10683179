"""``hwyeval bench --isolated``: the dense runs' scenario processes pinned to one core,
the command's other processes to the other cores, the machine's other load listed.

A step's maximum time is set by whatever else the machine does while it runs (a
scheduler slice of another process is 4-8 ms, several times the step). So the bench
judges the max only when the dense runs had a core of their own as far as this process
can arrange it: :func:`isolate` picks the core (the last one this process may use); the
dense command's scenario processes pin themselves to it
(:data:`suite.exec.worker.SCENARIO_CPUS_ENV`) and the command's own processes (the
parent with its budget and memory watchers, the forkserver) are pinned to the other
cores (``sched_setaffinity``, what ``taskset -c`` does): pinned beside the loop, the
parent's polling put the step p99 at 3.5 ms against 1.0 ms unpinned. Nothing stops
other processes from using that core, so :func:`busy_processes` samples every
process's CPU time over ``sample_s`` and lists the busy ones: the max is read together
with that list.

CPU shares come from ``/proc/<pid>/stat`` (fields 14-15: user and system time in clock
ticks; 39: the CPU it last ran on): share = delta ticks / (ticks per second x sample
time) x 100 [% of one core].
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path

__all__ = ["Isolation", "OtherProcess", "busy_processes", "isolate"]

PROC = Path("/proc")


@dataclass(frozen=True)
class OtherProcess:
    """A process other than the bench's, its CPU share over the sample [% of one core]
    and the CPU it last ran on (-1 unknown)."""

    pid: int
    name: str
    cpu_pct: float
    last_cpu: int = -1

    def __post_init__(self) -> None:
        if self.pid < 1 or self.cpu_pct < 0:
            raise ValueError(f"need pid >= 1 and cpu_pct >= 0, got {self.pid}, {self.cpu_pct}")

    def text(self) -> str:
        where = f" on CPU {self.last_cpu}" if self.last_cpu >= 0 else ""
        return f"{self.name} (pid {self.pid}) {self.cpu_pct:.0f} %{where}"


@dataclass(frozen=True)
class Isolation:
    """The core the dense runs are pinned to and the other processes busy at the time
    (at least ``min_pct`` of a core over ``sample_s``)."""

    cpu: int
    others: tuple[OtherProcess, ...]
    sample_s: float
    rest: frozenset[int] = frozenset()

    def __post_init__(self) -> None:
        if self.cpu < 0 or not self.sample_s > 0:
            raise ValueError(f"need cpu >= 0 and sample_s > 0, got {self.cpu}, {self.sample_s}")

    def line(self) -> str:
        busy = "; ".join(p.text() for p in self.others) or "none"
        rest = ",".join(str(c) for c in sorted(self.rest)) or "the same"
        return (f"isolated: the dense runs' scenario processes pinned to CPU {self.cpu}, the "
                f"command's other processes to CPU {rest}; other processes busy over "
                f"{self.sample_s:g} s (>= 1 % of a core): {busy}")


def _cpu_ticks(pid_dir: Path) -> tuple[str, int, int] | None:
    """(name, user + system ticks, last CPU) of one /proc/<pid>, None when it is gone."""
    try:
        raw = (pid_dir / "stat").read_text()
    except OSError:
        return None
    # the name is in parentheses and may hold spaces: split after the last ")"
    name = raw[raw.find("(") + 1: raw.rfind(")")]
    fields = raw[raw.rfind(")") + 2:].split()
    # fields[0] is stat's field 3 (state): utime, stime = fields 14, 15; processor = 39
    return name, int(fields[11]) + int(fields[12]), int(fields[36])


def _snapshot() -> dict[int, tuple[str, int, int]]:
    out = {}
    for entry in PROC.iterdir():
        if entry.name.isdigit():
            got = _cpu_ticks(entry)
            if got is not None:
                out[int(entry.name)] = got
    return out


def busy_processes(sample_s: float = 1.0, min_pct: float = 1.0,
                   exclude: frozenset[int] = frozenset()) -> tuple[OtherProcess, ...]:
    """The processes (not in ``exclude``, not this one) that used at least ``min_pct``
    [% of one core] over ``sample_s`` [s], busiest first."""
    if not sample_s > 0:
        raise ValueError(f"sample_s must be > 0, got {sample_s}")
    hz = os.sysconf("SC_CLK_TCK")
    before = _snapshot()
    t0 = time.monotonic()
    time.sleep(sample_s)
    after = _snapshot()
    dt = time.monotonic() - t0
    skip = exclude | {os.getpid()}
    out = []
    for pid, (name, ticks, cpu) in after.items():
        if pid in skip or pid not in before:
            continue
        pct = 100.0 * (ticks - before[pid][1]) / (hz * dt)
        if pct >= min_pct:
            out.append(OtherProcess(pid, name, pct, cpu))
    return tuple(sorted(out, key=lambda p: -p.cpu_pct))


def isolate(sample_s: float = 1.0) -> Isolation:
    """The core for the dense runs (the last this process may use) and the other load."""
    allowed = os.sched_getaffinity(0)
    cpu = max(allowed)
    return Isolation(cpu, busy_processes(sample_s), sample_s, frozenset(allowed - {cpu}))
