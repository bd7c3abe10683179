"""The identity of a run (:class:`reports.record.RunInfo`) from its scenario, and the
scenario's content hash (what ``hwyeval run --resume`` compares)."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from reports.record import EgoBox, RunInfo
from suite import __version__
from suite.catalog import Scenario

if TYPE_CHECKING:  # the plant's module imports numba; the parent process only builds jobs
    from controllers.plant.vehicle_model import VehicleParams

CONTENT_KEY = "content_sha256"  # key of RunInfo.scenario_spec holding the content hash
# Fields of Scenario.as_dict() that say where things are or how long we may wait, not
# what is simulated: they do not change a run's result, so they are not hashed.
UNHASHED_FIELDS = ("catalog_path", "net_path", "timeout_s")
_CHUNK_BYTES = 1 << 20


def file_sha256(path: Path) -> str:
    """SHA-256 of a file's bytes (hex). Raises OSError if it cannot be read."""
    digest = hashlib.sha256()
    with Path(path).open("rb") as fh:
        while chunk := fh.read(_CHUNK_BYTES):
            digest.update(chunk)
    return digest.hexdigest()


def scenario_tracks_path(scenario: Scenario) -> Path | None:
    """The resolved tracks file a scenario replays (None without ``replay``)."""
    replay = scenario.replay
    return replay.tracks_path if replay is not None else None


def scenario_content_sha256(scenario: Scenario, net_sha256: str | None = None,
                            tracks_sha256: str | None = None) -> str:
    """SHA-256 (hex) of everything a run of ``scenario`` depends on: every field of the
    resolved scenario but its paths and wall-clock budget (:data:`UNHASHED_FIELDS`), and
    the bytes of its network file (``net_sha256`` when already known) and, with a
    ``replay``, of its tracks file (``tracks_sha256`` when already known). Two scenarios
    with the same hash simulate the same thing with the same hwyeval version."""
    spec = {k: v for k, v in scenario.as_dict().items() if k not in UNHASHED_FIELDS}
    net = net_sha256 if net_sha256 is not None else file_sha256(scenario.net_path)
    content: dict[str, Any] = {"scenario": spec, "net_sha256": net}
    tracks = scenario_tracks_path(scenario)
    if tracks is not None:
        # the recording is part of the scenario: an edited tracks file is another one
        content["tracks_sha256"] = tracks_sha256 if tracks_sha256 is not None \
            else file_sha256(tracks)
    text = json.dumps(content, sort_keys=True, separators=(",", ":"), allow_nan=True,
                      default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def ego_box(vehicle: VehicleParams) -> EgoBox:
    return EgoBox(length_m=vehicle.length_m, width_m=vehicle.width_m,
                  cg_to_front_bumper_m=vehicle.cg_to_front_bumper_m,
                  cg_to_box_centre_m=vehicle.cg_to_box_centre_m,
                  cg_to_rear_axle_m=vehicle.cg_to_rear_axle_m)


def scenario_info(scenario: Scenario, catalog_name: str, vehicle: VehicleParams,
                  controller_params: Mapping[str, Any] | None = None,
                  content_sha256: str = "", identity: Mapping[str, str] | None = None
                  ) -> RunInfo:
    """Everything about the run known before it starts (controller parameters once
    built); ``content_sha256`` (:func:`scenario_content_sha256`, '' if unknown) goes
    into ``scenario_spec`` under :data:`CONTENT_KEY`, and each non-empty ``identity``
    hash (:mod:`suite.run.code_identity`: the code's, the plug-in controller's) under
    its key."""
    spec = scenario.as_dict()
    if content_sha256:
        spec[CONTENT_KEY] = content_sha256
    spec.update({k: v for k, v in (identity or {}).items() if v})
    return RunInfo(
        scenario=scenario.name, family=scenario.family, controller=scenario.controller.name,
        catalog=str(scenario.catalog_path), catalog_name=catalog_name, seed=int(scenario.seed),
        net=str(scenario.net_path), net_name=scenario.net, duration_s=float(scenario.duration_s),
        step_s=float(scenario.step_s), target_speed_mps=float(scenario.ego.target_speed_mps),
        allow_shoulder=bool(scenario.allow_shoulder), ego=ego_box(vehicle),
        controller_options=scenario.controller.options_dict(),
        controller_params=dict(controller_params or {}),
        criteria={k: (v if isinstance(v, str) else float(v))  # "off" stays "off"
                  for k, v in scenario.criteria.items()},
        scenario_spec=spec, record_radius_m=float(scenario.record_radius_m),
        hwyeval_version=__version__, friction=float(scenario.friction))
