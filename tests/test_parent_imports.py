"""What ``hwyeval run``'s parent process imports before it hands out the first job: the
modules that build jobs, show progress and prepare the output, without pandas (the
reports import it once the runs are done) and without the runner and its simulation
stack (the scenario processes' forkserver imports those meanwhile, on the other core).

Fresh interpreter: this test process has imported everything already."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SCRIPT = """
import json, sys
import suite.cli.run, suite.exec.catalog_run, suite.exec.progress
import suite.exec.outdir, suite.exec.executors, suite.exec.build
import reports.manifest
from suite.run.options import RunOptions
from suite.exec.jobs import RunJob
print(json.dumps(sorted(m for m in ("pandas", "suite.run.runner", "suite.run.loop",
                                    "suite.world.sumo", "reports.tables", "rerun", "libsumo")
                        if m in sys.modules)))
"""


def test_building_jobs_imports_neither_pandas_nor_the_runner() -> None:
    res = subprocess.run([sys.executable, "-c", textwrap.dedent(SCRIPT)], cwd=ROOT,
                         capture_output=True, text=True, timeout=120, check=False)
    assert res.returncode == 0, res.stderr[-2000:]
    assert res.stdout.strip().splitlines()[-1] == "[]"


def test_run_options_are_the_runners() -> None:
    """The runner's RunOptions is the light module's (one class, two import paths)."""
    from suite.run import runner
    from suite.run.options import RunOptions

    assert runner.RunOptions is RunOptions
