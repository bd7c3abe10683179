"""Property-based fuzzing of catalogs (hypothesis): whatever a catalog holds (wrong types,
missing and unknown keys, absurd values, hostile sweeps, broken and hostile networks,
broken TOML), ``hwyeval run`` either runs it and exits 0 or 1, or exits 2 naming the
file and the key; never a traceback.

Each example is a near-valid catalog with a few mutations, so that most are invalid
(they never start SUMO) and some run; the valid ones simulate at most a few tenths of
a second. Runs go through the real command line in this process (``suite.cli.main``),
so the scenario processes come from one warm forkserver.
"""

from __future__ import annotations

import contextlib
import copy
import io
import math
import re
import shutil
from collections import Counter
from pathlib import Path
from typing import Any

import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import sumo_nets
from suite.cli import main

pytestmark = [pytest.mark.sumo, pytest.mark.slow]

N_CATALOGS = 500

# ----------------------------------------------------------------------------- TOML out


def toml_string(text: str) -> str:
    """A TOML basic string: quote, backslash and control characters escaped."""
    def escape(ch: str) -> str:
        if ch in '"\\':
            return "\\" + ch
        if ord(ch) < 0x20 or ord(ch) == 0x7F:
            return f"\\u{ord(ch):04x}"
        return ch
    return '"' + "".join(escape(ch) for ch in text) + '"'


def toml_float(value: float) -> str:
    """A float as TOML writes it (nan, inf and -inf spelled out)."""
    if math.isnan(value):
        return "nan"
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    return repr(value)


