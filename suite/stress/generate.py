"""Write a stress catalog: plan, build the nets, resolve, write, validate, measure.

``OUT/`` receives (each run rewrites them; nothing else there is touched):

* ``catalog.toml``: the catalog, ``hwyeval run OUT/catalog.toml --out RUNS`` runs it;
* ``nets/<scenario>.net.xml`` and their netconvert sources ``nets/src/``; the real
  motorways a scenario uses are copied to ``nets/real/`` (the folder is self-contained);
* ``stress.json``: the generator's record (:class:`StressManifest`): command, seed, n,
  configuration, every scenario's plan and measured features, and the coverage.

The catalog is loaded with :func:`suite.catalog.load_catalog` (the registry checks the
controllers) before :func:`generate` returns: a catalog it writes is one ``hwyeval run``
accepts, or it raises.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from suite import __version__
from suite.catalog import Catalog, load_catalog
from suite.catalog.toml_write import dumps_catalog
from suite.road.network import RoadNetwork
from suite.stress.config import StressConfig
from suite.stress.coverage import Coverage, ScenarioFeatures, measure_catalog
from suite.stress.netgen import build_net, route_of
from suite.stress.plan import ScenarioPlan, plan_scenarios
from suite.stress.real import RealNet, real_nets
from suite.stress.scenarios import StressScenario, resolve

__all__ = ["StressCatalog", "StressManifest", "generate"]

CATALOG = "catalog.toml"
MANIFEST = "stress.json"
NETS = "nets"


@dataclass(frozen=True)
class StressManifest:
    """``stress.json``: how the catalog was made and what it covers."""

    generator: str
    hwyeval_version: str
    command: str
    seed: int
    n: int
    config: dict[str, Any]
    real_nets_dir: str | None
    plans: list[dict[str, Any]]
    features: list[dict[str, Any]]
    coverage: dict[str, Any]


@dataclass(frozen=True)
class StressCatalog:
    """A written stress catalog: its file, the validated catalog, what it covers."""

    path: Path
    catalog: Catalog
    scenarios: tuple[StressScenario, ...]
    features: tuple[ScenarioFeatures, ...]
    coverage: Coverage


def _clean(out_dir: Path) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    shutil.rmtree(out_dir / NETS, ignore_errors=True)
    for name in (CATALOG, MANIFEST):
        (out_dir / name).unlink(missing_ok=True)
    (out_dir / NETS / "real").mkdir(parents=True)


def _build(plan: ScenarioPlan, out_dir: Path, real: dict[str, RealNet], cfg: StressConfig
           ) -> StressScenario:
    nets = out_dir / NETS
    if plan.layout is not None:
        path = build_net(plan.layout, nets)
        route = route_of(plan.layout)
        rel = f"{NETS}/{path.name}"
    else:
        source = real[plan.real_net or ""]
        path = nets / "real" / source.name
        if not path.exists():
            shutil.copyfile(source.path, path)
        route = source.route
        rel = f"{NETS}/real/{source.name}"
    return resolve(plan, RoadNetwork.load(path), route, rel, cfg)


def _defaults(cfg: StressConfig) -> dict[str, Any]:
    return {"controller": cfg.controllers[0], "duration_s": float(cfg.duration_s),
            "step_s": float(cfg.step_s), "seed": 0}


def _header(command: str, seed: int, n: int, cfg: StressConfig) -> str:
    return (f"Stress catalog written by suite.stress (hwyeval {__version__}): {n} scenarios, "
            f"seed {seed}.\n{command}\nDistributions and features: docs/stress.md; "
            f"what was drawn and measured: {MANIFEST}.\nDo not edit: regenerate "
            f"(the same seed gives the same files). Duration {cfg.duration_s:g} s.")


def generate(n: int, seed: int, out_dir: str | Path, cfg: StressConfig | None = None, *,
             real_dir: Path | None = None, command: str = "") -> StressCatalog:
    """Write the stress catalog of ``n`` scenarios for ``seed`` into ``out_dir`` (module
    doc). ``real_dir``: the real motorways (None: none used). Raises ``CatalogError`` if
    the written catalog does not load, ``RuntimeError`` if netconvert fails."""
    cfg = cfg or StressConfig()
    out = Path(out_dir).resolve()
    _clean(out)
    real = {r.name: r for r in real_nets(real_dir)}
    plans = plan_scenarios(cfg, seed, n, tuple(sorted(real)))
    scenarios = [_build(p, out, real, cfg) for p in plans]
    tables = []
    for sc in scenarios:
        table = sc.table()
        if len(cfg.controllers) > 1:
            table["sweep"] = {"controller": list(cfg.controllers)}
        tables.append(table)
    (out / CATALOG).write_text(dumps_catalog(_header(command, seed, n, cfg), _defaults(cfg),
                                             tables), encoding="utf-8")
    catalog = load_catalog(out / CATALOG)
    features = measure_catalog(catalog, cfg)
    coverage = Coverage.of(features, cfg)
    manifest = StressManifest(
        generator="suite.stress", hwyeval_version=__version__, command=command, seed=seed,
        n=n, config=dataclasses.asdict(cfg),
        real_nets_dir=str(real_dir) if real else None,
        plans=[dataclasses.asdict(p) | {"name": p.name} for p in plans],
        features=[dataclasses.asdict(f) | {"features": sorted(f.features(cfg))}
                  for f in features],
        coverage=dataclasses.asdict(coverage))
    (out / MANIFEST).write_text(json.dumps(dataclasses.asdict(manifest), indent=1,
                                           allow_nan=True), encoding="utf-8")
    return StressCatalog(out / CATALOG, catalog, tuple(scenarios), tuple(features), coverage)
