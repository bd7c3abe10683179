"""Bundled one-directional highway networks for SUMO.

Each bundled net is a single highway carriageway (one driving direction, towards +X at
the start) made of several edges in series joined by priority junctions with straight-
through connections. The plain-XML sources live in :data:`SRC_DIR`
(``<name>.nod.xml`` / ``<name>.edg.xml``); the built ``<name>.net.xml`` files live in
:data:`NET_DIR` and are rebuilt with ``python -m sumo_nets.build``.

Units: lengths, widths and radii in metres, speeds in m/s, angles in degrees unless a
name says ``_rad``. Lane index 0 is the rightmost lane (SUMO convention).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

NET_DIR: Path = Path(__file__).resolve().parent
"""Directory holding the built ``<name>.net.xml`` files."""

SRC_DIR: Path = NET_DIR / "src"
"""Directory holding the plain-XML netconvert sources of each net."""

LANE_WIDTH_M = 3.5
"""Width of every traffic lane in every bundled net (m)."""

SHOULDER_WIDTH_M = 3.0
"""Width of the hard shoulder (lane 0) in nets that have one (m)."""

SPEED_LIMIT_MPS = 33.33
"""Speed limit of every lane in every bundled net (m/s, = 120 km/h)."""

SHOULDER_VCLASSES: tuple[str, ...] = ("emergency", "authority")
"""SUMO vehicle classes allowed on a hard shoulder; all other classes are disallowed."""


@dataclass(frozen=True)
class NetInfo:
    """Description of one bundled net.

    Attributes:
        name: registry key; the net file is ``NET_DIR / f"{name}.net.xml"``.
        description: one-line human description.
        traffic_lanes: number of lanes open to general traffic on every edge.
        has_shoulder: True if each edge has an extra hard-shoulder lane at index 0
            (so lane indices ``1..traffic_lanes`` are the traffic lanes).
        min_curve_radius_m: smallest horizontal curve radius of the road reference line
            (carriageway centre), in metres; ``None`` for a straight road.
        length_m: approximate length of the main route along the reference line (m).
        main_route: edge ids of the main route, upstream to downstream.
    """

    name: str
    description: str
    traffic_lanes: int
    has_shoulder: bool
    min_curve_radius_m: float | None
    length_m: float
    main_route: tuple[str, ...]

    @property
    def total_lanes(self) -> int:
        """Lanes per edge including the shoulder, if any."""
        return self.traffic_lanes + (1 if self.has_shoulder else 0)

    @property
    def first_traffic_lane(self) -> int:
        """Index of the rightmost lane open to general traffic (1 with a shoulder, else 0)."""
        return 1 if self.has_shoulder else 0

    @property
    def path(self) -> Path:
        """Path of the built ``.net.xml`` (may not exist before the first build)."""
        return NET_DIR / f"{self.name}.net.xml"


_ROUTE5: tuple[str, ...] = ("e0", "e1", "e2", "e3", "e4")

BUNDLED: dict[str, NetInfo] = {
    info.name: info
    for info in (
        NetInfo(
            name="straight_2lane",
            description="Straight 2-lane carriageway, 5 x 500 m edges",
            traffic_lanes=2,
            has_shoulder=False,
            min_curve_radius_m=None,
            length_m=2500.0,
            main_route=_ROUTE5,
        ),
        NetInfo(
            name="straight_3lane",
            description="Straight 3-lane carriageway, 5 x 500 m edges",
            traffic_lanes=3,
            has_shoulder=False,
            min_curve_radius_m=None,
            length_m=2500.0,
            main_route=_ROUTE5,
        ),
        NetInfo(
            name="straight_3lane_shoulder",
            description=(
                "Straight 3-lane carriageway plus a 3.0 m hard shoulder (lane 0, "
                "emergency/authority only), 5 x 500 m edges"
            ),
            traffic_lanes=3,
            has_shoulder=True,
            min_curve_radius_m=None,
            length_m=2500.0,
            main_route=_ROUTE5,
        ),
        NetInfo(
            name="curve_2lane",
            description=(
                "2-lane carriageway: 500 m straight, 120 deg left arc of R = 400 m "
                "(2 edges of 60 deg), 500 m + 300 m straight"
            ),
            traffic_lanes=2,
            has_shoulder=False,
            min_curve_radius_m=400.0,
            length_m=2137.7,
            main_route=_ROUTE5,
        ),
        NetInfo(
            name="s_curve_3lane",
            description=(
                "3-lane carriageway S-curve: 500 m straight, 50 deg left arc then "
                "50 deg right arc of R = 500 m, 2 x 400 m straight"
            ),
            traffic_lanes=3,
            has_shoulder=False,
            min_curve_radius_m=500.0,
            length_m=2172.7,
            main_route=_ROUTE5,
        ),
    )
}
"""All bundled nets by name."""


def available() -> list[str]:
    """Names of all bundled nets, sorted."""
    return sorted(BUNDLED)


def net_info(name: str) -> NetInfo:
    """The :class:`NetInfo` of bundled net ``name``; raises ``KeyError`` listing the names."""
    try:
        return BUNDLED[name]
    except KeyError:
        raise KeyError(
            f"unknown bundled net {name!r}; available nets: {', '.join(available())}"
        ) from None


def net_path(name: str) -> Path:
    """Path of the built ``<name>.net.xml``; raises ``KeyError`` listing the known names.

    The path is returned even if the file has not been built yet
    (build it with ``python -m sumo_nets.build --only NAME``).
    """
    return net_info(name).path


def sumo_home() -> str:
    """SUMO home directory of the installed ``eclipse-sumo`` wheel (``sumo.SUMO_HOME``).

    Also sets ``os.environ["SUMO_HOME"]`` to it if that variable is unset, so that SUMO
    binaries and libsumo started afterwards find their data files (XSD schemas, etc.).
    """
    import sumo  # the eclipse-sumo wheel

    home = str(sumo.SUMO_HOME)
    os.environ.setdefault("SUMO_HOME", home)
    return home


__all__ = [
    "BUNDLED",
    "LANE_WIDTH_M",
    "NET_DIR",
    "NetInfo",
    "SHOULDER_VCLASSES",
    "SHOULDER_WIDTH_M",
    "SPEED_LIMIT_MPS",
    "SRC_DIR",
    "available",
    "net_info",
    "net_path",
    "sumo_home",
]
