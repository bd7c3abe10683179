"""Parameter variation files (``ParameterValueDistribution``) -> parameter sets.

* Deterministic: each ``DeterministicSingleParameterDistribution`` (a ``DistributionSet``
  of values or a ``DistributionRange`` lower..upper by ``stepWidth``, both ends
  included) and each ``DeterministicMultiParameterDistribution`` (a
  ``ValueSetDistribution`` of ``ParameterValueSet`` s) is one axis; the sets are their
  cartesian product, the first axis varying slowest.
* Stochastic: ``numberOfTestRuns`` draws with ``randomSeed`` (numpy's PCG64) from each
  parameter's distribution (``UniformDistribution``, ``NormalDistribution``
  (with an optional ``Range``), ``LogNormalDistribution``, ``PoissonDistribution``,
  ``Histogram`` and ``ProbabilityDistributionSet``).

Values are kept as the strings the template's declarations read.

:func:`distribution_space` gives the same file as its *space* (one :class:`Axis` per
distribution) rather than its sets: what ``hwyeval search`` searches for a logical
scenario (:mod:`.logical`).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from suite.importers.openscenario.errors import fail_at
from suite.importers.openscenario.position_xml import num

__all__ = ["MAX_SETS", "Axis", "distribution_space", "parameter_sets", "template_of"]

MAX_SETS = 10_000_000  # a deterministic product larger than this is refused


def _fmt(v: float) -> str:
    return repr(round(v, 9)) if v != int(v) else f"{int(v)}.0"


def _range_values(el: Any) -> list[str]:
    step = num(el, "stepWidth")
    rng = el.find("Range")
    if rng is None or step <= 0.0:
        raise fail_at(el, "a DistributionRange needs a Range and a stepWidth > 0")
    lo, hi = num(rng, "lowerLimit"), num(rng, "upperLimit")
    n = int(math.floor((hi - lo) / step + 1e-9)) + 1
    return [_fmt(lo + k * step) for k in range(max(n, 0))]


def _single(el: Any) -> tuple[list[str], list[list[str]]]:
    name = str(el.get("parameterName", ""))
    kid = next((k for k in el if isinstance(k.tag, str)), None)
    if kid is not None and kid.tag == "DistributionSet":
        return [name], [[str(e.get("value", ""))] for e in kid.iterfind("Element")]
    if kid is not None and kid.tag == "DistributionRange":
        return [name], [[v] for v in _range_values(kid)]
    raise fail_at(kid if kid is not None else el, "a DistributionSet or DistributionRange "
                  "is required")


def _multi(el: Any) -> tuple[list[str], list[list[str]]]:
    vsd = el.find("ValueSetDistribution")
    if vsd is None:
        raise fail_at(el, "a ValueSetDistribution is required")
    sets = [{a.get("parameterRef", ""): a.get("value", "")
             for a in s.iterfind("ParameterAssignment")}
            for s in vsd.iterfind("ParameterValueSet")]
    names = sorted({k for s in sets for k in s})
    for s, el_set in zip(sets, vsd.iterfind("ParameterValueSet"), strict=True):
        if set(s) != set(names):
            raise fail_at(el_set, f"every ParameterValueSet must set {names}")
    return names, [[s[n] for n in names] for s in sets]


def _deterministic(el: Any) -> list[dict[str, str]]:
    axes: list[tuple[list[str], list[list[str]]]] = []
    for kid in el:
        if not isinstance(kid.tag, str):
            continue
        if kid.tag == "DeterministicSingleParameterDistribution":
            axes.append(_single(kid))
        elif kid.tag == "DeterministicMultiParameterDistribution":
            axes.append(_multi(kid))
        else:
            raise fail_at(kid, f"{kid.tag} is not supported")
    total = math.prod(len(v) for _, v in axes)
    if total > MAX_SETS:
        raise fail_at(el, f"{total} parameter sets, more than {MAX_SETS}")
    out = []
    for combo in itertools.product(*(v for _, v in axes)):
        d: dict[str, str] = {}
        for (names, _), values in zip(axes, combo, strict=True):
            d.update(zip(names, values, strict=True))
        out.append(d)
    return out


def _draw(el: Any, rng: np.random.Generator) -> float | str:
    tag = str(el.tag)
    if tag == "UniformDistribution":
        r = el.find("Range")
        return float(rng.uniform(num(r, "lowerLimit"), num(r, "upperLimit")))
    if tag in ("NormalDistribution", "LogNormalDistribution"):
        mean, var = num(el, "expectedValue"), num(el, "variance")
        v = float(rng.normal(mean, math.sqrt(var)))
        v = math.exp(v) if tag == "LogNormalDistribution" else v
        r = el.find("Range")
        return v if r is None else min(max(v, num(r, "lowerLimit")), num(r, "upperLimit"))
    if tag == "PoissonDistribution":
        return float(rng.poisson(num(el, "expectedValue")))
    if tag == "Histogram":
        bins = [(b.find("Range"), num(b, "weight")) for b in el.iterfind("Bin")]
        w = np.array([x[1] for x in bins], dtype=np.float64)
        k = int(rng.choice(len(bins), p=w / w.sum()))
        return float(rng.uniform(num(bins[k][0], "lowerLimit"), num(bins[k][0], "upperLimit")))
    if tag == "ProbabilityDistributionSet":
        elems = list(el.iterfind("Element"))
        w = np.array([num(e, "weight") for e in elems], dtype=np.float64)
        return str(elems[int(rng.choice(len(elems), p=w / w.sum()))].get("value", ""))
    raise fail_at(el, f"distribution {tag} is not supported")


def _stochastic(el: Any) -> list[dict[str, str]]:
    runs = int(num(el, "numberOfTestRuns"))
    rng = np.random.default_rng(int(num(el, "randomSeed", 0.0)))
    dists = list(el.iterfind("StochasticDistribution"))
    out = []
    for _ in range(runs):
        d: dict[str, str] = {}
        for dist in dists:
            kid = next(k for k in dist if isinstance(k.tag, str))
            v = _draw(kid, rng)
            d[str(dist.get("parameterName", ""))] = v if isinstance(v, str) else repr(v)
        out.append(d)
    return out


def template_of(root: Any, path: Path) -> Path:
    """The template (``ScenarioFile``) a variation file points at."""
    sf = root.find("ParameterValueDistribution/ScenarioFile")
    if sf is None or not sf.get("filepath"):
        raise fail_at(root, "a ParameterValueDistribution needs a ScenarioFile")
    return (path.parent / str(sf.get("filepath"))).resolve()


def parameter_sets(root: Any) -> list[dict[str, str]]:
    """Every parameter set of a variation file (module docstring)."""
    pvd = root.find("ParameterValueDistribution")
    kids = [k for k in pvd if isinstance(k.tag, str) and k.tag != "ScenarioFile"]
    if len(kids) != 1 or kids[0].tag not in ("Deterministic", "Stochastic"):
        raise fail_at(pvd, "one Deterministic or Stochastic distribution is required")
    return _deterministic(kids[0]) if kids[0].tag == "Deterministic" else _stochastic(kids[0])


# ------------------------------------------------------------------ the space
VALUES, GRID, RANGE, SETS = "values", "grid", "range", "sets"
SPREAD_SD = 3.0  # a normal (log-normal) distribution without a Range: mean +- 3 sd


@dataclass(frozen=True)
class Axis:
    """One distribution of a variation file, as a space. ``kind``:

    * ``values``: ``values`` the file's values of one parameter (a ``DistributionSet``,
      a ``ProbabilityDistributionSet``);
    * ``grid``: a ``DistributionRange``: ``values`` its steps, ``low``..``high`` its
      range;
    * ``range``: a stochastic distribution's range ``low``..``high`` (``integer``: a
      Poisson count);
    * ``sets``: a ``ValueSetDistribution``: ``sets`` its parameter value sets over
      ``names``."""

    kind: str
    names: tuple[str, ...]
    values: tuple[str, ...] = ()
    low: float = math.nan
    high: float = math.nan
    sets: tuple[dict[str, str], ...] = ()
    integer: bool = False


def _stochastic_axis(name: str, el: Any) -> Axis:
    """The range a stochastic distribution draws from: its ``Range`` (uniform, normal and
    log-normal clipped to it, Poisson), a normal's mean +- 3 sd (a log-normal's exp of
    it) without one, a Poisson's mean +- 3 sqrt(mean) (>= 0) without one, a histogram's
    lowest to highest bin; a probability set's values."""
    tag = str(el.tag)
    rng = el.find("Range")
    if tag == "ProbabilityDistributionSet":
        return Axis(VALUES, (name,), tuple(str(e.get("value", ""))
                                           for e in el.iterfind("Element")))
    if tag == "Histogram":
        bins = [b.find("Range") for b in el.iterfind("Bin")]
        if not bins or any(b is None for b in bins):
            raise fail_at(el, "a Histogram needs Bins with a Range each")
        return Axis(RANGE, (name,), low=min(num(b, "lowerLimit") for b in bins),
                    high=max(num(b, "upperLimit") for b in bins))
    if tag not in ("UniformDistribution", "NormalDistribution", "LogNormalDistribution",
                   "PoissonDistribution"):
        raise fail_at(el, f"distribution {tag} is not supported")
    integer = tag == "PoissonDistribution"
    if rng is not None:
        return Axis(RANGE, (name,), low=num(rng, "lowerLimit"), high=num(rng, "upperLimit"),
                    integer=integer)
    if tag == "UniformDistribution":
        raise fail_at(el, "a UniformDistribution needs a Range")
    mean = num(el, "expectedValue")
    if integer:
        spread = SPREAD_SD * math.sqrt(max(mean, 0.0))
        return Axis(RANGE, (name,), low=max(0.0, math.floor(mean - spread)),
                    high=math.ceil(mean + spread), integer=True)
    sd = math.sqrt(num(el, "variance"))
    lo, hi = mean - SPREAD_SD * sd, mean + SPREAD_SD * sd
    if tag == "LogNormalDistribution":
        lo, hi = math.exp(lo), math.exp(hi)
    return Axis(RANGE, (name,), low=lo, high=hi)


