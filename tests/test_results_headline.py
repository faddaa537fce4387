"""The report's headline is the compliant model's: the headline record and rows from the run's own
JSON with both uncertainties, the comparison paragraph, and the free mass's contact faces as
design data (TOML and command line, echoed, bad input refused)."""

import json
import math
from pathlib import Path

import pytest

from rpud_common import ParameterError
from results.contact_faces import ContactFaces

ROOT = Path(__file__).resolve().parent.parent


def _committed():
    return json.loads((ROOT / "results" / "default" / "summary.json").read_text())


def _est(mean, hw, n=32):
    return {"mean": mean, "ci95_half_width": hw, "members": n}


def _compliant_doc(masses=(0.001, 0.008)):
    """A compliant block shaped as results.stage_compliant writes it (numbers distinct per mass)."""
    rows = []
    for i, m in enumerate(masses):
        rows.append({"m_free_kg": m, "members": 32, "converged": True, "model_form_from": "this mass's study",
                     "mean_tool_ke_after_j": _est(1e-3 * (1 + 5 * i), 3e-5 * (1 + i)),
                     "tool_impact_rate_hz": _est(600.0 - 300 * i, 20.0), "tool_power_w": _est(0.6 + i, 0.02),
                     "model_form": {"mean_tool_ke_after_j": 4e-5 * (1 + 30 * i), "tool_impact_rate_hz": 30.0 * (1 + i),
                                    "tool_power_w": 0.1 * (1 + i)}})
    study = {f"{m * 1e3:g} g": {"cutoff": [dict(r, cutoff_hz=c) for c in (30e3, 61e3, 122e3)],
                                "stiffness": [dict(r, stiffness_factor=f) for f in (0.5, 2.0)],
                                "model_form": {}} for m, r in zip(masses, rows)}
    return {"cutoffs_hz": [30e3, 61e3, 122e3], "cutoff_factors": [0.5, 1.0, 2.0], "modes_hz": [0.0] + [20e3] * 32,
            "residual_m_per_n": 3.7e-10, "contact_time_s": 16.4e-6,
            "contact": {"face": "crowned", "face_radius_m": 6.2e-3, "face_radius_from": "a steel_45 sphere of the free mass",
                        "e_horn": 0.9, "e_tool": 0.8},
            "scenario": {"spring_force_n": 5.0, "t_from_s": 0.02, "t_end_s": 0.22},
            "settings": {"members": 16, "rel_tol": 0.05, "max_members": 32, "stiffness_factors": [0.5, 2.0]},
            "study": study, "rows": rows, "assumed": ["the faces"], "calibrated": ["gap, k0, c, v0 inherited"]}


def test_headline_record_and_rows_come_from_the_compliant_json():
    """summary.json's ``headline`` is the compliant row at the reference free mass, both
    uncertainties present and finite; the report's headline sentence, its table rows and the
    operating-point row show exactly those numbers (formatted here from the JSON)."""
    from results.report import headline_record, report_lines

    s = _committed()
    s["compliant_model"] = doc = _compliant_doc()
    s["headline"] = rec = headline_record(s)
    top = doc["rows"][-1]
    assert rec["model"] == "compliant_model" and rec["m_free_kg"] == 0.008
    for q in ("mean_tool_ke_after_j", "tool_impact_rate_hz", "tool_power_w"):
        assert rec[q]["mean"] == top[q]["mean"] and rec[q]["ci95_half_width"] == top[q]["ci95_half_width"]
        assert rec[q]["model_form"] == top["model_form"][q]
        assert all(math.isfinite(rec[q][k]) and rec[q][k] > 0 for k in ("ci95_half_width", "model_form"))
    kin = next(r for r in s["kinetic_energy_table"] if r["m_free_kg"] == 0.008)
    assert rec["comparison_tool_ke_j"]["kinematic_damper_a0"] == kin["device_fe"]["mean_tool_ke_after_j"]
    text = "\n".join(report_lines(s))

    def pm2(e, mf, k):
        return f"{e['mean'] * k:.3g} ± {e['ci95_half_width'] * k:.2g} ± {mf * k:.2g}"

    for r in doc["rows"]:
        mf = r["model_form"]
        assert (f"| {r['m_free_kg'] * 1e3:g} | {pm2(r['mean_tool_ke_after_j'], mf['mean_tool_ke_after_j'], 1e3)} "
                f"| {pm2(r['tool_impact_rate_hz'], mf['tool_impact_rate_hz'], 1.0)} ") in text
    ke = pm2(top["mean_tool_ke_after_j"], top["model_form"]["mean_tool_ke_after_j"], 1e3)
    assert f"tool kinetic energy {ke} mJ per impact" in text.split("\n")[2]          # the headline sentence
    assert f"compliant contacts {ke} (95 % CI, model form)" in text                    # the comparison paragraph
    assert "cannot recoil" in text and "does not converge" in text
    doc["rows"][-1]["model_form"]["tool_impact_rate_hz"] = 109.6        # 2 digits without an exponent
    s["headline"] = headline_record(s)
    assert "at 300 ± 20 ± 110 Hz" in report_lines(s)[2]


