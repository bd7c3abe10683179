"""The run layer's typed options (suite/exec/build.py, suite/exec/catalog_run.py,
suite/search/session.py): what the CLI parses into them, checked where they are made,
and the resume commands they print."""

from __future__ import annotations

from typing import Any

import pytest

from suite.cli import build_parser
from suite.cli.run import out_mode, run_settings
from suite.exec.build import RunSettings
from suite.exec.catalog_run import CatalogRunOptions, resume_command
from suite.search.run import resume_command as search_resume_command
from suite.search.session import SearchOptions


@pytest.mark.parametrize("kwargs", [{"jobs": -1}, {"executor": "slurm"}, {"timeout_s": 0.0},
                                    {"timeout_s": float("inf")}, {"max_memory_mb": -1}])
def test_bad_run_settings_raise(kwargs: dict[str, Any]) -> None:
    with pytest.raises(ValueError, match="RunSettings"):
        RunSettings(**kwargs)


def test_bad_catalog_run_options_raise() -> None:
    with pytest.raises(ValueError, match="mode"):
        CatalogRunOptions(catalog="c.toml", out="o", mode="append")
    with pytest.raises(ValueError, match="non-empty"):
        CatalogRunOptions(catalog="", out="o")


@pytest.mark.parametrize("kwargs", [{"budget": 0}, {"seed": -1}, {"sampler": "grid"},
                                    {"compare": ("tpe", "grid")}, {"mode": "append"},
                                    {"settings": RunSettings(jobs=0)}])
def test_bad_search_options_raise(kwargs: dict[str, Any]) -> None:
    with pytest.raises(ValueError, match="SearchOptions"):
        SearchOptions(**{"catalog": "c.toml", "out": "o", "budget": 4, **kwargs})


def test_run_resume_command_repeats_every_option_given() -> None:
    args = build_parser().parse_args(
        ["run", "c.toml", "--out", "o d", "--overwrite", "--jobs", "3", "--filter", "a*",
         "--no-log", "--timeout", "12.5", "--max-memory-mb", "0", "--plugin", "p.py",
         "--history", "h.db", "--no-fail"])
    options = CatalogRunOptions(catalog=args.catalog, out=args.out, settings=run_settings(args),
                                filter=args.filter, mode=out_mode(args), history=args.history,
                                no_fail=args.no_fail)
    assert options.mode == "overwrite"
    assert resume_command(options) == (
        "hwyeval run c.toml --out 'o d' --resume --filter 'a*' --jobs 3 --no-log --timeout "
        "12.5 --max-memory-mb 0 --plugin p.py --history h.db --no-fail")


def test_search_resume_command() -> None:
    args = build_parser().parse_args(
        ["search", "c.toml", "--out", "o", "--budget", "5", "--seed", "7", "--jobs", "2",
         "--no-shrink", "--shrink-points", "3", "--executor", "ray", "--ray-address", "auto"])
    options = SearchOptions(catalog=args.catalog, out=args.out, budget=args.budget,
                            settings=run_settings(args), seed=args.seed,
                            shrink=not args.no_shrink, shrink_points=args.shrink_points)
    assert search_resume_command(options) == (
        "hwyeval search c.toml --out o --budget 5 --sampler tpe --seed 7 --jobs 2 --resume "
        "--no-shrink --shrink-points 3 --executor ray --ray-address auto")