def _deterministic_axes(el: Any) -> list[Axis]:
    axes: list[Axis] = []
    for kid in el:
        if not isinstance(kid.tag, str):
            continue
        if kid.tag == "DeterministicSingleParameterDistribution":
            names, rows = _single(kid)
            dist = next(k for k in kid if isinstance(k.tag, str))
            values = tuple(r[0] for r in rows)
            if dist.tag == "DistributionRange":
                rng = dist.find("Range")
                axes.append(Axis(GRID, tuple(names), values, num(rng, "lowerLimit"),
                                 num(rng, "upperLimit")))
            else:
                axes.append(Axis(VALUES, tuple(names), values))
        elif kid.tag == "DeterministicMultiParameterDistribution":
            names, rows = _multi(kid)
            axes.append(Axis(SETS, tuple(names), sets=tuple(
                dict(zip(names, r, strict=True)) for r in rows)))
        else:
            raise fail_at(kid, f"{kid.tag} is not supported")
    return axes


def distribution_space(root: Any) -> list[Axis]:
    """The variation file's space: one :class:`Axis` per distribution, in file order."""
    pvd = root.find("ParameterValueDistribution")
    kids = [k for k in pvd if isinstance(k.tag, str) and k.tag != "ScenarioFile"]
    if len(kids) != 1 or kids[0].tag not in ("Deterministic", "Stochastic"):
        raise fail_at(pvd, "one Deterministic or Stochastic distribution is required")
    if kids[0].tag == "Deterministic":
        return _deterministic_axes(kids[0])
    axes = []
    for dist in kids[0].iterfind("StochasticDistribution"):
        kid = next((k for k in dist if isinstance(k.tag, str)), None)
        if kid is None:
            raise fail_at(dist, "a StochasticDistribution needs a distribution")
        axes.append(_stochastic_axis(str(dist.get("parameterName", "")), kid))
    return axes
