"""The fast paths of reading a run for its verdict give what the plain ones gave.

The typed decoder (:func:`reports.record.codec.decode_dataclass`) follows a plan made
once per record class: known answers for nested records, unions, tuples, tables and
defaults; errors naming the file and the dotted key; bool refused for numbers; the
constructor called positionally with the defaults its signature has, or by keywords
when it cannot be (its result is the one of ``cls(**given)``); real records read back
as they were written. Then the reader's shortcuts: the empty trace and neighbours of a
run read without them, the listing of run directories, the check of an older run's
parquet files, and the collector paused while a night is read.
"""

from __future__ import annotations

import dataclasses
import gc
import json
import os
from dataclasses import KW_ONLY, InitVar, dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np
import pytest
import synthetic_runs as sr

from reports.collector import collector_paused
from reports.record import RUN_JSON, RunInfo, RunOutcome, Verdict, iter_run_dirs, load_run
from reports.record.codec import RecordError, decode_dataclass, to_plain
from reports.record.columns import NeighbourColumns, Trace
from reports.record.meta import ReplayHandover, ReplaySummary, SsmSummary, SumoCollision
from reports.record.run import DamagedRun, check_run_files
from reports.record.verdict import BoundaryCrossing, MetricValue

PATH = "night/run_x/run.json"


@dataclass(frozen=True)
class Inner:
    label: str
    gain: float = 1.0
    limit: float | None = None


@dataclass(frozen=True)
class Outer:
    name: str
    count: int
    inner: Inner
    maybe: Inner | None = None
    items: tuple[Inner, ...] = ()
    tags: tuple[str, ...] = ()
    table: dict[str, float | None] = field(default_factory=dict)
    anything: Any = None
    flag: bool = False
    either: int | str = 0
    options: dict[str, Any] = field(default_factory=dict)


def _error(cls: type, data: Any, key: str = "") -> RecordError:
    with pytest.raises(RecordError) as info:
        decode_dataclass(cls, data, PATH, key)
    assert PATH in str(info.value)  # names the file
    return info.value


# ------------------------------------------------------------------ known answers


def test_a_nested_record_decodes_to_its_known_answer() -> None:
    data = {"name": "a", "count": 3, "inner": {"label": "i", "gain": 2, "limit": None},
            "maybe": {"label": "m", "limit": 0.5},
            "items": [{"label": "x"}, {"label": "y", "gain": -1.5, "limit": 7}],
            "tags": ["p", "q"], "table": {"k": 1, "n": None, "f": 2.5},
            "anything": {"free": [1, "two"]}, "flag": True}
    got = decode_dataclass(Outer, data, PATH)
    assert got == Outer(name="a", count=3, inner=Inner("i", 2.0, None),
                        maybe=Inner("m", 1.0, 0.5),
                        items=(Inner("x"), Inner("y", -1.5, 7.0)), tags=("p", "q"),
                        table={"k": 1.0, "n": None, "f": 2.5},
                        anything={"free": [1, "two"]}, flag=True)
    # ints read into float fields become floats (also inside a union and a table)
    assert type(got.inner.gain) is float and type(got.items[1].limit) is float
    assert type(got.table["k"]) is float
    assert list(got.table) == ["k", "n", "f"]  # the file's order


def test_missing_optional_fields_take_their_defaults() -> None:
    got = decode_dataclass(Outer, {"name": "a", "count": 0, "inner": {"label": "i"}}, PATH)
    assert got == Outer("a", 0, Inner("i"))
    assert got.maybe is None and got.items == () and got.table == {}
    other = decode_dataclass(Outer, {"name": "b", "count": 0, "inner": {"label": "i"}}, PATH)
    assert other.table is not got.table  # a default factory's value is the record's own


def test_null_and_a_record_both_fit_a_record_or_null() -> None:
    base = {"name": "a", "count": 0, "inner": {"label": "i"}}
    assert decode_dataclass(Outer, {**base, "maybe": None}, PATH).maybe is None
    assert decode_dataclass(Outer, {**base, "maybe": {"label": "z"}}, PATH).maybe == Inner("z")


def test_a_union_without_null_refuses_null() -> None:
    base = {"name": "a", "count": 0, "inner": {"label": "i"}}
    assert decode_dataclass(Outer, {**base, "either": "s"}, PATH).either == "s"
    assert decode_dataclass(Outer, {**base, "either": 4}, PATH).either == 4
    values: tuple[object, ...] = (None, 1.5, True, [])
    for value in values:
        err = _error(Outer, {**base, "either": value})
        assert err.key == "either" and err.got == value


def test_table_keys_are_strings() -> None:
    base = {"name": "a", "count": 0, "inner": {"label": "i"}}
    got = decode_dataclass(Outer, {**base, "options": {1: [2], "b": None},
                                   "table": {2: 1}}, PATH)
    assert got.options == {"1": [2], "b": None} and got.table == {"2": 1.0}


