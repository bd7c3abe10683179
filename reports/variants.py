"""Controller variants: the same controller with different options is its own column.

A catalog that sweeps ``controller.outer.cost = ["J1", "J2", "J3"]`` and
``controller.inner.preview = [true, false]`` runs six variants of ``two_loop``; the
report shows six columns, each labelled by the controller name and the options that
differ among that controller's runs (``two_loop outer.cost=J1 inner.preview=false``),
never one "two_loop" column that averages them. Options the same in every run of a
controller are left out of its labels.

The matrix row of a run is its scenario without what a controller sweep added to its
name (``cmp__cost_j1__preview_true`` → ``cmp``), so that a row holds one case for
every variant.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any

from reports.record import RunInfo


def flat_options(options: Mapping[str, Any], prefix: str = "") -> dict[str, str]:
    """Nested options as dotted key -> compact JSON text (``name`` left out)."""
    out: dict[str, str] = {}
    for key, value in options.items():
        if not prefix and key == "name":
            continue
        path = f"{prefix}{key}"
        if isinstance(value, Mapping):
            out.update(flat_options(value, f"{path}."))
        else:
            out[path] = value if isinstance(value, str) else json.dumps(value)
    return out


Controlled = tuple[str, Mapping[str, Any]]  # (controller name, its catalog options)


def variant_labels(runs: Sequence[Controlled | None]) -> list[str]:
    """A label per run (same order): controller name plus its differing options
    ('?' for a run whose controller is unknown)."""
    by_ctrl: dict[str, list[dict[str, str]]] = {}
    flats: list[dict[str, str] | None] = []
    for run in runs:
        if run is None:
            flats.append(None)
            continue
        flat = flat_options(run[1])
        flats.append(flat)
        by_ctrl.setdefault(run[0], []).append(flat)
    differing: dict[str, list[str]] = {}
    for ctrl, all_flat in by_ctrl.items():
        keys = sorted({k for f in all_flat for k in f})
        differing[ctrl] = [k for k in keys if len({f.get(k, "default") for f in all_flat}) > 1]
    labels = []
    for run, options in zip(runs, flats, strict=True):
        if run is None or options is None:
            labels.append("")
            continue
        parts = [f"{k}={options.get(k, 'default')}" for k in differing[run[0]]]
        labels.append(" ".join([run[0], *parts]))
    return labels


def matrix_row(info: RunInfo | None, scenario: str, controller: str) -> str:
    """The scenario without its controller-sweep name parts (module doc)."""
    if info is not None:
        sweep = info.scenario_spec.get("sweep_values") or {}
        parts = scenario.split("__")
        if isinstance(sweep, Mapping) and sweep and len(parts) == len(sweep) + 1:
            kept = [part for key, part in zip(sweep, parts[1:], strict=True)
                    if not str(key).startswith("controller")]
            return "__".join([parts[0], *kept])
    ctrl = "".join(ch if ch.isalnum() or ch == "_" else "_" for ch in controller.lower())
    kept = [p for p in scenario.split("__") if p != ctrl]
    return "__".join(kept) or scenario
