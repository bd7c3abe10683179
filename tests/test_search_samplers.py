"""Each sampler is deterministic per seed however its batches are made."""

from __future__ import annotations

import optuna
import pytest

from suite.search.samplers import SAMPLERS, make_sampler

optuna.logging.set_verbosity(optuna.logging.ERROR)


def _draw(kind: str, n: int, batch_every: int, seed: int = 3) -> list[tuple[float, float]]:
    """n points of a 2-D study on f(x, y) = (x - 0.8)^2 + (y - 0.1)^2, the sampler made
    anew every ``batch_every`` trials (as the loop does per batch)."""
    study = optuna.create_study(sampler=make_sampler(kind, seed, 0, 0))
    points = []
    for i in range(n):
        if i % batch_every == 0:
            study.sampler = make_sampler(kind, seed, 0, i // batch_every)
        t = study.ask()
        x, y = t.suggest_float("x", 0.0, 1.0), t.suggest_float("y", 0.0, 1.0)
        study.tell(t, (x - 0.8) ** 2 + (y - 0.1) ** 2)
        points.append((x, y))
    return points


@pytest.mark.parametrize("kind", SAMPLERS)
def test_the_same_seed_and_batching_draw_the_same_points(kind: str) -> None:
    assert _draw(kind, 16, 4) == _draw(kind, 16, 4)
    assert _draw(kind, 16, 4, seed=4) != _draw(kind, 16, 4)


def test_tpe_closes_in_on_the_minimum_after_its_start() -> None:
    pts = _draw("tpe", 40, 1)
    best = min((x - 0.8) ** 2 + (y - 0.1) ** 2 for x, y in pts[20:])
    assert best < 0.01
