"""A sampling profile of the dense target's loop: where a control step's time goes.

Two steps, so that the sampler is a separate program (py-spy, ``pip install py-spy``)
and nothing of it runs inside the process it measures::

    py-spy record -r 500 -f raw -o prof.txt -- python -m suite.bench.profile run OUT [--seeds N]
    python -m suite.bench.profile shares prof.txt [--top 40]

``run`` runs the dense target (:func:`suite.bench.catalogs.dense_catalog`, traffic seeds
3, 4, ..., logs off) in one process after the scenario processes' preload, as the
forkserver's children do. ``shares`` reads py-spy's raw (collapsed) stacks and prints,
over the samples inside the run loop (:func:`suite.run.loop._steps`), each function's
inclusive share (samples with it anywhere below the loop) and self share (samples with
it innermost; compiled kernels count as the Python function that called them). Shares
are ratios within one profile, so two profiles taken one after the other on a shared
machine compare where absolute times would not.
"""

from __future__ import annotations

import argparse
import collections
import sys
from dataclasses import dataclass
from pathlib import Path

LOOP_FRAME = "_steps"


@dataclass(frozen=True)
class Shares:
    """samples: samples inside the loop; inclusive / self_: function -> samples."""

    samples: int
    inclusive: dict[str, int]
    self_: dict[str, int]

    def __post_init__(self) -> None:
        if self.samples < 0:
            raise ValueError(f"samples must be >= 0, got {self.samples}")


def _function(frame: str) -> str:
    """``name (path/to/file.py:line)`` -> ``name file.py`` (lines merged)."""
    name, _, where = frame.partition(" (")
    file = where.rsplit(":", 1)[0].rsplit("/", 1)[-1] if where else ""
    return f"{name} {file}".strip()


def read_shares(raw: str, loop_frame: str = LOOP_FRAME) -> Shares:
    """Aggregate py-spy's raw output (one ``frame;frame;... count`` line per stack,
    outermost first) over the stacks that pass through ``loop_frame``."""
    inclusive: collections.Counter[str] = collections.Counter()
    innermost: collections.Counter[str] = collections.Counter()
    total = 0
    for number, line in enumerate(raw.splitlines(), 1):
        if not line.strip():
            continue
        stack, _, count = line.rpartition(" ")
        if not count.isdigit():
            raise ValueError(f"line {number}: expected 'frames count', got {line[:80]!r}")
        frames = stack.split(";")
        at = next((i for i, f in enumerate(frames) if f.split(" (")[0] == loop_frame), None)
        if at is None:
            continue
        n = int(count)
        total += n
        below = [_function(f) for f in frames[at + 1:]]
        for name in set(below):
            inclusive[name] += n
        innermost[below[-1] if below else f"{loop_frame} (itself)"] += n
    return Shares(total, dict(inclusive), dict(innermost))


def format_shares(shares: Shares, top: int) -> str:
    if shares.samples == 0:
        return f"no samples inside {LOOP_FRAME}: was the loop running while py-spy sampled?"
    lines = [f"samples inside the loop: {shares.samples}", "inclusive:"]
    for name, n in collections.Counter(shares.inclusive).most_common(top):
        lines.append(f"  {100.0 * n / shares.samples:5.1f} %  {name}")
    lines.append("self:")
    for name, n in collections.Counter(shares.self_).most_common(top):
        lines.append(f"  {100.0 * n / shares.samples:5.1f} %  {name}")
    return "\n".join(lines)


def run_dense(out: Path, seeds: int) -> None:
    """The dense target's runs, in this process, prepared as the forkserver is
    (:func:`suite.exec.prepare.prepare_process`)."""
    from suite.exec.prepare import prepare_process

    prepare_process()
    from suite.bench.catalogs import dense_catalog
    from suite.catalog import load_catalog
    from suite.run.options import RunOptions
    from suite.run.runner import run_scenario

    out.mkdir(parents=True, exist_ok=False)
    catalog = out / "dense.toml"
    catalog.write_text(dense_catalog(seeds, 40.0))
    for k, scenario in enumerate(load_catalog(catalog).scenarios):
        run_scenario(scenario, out / f"run{k}", RunOptions(write_rrd=False))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m suite.bench.profile", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="what", required=True)
    r = sub.add_parser("run", help="run the dense target (under py-spy)")
    r.add_argument("out", type=Path, help="a new folder for the runs")
    r.add_argument("--seeds", type=int, default=2, help="dense runs (default 2)")
    s = sub.add_parser("shares", help="where the loop's samples are")
    s.add_argument("raw", type=Path, help="py-spy record -f raw output")
    s.add_argument("--top", type=int, default=40)
    args = ap.parse_args(argv)
    if args.what == "run":
        if args.seeds < 1:
            print("error: --seeds must be >= 1", file=sys.stderr)
            return 2
        if args.out.exists():
            print(f"error: {args.out} exists: the runs go into a new folder", file=sys.stderr)
            return 2
        run_dense(args.out, args.seeds)
        return 0
    try:
        text = args.raw.read_text()
        shares = read_shares(text)
    except (OSError, ValueError) as exc:
        print(f"error: {args.raw}: {exc}", file=sys.stderr)
        return 2
    print(format_shares(shares, args.top))
    return 0


if __name__ == "__main__":
    sys.exit(main())
