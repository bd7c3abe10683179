"""Test nets built with SUMO's netconvert from plain XML: the one place the tests run it.

* :func:`netconvert_exe` -- the eclipse-sumo wheel's netconvert; the calling test (or
  fixture) is skipped when SUMO is not installed. conftest's session fixture
  ``netconvert`` is this.
* :func:`build_plain_net` -- writes ``<name>.nod.xml``, ``<name>.edg.xml`` (and
  ``<name>.con.xml`` when given connections) into ``out_dir`` and runs netconvert on them
  into ``<name>.net.xml``; returns that path. The same inputs and options are converted
  once per test session (per xdist worker): a second call writes the first call's net,
  its header's paths naming the new directory, as netconvert would have. conftest's
  session fixture ``plain_net`` is this function.

A failed conversion raises :class:`RuntimeError` with netconvert's messages;
``warnings_are_errors`` makes a warning one too (tests/feature_nets.py's nets).
"""

from __future__ import annotations

import os
import subprocess
from collections.abc import Sequence
from pathlib import Path
from typing import Protocol

import pytest

from sumo_nets import sumo_home
from sumo_nets.build import netconvert_path

# (name, nodes, edges, connections, options, warnings_are_errors) -> (net text, its dir)
_BUILT: dict[tuple[str, str, str, str | None, tuple[str, ...], bool], tuple[str, Path]] = {}


class PlainNet(Protocol):
    """The type of :func:`build_plain_net` (conftest's ``plain_net`` fixture)."""

    def __call__(self, out_dir: Path, name: str, nodes: str, edges: str,
                 connections: str | None = None, options: Sequence[str] = (), *,
                 warnings_are_errors: bool = False) -> Path: ...


def netconvert_exe() -> Path:
    """Path of SUMO's netconvert; skips the caller when SUMO is absent."""
    try:
        return netconvert_path()
    except (ImportError, FileNotFoundError) as exc:
        pytest.skip(f"SUMO's netconvert is not available: {exc}")


def build_plain_net(out_dir: Path, name: str, nodes: str, edges: str,
                    connections: str | None = None, options: Sequence[str] = (), *,
                    warnings_are_errors: bool = False) -> Path:
    """``out_dir/<name>.net.xml`` built from the plain XML texts ``nodes``, ``edges`` and
    ``connections`` (whole files) with netconvert's extra ``options``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    sources = {"nod": nodes, "edg": edges}
    if connections is not None:
        sources["con"] = connections
    for suffix, text in sources.items():
        (out_dir / f"{name}.{suffix}.xml").write_text(text)
    out = out_dir / f"{name}.net.xml"
    key = (name, nodes, edges, connections, tuple(options), warnings_are_errors)
    if key in _BUILT:
        text, built_in = _BUILT[key]
        out.write_text(text.replace(str(built_in), str(out_dir)))
        return out
    flags = {"nod": "--node-files", "edg": "--edge-files", "con": "--connection-files"}
    cmd = [str(netconvert_exe())]
    for suffix in sources:
        cmd += [flags[suffix], str(out_dir / f"{name}.{suffix}.xml")]
    cmd += [*options, "--output-file", str(out)]
    res = subprocess.run(cmd, capture_output=True, text=True, check=False,
                         env={**os.environ, "SUMO_HOME": sumo_home()})
    msgs = (res.stdout + res.stderr).strip()
    if res.returncode != 0 or (warnings_are_errors and ("Warning" in msgs or "Error" in msgs)):
        raise RuntimeError(f"netconvert failed{' or warned' * warnings_are_errors} "
                           f"for {name}:\n{msgs}")
    _BUILT[key] = (out.read_text(), out_dir)
    return out
