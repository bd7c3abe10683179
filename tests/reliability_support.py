"""Shared by the reliability tests: tiny catalogs, a plug-in of misbehaving controllers,
running ``python -m suite``, and finding the processes a run left behind."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
MARKER_ENV = "HWYEVAL_TEST_MARKER"
# results.csv columns that are wall-clock measurements (differ between two runs)
TIMING = re.compile(r"(wall|realtime|_ms_|step_ms|step_var|deadline|time_ms|log_s|_s_p\d\d)")

DEFAULTS = '[defaults]\ncontroller = "lane_keep"\nduration_s = {duration}\nstep_s = 0.05\n'

# Controllers that misbehave in the scenario process only (validation builds them, but
# only the runner calls reset): one kills its process, one hangs before the first step.
PLUGIN_SOURCE = '''
import os
import signal
import time

from controllers import registry


class _Wrapped:
    def __init__(self, inner):
        self._inner = inner

    def __getattr__(self, name):
        return getattr(self._inner, name)


class DoomedAtStart(_Wrapped):
    def reset(self, context):
        os.kill(os.getpid(), signal.SIGKILL)


class HangsAtStart(_Wrapped):
    def reset(self, context):
        time.sleep(1e6)


registry.register("doomed_at_start",
                  lambda options: DoomedAtStart(registry.make("lane_keep", options)))
registry.register("hangs_at_start",
                  lambda options: HangsAtStart(registry.make("lane_keep", options)))
'''


def plugin_file(directory: Path) -> Path:
    """The misbehaving controllers' plug-in, written as ``reliability_plugin.py``."""
    path = Path(directory) / "reliability_plugin.py"
    path.write_text(PLUGIN_SOURCE)
    return path


def scenario_toml(name: str, *, lane: int = 0, pos_m: float = 60.0, speed_mps: float = 20.0,
                  extra: str = "") -> str:
    target = f", target_speed_mps = {speed_mps}" if speed_mps == 0 else ""
    return (f'[[scenario]]\nname = "{name}"\nnet = "straight_2lane"\n'
            f"ego = {{ lane = {lane}, pos_m = {pos_m}, speed_mps = {speed_mps}{target} }}\n"
            f"{extra}")


def write_catalog(path: Path, scenarios: Sequence[str], duration_s: float = 2.0) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(DEFAULTS.format(duration=duration_s) + "".join(scenarios))
    return path


def hwyeval(*args: str, timeout_s: float = 600.0, env: dict[str, str] | None = None
            ) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "suite", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=timeout_s, env=env)


class Background:
    """``python -m suite ARGS`` in a session of its own (as a shell job is), its output
    collected line by line while it runs."""

    def __init__(self, *args: str, env: dict[str, str] | None = None) -> None:
        self.proc = subprocess.Popen([sys.executable, "-m", "suite", *args], cwd=ROOT,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                     start_new_session=True, env=env)
        self.stdout: list[str] = []
        self.stderr: list[str] = []
        self._threads = [threading.Thread(target=self._pump, args=(stream, sink), daemon=True)
                         for stream, sink in ((self.proc.stdout, self.stdout),
                                              (self.proc.stderr, self.stderr))]
        for thread in self._threads:
            thread.start()

    @staticmethod
    def _pump(stream: object, sink: list[str]) -> None:
        for line in stream:  # type: ignore[attr-defined]
            sink.append(line)

    def wait(self, timeout_s: float) -> int:
        code = self.proc.wait(timeout=timeout_s)
        for thread in self._threads:
            thread.join(5.0)
        return code

    @property
    def out(self) -> str:
        return "".join(self.stdout)

    @property
    def err(self) -> str:
        return "".join(self.stderr)

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(10)


def marked_env(marker: str) -> dict[str, str]:
    """This environment plus the marker every descendant process inherits."""
    return {**os.environ, MARKER_ENV: marker}


def marked_pids(marker: str) -> list[int]:
    """Live processes (zombies excluded) whose environment carries ``marker``."""
    needle = f"{MARKER_ENV}={marker}".encode()
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            if stat.rsplit(")", 1)[1].split()[0] == "Z":
                continue
            env = (entry / "environ").read_bytes()
        except OSError:
            continue
        if needle in env.split(b"\0"):
            found.append(int(entry.name))
    return found


def results(out: Path) -> pd.DataFrame:
    return pd.read_csv(out / "results.csv").set_index("scenario").sort_index()


def without_timing(frame: pd.DataFrame) -> pd.DataFrame:
    return frame.drop(columns=[c for c in frame.columns if TIMING.search(c)])


def wait_for(predicate: object, timeout_s: float, what: str) -> None:
    """Poll ``predicate()`` every 20 ms until it is true; AssertionError after
    ``timeout_s`` [s] naming ``what``."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():  # type: ignore[operator]
            return
        time.sleep(0.02)
    raise AssertionError(f"timed out waiting for {what}")


def staging(out: Path) -> list[Path]:
    """The staging directories of the runs in flight in ``out``."""
    return [p for p in out.iterdir() if p.name.startswith(".partial-")] if out.is_dir() else []