def test_any_mapping_is_a_table() -> None:
    data = MappingProxyType({"name": "a", "count": 1,
                             "inner": MappingProxyType({"label": "i"})})
    assert decode_dataclass(Outer, data, PATH) == Outer("a", 1, Inner("i"))


def test_a_metric_with_its_boundary_crossing() -> None:
    crossing = {"kind": "lane", "lane_id": "a_0", "edge_id": "a", "side": "left",
                "excess_m": 0.4, "step": 12, "t_s": 0.6, "corner": "front-left"}
    data = {"name": "max_offroad_m", "value": 0.4, "unit": "m", "kind": "safety",
            "better": "lower", "worst_step": 12, "crossing": crossing}
    got = decode_dataclass(MetricValue, data, PATH)
    assert got == MetricValue("max_offroad_m", 0.4, "m", "safety", "lower", 12, "",
                              BoundaryCrossing("lane", "a_0", "a", "left", 0.4, 12, 0.6,
                                               "front-left"))
    assert decode_dataclass(MetricValue, {**data, "worst_step": None,
                                          "crossing": None}, PATH).crossing is None


# ------------------------------------------------------------------------ errors


def test_a_missing_required_key_is_named_by_its_dotted_key() -> None:
    data = {"name": "a", "count": 1, "inner": {"label": "i"},
            "items": [{"label": "x"}, {"gain": 1.0}]}
    err = _error(Outer, data, "verdict")
    assert err.key == "verdict.items.1.label" and err.got == "<missing>"
    assert "verdict.items.1.label" in str(err)
    assert _error(Outer, {"name": "a", "inner": {"label": "i"}}).key == "count"


def test_a_wrong_type_deep_inside_names_its_dotted_key_and_what_was_expected() -> None:
    shallow = _error(Inner, {"label": "i", "gain": "fast"})
    assert shallow.key == "gain" and shallow.got == "fast" and shallow.expected
    data = {"name": "a", "count": 1, "inner": {"label": "i"},
            "items": [{"label": "x"}, {"label": "y", "gain": "fast"}]}
    deep = _error(Outer, data, "info")
    assert deep.key == "info.items.1.gain" and "info.items.1.gain" in str(deep)
    assert deep.got == "fast" and deep.expected == shallow.expected  # a number, both
    table = _error(Outer, {**data, "items": [], "table": {"k": 1.0, "bad": "x"}}, "info")
    assert table.key == "info.table.bad" and table.got == "x"
    tags = _error(Outer, {**data, "items": [], "tags": ["a", 3]})
    assert tags.key == "tags.1" and tags.got == 3


def test_a_value_fitting_no_member_of_a_union_is_named_at_the_union() -> None:
    data = {"name": "a", "count": 1, "inner": {"label": "i"}, "maybe": {"gain": 1.0}}
    err = _error(Outer, data)
    assert err.key == "maybe" and err.got == {"gain": 1.0}
    assert _error(Inner, {"label": "i", "limit": "x"}).key == "limit"


def test_not_a_table_is_named_at_its_key() -> None:
    assert _error(Outer, {"name": "a", "count": 1, "inner": [1]}, "info").key == "info.inner"
    assert _error(Outer, None).key == ""
    assert _error(Outer, {"name": "a", "count": 1, "inner": {"label": "i"},
                          "items": {"label": "x"}}).key == "items"


@pytest.mark.parametrize("value", [True, False])
def test_bool_is_no_number(value: bool) -> None:
    base = {"name": "a", "count": 1, "inner": {"label": "i"}}
    assert _error(Outer, {**base, "count": value}).key == "count"
    assert _error(Outer, {**base, "inner": {"label": "i", "gain": value}}).key == "inner.gain"
    assert _error(Outer, {**base, "inner": {"label": "i", "limit": value}}).key == "inner.limit"
    assert _error(Outer, {**base, "table": {"k": value}}).key == "table.k"
    assert _error(Outer, {**base, "flag": 1}).key == "flag"  # nor a number a bool
    assert decode_dataclass(Outer, {**base, "flag": value}, PATH).flag is value


def test_a_refused_record_is_an_error_at_its_key_with_the_constructors_reason() -> None:
    data = {"name": "m", "value": 1.0, "unit": "s", "kind": "no-such-kind"}
    err = _error(MetricValue, data, "verdict.metrics.4")
    assert err.key == "verdict.metrics.4" and isinstance(err.__cause__, ValueError)


