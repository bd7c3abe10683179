"""The identity of a run (:class:`reports.record.RunInfo`) from its scenario: the
scenario's content hash (what ``hwyeval run --resume`` compares) and the split set-up
digests of :mod:`reports.identity` (the test, the limits, the system under test) that
``compare`` and the history tell changes apart by."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from reports.identity import (
    CONTENT_KEY,
    CONTROLLER_KEY,
    LIMITS_KEY,
    SUT_KEY,
    TEST_KEY,
    limits_sha256,
    sut_sha256,
    test_sha256,
)
from reports.metrics.criteria import Criteria
from reports.record import EgoBox, RunInfo
from suite import __version__
from suite.catalog import Scenario

if TYPE_CHECKING:  # the plant's module imports numba; the parent process only builds jobs
    from controllers.plant.vehicle_model import VehicleParams

__all__ = ["CONTENT_KEY", "UNHASHED_FIELDS", "ego_box", "file_sha256", "scenario_content_sha256",
           "scenario_info", "scenario_setup_hashes", "scenario_tracks_path"]

# Fields of Scenario.as_dict() that say where things are or how long we may wait, not
# what is simulated (labels: the groups it is reported in): they do not change a
# run's result, so they are not hashed.
UNHASHED_FIELDS = ("catalog_path", "net_path", "timeout_s", "labels")
_CHUNK_BYTES = 1 << 20


def file_sha256(path: Path) -> str:
    """SHA-256 of a file's bytes (hex). Raises OSError if it cannot be read."""
    digest = hashlib.sha256()
    with Path(path).open("rb") as fh:
        while chunk := fh.read(_CHUNK_BYTES):
            digest.update(chunk)
    return digest.hexdigest()


# (resolved path, size, mtime_ns) -> SHA-256: a worker process hashes each net once
_FILE_HASHES: dict[tuple[Path, int, int], str] = {}


def _cached_sha256(path: Path) -> str:
    """:func:`file_sha256`, remembered per file state; '' when it cannot be read (the
    run then fails loading it and says why)."""
    try:
        st = Path(path).stat()
        key = (Path(path).resolve(), st.st_size, st.st_mtime_ns)
        if key not in _FILE_HASHES:
            _FILE_HASHES[key] = file_sha256(path)
        return _FILE_HASHES[key]
    except OSError:
        return ""


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


def scenario_setup_hashes(scenario: Scenario, controller_params: Mapping[str, Any] | None,
                          controller_code: str) -> dict[str, str]:
    """The three set-up digests of a run of ``scenario`` (:mod:`reports.identity`): the
    test (the net's and tracks' bytes read here, once per file state), the limits in
    force (the metrics' defaults with the catalog's overrides) and the system under test
    (controller name, its resolved parameters, or its catalog options when it was not
    built, and ``controller_code``)."""
    tracks = scenario_tracks_path(scenario)
    spec = {k: v for k, v in scenario.as_dict().items() if k not in UNHASHED_FIELDS}
    params = dict(controller_params) if controller_params else \
        scenario.controller.options_dict()
    return {
        TEST_KEY: test_sha256(spec, _cached_sha256(scenario.net_path),
                              _cached_sha256(tracks) if tracks is not None else None),
        LIMITS_KEY: limits_sha256(Criteria.from_overrides(dict(scenario.criteria)).as_dict()),
        SUT_KEY: sut_sha256(scenario.controller.name, params, controller_code),
    }


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
    into ``scenario_spec`` under :data:`CONTENT_KEY`, each non-empty ``identity``
    hash (:mod:`suite.run.code_identity`: hwyeval's code, the controller's code) under
    its key, and the set-up digests of :func:`scenario_setup_hashes` under theirs."""
    spec = scenario.as_dict()
    if content_sha256:
        spec[CONTENT_KEY] = content_sha256
    spec.update({k: v for k, v in (identity or {}).items() if v})
    spec.update(scenario_setup_hashes(scenario, controller_params,
                                      str((identity or {}).get(CONTROLLER_KEY, ""))))
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
