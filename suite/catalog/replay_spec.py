"""The spec of recorded traffic (:class:`ReplaySpec`, :mod:`suite.catalog.specs`): the
tracks file, replay or reactive mode, and what the recorded vehicles may do."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

from suite.catalog import rules
from suite.catalog.frozen import FrozenMap
from suite.catalog.rules import Rule
from suite.catalog.tracks import TRACK_ID_PREFIX

REPLAY_MODES = ("replay", "reactive")


# Lane changes of a reactive (handed-over) recorded vehicle -> SUMO lane-change mode:
# none at all, only those its route needs (where a lane ends), or SUMO's default set.
REPLAY_LANE_CHANGES: Mapping[str, int] = FrozenMap({"none": 0, "strategic": 1, "all": 1621})


def _choice(options: tuple[str, ...]) -> Rule:
    what = f"one of {list(options)}"

    def check(v: Any) -> str | None:
        return None if isinstance(v, str) and v in options else what

    return check


def _tracks_name(v: Any) -> str | None:
    problem = rules.nameable_path(v)
    if not isinstance(v, str) or not v:
        return "a tracks file path (Parquet, suite.catalog.tracks), relative to the catalog"
    return problem


def _ego_track_id(v: Any) -> str | None:
    """None (no recorded ego), or a track id as the tracks file has them."""
    if v is None or (isinstance(v, str) and v.startswith(TRACK_ID_PREFIX)
                     and len(v) > len(TRACK_ID_PREFIX)):
        return None
    return (f"the id of the recorded ego's track in the tracks file "
            f"('{TRACK_ID_PREFIX}<id in the recording>')")


@dataclass(frozen=True)
class ReplaySpec:
    """Recorded traffic around the ego (:mod:`suite.world.replay`, docs/replay.md).

    ``tracks``: the tracks file (:mod:`suite.catalog.tracks`) as the catalog names it,
    relative to the catalog file (or absolute); ``tracks_path`` its resolved path (set by
    the loader; ``None`` until then). ``mode``: ``"replay"`` (every recorded vehicle
    follows its recording, blind to the ego) or ``"reactive"`` (a recorded vehicle hands
    over to SUMO's car-following driver once its time gap behind the ego, gap / its speed
    [s], is below ``handover_time_gap_s`` [s] (> 0) with the ego in its lane or about to
    be, or whenever it is behind the ego in the ego's lane). ``lane_changes``: what a
    handed-over vehicle may change lanes for: ``"none"``, ``"strategic"`` (only to stay
    on its route) or ``"all"`` (SUMO's default lane-change model).

    ``ego_track``: the id of the ego's own recorded track in the tracks file (None: the
    recording has no recorded ego). That track is never replayed as traffic (it would
    sit on the ego); the controller ``recorded`` drives the ego along it. The loader
    checks it exists, has two samples or more and starts at run time 0
    (:func:`suite.catalog.tracks.ego_track_problem`)."""

    tracks: str
    mode: str = "replay"
    handover_time_gap_s: float = 1.0
    lane_changes: str = "strategic"
    tracks_path: Path | None = None
    ego_track: str | None = None

    _RULES: ClassVar[dict[str, Rule]] = {
        "tracks": _tracks_name, "mode": _choice(REPLAY_MODES),
        "handover_time_gap_s": rules.num(0.0, strict=True),
        "lane_changes": _choice(tuple(REPLAY_LANE_CHANGES)),
        "ego_track": _ego_track_id,
    }
    _REQUIRED: ClassVar[tuple[str, ...]] = ("tracks",)

    def __post_init__(self) -> None:
        rules.check_fields(self)
        rules.as_float(self, "handover_time_gap_s")
        if self.tracks_path is not None:
            object.__setattr__(self, "tracks_path", Path(self.tracks_path))

    @property
    def reactive(self) -> bool:
        return self.mode == "reactive"

    @property
    def lane_change_mode(self) -> int:
        """SUMO's lane-change mode of a handed-over vehicle (``REPLAY_LANE_CHANGES``)."""
        return int(REPLAY_LANE_CHANGES[self.lane_changes])

    def as_dict(self) -> dict[str, Any]:
        """The catalog's keys (``tracks_path`` is machine-specific, as ``net_path``;
        ``ego_track`` only when set, so that a scenario without a recorded ego keeps the
        dict, and the identity, it had)."""
        out: dict[str, Any] = {"tracks": self.tracks, "mode": self.mode,
                               "handover_time_gap_s": self.handover_time_gap_s,
                               "lane_changes": self.lane_changes}
        if self.ego_track is not None:
            out["ego_track"] = self.ego_track
        return out
