"""A Ray actor's folder outlives an actor killed with its node (no close()): the next
actor on the node removes the folders of actors whose process is gone, and only those."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from suite.exec.ray.actor import HOME_PREFIX, remove_stale_homes


def test_only_the_folders_of_ended_actors_are_removed(tmp_path: Path) -> None:
    ended = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                           capture_output=True, text=True, check=True)
    dead_pid = int(ended.stdout)
    stale = tmp_path / f"{HOME_PREFIX}{dead_pid}-abc"
    live = tmp_path / f"{HOME_PREFIX}{os.getpid()}-xyz"
    other = tmp_path / f"{HOME_PREFIX}notapid"  # not an actor's folder: left alone
    for folder in (stale, live, other):
        (folder / "files").mkdir(parents=True)
    assert remove_stale_homes(tmp_path) == [stale]
    assert not stale.exists() and live.is_dir() and other.is_dir()
