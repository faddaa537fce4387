"""Shared test configuration: the slow tier and the verification-manual recorder.

Slow tests
    ``make test-fast`` runs ``pytest -m "not slow"``. The tests listed in ``SLOW`` below were
    measured (``pytest -n 2 --dist loadfile --durations=0``) to take seconds each; they are marked
    ``slow`` here rather than by decorators so the list is in one place and is re-measured as one.
    Every test still runs in the full ``make test``.

Order of the files
    ``make test`` hands whole files to two xdist workers (``--dist loadfile``), each taking the next
    file when it finishes one. A worker that starts a long file last runs alone while the other
    idles, so the files listed in ``HEAVY_FIRST`` (the most expensive, measured) go first and the
    many short files fill the end; xdist's own reordering (by the number of tests in a file, which
    puts a costly file of three tests near the end) is switched off for that.

Verification records
    Tests marked ``vv`` take the ``vv`` fixture and call ``vv.record(...)`` with the reference
    value and the value they computed. Each call writes one JSON file to ``docs/_generated/vv/``
    (``RPUD_VV_DIR`` overrides the folder); the documentation's Verification manual renders one
    page per file. One file per check, named by the check, so parallel xdist workers never write
    the same file.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
VV_DIR = Path(os.environ.get("RPUD_VV_DIR", ROOT / "docs" / "_generated" / "vv"))

# Measured slow: setup + call + teardown over 0.5 s in
# `pytest -n 2 --dist loadfile --durations=0` (a test id prefix: a whole file when every test of it
# is slow, else a test function, or one parametrised case). Re-measure the same way when tests change.
SLOW: tuple[str, ...] = (
    "tests/test_api.py::test_harmonic_results",
    "tests/test_api.py::test_plot_functions_draw_on_the_callers_axes",
    "tests/test_axisym_reference.py::test_3d_default_mesh_against_the_reference",
    "tests/test_bolt.py::test_bolt_shift_of_the_working_resonance_within_the_1d_bounds",
    "tests/test_bolt.py::test_bolt_tension_equals_the_stack_compression",
    "tests/test_bolt.py::test_bolt_is_bonded_at_both_ends_and_free_along_the_rings",
    "tests/test_bolt.py::test_threaded_bolt_is_bonded_over_its_engagement_only",
    "tests/test_bolt.py::test_threaded_shank_carries_the_preload_without_shear",
    "tests/test_bolt.py::test_threaded_bolt_shift_within_the_1d_bounds",
    "tests/test_bolt.py::test_documented_bolt_shift_is_the_article_drills",
    "tests/test_bolt.py::test_documented_joint_shift_is_the_bolted_examples",
    "tests/test_bolted_design.py::test_bolted_example_is_matched_and_drives_the_rotor",
    "tests/test_bolted_design.py::test_default_drill_is_the_threaded_bolted_design_and_drives_the_rotor",
    "tests/test_bolted_design.py::test_default_horn_with_the_bolt_absorbs_the_teeth_torsion",
    "tests/test_bolted_design.py::test_default_horn_back_leaves_the_driving_mode_below_the_drive",
    "tests/test_bvd.py::test_harmonic_command_takes_its_losses_from_a_measured_sweep",
    "tests/test_drilling_compliant.py::test_zero_load_is_the_compliant_free_run",
    "tests/test_drilling_compliant.py::test_window_energy_balance_closes",
    "tests/test_drilling_compliant.py::test_heavy_horn_stiff_contacts_rigid_tool_give_the_kinematic_drilling_model",
    "tests/test_drilling_compliant.py::test_sweep_is_reproducible_and_carries_the_model_status",
    "tests/test_drilling_compliant.py::test_cli_fem_horn_refuses_bad_input_before_the_fe_build",
    "tests/test_drilling_compliant.py::test_pipeline_stage_drills_on_the_fe_horn_beside_the_kinematic_comparison",
    "tests/test_preload_errors.py::test_two_level_estimate_bounds_the_true_error_of_the_window_and_the_heat",
    "tests/test_preload_window.py",
    "tests/test_thermal.py::test_heat_is_input_minus_delivered_power",
    "tests/test_thermal.py::test_lumped_body_of_the_stack_from_its_materials",
    "tests/test_thermal.py::test_lumped_body_of_a_sector_is_the_whole_drill",
    "tests/test_axisym_reference.py::test_default_design_bending_and_torsion_references_converge",
    "tests/test_axisym_reference.py::test_reference_converges_at_order_4_to_the_independent_values",
    "tests/test_axisym_reference.py::test_sandwich_bending_and_torsion_harmonics_against_the_3d_toolkit",
    "tests/test_axisym_reference.py::test_sandwich_lossless_admittance_vanishes_at_the_anti_resonance",
    "tests/test_axisym_reference.py::test_sandwich_reference_converges",
    "tests/test_axisym_reference.py::test_sandwich_3d_against_the_reference",
    "tests/test_cad.py::test_declared_lengths_morph_like_the_parametric_lengths",
    "tests/test_cad.py::test_export_reads_back_with_the_parametric_layout",
    "tests/test_cad.py::test_round_trip_mesh_structure",
    "tests/test_cad.py::test_round_trip_working_mode_at_the_default_mesh",
    "tests/test_cli_fuzz.py::test_design_files_are_refused_cleanly",
    "tests/test_cli_fuzz.py::test_geometry_cli_refuses_cleanly",
    "tests/test_cli_fuzz.py::test_harmonic_cli_refuses_cleanly",
    "tests/test_cli_fuzz.py::test_modal_cli_refuses_cleanly",
    "tests/test_cli_fuzz.py::test_results_cli_refuses_cleanly",
    "tests/test_common.py",
    "tests/test_compliant_engine.py::test_kernel_reproduces_the_python_reference",
    "tests/test_compliant_engine.py::test_window_energy_balance_closes",
    "tests/test_compliant_engine.py::test_window_statistics_count_the_reference_contacts",
    "tests/test_contact_fe.py",
    "tests/test_contact_loop.py",
    "tests/test_stage_compliant.py::test_truncated_horn_is_a_fresh_horn_at_the_lower_cutoff",
    "tests/test_stage_compliant.py::test_stage_chooses_the_cutoff_from_the_contact_time",
    "tests/test_stage_compliant.py::test_compliant_model_cannot_reach_the_article_rate",
    "tests/test_cyclic.py::test_command_line_rules_meet_the_targets_on_the_design_without_slots",
    "tests/test_cyclic.py::test_command_line_solves_the_default_design_by_harmonics",
    "tests/test_cyclic.py::test_harmonics_equal_the_whole_drill",
    "tests/test_cyclic.py::test_replicated_mesh_closes",
    "tests/test_cyclic.py::test_sector_facet_sets_are_the_whole_drills",
    "tests/test_discretisation_error.py",
    "tests/test_doctests.py::test_examples_run[fem.assembly]",
    "tests/test_doctests.py::test_examples_run[fem.harmonic]",
    "tests/test_doctests.py::test_examples_run[fem.modal]",
    "tests/test_doctests.py::test_examples_run[impact.model]",
    "tests/test_doctests.py::test_examples_run[impact.stats]",
    "tests/test_doctests.py::test_examples_run[geometry]",
    "tests/test_entry_points.py::test_installed_command_runs_like_python_m[rpud-modal---modes=abc]",
    "tests/test_entry_points.py::test_installed_command_runs_like_python_m[rpud-harmonic---voltage=inf]",
    "tests/test_error_cli.py",
    "tests/test_examples.py",
    "tests/test_examples_studies.py",
    "tests/test_explore_hostile.py::test_bad_resume_record_is_refused[list]",
    "tests/test_explore_hostile.py::test_fuzzed_study_files_are_refused",
    "tests/test_explore_hostile.py::test_interrupt_is_one_line",
    "tests/test_explore_hostile.py::test_long_study_is_refused_with_its_estimate[data0]",
    "tests/test_explore_hostile.py::test_long_study_is_refused_with_its_estimate[data1]",
    "tests/test_explore_hostile.py::test_normal_run_is_silent_on_stderr",
    "tests/test_explore_hostile.py::test_silent_scheduler_ends_within_the_timeout",
    "tests/test_explore_hostile.py::test_valid_and_foreign_records_resume_without_a_cluster",
    "tests/test_facets.py::test_swept_flange_is_inverted_exactly",
    "tests/test_explore.py",
    "tests/test_rotor_study.py::test_study_rotor_row_is_the_rotor_stage",
    "tests/test_fem_assembly.py::test_solver_backends_agree_real_and_complex",
    "tests/test_fem_convergence.py",
    "tests/test_fem_eigen.py::test_block_modal_equals_arpack",
    "tests/test_fem_eigen.py::test_block_modal_rigid_modes",
    "tests/test_fem_eigen.py::test_clamped_factor_reuse_and_choices",
    "tests/test_fem_eigen.py::test_joint_open_circuit_runs_alone_and_equals_seeded",
    "tests/test_fem_eigen.py::test_matching_reuse_gives_identical_results",
    "tests/test_fem_eigen.py::test_matching_warm_start_same_modes_fewer_solves",
    "tests/test_fem_harmonic.py::test_a_basis_that_cannot_represent_the_band_is_refused",
    "tests/test_fem_harmonic.py::test_admittance_peak_and_dip_at_resonance_and_antiresonance",
    "tests/test_fem_harmonic.py::test_anti_resonance_with_dielectric_loss_equals_direct",
    "tests/test_fem_harmonic.py::test_harmonic_cli_drives_the_coupled_mode_and_says_what_it_drives",
    "tests/test_fem_harmonic.py::test_modal_ring_up_equals_full_newmark",
    "tests/test_fem_harmonic.py::test_modal_superposition_equals_direct_solution",
    "tests/test_fem_harmonic.py::test_modal_sweep_equals_direct_across_the_whole_band",
    "tests/test_fem_harmonic.py::test_modal_sweep_over_three_resonances_equals_direct",
    "tests/test_fem_harmonic.py::test_peak_amplitude_scales_with_q_and_is_unbounded_without_loss",
    "tests/test_fem_harmonic.py::test_ring_up_settles_on_the_harmonic_amplitude",
    "tests/test_fem_harmonic.py::test_static_admittance_is_parallel_plate_capacitance",
    "tests/test_fem_harmonic.py::test_tip_damper_in_modal_basis_equals_direct_solution",
    "tests/test_fem_matching.py",
    "tests/test_fem_modal.py::test_steel_rod_longitudinal_and_torsional",
    "tests/test_fem_modeshape.py::test_free_bar_first_longitudinal_and_torsional_modes",
    "tests/test_fem_reduced.py::test_steady_tip_and_charge_equal_the_direct_working_point[None-0.995]",
    "tests/test_geometry_cli.py::test_gmsh_time_limit_ends_in_one_line",
    "tests/test_geometry_cli.py::test_write_default_then_build_everything",
    "tests/test_geometry_design.py::test_1d_reference_validity_slender_and_stubby_rods",
    "tests/test_geometry_mesh.py::test_default_mesh_size_order_and_volumes",
    "tests/test_geometry_mesh.py::test_rpud_variants",
    "tests/test_geometry_mesh.py::test_same_design_same_mesh",
    "tests/test_hostile_materials_cad.py::test_fuzz_every_field_out_of_range_is_refused_naming_it",
    "tests/test_hostile_materials_cad.py::test_fuzz_material_files_end_in_one_line",
    "tests/test_hostile_options.py::test_weightless_free_mass_runs_in_bounded_time",
    "tests/test_impact.py::test_cross_check_against_solve_ivp[kernel-changes0]",
    "tests/test_impact.py::test_cross_check_against_solve_ivp[python-changes0]",
    "tests/test_impact_coupled.py::test_energy_balance_closes_over_0p1_s",
    "tests/test_impact_coupled.py::test_fem_horn_cli_end_to_end_on_a_coarse_drill",
    "tests/test_impact_coupled.py::test_no_impacts_tip_equals_the_harmonic_working_point",
    "tests/test_impact_coupled.py::test_random_compliant_cases_finish_in_bounded_time",
    "tests/test_impact_coupled.py::test_random_coupled_cases_finish_and_never_interpenetrate",
    "tests/test_impact_kernel.py::test_kernel_equals_python_event_by_event",
    "tests/test_impact_stats.py::test_cli_bad_input_exit_2_one_line_no_file[args8-gap]",
    "tests/test_impact_stats.py::test_cli_statistics_json",
    "tests/test_impact_stats.py::test_cli_sweep_one_mass_writes_json_and_csv",
    "tests/test_layout.py::test_import_graph_is_one_way_and_acyclic",
    "tests/test_sector_paths.py::test_own_design_gets_its_estimated_error_on_the_sector",
    "tests/test_sector_paths.py::test_energy_shares_of_the_swept_whole_drill_are_the_sectors",
    "tests/test_sector_paths.py::test_sector_path_meets_the_axisymmetric_reference_and_its_error_covers_it",
    "tests/test_sector_system.py::test_sector_modes_are_the_whole_drills_axisymmetric_modes",
    "tests/test_sector_system.py::test_working_point_equals_the_whole_drill",
    "tests/test_sector_system.py::test_capacitances_equal_the_whole_drill",
    "tests/test_sector_system.py::test_direct_sweep_and_ring_up_equal_the_whole_drill",
    "tests/test_sector_system.py::test_reduced_transducer_equals_the_whole_drills_working_mode",
    "tests/test_sector_system.py::test_clamped_modes_equal_the_whole_drill",
    "tests/test_sector_system.py::test_sector_system_refuses_what_it_cannot_restrict",
    "tests/test_mesh_grading.py",
    "tests/test_no_history.py",
    "tests/test_notches.py::test_grading_puts_the_edge_size_along_the_apex_lines",
    "tests/test_notches.py::test_notch_edges_counted_and_measured[left-handed",
    "tests/test_notches.py::test_notch_edges_counted_and_measured[rectangular",
    "tests/test_provenance.py::test_a_command_writes_the_record_with_its_command_line",
    "tests/test_report_html.py::test_report_html_in_a_real_browser",
    "tests/test_report_html.py::test_the_browser_check_sees_a_broken_page",
    "tests/test_results_pipeline.py",
    "tests/test_results_sector_pipeline.py",
    "tests/test_default_design_answers.py",
    "tests/test_revolve.py::test_bending_and_torsion_against_the_converged_harmonics",
    "tests/test_revolve.py::test_matching_on_the_swept_mesh_agrees_with_a_fresh_mesh_of_the_tuned_design",
    "tests/test_revolve.py::test_swept_mesh_volumes_groups_and_quality",
    "tests/test_revolve.py::test_working_mode_within_the_target_of_the_converged_answer",
    "tests/test_signals.py::test_geometry_cli_while_gmsh_meshes",
    "tests/test_signals.py::test_later_pipeline_stages_end_cleanly",
    "tests/test_signals.py::test_pipeline_stages_end_cleanly",
    "tests/test_stress.py::test_cli_stress_table_states_a_two_mesh_error",
    "tests/test_stress.py::test_coarse_table_is_the_working_point_at_the_drive_voltage",
    "tests/test_stress.py::test_free_free_bar_first_longitudinal_mode_against_1d_closed_form",
    "tests/test_stress.py::test_preload_in_a_langevin_stack_carries_p_through_the_ceramic",
    "tests/test_stress.py::test_static_preload_gives_p_over_a_in_the_ceramic",
    "tests/test_stress.py::test_table_text_json_and_outputs",
    "tests/test_stress_sector.py",
    "tests/test_thin_layers.py::test_50um_layer_acts_as_a_constrained_spring",
    "tests/test_thin_layers.py::test_layered_mesh_matches_free_tetrahedra",
    "tests/test_thin_layers.py::test_layers_between_unlike_neighbours_stay_conformal",
    "tests/test_thin_layers.py::test_sandwich_thickness_mode_converges",
)


HEAVY_FIRST: tuple[str, ...] = (
    "tests/test_default_design_answers.py",
    "tests/test_discretisation_error.py",
    "tests/test_examples_studies.py",
    "tests/test_results_pipeline.py",
    "tests/test_bolt.py",
    "tests/test_bolted_design.py",
    "tests/test_stage_compliant.py",
    "tests/test_fem_matching.py",
    "tests/test_cyclic.py",
    "tests/test_sector_system.py",
    "tests/test_signals.py",
    "tests/test_examples.py",
    "tests/test_sector_paths.py",
    "tests/test_fem_harmonic.py",
    "tests/test_fillets.py",
    "tests/test_fem_eigen.py",
    "tests/test_revolve.py",
    "tests/test_drilling_compliant.py",
    "tests/test_results_sector_pipeline.py",
    "tests/test_cad.py",
    "tests/test_explore.py",
    "tests/test_axisym_reference.py",
    "tests/test_contact_fe.py",
)
"""The files that cost the most (setup + calls summed per file, ``pytest -n 2 --dist loadfile
--durations=0``), most expensive first: they run first (module docstring). Re-measure the same
way, on a quiet machine, when tests change."""


def pytest_configure(config):
    """Keep the collection order (HEAVY_FIRST first) when xdist hands out files."""
    if hasattr(config.option, "loadscopereorder"):
        config.option.loadscopereorder = False


def pytest_collection_modifyitems(config, items):
    """Mark every test whose node id starts with an entry of SLOW as ``slow``, and every test that
    takes the ``vv`` fixture as ``vv`` (so ``pytest -m vv`` regenerates the V&V records); put the
    files of HEAVY_FIRST first, in its order (a stable sort: the order inside a file is kept)."""
    rank = {path: i for i, path in enumerate(HEAVY_FIRST)}
    items[:] = sorted(items, key=lambda item: rank.get(item.nodeid.replace("\\", "/").split("::")[0],
                                                       len(HEAVY_FIRST)))
    for item in items:
        if "vv" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.vv)
        nodeid = item.nodeid.replace("\\", "/")
        if any(nodeid == s or nodeid.startswith(s + "::") or nodeid.startswith(s + "[") for s in SLOW):
            item.add_marker(pytest.mark.slow)


class VVRecorder:
    """Writes verification records: one JSON per check, read by the docs' V&V manual.

    Parameters
    ----------
    folder : pathlib.Path
        Where the records go.
    nodeid : str
        The pytest id of the test that records (printed on the check's page).
    """

    def __init__(self, folder: Path, nodeid: str):
        self.folder = folder
        self.nodeid = nodeid

    def record(self, check_id: str, *, title: str, description: str, reference: str, assumptions: str,
               target: float, computed: float, tolerance: float, unit: str = "",
               tolerance_kind: str = "relative", quantity: str = "") -> dict:
        """Record one check and return its record.

        Parameters
        ----------
        check_id : str
            Short stable identifier, e.g. ``"VV-AX-01"`` (the file name and the page's name).
        title, description, reference, assumptions : str
            The ANSYS Verification Manual sections (Markdown allowed).
        target : float
            The reference value, in ``unit``.
        computed : float
            The toolkit's value, in ``unit``.
        tolerance : float
            The test's acceptance: relative (``|computed/target - 1|``) or absolute
            (``|computed - target|``, in ``unit``), per ``tolerance_kind``.
        unit : str
            Unit of target and computed (empty for dimensionless).
        tolerance_kind : {"relative", "absolute"}
            How ``tolerance`` is applied.
        quantity : str
            What the number is (e.g. "first thickness resonance").

        Returns
        -------
        dict
            The record written, with ``ratio`` (computed/target, None for a zero target) and
            ``passed`` (the test's own criterion).
        """
        if tolerance_kind not in ("relative", "absolute"):
            raise ValueError(f"tolerance_kind must be 'relative' or 'absolute', got {tolerance_kind!r}")
        target, computed = float(target), float(computed)
        ratio = computed / target if target != 0 else None
        if tolerance_kind == "relative":
            deviation = abs(computed / target - 1.0) if target != 0 else math.inf
        else:
            deviation = abs(computed - target)
        rec = {
            "id": check_id, "title": title, "quantity": quantity, "description": description,
            "reference": reference, "assumptions": assumptions, "unit": unit,
            "target": target, "computed": computed, "ratio": ratio,
            "tolerance": float(tolerance), "tolerance_kind": tolerance_kind,
            "deviation": deviation, "passed": bool(deviation <= tolerance), "test": self.nodeid,
        }
        self.folder.mkdir(parents=True, exist_ok=True)
        tmp = self.folder / f".{check_id}.{os.getpid()}.tmp"
        tmp.write_text(json.dumps(rec, indent=1) + "\n")
        os.replace(tmp, self.folder / f"{check_id}.json")    # atomic: a reader never sees half a file
        return rec


@pytest.fixture
def vv(request) -> VVRecorder:
    """The verification recorder of the requesting test (see ``VVRecorder.record``)."""
    return VVRecorder(VV_DIR, request.node.nodeid)