def test_an_unsupported_field_type_is_a_type_error_naming_the_key() -> None:
    @dataclass
    class Odd:
        a: int
        weird: set[int] = field(default_factory=set)

    assert decode_dataclass(Odd, {"a": 1}, PATH) == Odd(1)  # only a value of it is one
    with pytest.raises(TypeError, match=r"root\.weird"):
        decode_dataclass(Odd, {"a": 1, "weird": [1]}, PATH, "root")


# ------------------------------------------------ the constructor, as it would be called


@dataclass
class CustomInit:
    a: int
    b: int = 2

    def __init__(self, a: int, b: int = 7) -> None:  # its own default, not the field's
        self.a = a
        self.b = b * 10


@dataclass
class KeywordOnly:
    a: int
    _: KW_ONLY
    b: int = 3


@dataclass
class WithInitVar:
    a: int
    scale: InitVar[int] = 2

    def __post_init__(self, scale: int) -> None:
        self.a *= scale


@dataclass
class NotInInit:
    a: int
    seen: list[int] = field(default_factory=list, init=False)


@dataclass
class Recursive:
    value: int
    children: tuple[Recursive, ...] = ()


@pytest.mark.parametrize(("cls", "given"), [
    (CustomInit, {"a": 1}), (CustomInit, {"a": 1, "b": 3}), (KeywordOnly, {"a": 1}),
    (KeywordOnly, {"a": 1, "b": 5}), (WithInitVar, {"a": 2}), (NotInInit, {"a": 4}),
    (Recursive, {"value": 1}),
])
def test_the_record_is_what_its_constructor_makes_of_the_given_fields(
        cls: type, given: dict[str, Any]) -> None:
    assert decode_dataclass(cls, given, PATH) == cls(**given)


def test_a_record_may_hold_its_own_class() -> None:
    data = {"value": 1, "children": [{"value": 2}, {"value": 3, "children": [{"value": 4}]}]}
    assert decode_dataclass(Recursive, data, PATH) == Recursive(
        1, (Recursive(2), Recursive(3, (Recursive(4),))))
    bad = {"value": 1, "children": [{"value": 2, "children": [{"value": "x"}]}]}
    assert _error(Recursive, bad).key == "children.0.children.0.value"


# ------------------------------------------------------------------ real records


def _round_trip(value: Any) -> Any:
    return decode_dataclass(type(value), json.loads(json.dumps(to_plain(value))), PATH)


def test_real_records_read_back_as_written() -> None:
    records = dict(sr.catalog_records())
    for name in ("stalled_pass_left__ctrl_a", "rear_end__ctrl_a"):
        record = sr.judge(records[name])
        assert record.verdict is not None and record.verdict.metrics
        for value in (record.info, record.outcome, record.verdict):
            back = _round_trip(value)
            # NaN metric values (not measurable) make == false for any two records; the
            # repr shows every value exactly (floats round-trip), its type and order
            assert type(back) is type(value) and repr(back) == repr(value)
    rear_end = sr.judge(records["rear_end__ctrl_a"]).verdict
    assert rear_end is not None and rear_end.failures and rear_end.failures[0].step is not None
    info = dataclasses.replace(sr.base_info("x"), ego=dataclasses.replace(
        sr.base_info("x").ego, cg_to_rear_axle_m=1.4), criteria={"max_jerk": 3.0})
    assert _round_trip(info) == info  # without a NaN, equal
    outcome = RunOutcome(end="timeout", error="slow", wall_s=5.0, sim_time_s=10.0, steps=200,
                         peak_rss_mb=300.0, log_s=0.25, ssm=SsmSummary(2, 1.5, None),
                         sumo_collisions=(SumoCollision(1.0, "ego", "v1", "collision"),),
                         replay=ReplaySummary("t.csv", "reactive", 3,
                                              (ReplayHandover("v1", 2.5),)))
    assert _round_trip(outcome) == outcome


# -------------------------------------------------------------- the reader's shortcuts


def _same_columns(a: Any, b: Any) -> None:
    columns_a, columns_b = list(a.columns()), list(b.columns())
    assert [n for n, _ in columns_a] == [n for n, _ in columns_b]
    for (_, x), (_, y) in zip(columns_a, columns_b, strict=True):
        assert x.dtype == y.dtype and x.shape == y.shape


def test_a_run_read_without_its_trace_holds_an_empty_one_of_its_own(tmp_path: Path) -> None:
    runs = [sr.write_run(tmp_path / name, sr.straight_trace(duration_s=2.0))
            for name in ("a", "b")]
    first, second = (load_run(r, trace=False, neighbours=False, arrays=False,
                              series=False, road=False) for r in runs)
    empty = Trace.empty()
    for record in (first, second):
        assert len(record.trace) == 0 and record.trace.extra == {}
        assert record.trace.step.dtype == empty.step.dtype
        assert record.trace.t_s.dtype == empty.t_s.dtype
        for group in ("ego", "decision", "safety", "controller", "timing"):
            _same_columns(getattr(record.trace, group), getattr(empty, group))
        _same_columns(record.neighbours, NeighbourColumns.allocate(0))
    assert first.trace is not second.trace and first.trace.ego is not second.trace.ego
    assert first.trace.extra is not second.trace.extra
    assert first.neighbours is not second.neighbours
    full = load_run(runs[0])  # asked for: read from the file, as before
    assert len(full.trace) == 40 and np.isfinite(full.trace.t_s).all()