def test_without_the_compliant_stage_the_kinematic_headline_says_why():
    """The whole-drill path (or compliant_members 0): the kinematic horn heads the report, its
    model-form estimate is stated as not estimated with the reason, never silently null."""
    from results.report import headline_record, headline_text

    s = _committed()
    s["compliant_model"] = None
    rec = headline_record(s, "the compliant stage runs on the k = 0 sector path only")
    assert rec["model"] == "impacts.device_fe" and rec["mean_tool_ke_after_j"]["model_form"] is None
    assert "k = 0 sector path only" in rec["model_form_note"]
    assert "not estimated: the compliant stage runs on the k = 0 sector path only" in headline_text({**s, "headline": rec})


def test_contact_faces_give_the_hertz_stiffness_of_their_geometry():
    """A crowned face of radius R on a flat: k = 4/3 E* sqrt(R) (Johnson eq. 4.22 with the flat's
    infinite radius), E* of the horn's and the free mass's materials; with no radius, R is that
    of a steel sphere of the free mass (3 m / (4 pi rho))^(1/3). Exact formulas: 1e-12."""
    import geometry
    from geometry.materials import get_material
    from results.stage_compliant import CompliantSettings, contact_laws

    design = geometry.default_design()
    steel, horn = get_material("steel_45", design.library), get_material(design.part_material("horn"), design.library)
    e_star = 1.0 / ((1 - horn.poisson_ratio ** 2) / horn.youngs_modulus + (1 - steel.poisson_ratio ** 2) / steel.youngs_modulus)
    hl, _, info = contact_laws(design, 0.008, 0.9, 0.8, CompliantSettings(faces=ContactFaces(face_radius=5e-3)))
    assert hl.stiffness == pytest.approx(4 / 3 * e_star * math.sqrt(5e-3), rel=1e-12)
    assert info["face_radius_from"] == "given" and info["face"] == "crowned"
    hl, _, info = contact_laws(design, 0.008, 0.9, 0.8, CompliantSettings())
    r = (3 * 0.008 / (4 * math.pi * steel.density)) ** (1 / 3)
    assert info["face_radius_m"] == pytest.approx(r, rel=1e-12)
    assert hl.stiffness == pytest.approx(4 / 3 * e_star * math.sqrt(r), rel=1e-12)
    flat = ContactFaces(face_radius=5e-3, edge_radius=1e-3, face_tilt_deg=2.0)
    _, _, info = contact_laws(design, 0.008, 0.9, 0.8, CompliantSettings(faces=flat))
    assert info["face"] == "flat" and info["radii_m"][1] == pytest.approx(1e-3)      # the rim's radius across
    assert info["radii_m"][0] == pytest.approx((5e-3 - 1e-3) / math.sin(math.radians(2.0)) + 1e-3, rel=1e-12)


