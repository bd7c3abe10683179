"""docs/catalog.md: every scenario key the loader accepts is documented, and every
```toml example block is a catalog that loads."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from suite.catalog import load_catalog
from suite.catalog.keys import DEFAULT_KEYS, OPTIONAL_SUBKEYS, SCENARIO_KEYS
from suite.catalog.tracks import Track, TrackSet, write_tracks

DOC = Path(__file__).resolve().parents[1] / "docs" / "catalog.md"
_BLOCK = re.compile(r"^```toml\n(.*?)^```", re.S | re.M)


def _blocks() -> list[str]:
    return _BLOCK.findall(DOC.read_text(encoding="utf-8"))


def _write_tracks_named_in(doc: dict[str, object], folder: Path) -> None:
    """A small valid tracks file (one car on straight_3lane's lane 0, 10 s) for every
    ``replay.tracks`` the example names."""
    scenarios = doc.get("scenario", [])
    assert isinstance(scenarios, list)
    for sc in scenarios:
        replay = sc.get("replay") if isinstance(sc, dict) else None
        if not isinstance(replay, dict):
            continue
        t = np.linspace(0.0, 10.0, 101)
        car = Track("rec_1", "car", 4.5, 1.8, t, 150.0 + 20.0 * t, np.full_like(t, -1.6),
                    np.zeros_like(t), np.full_like(t, 20.0))
        write_tracks(folder / str(replay["tracks"]), TrackSet((car,), 0.1))


def test_every_scenario_key_is_documented() -> None:
    text = DOC.read_text(encoding="utf-8")
    for key in (*SCENARIO_KEYS, *DEFAULT_KEYS):
        assert f"| `{key}` |" in text, key
    for table, subkeys in OPTIONAL_SUBKEYS.items():
        for sub in subkeys:
            assert f"`{sub}`" in text, f"{table}.{sub}"


def test_the_doc_has_examples() -> None:
    assert len(_blocks()) >= 8


@pytest.mark.parametrize("index", range(len(_blocks())))
def test_example_block_loads(index: int, tmp_path: Path) -> None:
    text = _blocks()[index]
    _write_tracks_named_in(tomllib.loads(text), tmp_path)
    path = tmp_path / f"example{index}.toml"
    path.write_text(text, encoding="utf-8")
    catalog = load_catalog(path)
    assert len(catalog.scenarios) >= 1


def test_sweep_example_expands_to_the_documented_names(tmp_path: Path) -> None:
    text = next(b for b in _blocks() if 'name = "s3_stall"' in b)
    path = tmp_path / "sweep.toml"
    path.write_text(text, encoding="utf-8")
    names = [s.name for s in load_catalog(path).scenarios]
    assert len(names) == 8
    assert names[0] == "s3_stall__pos300__vph0__costj1"
    assert names[-1] == "s3_stall__pos500__vph2000__costj3"


def test_criteria_example_merges_name_by_name(tmp_path: Path) -> None:
    text = next(b for b in _blocks() if 'name = "tight_gap_allowed"' in b)
    path = tmp_path / "criteria.toml"
    path.write_text(text, encoding="utf-8")
    (scenario,) = load_catalog(path).scenarios
    assert dict(scenario.criteria) == {"max_abs_lat_acc_mps2": 3.0, "min_gap_m": "off",
                                       "min_ttc_s": 1.5}
