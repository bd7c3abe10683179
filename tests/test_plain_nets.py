"""tests/plain_nets.py: a plain-XML net is converted once per session, and a second call
writes it where netconvert would have, naming its own directory."""

from __future__ import annotations

from pathlib import Path

from suite.road.network import RoadNetwork
from tests.plain_nets import PlainNet

NODES = '<nodes>\n  <node id="a" x="0" y="0"/>\n  <node id="b" x="400" y="0"/>\n</nodes>\n'
EDGES = '<edges>\n  <edge id="e0" from="a" to="b" numLanes="2" speed="30"/>\n</edges>\n'


def test_the_same_inputs_convert_once_and_land_in_each_directory(
        tmp_path: Path, plain_net: PlainNet) -> None:
    first = plain_net(tmp_path / "one", "line", NODES, EDGES)
    again = plain_net(tmp_path / "two", "line", NODES, EDGES)
    assert (first.parent, again.parent) == (tmp_path / "one", tmp_path / "two")
    assert (tmp_path / "two" / "line.nod.xml").read_text() == NODES
    text = again.read_text()
    assert str(tmp_path / "two" / "line.nod.xml") in text and str(tmp_path / "one") not in text
    assert text == first.read_text().replace(str(tmp_path / "one"), str(tmp_path / "two"))
    net = RoadNetwork.load(again)
    assert list(net.default_route()) == ["e0"] and net.lane_count("e0") == 2
