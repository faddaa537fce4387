"""The rotor in design studies (results.study, results.explore, results.rotor_stage.study_rotor).

References and tolerances:
- a study point's rotor outputs and their errors against the pipeline's rotor stage
  (results.rotor_stage) called on the same working point, design, rotor data and discretisation-
  error estimate: the same model at the same inputs, so equal to round-off (1e-12 relative: the
  per-volt teeth amplitude times the voltage is one rounding away from the amplitude at the
  voltage; the errors, differences of such values, 1e-9);
- the stall torque with the study's preload and friction against the Coulomb bound
  ``mu F r`` (exact), with the contact radius of the design;
- bad study files: refused on loading, naming the table and key.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from rpud_common import ParameterError
from results.study import study_from_mapping

ROTOR_STUDY = {"study": {"name": "rotor", "stages": ["mesh", "match", "harmonic", "rotor"], "sampling": "list"},
               "settings": {"match": False, "refine": 2.0},
               "points": [{"rotor.preload": 25.0, "rotor.mu": 0.3}, {"rotor.preload": 18.0, "rotor.mu": 0.2}]}


@pytest.mark.parametrize("patch, where", [
    ({"study": {"name": "x", "stages": ["mesh", "rotor"]}}, "study.stages"),
    ({"study": {"name": "x", "stages": ["mesh", "match", "rotor"]}}, "study.stages"),
    ({"study": {"name": "x", "stages": ["mesh", "match", "harmonic"]},
      "parameters": {"rotor.preload": {"values": [20.0]}}}, "parameters.rotor.preload"),
    ({"study": {"name": "x", "stages": ["mesh", "match", "harmonic", "rotor"]},
      "parameters": {"rotor.colour": {"values": [1.0]}}}, "parameters.rotor.colour"),
    ({"study": {"name": "x", "stages": ["mesh", "match", "harmonic", "rotor"]},
      "parameters": {"rotor.mu": {"values": [0.2, 5.0]}}}, "parameters.rotor.mu"),
    ({"study": {"name": "x", "stages": ["mesh", "match", "harmonic"], "outputs": ["rotor_no_load_rpm"]}},
     "study.outputs"),
])
def test_bad_rotor_study_names_the_key(patch, where):
    data = {"parameters": {"horn.length": {"values": [0.06]}}} | patch
    with pytest.raises(ParameterError) as e:
        study_from_mapping(data)
    assert e.value.name == where


def test_rotor_parameters_group_and_base_values():
    st = study_from_mapping({"study": {"name": "x", "stages": ["mesh", "match", "harmonic", "impact", "rotor"],
                                       "sampling": "tolerance", "samples": 2},
                             "parameters": {"rotor.preload": {"tolerance": 0.1},
                                            "coupler.tooth_width": {"tolerance": 0.1}}})
    from results.explore_tasks import rotor_values, split_point

    assert [p.group for p in st.parameters] == ["rotor", "design"]
    nominal = st.points()[0]
    assert nominal["rotor.preload"] == 18.0
    design, _, _, impact = split_point(st, nominal)
    assert list(design) == ["coupler.tooth_width"] and impact == {}
    assert rotor_values(nominal) == {"preload": 18.0}


@pytest.fixture(scope="module")
def rotor_rows():
    """The two-point rotor study, sequentially, with the shared harmonic task's result kept."""
    import results.explore as explore

    kept, ests = [], []
    real, real_est = explore.task_harmonic, explore.task_teeth_error

    def keep(*args):
        kept.append(real(*args))
        return kept[-1]

    def keep_est(*args):
        ests.append(real_est(*args))
        return ests[-1]

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(explore, "task_harmonic", keep)
        mp.setattr(explore, "task_teeth_error", keep_est)
        study = study_from_mapping(ROTOR_STUDY)
        rows = explore.run_sequential(study)
    return study, rows, kept, ests


