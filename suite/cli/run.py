"""``hwyeval run CATALOG --out DIR``: run a catalog, write its reports, say how it went.

This module parses: the run itself is :func:`suite.exec.catalog_run.run_catalog` (its
steps, exit codes and the handling of SIGINT and SIGTERM are described there), with the
night added to ``--history DB`` by :func:`suite.cli.history.add_run_to_history`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from suite.cli.common import Output
from suite.exec.build import RunSettings
from suite.exec.catalog_run import CatalogRunOptions, run_catalog

__all__ = ["cmd_run", "out_mode", "run_settings"]


def run_settings(args: argparse.Namespace) -> RunSettings:
    """How the runs of ``run`` or ``search`` execute, from their common flags."""
    return RunSettings(jobs=args.jobs, executor=args.executor, ray_address=args.ray_address,
                       no_log=args.no_log, timeout_s=args.timeout,
                       max_memory_mb=args.max_memory_mb, plugins=tuple(args.plugin or ()))


def out_mode(args: argparse.Namespace) -> str:
    """fresh, resume or overwrite, from ``--resume`` and ``--overwrite``."""
    return "resume" if args.resume else "overwrite" if args.overwrite else "fresh"


def cmd_run(args: argparse.Namespace) -> int:
    text = Output()

    def add_night(db: str, out: Path) -> bool:
        from suite.cli.history import add_run_to_history

        return add_run_to_history(db, out, text)

    options = CatalogRunOptions(catalog=str(args.catalog), out=str(args.out),
                                settings=run_settings(args), filter=args.filter,
                                mode=out_mode(args), history=args.history, no_fail=args.no_fail)
    return run_catalog(options, text, add_night).exit_code
