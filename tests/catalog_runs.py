"""Run a catalog written by a test through the real CLI (``python -m suite run``) in a
subprocess: one libsumo simulation per process, as production runs it."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run_catalog(base: Path, text: str) -> Path:
    """Write ``text`` as ``base/catalog.toml``, run it into ``base/out`` on two workers
    without Rerun logs and return ``base/out``; any exit but 0 (all passed) or 1 (some
    did not) fails the calling test with the command's output."""
    catalog = base / "catalog.toml"
    catalog.write_text(text)
    out = base / "out"
    proc = subprocess.run([sys.executable, "-m", "suite", "run", str(catalog), "--out",
                           str(out), "--jobs", "2", "--no-log"], cwd=ROOT,
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode in (0, 1), proc.stdout + proc.stderr
    return out