def toml_value(value: Any) -> str:
    """``value`` as an inline TOML value (one line)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return toml_float(value)
    if isinstance(value, str):
        return toml_string(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{toml_string(str(k))} = {toml_value(v)}"
                                for k, v in value.items()) + " }"
    raise TypeError(f"no TOML for {value!r}")


def toml_document(doc: dict[str, Any]) -> str:
    return "".join(f"{toml_string(k)} = {toml_value(v)}\n" for k, v in doc.items())


# ----------------------------------------------------------------------------- nets

XXE = ('<?xml version="1.0"?>\n<!DOCTYPE net [ <!ENTITY xxe SYSTEM "file:///etc/passwd"> ]>\n'
       '<net version="1.20"><edge id="&xxe;"/></net>\n')
BOMB = ('<?xml version="1.0"?>\n<!DOCTYPE lolz [ <!ENTITY lol "lol">'
        + "".join(f'<!ENTITY lol{i} "{("&lol" + (str(i - 1) if i > 1 else "") + ";") * 10}">'
                  for i in range(1, 10))
        + ' ]>\n<net version="1.20"><edge id="&lol9;"/></net>\n')


def hostile_nets(folder: Path) -> list[str]:
    """Network values a catalog may name: bundled, good copies, and hostile files."""
    folder.mkdir(parents=True, exist_ok=True)
    good = Path(sumo_nets.net_path("straight_2lane"))
    shutil.copy(good, folder / "copy.net.xml")
    text = good.read_text()
    (folder / "truncated.net.xml").write_text(text[: len(text) // 2])
    (folder / "xxe.net.xml").write_text(XXE)
    (folder / "bomb.net.xml").write_text(BOMB)
    (folder / "binary.net.xml").write_bytes(bytes(range(256)) * 8)
    (folder / "empty.net.xml").write_text("")
    (folder / "no_edges.net.xml").write_text('<?xml version="1.0"?>\n<net version="1.20"/>\n')
    (folder / "not_a_net.net.xml").write_text("<html><body>hello</body></html>")
    (folder / "dir.net.xml").mkdir(exist_ok=True)
    return ["straight_2lane", "straight_3lane", "curve_2lane", "copy.net.xml",
            str(folder / "copy.net.xml"), "truncated.net.xml", "xxe.net.xml", "bomb.net.xml",
            "binary.net.xml", "empty.net.xml", "no_edges.net.xml", "not_a_net.net.xml",
            "dir.net.xml", "missing.net.xml", "../../../../etc/passwd", "/dev/null", "",
            "straight_9lane", "a" * 300, "nets/\x00.net.xml"]


# ----------------------------------------------------------------------------- catalogs

SCALARS = st.one_of(
    st.booleans(),
    st.integers(min_value=-2**63, max_value=2**63 - 1),
    st.sampled_from([0, 1, -1, 2, 3, 5, 2**31, 10**9]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, 0.05, 0.1, 0.2, -0.05, 1e-5, 1e9, 1e300, 25.0, 300.0]),
    st.text(st.characters(blacklist_categories=("Cs",)), max_size=12),  # TOML: no surrogates
    st.sampled_from(["", "lane_keep", "two_loop", "sumo", "J3", "left", "../x", "\x00",
                     "e0", "0", "nan", "a" * 300]),
)
VALUES = st.recursive(SCALARS, lambda inner: st.one_of(
    st.lists(inner, max_size=3),
    st.dictionaries(st.text(st.characters(blacklist_categories=("Cs",)), max_size=8)
                    | st.sampled_from(["lane", "pos_m", "name", "t_s"]),
                    inner, max_size=3)), max_leaves=6)
# short, so that a valid catalog runs fast (SUMO steps of 50 ms)
DURATIONS = st.sampled_from([0.05, 0.1, 0.15, 0.2, 0.0, -1.0, 1e9, math.nan, math.inf, "0.1",
                             True, 3])
PATHS = st.sampled_from([
    "name", "net", "route", "ego", "ego.lane", "ego.pos_m", "ego.speed_mps",
    "ego.target_speed_mps", "ego.colour", "stalled", "stalled.0", "stalled.0.lane",
    "stalled.0.pos_m", "stalled.0.length_m", "stalled.1.pos_m", "traffic",
    "traffic.vehicles_per_hour", "traffic.lanes", "traffic.lane_speeds_mps", "traffic.seed",
    "controller", "controller.name", "controller.lookahead_min_m", "controller.outer.cost",
    "duration_s", "step_s", "sumo_step_s", "seed", "allow_shoulder", "criteria",
    "criteria.max_abs_lat_acc_mps2", "criteria.max_collision", "criteria.nonsense",
    "record_radius_m", "timeout_s", "friction", "ramp_traffic", "ramp_traffic.0.edge",
    "actors", "actors.0.events", "actors.0.events.0.t_s", "sweep", "unknown_key",
])


def base_scenario(name: str) -> dict[str, Any]:
    return {"name": name, "net": "straight_2lane",
            "ego": {"lane": 0, "pos_m": 60.0, "speed_mps": 20.0},
            "controller": "lane_keep", "duration_s": 0.1, "step_s": 0.05}


def set_at(doc: Any, path: str, value: Any) -> None:
    """Set ``value`` at a dotted path, making tables on the way; a path through a
    scalar or a missing list item replaces what is there (a mutation, not a rule)."""
    comps = path.split(".")
    node = doc
    for comp in comps[:-1]:
        if isinstance(node, list):
            index = int(comp) if comp.isdigit() else 0
            while len(node) <= index:
                node.append({})
            if not isinstance(node[index], dict | list):
                node[index] = {}
            node = node[index]
        else:
            if not isinstance(node.get(comp), dict | list):
                node[comp] = [] if comp in ("stalled", "ramp_traffic", "actors",
                                            "events") else {}
            node = node[comp]
    last = comps[-1]
    if isinstance(node, list):
        index = int(last) if last.isdigit() else 0
        while len(node) <= index:
            node.append({})
        node[index] = value
    else:
        node[last] = value


def delete_at(doc: Any, path: str) -> None:
    node = doc
    comps = path.split(".")
    for comp in comps[:-1]:
        node = node[int(comp)] if isinstance(node, list) and comp.isdigit() \
            and int(comp) < len(node) else node.get(comp) if isinstance(node, dict) else None
        if node is None:
            return
    if isinstance(node, dict):
        node.pop(comps[-1], None)


def _add_extras(draw: st.DrawFn, sc: dict[str, Any], extras: set[str]) -> None:
    """The optional tables ``extras`` names, drawn into scenario ``sc``."""
    if "stalled" in extras:
        sc["stalled"] = [{"lane": 1, "pos_m": draw(st.sampled_from([300.0, 61.0, -5.0, 1e9]))}]
    if "traffic" in extras:
        sc["traffic"] = {"vehicles_per_hour": draw(st.sampled_from([0, 600, -1, 1e9]))}
    if "criteria" in extras:
        sc["criteria"] = {"max_abs_lat_acc_mps2": draw(SCALARS)}
    if "seed" in extras:
        sc["seed"] = draw(SCALARS)
    if "actors" in extras:
        sc["actors"] = [{"id": "a1", "lane": 1, "pos_m": 200.0, "speed_mps": 10.0,
                         "events": [{"t_s": 0.05, "lane_change": -1}]}]
    if "sweep" in extras:
        sc["sweep"] = {draw(PATHS): draw(st.lists(VALUES, max_size=3))
                       for _ in range(draw(st.integers(1, 2)))}


def _mutate(draw: st.DrawFn, doc: dict[str, Any], scenarios: list[dict[str, Any]],
            nets: list[str]) -> None:
    """One drawn mutation of ``doc``: a value set or deleted in a scenario, its net
    replaced, a default or a top-level key written."""
    target = draw(st.sampled_from(scenarios))
    kind = draw(st.sampled_from(["set", "set", "set", "delete", "net", "net", "defaults",
                                 "top"]))
    if kind == "set":
        set_at(target, draw(PATHS), draw(VALUES))
    elif kind == "delete":
        delete_at(target, draw(PATHS))
    elif kind == "net":
        target["net"] = draw(st.sampled_from(nets))
    elif kind == "defaults":
        if not isinstance(doc.get("defaults"), dict):
            doc["defaults"] = {}
        doc["defaults"][draw(PATHS).split(".")[0]] = draw(VALUES)
    else:
        doc[draw(st.sampled_from(["scenario", "defaults", "extra"]))] = draw(VALUES)


@st.composite
def catalogs(draw: st.DrawFn, nets: list[str]) -> tuple[str, int]:
    """(TOML text, number of [[scenario]] tables it was built with)."""
    scenarios = [base_scenario("fz")]
    extras = draw(st.sets(st.sampled_from(["stalled", "traffic", "criteria", "sweep", "seed",
                                           "second", "actors"]), max_size=3))
    sc = scenarios[0]
    sc["duration_s"] = draw(DURATIONS)
    _add_extras(draw, sc, extras)
    if "second" in extras:
        second = copy.deepcopy(sc)
        second["name"] = draw(st.sampled_from(["fz", "fz2", "fz__x", "FZ"]))
        scenarios.append(second)
    doc: dict[str, Any] = {"scenario": scenarios}
    for _ in range((draw(st.integers(0, 15)) + 3) // 4):  # 0 mutations in 1/16 of them
        _mutate(draw, doc, scenarios, nets)
    text = toml_document(doc)
    if draw(st.integers(0, 19)) == 0:  # broken TOML now and then
        cut = draw(st.integers(0, len(text)))
        text = text[:cut] + draw(st.sampled_from(["", "[[", "= =", "\x00", '"', "\n[x]\na=1"]))
    return text, len(scenarios)


ISSUE = re.compile(r"^(?P<file>.+?): (?P<key>[^\s:]+)( \(scenario [^)]*\))?: expected ", re.M)


def test_fuzzed_catalogs_run_or_exit_2_naming_a_key(tmp_path_factory: pytest.TempPathFactory
                                                    ) -> None:
    root = tmp_path_factory.mktemp("fuzz_catalogs")
    cat_dir = root / "cat"
    nets = hostile_nets(cat_dir)
    outcomes: Counter[int] = Counter()

    @settings(max_examples=N_CATALOGS, deadline=None, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                     HealthCheck.large_base_example])
    @given(catalogs(nets))
    def check(example: tuple[str, int]) -> None:
        text, _ = example
        index = sum(outcomes.values())
        catalog = cat_dir / f"c{index}.toml"
        catalog.write_text(text, errors="surrogatepass")
        out = root / "out" / f"o{index}"
        stdout, stderr = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
            code = main(["run", str(catalog), "--out", str(out), "--no-log", "--jobs", "1"])
        outcomes[code] += 1
        err = stderr.getvalue()
        assert "Traceback" not in err, err
        assert code in (0, 1, 2), (code, err)
        if code == 2:
            found = ISSUE.search(err)
            assert found and found["file"] == str(catalog), err
            assert not out.exists(), "an invalid catalog wrote to --out"
            return
        res = pd.read_csv(out / "results.csv")
        assert len(res) >= 1 and set(res["status"]) <= {"pass", "fail", "error", "timeout"}
        assert (code == 0) == bool((res["status"] == "pass").all()), res["status"]

    check()
    print('FUZZ OUTCOMES', dict(outcomes))
    assert sum(outcomes.values()) >= N_CATALOGS, outcomes
    assert outcomes[2] > 0 and outcomes[0] + outcomes[1] > 0, outcomes  # both kinds seen
