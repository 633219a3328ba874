"""Shared fixtures (the real C3D files, skipped cleanly when absent; the shipped samples) and
the test tiers: each test is marked from the fixtures it uses.

* ``real``: it uses :func:`real_c3d` or :func:`shared_c3d` (the real lab captures);
* ``samples``: it uses :func:`sample_dir` (the shipped synthetic captures, ``sample_c3d/``);
* ``slow``: it is listed in :data:`SLOW` (over about 4 s on the 2-core development machine).

``pytest -m "not slow"`` is the fast tier; ``pytest`` (all tiers) is what CI runs.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_C3D = Path(os.environ.get("MOCAPLIB_SHARED_C3D", REPO.parent / "shared" / "data" / "c3d"))
SAMPLES = REPO / "sample_c3d"


def real_files() -> list[Path]:
    """All real C3D files, sorted; empty when the shared data is absent."""
    if not SHARED_C3D.is_dir():
        return []
    return sorted(SHARED_C3D.rglob("*.c3d"))


@pytest.fixture
def shared_c3d() -> Path:
    """The folder of real C3D files; the test is skipped when it is absent."""
    if not SHARED_C3D.is_dir():
        pytest.skip(f"real C3D files not found at {SHARED_C3D}")
    return SHARED_C3D


@pytest.fixture(scope="session")
def real_c3d():
    """``real_c3d(relative)``: one real file by its path relative to the shared folder; the
    test is skipped when the file is absent."""
    def real_file(relative: str) -> Path:
        path = SHARED_C3D / relative
        if not path.is_file():
            pytest.skip(f"real C3D file not found: {path}")
        return path
    return real_file


@pytest.fixture(scope="session")
def sample_dir() -> Path:
    """The shipped sample captures (``sample_c3d/``); they are part of the repository."""
    assert any(SAMPLES.glob("*.c3d")), f"the shipped samples are missing from {SAMPLES}"
    return SAMPLES


#: Tests that take over about 1.1 s (``pytest --durations=0`` on the 2-core development machine,
#: idle), by file and function name (every parametrisation of it): the fast tier
#: (``-m "not slow"``, under 2 minutes there) leaves them to the full suite.
SLOW = {
    ("test_facade.py", "test_the_package_fit_is_the_fit_command_on_the_real_files"),
    ("test_forward_reference.py", "test_a_lab_walk_sets_its_static_within_the_tolerance"),
    ("test_report.py", "test_capture_figures_drawn_by_two_processes_are_those_drawn_by_one"),
    ("test_report.py", "test_report_in_headless_chromium"),
    ("test_lab_agreement.py", "test_leg_flexion_offsets_agree_with_plug_in_gait"),
    ("test_lab_agreement.py", "test_leg_flexion_offsets_agree_with_plug_in_gait_without_a_static"),
    ("test_filtering.py", "test_automatic_cutoffs_of_the_real_files_are_those_of_the_filter_applied"),
    ("test_filtering.py", "test_automatic_cutoffs_of_the_samples_are_those_of_the_filter_applied"),
    ("test_sessions.py", "test_the_shared_files_with_two_statics_build_without_failure"),
    ("test_synth_samples.py", "test_fitted_angles_meet_the_targets_against_the_independent_body"),
    ("test_synth_samples.py", "test_fitted_angles_that_miss_the_targets_are_no_worse_than_measured"),
    ("test_synth_samples.py", "test_synth_replaces_only_its_own_earlier_output"),
    ("test_synth.py", "test_swing_knee_velocity_has_no_step"),
    ("test_clusters.py", "test_a_cluster_capture_fits_as_well_as_the_anatomical_set"),
    ("test_clusters.py", "test_a_cluster_capture_without_static_fits_as_well_as_the_anatomical_set"),
    ("test_clusters.py", "test_a_cluster_capture_without_static_is_no_worse_than_measured"),
    ("test_clusters.py", "test_the_free_pose_cluster_walk_is_no_worse_than_measured"),
    ("test_clusters.py", "test_the_cluster_dofs_worse_than_the_anatomical_set_are_no_more_than_measured"),
    ("test_clusters.py", "test_synth_to_library_with_clusters"),
    ("test_criteria.py", "test_internal_power_is_computed_for_every_real_entry"),
    ("test_criteria.py", "test_internal_power_is_computed_for_every_entry"),
    ("test_faults.py", "test_a_real_full_disk_during_a_build_keeps_the_old_pair"),
    ("test_faults.py", "test_hostile_names_and_links_in_an_input_folder"),
    ("test_report.py", "test_report_marks_mirror_images_and_counts_coverage_without_them"),
    ("test_retarget.py", "test_self_retargeting_target_on_the_synthetic_walks"),
    ("test_forward_reference.py", "test_each_static_gets_the_offset_of_its_subjects_references"),
    ("test_pipeline.py", "test_one_and_two_jobs_give_the_same_bytes_on_sample_captures"),
    ("test_clusters.py", "test_every_dof_of_a_cluster_capture_within_1_degree_of_the_anatomical_set"),
    ("test_criteria.py", "test_internal_power_of_natural_real_walks_is_in_the_published_range"),
    ("test_criteria.py", "test_internal_power_of_natural_synthetic_walks_is_in_the_published_range"),
    ("test_criteria.py", "test_internal_power_of_natural_real_walks_is_no_lower_than_measured"),
    ("test_criteria.py", "test_internal_power_of_natural_synthetic_walks_is_no_lower_than_measured"),
    ("test_faults.py", "test_oversized_numbers_in_the_sidecar_cost_the_report_nothing"),
    ("test_pipeline.py", "test_several_statics_each_capture_gets_its_subjects"),
    ("test_cycles.py", "test_synthetic_truth_shoulders_give_the_true_velocities"),
    ("test_retarget.py", "test_self_retargeting_target_on_the_real_walks"),
    ("test_retarget.py", "test_most_real_walks_give_a_chosen_cycle_to_retarget"),
    ("test_repairs.py", "test_walking3_swapped_acromions_are_undone_with_its_static"),
    ("test_synth_samples.py", "test_regenerated_samples_are_identical"),
    ("test_sessions.py", "test_a_capture_without_a_complete_cycle_gives_no_entry_and_says_why"),
    ("test_protocols.py", "test_computed_points_are_those_of_their_definition_pair_by_pair"),
    ("test_statures.py", "test_a_shorter_and_a_taller_subject_are_fitted_within_the_targets"),
    ("test_statures.py", "test_a_shorter_and_a_taller_subject_are_fitted_no_worse_than_measured"),
    ("test_statures.py", "test_a_shorter_and_a_taller_subject_get_their_velocities"),
    ("test_statures.py", "test_a_shorter_and_a_taller_subject_get_a_skeleton_of_their_size"),
    ("test_report_motion.py", "test_blending_in_javascript_is_the_control_spaces"),
    ("test_report.py", "test_report_falls_back_without_opengl"),
    ("test_draft.py", "test_a_cluster_set_is_drafted_and_fits"),
    ("test_report.py", "test_envelope_and_planned_captures_from_a_capture_plan"),
    ("test_synth_session.py", "test_one_session_shares_the_placement"),
    ("test_report.py", "test_report_detects_a_crashing_renderer"),
    ("test_report.py", "test_report_command"),
    ("test_forward_reference.py", "test_build_measures_the_offset_and_the_library_records_it"),
    ("test_clusters.py", "test_tracking_offsets_are_measured_on_the_static"),
    ("test_mirror_build.py", "test_the_right_turns_of_a_real_session_gain_left_turns"),
    ("test_clusters.py", "test_a_cluster_capture_has_rigid_plates_and_no_static_only_markers"),
    ("test_cli_fit.py", "test_fit_takes_the_static_that_shows_the_subject"),
    ("test_zero_config.py", "test_a_drafted_protocol_gives_the_shipped_protocols_entry"),
    ("test_zero_config.py", "test_the_drafted_protocols_are_written_beside_the_library_and_recorded"),
    ("test_zero_config.py", "test_a_cluster_set_without_static_builds_with_its_drafted_protocol"),
    ("test_activity.py", "test_a_mixed_take_gives_one_entry_per_activity"),
    ("test_activity.py", "test_a_session_trims_and_picks_the_cycles_of_a_capture"),
    ("test_activity.py", "test_all_cycles_with_qc_waived_never_writes_what_validate_refuses"),
    ("test_activity.py", "test_an_entry_validation_refuses_is_left_out_with_a_warning"),
    ("test_activity.py",
     "test_a_slope_is_measured_left_out_by_default_and_kept_flagged_on_request"),
    ("test_activity.py",
     "test_a_marker_sample_removed_as_an_outlier_keeps_its_cycle_and_is_not_a_gap"),
    ("test_activity.py",
     "test_the_library_and_the_report_say_what_each_capture_was_calibrated_from"),
    ("test_planting.py", "test_query_outputs_have_planted_feet"),
    ("test_planting.py", "test_retargeted_outputs_hold_up"),
    ("test_planting.py", "test_a_loop_steps_from_its_last_frame_to_its_first_as_between_any_two"),
    ("test_planting.py", "test_stances_end_at_the_entries_toe_offs"),
    ("test_planting.py", "test_the_path_follower_plants_its_feet"),
    ("test_legs.py", "test_the_sample_entries_planted_series_are_those_of_the_generic_solve"),
    ("test_dask_batches.py", "test_batches_on_a_local_cluster_give_the_libraries_of_local_jobs"),
    ("test_dask_batches.py", "test_a_batch_runs_with_one_blas_thread"),
    ("test_dask_batches.py", "test_a_capture_that_kills_its_worker_fails_alone_and_its_batch_lands"),
}
#: The marker each fixture gives the tests that use it (directly or through other fixtures).
FIXTURE_MARKERS = {"real_c3d": "real", "shared_c3d": "real", "sample_dir": "samples"}


def pytest_collection_modifyitems(config, items):
    """Mark each test ``real`` / ``samples`` from its fixtures and ``slow`` from :data:`SLOW`;
    a name in :data:`SLOW` that its module no longer defines is an error."""
    for item in items:
        for fixture in set(getattr(item, "fixturenames", ())) & set(FIXTURE_MARKERS):
            item.add_marker(FIXTURE_MARKERS[fixture])
        module = item.module
        key = (Path(module.__file__).name, getattr(item, "originalname", item.name))
        if key in SLOW:
            item.add_marker("slow")
        for file_name, function in SLOW:
            if file_name == key[0] and not hasattr(module, function):
                raise pytest.UsageError(f"tests/conftest.py SLOW names {file_name}::{function}, "
                                        "which does not exist: update SLOW")


def plan_capture(name: str, height: float, folder: Path):
    """The sample plan's capture ``name`` for a subject ``height`` m tall (same seeds and marker
    placement, :meth:`mocaplib.synth.PlannedCapture.for_height`), written into ``folder`` as
    ``<name>_<height>.c3d``. Returns its path and the :class:`~mocaplib.synth.SynthCapture`."""
    from mocaplib.synth.capture import write_capture
    from mocaplib.synth.plan import load_plan

    planned = next(c for c in load_plan(REPO / "protocols" / "paper_plan.toml").captures
                   if c.name == name)
    capture = planned.for_height(height).generate()
    return write_capture(capture, folder, f"{name}_{height:.2f}")[0], capture
