"""``python -m suite.stress --n 300 --seed S --out DIR``: write a stress catalog
(docs/stress.md)."""

from __future__ import annotations

import argparse
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path

from suite.catalog import CatalogError
from suite.stress.config import StressConfig
from suite.stress.generate import generate
from suite.stress.real import default_real_dir


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="python -m suite.stress",
        description="Write a stress catalog: generated nets (2-4 lanes, shoulder or not, one "
                    "curve), stalled cars, traffic, slower passing-lane traffic, on-ramps, a "
                    "close stall, and the real motorways of ../shared/nets_real.")
    ap.add_argument("--n", type=int, required=True, help="number of scenarios")
    ap.add_argument("--seed", type=int, required=True, help="seed (same seed: same files)")
    ap.add_argument("--out", type=Path, required=True,
                    help="output folder (catalog.toml, nets/, stress.json are rewritten)")
    ap.add_argument("--duration-s", type=float, default=StressConfig.duration_s,
                    help="simulated time of each scenario [s] (default %(default)s)")
    ap.add_argument("--controller", action="append", default=None, metavar="NAME",
                    help="controller to run (repeat for several: each scenario is swept over "
                         "them, e.g. --controller two_loop --controller sumo); default two_loop")
    ap.add_argument("--real-nets", type=Path, default=None, metavar="DIR",
                    help="folder of the real motorways and their catalog.toml (default: "
                         "../shared/nets_real beside the repository, if present)")
    ap.add_argument("--no-real", action="store_true", help="generated nets only")
    ap.add_argument("--real-share", type=float, default=StressConfig.real_share,
                    help="share of scenarios on the real motorways (default %(default)s)")
    ap.add_argument("--wet-share", type=float, default=StressConfig.wet_share,
                    help="share of scenarios on a wet road, friction 0.5-0.7 (default "
                         "%(default)s)")
    return ap


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.n < 0:
        print("error: --n must be >= 0", file=sys.stderr)
        return 2
    try:
        cfg = StressConfig(duration_s=args.duration_s, real_share=args.real_share,
                           wet_share=args.wet_share,
                           controllers=tuple(args.controller or ("two_loop",)))
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    real_dir = None if args.no_real else (args.real_nets or default_real_dir())
    if real_dir is not None and not (real_dir / "catalog.toml").is_file():
        if args.real_nets is not None:
            print(f"error: no catalog.toml in --real-nets {real_dir}", file=sys.stderr)
            return 2
        real_dir = None
    command = "python -m suite.stress " + shlex.join(
        list(argv) if argv is not None else sys.argv[1:])
    try:
        result = generate(args.n, args.seed, args.out, cfg, real_dir=real_dir, command=command)
    except CatalogError as exc:
        print(f"error: the generated catalog does not load:\n{exc}", file=sys.stderr)
        return 1
    print(f"wrote {result.path} ({len(result.catalog)} runs of {args.n} scenarios)")
    for line in result.coverage.lines():
        print(f"  {line}")
    missing = result.coverage.missing(expect_real=real_dir is not None and cfg.real_share > 0)
    if missing:
        print(f"note: not covered: {', '.join(missing)} (with the default shares 8 scenarios "
              "cover everything)")
    print(f"run it: hwyeval run {result.path} --out RUNS --jobs N --no-log")
    return 0


if __name__ == "__main__":
    sys.exit(main())
