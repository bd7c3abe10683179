"""The default route keeps to the through carriageway: on real OpenStreetMap nets the
longest edge path used to run through ``highway.motorway_link`` edges (an exit and a
re-entry), so ``pos_m`` meant another place; link edges are used only where nothing
else is left, and a route that uses them is named by the CLI."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from suite.road.network import RoadNetwork

ROOT = Path(__file__).resolve().parents[1]
REAL = ROOT.parent / "shared" / "nets_real"
NETS = sorted(REAL.glob("*.net.xml"))

pytestmark = pytest.mark.skipif(not NETS, reason="../shared/nets_real absent")


@pytest.mark.parametrize("net_path", NETS, ids=lambda p: p.stem)
def test_no_link_edge_in_a_default_route(net_path: Path) -> None:
    net = RoadNetwork.load(net_path)
    route = net.default_route()
    assert net.link_edges(route) == []
    assert net.route_length_m(route) > 5000.0  # the carriageway, not a fragment of it
    # the nets do have link edges (ramps), so the rule is exercised
    assert any(net.is_link(e) for e in net.edge_ids())


def test_a_route_through_link_edges_is_warned_about_and_listed(tmp_path: Path) -> None:
    net_path = next(p for p in NETS if RoadNetwork.load(p).link_edges(
        _longest_with_links(RoadNetwork.load(p))))
    net = RoadNetwork.load(net_path)
    route = _longest_with_links(net)
    catalog = tmp_path / "links.toml"
    edges = ", ".join(f'"{e}"' for e in route)
    catalog.write_text('[defaults]\ncontroller = "two_loop"\nduration_s = 5.0\nstep_s = 0.02\n'
                       f'[[scenario]]\nname = "via_ramps"\nnet = "{net_path}"\n'
                       f'route = [{edges}]\nego = {{ lane = 0, pos_m = 100.0, '
                       'speed_mps = 25.0 }\n')
    proc = subprocess.run([sys.executable, "-m", "suite", "list", str(catalog), "-v"],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "via_ramps" in proc.stderr  # the warning names the scenario
    assert all(e in proc.stderr for e in net.link_edges(route))
    assert proc.stdout.count("[link]") == len(net.link_edges(route))


def _longest_with_links(net: RoadNetwork) -> tuple[str, ...]:
    """The longest path when link edges count (what the default route was)."""
    saved = net.is_link
    try:
        net.is_link = lambda edge_id: False  # type: ignore[method-assign]
        return net._longest_path()
    finally:
        net.is_link = saved  # type: ignore[method-assign]
