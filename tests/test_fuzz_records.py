"""Property-based fuzzing of run records for ``hwyeval report`` (hypothesis, W10): an
output holds a good run and a run whose run.json, road.json or per-step files were
replaced by anything (any JSON value, a valid file with keys deleted or given values
of other types, bytes that are not JSON or parquet). ``report`` never crashes, writes
all its files (junit.xml well-formed), reports the good run as before and the bad one
as an error whenever its directory cannot be read."""

from __future__ import annotations

import contextlib
import copy
import io
import itertools
import json
import shutil
import xml.etree.ElementTree as ET
from collections import Counter
from pathlib import Path
from typing import Any

import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import tests.synthetic_runs as sr
from reports.record import RunOutcome, StalledVehicle, SumoCollision, load_run
from suite.cli import main

pytestmark = pytest.mark.slow

N_RECORDS = 200
FILES = ("run.json", "road.json", "trace.parquet", "series.parquet", "neighbours.parquet",
         "controller_arrays.npz", "traceback.txt")

JSON = st.recursive(
    st.none() | st.booleans() | st.integers(-2**70, 2**70) | st.floats()
    | st.text(max_size=10) | st.sampled_from(["pass", "error", "ok", "timeout", "fail", ""]),
    lambda inner: st.lists(inner, max_size=3)
    | st.dictionaries(st.text(max_size=8), inner, max_size=3), max_leaves=8)
BYTES = st.binary(max_size=200) | st.sampled_from([b"", b"{", b"[1, 2", b"\xff\xfe", b"PAR1"])


def _paths(node: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every key path into the dicts and lists of a JSON document."""
    out = [prefix] if prefix else []
    if isinstance(node, dict):
        for key, value in node.items():
            out.extend(_paths(value, (*prefix, key)))
    elif isinstance(node, list):
        for i, value in enumerate(node[:3]):
            out.extend(_paths(value, (*prefix, i)))
    return out


@st.composite
def mutated(draw: st.DrawFn, doc: Any) -> Any:
    """``doc`` with 1-3 of its values replaced by any JSON value, or deleted."""
    doc = copy.deepcopy(doc)
    for _ in range(draw(st.integers(1, 3))):
        paths = _paths(doc)
        if not paths:
            return draw(JSON)
        *parents, last = draw(st.sampled_from(paths))
        node = doc
        for key in parents:
            node = node[key]
        if isinstance(node, dict) and draw(st.booleans()):
            node.pop(last, None)
        elif isinstance(node, dict | list):
            node[last] = draw(JSON)
    return doc


def _template(root: Path) -> Path:
    """An output with the runs 'good' and 'bad' (a collision, stalled cars, SSM...)."""
    out = root / "template"
    sr.write_run(out / "good", sr.straight_trace(4.0))
    trace = sr.straight_trace(4.0)
    outcome = RunOutcome(wall_s=2.0, sim_time_s=4.0, steps=len(trace), stop_reason="duration",
                         stalled=(StalledVehicle("s0", 300.0, 0.0, 0.0, 4.8, 1.9, 0),),
                         sumo_collisions=(SumoCollision(1.0, "ego", "s0", "collision"),))
    sr.write_run(out / "bad", trace, outcome=outcome)
    return out


@st.composite
def damage(draw: st.DrawFn, template: Path) -> tuple[str, bytes | None, bool]:
    """(file of 'bad' to change, its new bytes or None to delete it, whether the run
    certainly cannot be read any more)."""
    name = draw(st.sampled_from(FILES))
    kind = draw(st.sampled_from(["mutate", "mutate", "json", "bytes", "delete"]))
    path = template / "bad" / name
    if name.endswith(".json") and kind == "mutate":
        doc = json.loads(path.read_text())
        return name, json.dumps(draw(mutated(doc)), allow_nan=True).encode(), False
    if kind == "json":
        value = draw(JSON)
        unreadable = name == "run.json" and not isinstance(value, dict) or \
            name == "road.json" and not isinstance(value, dict)
        return name, json.dumps(value, allow_nan=True).encode(), unreadable
    if kind == "bytes" or name.endswith(".json"):
        data = draw(BYTES)
        return name, data, name != "traceback.txt" and not _is_json(data)
    return name, None, name == "run.json"


def _is_json(data: bytes) -> bool:
    try:
        json.loads(data)
    except ValueError:
        return False
    return True


def test_report_never_crashes_on_malformed_records(tmp_path_factory: pytest.TempPathFactory
                                                   ) -> None:
    root = tmp_path_factory.mktemp("fuzz_records")
    template = _template(root)
    reference = root / "reference"
    shutil.copytree(template, reference)
    assert main(["report", str(reference)]) == 0
    good_row = pd.read_csv(reference / "results.csv").set_index("run").loc["good"]
    seen: Counter[str] = Counter()
    numbers = itertools.count()

    @settings(max_examples=N_RECORDS, deadline=None, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(damage(template))
    def check(change: tuple[str, bytes | None, bool]) -> None:
        name, data, unreadable = change
        out = root / f"o{next(numbers)}"
        shutil.copytree(template, out)
        target = out / "bad" / name
        if data is None:
            target.unlink(missing_ok=True)
        else:
            target.write_bytes(data)
        stdout, stderr = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
            code = main(["report", str(out)])
        assert code == 0, stderr.getvalue()
        res = pd.read_csv(out / "results.csv").set_index("run")
        assert sorted(res.index) == ["bad", "good"]
        assert res.loc["good", "status"] == good_row["status"]
        assert res.loc["good", "min_gap_m"] == good_row["min_gap_m"]
        ET.parse(out / "junit.xml")  # well-formed
        assert (out / "report.html").stat().st_size > 0
        try:
            load_run(out / "bad")
            readable = True
        except Exception:  # noqa: BLE001 - whatever it raises, the report must say error
            readable = False
        assert not (unreadable and readable), (name, data)
        if not readable:
            assert res.loc["bad", "status"] == "error", (name, data)
        seen["unreadable" if not readable else res.loc["bad", "status"]] += 1
        shutil.rmtree(out)

    check()
    assert sum(seen.values()) >= N_RECORDS and seen["unreadable"] > N_RECORDS // 4, seen
