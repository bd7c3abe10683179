"""The search loop on a cheap fake objective (no SUMO): a seeded sampler finds a planted
failing region; a search is deterministic for a seed and batch size; an interrupted
search resumed from its journal equals an uninterrupted one; the shrinking moves toward
the nominal point within the failure mode."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from reports.metrics.criteria import CRITERIA_METRICS, Criteria
from reports.metrics.values import measured
from reports.record import Verdict
from suite.search.loop import SAMPLERS, SearchSettings, objective, open_storage, search_family
from suite.search.shrink import shrink_bound, shrink_failures
from suite.search.space import Family, Param, load_search_catalog

CATALOG = """
[defaults]
controller = "lane_keep"
duration_s = 5.0
step_s = 0.02
[[scenario]]
name = "fake"
net = "straight_3lane"
ego = { lane = 1, pos_m = 50.0, speed_mps = 25.0 }
stalled = [ { lane = 1, pos_m = 400.0 } ]
[scenario.search]
"stalled.0.pos_m" = { min = 100.0, max = 900.0 }
"ego.speed_mps" = { min = 18.0, max = 33.0 }
"""

# The planted region: stalled.0.pos_m in [120, 160] and ego.speed_mps >= 30 (1 % of
# the space); TTC falls linearly with the distance to it.
REGION = ((120.0, 160.0), (30.0, 33.0))


def fake_ttc(pos: float, speed: float) -> float:
    (plo, phi), (slo, _) = REGION
    dp = max(plo - pos, pos - phi, 0.0) / 800.0
    ds = max(slo - speed, 0.0) / 15.0
    return 1.0 + 4.0 * math.hypot(dp, ds) if (dp or ds) else 0.5


class FakeRunner:
    """A batch runner whose 'run' is the fake TTC; ``stop_at``: the call that returns
    None (an interrupted batch)."""

    def __init__(self, stop_at: int | None = None) -> None:
        self.calls = 0
        self.stop_at = stop_at
        self.names: list[str] = []

    def __call__(self, scenarios: Sequence[Any]) -> list[Any] | None:
        self.calls += 1
        if self.stop_at is not None and self.calls == self.stop_at:
            return None
        out = []
        lims: dict[str, float | None] = {c: None for c in CRITERIA_METRICS}
        lims["min_ttc_s"] = 0.95
        crit = Criteria(**lims)  # type: ignore[arg-type]
        for sc in scenarios:
            self.names.append(sc.name)
            found = [measured("min_ttc_s", fake_ttc(sc.stalled[0].pos_m, sc.ego.speed_mps),
                              "s", "safety")]
            failures = crit.check(found)
            status = "fail" if failures else "pass"
            out.append(SimpleNamespace(
                status=status, run_dir=None,
                verdict=Verdict(status=status, metrics=tuple(m.metric for m in found),
                                failures=failures, criteria=crit.as_dict())))
        return out


@pytest.fixture(scope="module")
def family(tmp_path_factory: pytest.TempPathFactory) -> Family:
    path = tmp_path_factory.mktemp("cat") / "fake.toml"
    path.write_text(CATALOG)
    return load_search_catalog(path).families[0]


def _search(family: Family, journal: Path, sampler: str, seed: int, budget: int,
            jobs: int = 1, runner: FakeRunner | None = None) -> Any:
    storage, backend = open_storage(str(journal))
    settings = SearchSettings(budget_runs=budget, sampler=sampler, seed=seed, batch_size=jobs)
    return search_family(family, 0, settings, storage, runner or FakeRunner(),
                         journal=backend)


def _key(result: Any) -> list[tuple[Any, ...]]:
    return [(t.trial, t.values, t.status, t.robustness) for t in result.trials]


@pytest.mark.slow
def test_tpe_finds_the_planted_region_random_sampling_rarely_does(family: Family,
                                                                  tmp_path: Path) -> None:
    found_tpe = found_random = 0
    for seed in range(3):
        tpe = _search(family, tmp_path / f"tpe{seed}.journal", "tpe", seed, 60)
        rnd = _search(family, tmp_path / f"rnd{seed}.journal", "random", seed, 60)
        found_tpe += bool(tpe.failures)
        found_random += bool(rnd.failures)
        for t in tpe.failures:  # a failure is in the planted region
            (plo, phi), (slo, shi) = REGION
            assert plo <= t.values[0] <= phi and slo <= t.values[1] <= shi
    assert found_tpe == 3
    assert found_random <= found_tpe


@pytest.mark.parametrize("sampler", SAMPLERS)
def test_deterministic_for_a_seed_and_batch(family: Family, tmp_path: Path,
                                            sampler: str) -> None:
    a = _search(family, tmp_path / "a.journal", sampler, 7, 12, jobs=3)
    b = _search(family, tmp_path / "b.journal", sampler, 7, 12, jobs=3)
    c = _search(family, tmp_path / "c.journal", sampler, 8, 12, jobs=3)
    assert _key(a) == _key(b)
    assert len(a.runs) == 12
    assert [t.values for t in a.trials] != [t.values for t in c.trials]


@pytest.mark.slow
@pytest.mark.parametrize("sampler", SAMPLERS)
@pytest.mark.parametrize("jobs", [1, 3])
def test_resume_after_an_interruption_equals_an_uninterrupted_search(
        family: Family, tmp_path: Path, sampler: str, jobs: int) -> None:
    whole = _search(family, tmp_path / "whole.journal", sampler, 3, 14, jobs=jobs)
    journal = tmp_path / "cut.journal"
    first = _search(family, journal, sampler, 3, 14, jobs=jobs, runner=FakeRunner(stop_at=3))
    assert first.stopped and len(first.runs) < 14
    again = _search(family, journal, sampler, 3, 14, jobs=jobs)  # a new process's storage
    assert not again.stopped
    assert _key(again) == _key(whole)


def test_a_finished_search_resumed_runs_nothing(family: Family, tmp_path: Path) -> None:
    whole = _search(family, tmp_path / "j.journal", "tpe", 1, 8)
    runner = FakeRunner()
    again = _search(family, tmp_path / "j.journal", "tpe", 1, 8, runner=runner)
    assert runner.calls == 0 and _key(again) == _key(whole)


def test_refused_points_are_told_counted_and_not_run(tmp_path: Path) -> None:
    # the ego and a stalled car on one lane must not overlap: the catalog refuses that
    text = CATALOG.replace('"stalled.0.pos_m" = { min = 100.0, max = 900.0 }',
                           '"stalled.0.pos_m" = { min = 100.0, max = 140.0 }').replace(
        '"ego.speed_mps" = { min = 18.0, max = 33.0 }', '"ego.pos_m" = { min = 40.0, max = 200.0 }')
    path = tmp_path / "r.toml"
    path.write_text(text)
    fam = load_search_catalog(path).families[0]
    runner = FakeRunner()
    res = _search(fam, tmp_path / "r.journal", "random", 0, 30, runner=runner)
    assert len(res.runs) == 30 and len(runner.names) == 30
    assert res.refused >= 1
    for t in res.trials:
        if not t.ran:
            assert t.reason and not t.run and abs(t.values[0] - t.values[1]) < 15.0


def test_shrink_moves_toward_the_nominal_point_in_the_same_mode(family: Family,
                                                                tmp_path: Path) -> None:
    res = _search(family, tmp_path / "s.journal", "tpe", 0, 60)
    assert res.failures
    cases, tried, ok = shrink_failures(res.family, res.failures, FakeRunner(), points=4)
    assert ok and cases and tried
    # the runs beside the budget that the search announces bound what it runs
    assert len(tried) <= shrink_bound(res.family, res.failures, points=4)
    for case in cases:
        assert case.result.is_failure and case.result.mode == case.mode
        assert res.family.distance(case.result.values) <= \
            res.family.distance(case.origin.values) + 1e-12


def test_param_toward() -> None:
    p = Param("x", "int", 0.0, 10.0)
    assert p.toward(2, 9, 0.0) == 2 and p.toward(2, 9, 1.0) == 9
    assert p.toward(2, 9, 0.5) == 6  # 5.5 rounded toward 9
    f = Param("y", "float", 0.0, 1.0)
    assert f.toward(0.2, 0.6, 0.25) == pytest.approx(0.3)
    c = Param("z", "choice", choices=("a", "b"))
    assert c.toward("a", "b", 0.0) == "a" and c.toward("a", "b", 1.0) == "b"


def test_the_told_objective_is_a_soft_minimum_of_the_margins() -> None:
    assert objective([2.0]) == 2.0
    assert math.isnan(objective([])) and math.isnan(objective([math.inf]))
    two = objective([1.0, 1.0])
    assert math.isclose(two, 1.0 - math.log(2.0))  # tau ln n below the minimum
    far = objective([1.0, 50.0, math.inf])
    assert 1.0 - 1e-12 < far + 1e-9 and far <= 1.0
    assert objective([1.0, 1.5]) < objective([1.0, 5.0]) <= 1.0  # a near margin counts
    assert objective([-0.5, 3.0]) < 0.0
    assert objective([1.0, 1.5], tau=None) == 1.0
