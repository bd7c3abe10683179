#!/usr/bin/env python3
"""Set up hwyeval on a fresh machine (only Python 3.11 + pip needed), then act.

    python3 bootstrap.py demo   # venv + install, then run catalogs/demo.toml end to end
    python3 bootstrap.py test   # venv + install (test extras, Chromium), then lint-imports,
                                # ruff, mypy --strict and pytest on both cores: the fast
                                # lane, then the slow tests

The virtual environment lives in .venv; installation is skipped when
pyproject.toml has not changed since the last one (a hash stamp in .venv).
Chromium (for the HTML report test) comes from Debian's packages via apt-get
when it is missing and we are root.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent
VENV = ROOT / ".venv"
PY = VENV / "bin" / "python"


def sh(cmd: list[str], **kw: object) -> None:
    print("+", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True, **kw)  # type: ignore[call-overload]


def ensure_venv(extras: str) -> None:
    if not PY.exists():
        venv.EnvBuilder(with_pip=True).create(VENV)
    stamp = VENV / f".installed-{extras or 'base'}"
    digest = hashlib.sha256((ROOT / "pyproject.toml").read_bytes()).hexdigest()
    if stamp.exists() and stamp.read_text() == digest:
        return
    sh([str(PY), "-m", "pip", "install", "-q", "--upgrade", "pip"])
    target = f".[{extras}]" if extras else "."
    sh([str(PY), "-m", "pip", "install", "-q", "-e", target], cwd=ROOT)
    stamp.write_text(digest)


EXAMPLE_PLUGIN = ROOT / "examples" / "hwyeval_example_controller"


def ensure_example_plugin() -> None:
    """pip install -e the example controller plug-in (its entry point is what the
    plug-in tests run); skipped when the venv already has it from this checkout."""
    probe = ("import importlib.metadata as m, sys; d = m.distribution("
             "'hwyeval-example-controller'); sys.exit(0 if d.read_text('direct_url.json') "
             f"and {str(EXAMPLE_PLUGIN.as_uri())!r} in d.read_text('direct_url.json') else 1)")
    if subprocess.run([str(PY), "-c", probe], capture_output=True).returncode == 0:
        return
    sh([str(PY), "-m", "pip", "install", "-q", "--no-deps", "-e", str(EXAMPLE_PLUGIN)], cwd=ROOT)


COMMONROAD_PACKAGES = ("commonroad-io>=2024.1", "commonroad-vehicle-models>=2")
# commonroad-io's requirements except its protobuf==3.20.2 pin (the cluster extra's ray
# needs protobuf >= 5; the importer reads XML only: docs/recorded.md).
COMMONROAD_REQUIREMENTS = ("iso3166", "lxml", "networkx", "omegaconf", "rtree",
                           "shapely>=2,<3", "matplotlib", "pillow", "tqdm")


def ensure_commonroad() -> None:
    """Install the CommonRoad importer's commonroad-io into the venv with ``--no-deps``
    (beside the cluster extra's protobuf) plus its other requirements; skipped when its
    XML reader already imports."""
    probe = "from commonroad.common.reader.file_reader_xml import XMLFileReader"
    if subprocess.run([str(PY), "-c", probe], capture_output=True).returncode == 0:
        return
    sh([str(PY), "-m", "pip", "install", "-q", *COMMONROAD_REQUIREMENTS])
    sh([str(PY), "-m", "pip", "install", "-q", "--no-deps", *COMMONROAD_PACKAGES])


def ensure_chromium() -> None:
    if shutil.which("chromium") and shutil.which("chromedriver"):
        return
    if os.geteuid() != 0:
        print("warning: chromium/chromedriver missing and not root: the browser test will fail; "
              "install Debian's 'chromium chromium-driver'", file=sys.stderr)
        return
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    sh(["apt-get", "update", "-q"], env=env)
    sh(["apt-get", "install", "-y", "-q", "chromium", "chromium-driver"], env=env)


def run_tests(args: list[str]) -> int:
    """pytest on both cores (pytest-xdist, a test file's tests on one worker so its module
    fixtures run once): with no arguments the fast lane first (``-m "not slow"``), then
    the slow tests, then the ``serial`` ones alone (they race processes and signals
    against the clock); with arguments, one run of those. A run that collects no test
    (pytest's exit 5) is a failure."""
    parallel = ["-n", "2", "--dist", "loadfile"]
    lanes = [[*parallel, *args]] if args else [[*parallel, "-m", "not slow and not serial"],
                                                [*parallel, "-m", "slow and not serial"],
                                                ["-m", "serial"]]
    worst = 0
    for lane in lanes:
        code = subprocess.run([str(PY), "-m", "pytest", *lane], cwd=ROOT).returncode
        if code == 5:
            print("pytest collected no tests: that is a failure here", file=sys.stderr)
            code = 1
        worst = worst or code
    return worst


def main(argv: list[str]) -> int:
    action = argv[1] if len(argv) > 1 else "demo"
    if action == "demo":
        ensure_venv("baselines")
        out = ROOT / "runs" / "demo"
        catalog = ROOT / "catalogs" / "demo.toml"
        # runs/demo is the demo's own output: a second demo replaces the first.
        code = subprocess.run([str(VENV / "bin" / "hwyeval"), "run", str(catalog),
                               "--out", str(out), "--overwrite", *argv[2:]]).returncode
        # Exit 1 means the catalog ran and some verdicts are "fail" (the SUMO driver
        # model brakes harder than nuPlan's comfort limits): that is the demo's content.
        # Only invalid input (2) or a crash of the tool itself fails the demo command.
        print(f"demo finished (hwyeval exit code {code}); open {out / 'report.html'}")
        return 0 if code in (0, 1) else code
    if action == "test":
        ensure_venv("test,baselines,cluster")
        ensure_example_plugin()
        ensure_commonroad()
        ensure_chromium()
        # Architecture, lint and types first (seconds), then the tests; all of them run
        # whatever the others say, and any failure fails the command.
        checks = [[str(VENV / "bin" / "lint-imports")],
                  [str(VENV / "bin" / "ruff"), "check", "."],
                  [str(VENV / "bin" / "mypy"), "suite", "reports", "controllers", "sumo_nets"]]
        failed = [c[0].rsplit("/", 1)[-1] for c in checks
                  if subprocess.run(c, cwd=ROOT).returncode != 0]
        code = run_tests(argv[2:])
        if failed:
            print(f"failed checks: {', '.join(failed)}", file=sys.stderr)
            return code or 1
        return code
    print(__doc__, file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv))
