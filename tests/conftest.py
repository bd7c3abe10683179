"""Test configuration: the markers (``--strict-markers`` is on, pyproject's addopts) and
the fast lane.

Markers:

* ``sumo``: needs a real libsumo simulation (an integration test);
* ``slow``: takes more than ~1.5 s on a 2-core machine; ``pytest -m "not slow"`` is the
  fast lane (under 3 minutes), plain ``pytest`` runs everything;
* ``browser``: needs headless Chromium.

A test file marks its own slow tests (``pytestmark`` or ``@pytest.mark.slow``);
:data:`SLOW_TESTS` adds the ones measured slow with ``pytest --durations=0`` (setup + call
+ teardown > 1.5 s, all parametrisations summed) that their files do not mark.
Re-measure after adding heavy tests.
"""

from __future__ import annotations

import pytest

MARKERS = {
    "sumo": "needs a real libsumo simulation (integration test)",
    "slow": "takes more than ~1.5 s (deselect with -m 'not slow': the fast lane)",
    "browser": "needs headless Chromium",
    "serial": "races processes and signals against the clock: the test command runs these "
              "alone, after the two parallel lanes",
}

# Test node ids relative to tests/, without parameters (all parametrisations), measured slow.
SLOW_TESTS = frozenset({
    "test_behaviour_sumo.py::test_a_slower_car_in_the_passing_lane_is_followed",
    "test_bench.py::test_a_real_command_is_timed",
    "test_bench.py::test_the_floor_study_times_real_runs",
    "test_cli_reports.py::test_compare_gate_exit_codes",
    "test_collision_geometry_sumo.py::test_a_collision_only_sumo_reports_is_no_collision",
    "test_compare_kinds.py::test_a_misspelt_metric_in_the_tolerances_exits_2",
    "test_compare_kinds.py::test_the_cli_json_kinds_the_same_night_and_the_default_output",
    "test_early_warmup.py::test_a_resume_with_nothing_to_run_leaves_no_forkserver",
    "test_early_warmup.py::test_an_input_error_leaves_no_forkserver",
    "test_foundation_sumo.py::test_bad_catalog_exits_2_naming_file_scenario_and_key",
    "test_foundation_sumo.py::test_run_exit_code_is_one_when_anything_fails",
    "test_foundation_sumo.py::test_same_seed_same_catalog_gives_identical_results",
    "test_fuzz_records.py::test_report_never_crashes_on_malformed_records",
    "test_history_store.py::test_a_writer_waits_for_the_lock_and_gives_up_with_exit_2",
    "test_history_store.py::test_cli_exit_codes_and_json",
    "test_history_store.py::test_compare_against_the_last_night_of_the_catalog_or_the_last_pass",
    "test_history_store.py::test_two_history_add_processes_at_once_both_land_whole",
    "test_out_lock.py::test_a_second_run_into_the_same_out_exits_2_and_writes_nothing",
    "test_plugins.py::test_entry_point_and_bare_module_plugins_run_to_pass_locally",
    "test_real_motorways_sumo.py::test_free_drives_in_every_through_lane_pass",
    "test_reliability_catalog.py::test_a_stalled_car_close_ahead_of_a_fast_ego_runs_without_an_error",
    "test_reliability_catalog.py::test_the_longest_allowed_name_runs",
    "test_reliability_outdir.py::test_a_report_target_that_is_not_a_file_exits_2",
    "test_reliability_outdir.py::test_out_that_is_or_lies_under_a_file_exits_2_before_writing",
    "test_reliability_outdir.py::test_overwrite_refuses_a_directory_that_is_not_an_hwyeval_output",
    "test_reliability_outdir.py::test_overwrite_reports_exactly_the_new_runs_and_the_exit_code_covers_them",
    "test_reliability_outdir.py::test_resume_after_a_catalog_change_reruns_only_the_changed_scenario",
    "test_reliability_outdir.py::test_resume_refuses_an_output_holding_runs_of_other_scenarios",
    "test_reliability_outdir.py::test_run_into_an_earlier_output_is_refused_and_loses_nothing",
    "test_reliability_reports.py::test_compare_with_a_missing_or_directory_tolerances_exits_2",
    "test_reliability_reports.py::test_compare_with_bad_tolerances_exits_2",
    "test_reliability_reports.py::test_compare_with_nothing_to_compare_exits_2",
    "test_reliability_reports.py::test_report_marks_a_malformed_road_json_as_an_error",
    "test_reliability_reports.py::test_report_marks_a_malformed_run_json_as_an_error",
    "test_reliability_runs.py::test_a_duration_no_run_can_hold_is_refused_at_validation",
    "test_reliability_runs.py::test_a_process_that_hangs_before_its_loop_is_killed_at_its_budget",
    "test_reliability_runs.py::test_every_job_gets_a_finite_budget_and_the_default_ends_a_run",
    "test_reliability_runs.py::test_killed_and_timed_out_runs_carry_their_controller_and_nan_metrics",
    "test_report_browser.py::test_the_failures_list_is_the_first_thing_under_the_header",
    "test_report_browser.py::test_tick_labels_equal_their_gridline_values",
    "test_reports.py::test_html_size_for_a_large_catalog",
    "test_rerun_sumo.py::test_entity_paths_of_a_real_run",
    "test_robustness.py::test_robustness_is_negative_exactly_when_the_verdict_fails",
    "test_search_loop.py::test_resume_after_an_interruption_equals_an_uninterrupted_search",
    "test_search_loop.py::test_tpe_finds_the_planted_region_random_sampling_rarely_does",
    "test_search_sumo.py::test_ctrl_c_then_resume_equals_the_uninterrupted_search",
    "test_search_sumo.py::test_every_trial_is_a_run_directory_the_reports_read",
    "test_search_sumo.py::test_found_toml_replays_with_the_same_status_and_robustness",
    "test_search_sumo.py::test_resume_refuses_other_settings",
    "test_signals.py::test_a_stop_then_resume_gives_the_results_of_one_uninterrupted_run",
    "test_signals.py::test_signal_to_the_parent_leaves_no_process_after_5_s",
    "test_stress.py::test_small_catalog_is_valid_covers_everything_and_is_deterministic",
    "test_sumo_nets.py::test_loads_and_drives_in_libsumo",
    "test_target_ramp.py::test_ipopt_baseline_ramps_the_same_way",
    "test_warmup_coverage.py::test_a_scenario_after_the_preload_loads_no_kernel",
})


def pytest_configure(config: pytest.Config) -> None:
    for name, doc in MARKERS.items():
        config.addinivalue_line("markers", f"{name}: {doc}")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    del config
    for item in items:
        nodeid = item.nodeid.removeprefix("tests/")
        if nodeid.split("[")[0] in SLOW_TESTS:
            item.add_marker(pytest.mark.slow)