def test_study_rotor_row_is_the_rotor_stage(rotor_rows):
    import geometry
    from impact.rotor import bit_friction_torque
    from results.pipeline import PipelineSettings
    from results.rotor_stage import BIT, TeethReport, pipeline_rotor_stage, rotor_params_from_design, rotor_stage

    study, rows, kept, ests = rotor_rows
    assert len(kept) == 1 and len(ests) == 1 and all(r["status"] == "ok" for r in rows), rows
    harm, est, volt, wob = kept[0], ests[0], study.settings.voltage, PipelineSettings().wob
    design = geometry.default_design()
    wp = harm.wp
    axial = abs(wp.surfaces["teeth_tops"]["axial"]) * volt
    # the error box of the study's own estimate (a solve 1.4x coarser than the study's mesh)
    teeth = TeethReport(freq_hz=harm.f_w, axial_m=axial, axial_error_m=axial * est.relative("teeth_axial_per_volt_m"),
                        ratio=wp.teeth_ellipse_ratio, ratio_error=est.error("teeth_ellipse_ratio"),
                        phase_deg=wp.teeth_phase_deg, phase_error_deg=est.error("teeth_phase_deg"))
    assert teeth.axial_error_m > 0 and teeth.ratio_error > 0 and teeth.phase_error_deg > 0
    # the first point: preload and friction set by the study
    params = rotor_params_from_design(design).with_(preload=25.0, mu=0.3)
    ref = rotor_stage(teeth, params, bit_friction_torque(wob, *BIT), 0.0)
    # the second point at the default rotor data: the pipeline's own stage on the working point at the voltage
    at_volt = SimpleNamespace(surfaces={"teeth_tops": {"axial": axial}}, teeth_ellipse_ratio=wp.teeth_ellipse_ratio,
                              teeth_phase_deg=wp.teeth_phase_deg, power_w=1.0)
    pipe = pipeline_rotor_stage(design, at_volt, harm.f_w, est, wob)
    for row, out in zip(rows, (ref, pipe)):
        j = out["json"]
        for column, key in (("rotor_no_load_rpm", "no_load_speed_rpm"), ("rotor_stall_torque_n_m", "stall_torque_n_m"),
                            ("rotor_load_rpm", "load_speed_rpm")):
            assert row[column] == pytest.approx(j[key], rel=1e-12)
            # an error is a difference of two such values (~10 % of them): 1e-12 / 0.1, with margin
            assert row[f"{column}_error"] == pytest.approx(j[f"{key}_error"], rel=1e-9, abs=1e-12 * abs(j[key]))
        assert row["rotor_hovers"] == float(j["hover"]["holds"])
        assert row["rotor_note"] == ""
    assert rows[1]["rotor_no_load_rpm_error"] > 0
    # the study's preload and friction reached the contact: the Coulomb bound with them, and a different torque
    bound = 0.3 * 25.0 * params.radius
    assert 0 < rows[0]["rotor_stall_torque_n_m"] <= bound * (1 + 1e-12)
    assert rows[1]["rotor_stall_torque_n_m"] <= 0.2 * 18.0 * params.radius * (1 + 1e-12)
    assert not math.isclose(rows[0]["rotor_stall_torque_n_m"], rows[1]["rotor_stall_torque_n_m"], rel_tol=1e-3)


def test_main_effect_bars_of_rotor_outputs_are_mean_error_bounds():
    # two points per preload level: a level mean's bound is the mean of the points' bounds (bounds add
    # linearly), drawn in the plotted unit (mN m); an impact output's CI combines in quadrature
    from results.explore_figures import axis_label, main_effects

    rows = [{"status": "ok", "in.rotor.preload": f, "rotor_stall_torque_n_m": t, "rotor_stall_torque_n_m_error": e}
            for f, t, e in ((18.0, 0.045, 0.0), (18.0, 0.047, 0.002), (25.0, 0.06, 0.004), (25.0, 0.064, 0.002))]
    study = SimpleNamespace(parameters=[SimpleNamespace(name="rotor.preload")], outputs=["rotor_stall_torque_n_m"],
                            stages=("mesh", "match", "harmonic", "rotor"))
    (ax,) = main_effects(SimpleNamespace(rows=rows, study=study))
    bars = ax.containers[0]
    assert bars.get_label() == "mean, error bound"
    half = [abs(seg[1][1] - seg[0][1]) / 2 for seg in bars.lines[2][0].get_segments()]
    assert half == pytest.approx([1.0, 3.0])                        # mN m: (0 + 2) / 2, (4 + 2) / 2
    assert ax.get_ylabel() == axis_label("rotor_stall_torque_n_m") == "rotor stall torque (mN m)"