def test_contact_faces_round_trip_through_toml_and_the_command_line(tmp_path):
    """The [contact] table and the options give the same faces; the options override the file;
    the inputs line and the pipeline settings carry them."""
    from results.__main__ import _inputs, _settings, build_parser, check_options

    faces = ContactFaces(face_radius=4e-3, edge_radius=5e-4, face_tilt_deg=1.5, tool_material="steel_45")
    path = tmp_path / "c.toml"
    path.write_text(faces.to_toml() + '\n[impact]\ngap = 2e-3\n')
    assert ContactFaces.from_toml(path) == faces
    args = build_parser().parse_args(["--contact", str(path), "--face-tilt", "3"])
    check_options(args)
    settings = _settings(args)
    assert settings.faces == ContactFaces(face_radius=4e-3, edge_radius=5e-4, face_tilt_deg=3.0)
    args = build_parser().parse_args(["--face-radius", "0.006"])
    check_options(args)
    import geometry

    line = _inputs(geometry.default_design(), _settings(args), tmp_path / "o")["compliant model"]
    assert line == "16-64 members per case, 95 % CI within 0.05 (study 0.1), crowned face R = 6 mm"


def test_compliant_ci_targets_reach_the_stage_and_the_inputs_line(tmp_path):
    import geometry
    from results.__main__ import _inputs, _settings, build_parser, check_options

    args = build_parser().parse_args(["--compliant-rel-tol", "0.03", "--compliant-study-rel-tol", "0.2",
                                      "--compliant-max-members", "128"])
    check_options(args)
    settings = _settings(args)
    stage = settings.compliant_settings()
    assert (stage.rel_tol, stage.study_rel_tol, stage.max_members, stage.members) == (0.03, 0.2, 128, 16)
    line = _inputs(geometry.default_design(), settings, tmp_path / "o")["compliant model"]
    assert line.startswith("16-128 members per case, 95 % CI within 0.03 (study 0.2), ")


@pytest.mark.parametrize("argv, name", [
    (["--face-radius", "0"], "--face-radius"), (["--face-radius", "nan"], "--face-radius"),
    (["--face-tilt", "2"], "--face-tilt"), (["--edge-radius", "1e-3"], "--edge-radius"),
    (["--edge-radius", "6e-3", "--face-radius", "5e-3", "--face-tilt", "2"], "--edge-radius"),
    (["--edge-radius", "1e-3", "--face-radius", "5e-3", "--face-tilt", "90"], "--face-tilt"),
    (["--face-radius", "5e-3", "--compliant-members", "0"], "--face-radius"),
    (["--compliant-max-members", "8"], "--compliant-max-members"), (["--compliant-members", "1"], "--compliant-members"),
    (["--compliant-rel-tol", "0"], "--compliant-rel-tol"), (["--compliant-study-rel-tol", "1"], "--compliant-study-rel-tol"),
    (["--compliant-rel-tol", "nan"], "--compliant-rel-tol"),
    (["--compliant-study-rel-tol", "0.1", "--compliant-members", "0"], "--compliant-study-rel-tol"),
    (["--contact", "missing.toml"], "--contact")])
def test_bad_contact_options_are_one_line_exit_2_nothing_written(argv, name):
    from test_cli_fuzz import run_clean

    from results.__main__ import main

    run_clean(main, argv + ["--out", "res", "-q"])
    with pytest.raises(ParameterError, match=f"^{name} = "):
        from results.__main__ import build_parser, check_options

        check_options(build_parser().parse_args(argv))


def test_contact_table_with_unknown_keys_or_no_table_is_refused(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[contact]\nface_radus = 1e-3\n")
    with pytest.raises(ParameterError, match="face_radus"):
        ContactFaces.from_toml(bad)
    other = tmp_path / "other.toml"
    other.write_text("[impact]\ngap = 2e-3\n")
    with pytest.raises(ParameterError, match="no \\[contact\\] table"):
        ContactFaces.from_toml(other)
