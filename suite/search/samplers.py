"""The samplers a search can use, all Optuna's, and how each batch's is made.

``tpe``: Optuna's multivariate TPE (a joint Parzen estimator over all parameters, so a
failing region that is a slab across two parameters is modelled as one), after
:data:`TPE_STARTUP_TRIALS` random points; ``cmaes``: CMA-ES with random points where it
cannot sample; ``qmc``: a scrambled Sobol sequence; ``random``: independent uniform.

A space-filling start (a Sobol design of 8 points, then TPE with 100 candidates per
draw) was tried against this on ``catalogs/search_families.toml`` (budget 60, seeds
0-4): median runs to the first failure 9 / 13 / 20 for stall_close / cut_in /
blocked_pass against 9 / 14 / 13 with the random start, so it was not kept.

Each batch's sampler is made anew with a seed derived from (seed, family, batch)
(:func:`make_sampler`): what it draws depends on the seed and the trials told so far
only, so a batch asked together (``--jobs``) and a resumed search draw what an
uninterrupted search draws. The Sobol sequence keeps one seed per study instead: it is
indexed by the points drawn so far (kept in the storage).
"""

from __future__ import annotations

import optuna

__all__ = ["SAMPLERS", "TPE_STARTUP_TRIALS", "make_sampler"]

SAMPLERS = ("tpe", "cmaes", "random", "qmc")
TPE_STARTUP_TRIALS = 6  # random points before TPE takes over


def _derived_seed(seed: int, family_index: int, batch: int) -> int:
    return (seed * 1_000_003 + family_index * 10_007 + batch * 7_919 + 1) % (2 ** 31 - 1)


def _sobol(seed: int, family_index: int) -> optuna.samplers.QMCSampler:
    # One seed for the whole study: the scrambled sequence is indexed by the points
    # drawn so far (kept in the storage), so every batch continues the same sequence.
    return optuna.samplers.QMCSampler(qmc_type="sobol", scramble=True,
                                      seed=seed + family_index,
                                      warn_independent_sampling=False,
                                      warn_asynchronous_seeding=False)


def make_sampler(kind: str, seed: int, family_index: int, batch: int
                 ) -> optuna.samplers.BaseSampler:
    """The sampler of family ``family_index``'s batch ``batch``: made anew per batch
    with a seed derived from (``seed``, family, batch), except the Sobol sequences,
    which keep one seed per study (module doc)."""
    s = _derived_seed(seed, family_index, batch)
    if kind == "tpe":
        return optuna.samplers.TPESampler(seed=s, n_startup_trials=TPE_STARTUP_TRIALS,
                                          multivariate=True, warn_independent_sampling=False)
    if kind == "cmaes":
        return optuna.samplers.CmaEsSampler(
            seed=s, warn_independent_sampling=False,
            independent_sampler=optuna.samplers.RandomSampler(seed=s))
    if kind == "qmc":
        return _sobol(seed, family_index)
    if kind == "random":
        return optuna.samplers.RandomSampler(seed=s)
    raise ValueError(f"sampler: expected one of {SAMPLERS}, got {kind!r}")