def test_run_directories_are_listed_as_before(tmp_path: Path) -> None:
    out = tmp_path / "out"
    for name in ("b", "a", "B", "a-1", "a_1", ".hidden", "no_json", "json_dir",
                 "json_link", "json_broken"):
        (out / name).mkdir(parents=True)
    for name in ("b", "a", "B", "a-1", "a_1", ".hidden"):
        (out / name / RUN_JSON).write_text("{}")
    (out / "json_dir" / RUN_JSON).mkdir()
    (out / "json_link" / RUN_JSON).symlink_to(out / "a" / RUN_JSON)
    (out / "json_broken" / RUN_JSON).symlink_to(out / "gone.json")
    (out / "dir_link").symlink_to(out / "a", target_is_directory=True)
    (out / "file").write_text("")
    expected = [out / name for name in sorted(["b", "a", "B", "a-1", "a_1"])]
    assert iter_run_dirs(out) == expected
    assert iter_run_dirs(str(out)) == expected
    assert iter_run_dirs(out / "file") == [] and iter_run_dirs(tmp_path / "none") == []


def test_an_older_runs_parquet_files_are_checked_as_before(tmp_path: Path) -> None:
    run = tmp_path / "run"
    run.mkdir()
    check_run_files(run, (), judged_steps=False)  # nothing there, nothing asked for
    with pytest.raises(DamagedRun) as info:
        check_run_files(run, (), judged_steps=True)
    assert info.value.problems == ("trace.parquet: missing", "series.parquet: missing")
    (run / "trace.parquet").mkdir()  # not a file
    (run / "series.parquet").write_bytes(b"not parquet")
    os.symlink(run / "gone.parquet", run / "neighbours.parquet")  # a broken link
    with pytest.raises(DamagedRun) as info:
        check_run_files(run, (), judged_steps=True)
    problems = info.value.problems
    assert problems[0] == "trace.parquet: missing" and len(problems) == 2
    assert problems[1].startswith("series.parquet: not a readable parquet file")


def test_the_collector_is_paused_within_and_as_it_was_after() -> None:
    was = gc.isenabled()
    try:
        gc.enable()
        with collector_paused():
            assert not gc.isenabled()
        assert gc.isenabled()
        with pytest.raises(KeyError), collector_paused():
            raise KeyError("x")
        assert gc.isenabled()
        gc.disable()
        with collector_paused():
            assert not gc.isenabled()
        assert not gc.isenabled()  # left as it was
    finally:
        if was:
            gc.enable()
        else:
            gc.disable()


def test_verdict_and_info_decode_from_a_run_json(tmp_path: Path) -> None:
    run = sr.write_run(tmp_path / "r", sr.straight_trace(duration_s=2.0))
    doc = json.loads((run / RUN_JSON).read_text())
    info = decode_dataclass(RunInfo, doc["info"], PATH, "info")
    verdict = decode_dataclass(Verdict, doc["verdict"], PATH, "verdict")
    loaded = load_run(run, trace=False)
    assert repr(info) == repr(loaded.info) and repr(verdict) == repr(loaded.verdict)
    doc["verdict"]["metrics"][3]["worst_step"] = 1.5
    with pytest.raises(RecordError) as err:
        decode_dataclass(Verdict, doc["verdict"], PATH, "verdict")
    assert err.value.key == "verdict.metrics.3.worst_step"


def test_a_night_read_refuses_a_trace_overwritten_in_place(tmp_path: Path) -> None:
    """collect_runs gives every run of the night, in the directories' order; a run whose
    trace was overwritten in place (same size, other bytes) is refused (an 'error'
    entry naming why), the others are read."""
    import reports.tables as tables

    out = sr.make_catalog(tmp_path / "night")
    damaged = sorted(p for p in out.iterdir() if (p / "trace.parquet").is_file())[1]
    size = (damaged / "trace.parquet").stat().st_size
    (damaged / "trace.parquet").write_bytes(b"\0" * size)
    entries = tables.collect_runs(out)
    assert [e.run_dir for e in entries] == iter_run_dirs(out)
    assert len(entries) >= 4
    refused = [e for e in entries if e.unreadable]
    assert [e.run_dir for e in refused] == [damaged]
    assert refused[0].status == "error"
    assert all(e.verdict is not None for e in entries if not e.unreadable)
