"""The keys a scenario table may have: which are required, which may come from
``[defaults]``, and the optional keys of its sub-tables (valid sweep targets even when
unset)."""

from __future__ import annotations

__all__ = ["DEFAULT_KEYS", "OPTIONAL_SUBKEYS", "REQUIRED_KEYS", "SCENARIO_KEYS"]

SCENARIO_KEYS = (
    "name", "net", "route", "ego", "stalled", "traffic", "controller", "duration_s", "step_s",
    "seed", "allow_shoulder", "criteria", "record_radius_m", "timeout_s", "friction",
    "ramp_traffic", "actors", "sumo_step_s", "replay", "sweep", "search", "xfail",
    "storyboard", "labels", "openscenario",
)
# ``search`` is read by ``hwyeval search`` (suite.search.space); run and list ignore it.
# ``xfail`` marks one scenario as a known failure: never a default for every scenario.
# ``labels`` names groups a scenario belongs to (a report groups runs by them).
# ``openscenario`` names the OpenSCENARIO template and parameter values a scenario was
# imported from (data: ``hwyeval search`` imports the template per point; run ignores it).
DEFAULT_KEYS = tuple(k for k in SCENARIO_KEYS
                     if k not in ("name", "sweep", "search", "xfail", "openscenario"))
REQUIRED_KEYS = ("name", "net", "ego", "controller", "duration_s", "step_s")
OPTIONAL_SUBKEYS: dict[str, tuple[str, ...]] = {
    "ego": ("lane", "pos_m", "speed_mps", "target_speed_mps"),
    "stalled.*": ("lane", "pos_m", "length_m", "width_m"),
    "traffic": ("vehicles_per_hour", "seed", "speed_mps", "lanes", "speed_factor_dev",
                "lane_speeds_mps"),
    "ramp_traffic.*": ("edge", "vehicles_per_hour", "speed_mps"),
    "actors.*": ("id", "lane", "pos_m", "ahead_of_ego_m", "speed_mps", "length_m", "width_m",
                 "events"),
    "xfail": ("reason", "strict"),
    "replay": ("tracks", "mode", "handover_time_gap_s", "lane_changes", "ego_track"),
}
