"""The history's pure computations: the night and revision a scenario started failing,
the last good revision, the flaky rule (same hash and revision, or >= 3 alternations)."""

from __future__ import annotations

import datetime as dt
import math

from reports.history import FLAKY_ALTERNATIONS, NightInfo, scenario_trend

T0 = dt.datetime(2026, 11, 1, 3, 0, tzinfo=dt.UTC)


def nights(revisions: list[str], dirty: bool | None = False) -> list[NightInfo]:
    return [NightInfo(night_id=f"n{k + 1:02d}", started_at=T0 + dt.timedelta(days=k),
                      git_revision=rev, hwyeval_version="0.1.0", host="ci",
                      catalog="/c/nightly.toml", git_dirty=dirty)
            for k, rev in enumerate(revisions)]


def test_a_regression_names_its_first_night_revision_and_last_good_revision() -> None:
    ns = nights(["a"] * 5 + ["b"] * 5)
    st = ["pass"] * 5 + ["fail"] * 5  # broke at night 6 (revision b), last pass night 5
    t = scenario_trend("s", ns, st, ["h1"] * 5 + ["h2"] * 5)
    assert t.status_now == "fail" and t.failing_now
    assert (t.first_failing_night, t.first_failing_revision) == ("n06", "b")
    assert (t.last_good_night, t.last_good_revision) == ("n05", "a")
    assert not t.flaky and t.alternations == 1


def test_absent_nights_are_skipped_and_a_never_passing_scenario_has_no_last_good() -> None:
    ns = nights(["a", "b", "c", "d"])
    t = scenario_trend("s", ns, ["fail", None, "error", "fail"])
    assert t.first_failing_night == "n01" and t.last_good_night is None
    t = scenario_trend("s", ns, ["pass", "fail", None, "timeout"])
    assert (t.first_failing_night, t.last_good_night) == ("n02", "n01")
    assert scenario_trend("s", ns, ["fail", "pass", "pass", None]).status_now == "absent"


def test_a_status_change_with_the_same_hash_and_revision_is_flaky() -> None:
    ns = nights(["a", "a", "b", "b"])
    t = scenario_trend("s", ns, ["pass", "fail", "fail", "fail"], ["h"] * 4)
    assert t.flaky and t.alternations == 1 and len(t.flaky_reasons) == 1
    # the same change across a revision or a scenario change is not
    assert not scenario_trend("s", ns, ["pass", "pass", "fail", "fail"], ["h"] * 4).flaky
    assert not scenario_trend("s", ns, ["pass", "fail", "fail", "fail"],
                              ["h", "h2", "h2", "h2"]).flaky


def test_unknown_or_dirty_revisions_never_count_as_the_same_code() -> None:
    st, hs = ["pass", "fail"], ["h", "h"]
    assert not scenario_trend("s", nights(["", ""]), st, hs).flaky
    assert not scenario_trend("s", nights(["a", "a"], dirty=True), st, hs).flaky
    assert not scenario_trend("s", nights(["a", "a"]), st, ["", ""]).flaky


def test_three_alternations_are_flaky_two_are_a_regression_and_its_fix() -> None:
    revs = [f"r{k}" for k in range(8)]  # a new revision every night: rule 1 never fires
    two = ["pass", "pass", "fail", "fail", "pass", "pass", "pass", "pass"]
    assert scenario_trend("s", nights(revs), two).alternations == 2
    assert not scenario_trend("s", nights(revs), two).flaky
    three = ["pass", "fail", "pass", "fail", "fail", "fail", "fail", "fail"]
    t = scenario_trend("s", nights(revs), three)
    assert t.alternations == FLAKY_ALTERNATIONS and t.flaky
    # absent nights do not break a sequence of alternations
    t = scenario_trend("s", nights(revs), ["pass", None, "fail", None, "pass", "fail", None,
                                           None])
    assert t.alternations == 3 and t.flaky and t.status_now == "absent"


def test_the_metric_and_limit_ride_along() -> None:
    t = scenario_trend("s", nights(["a", "b"]), ["pass", "fail"], None, [1.5, math.inf], 0.95)
    assert t.values == (1.5, math.inf) and t.limit == 0.95
