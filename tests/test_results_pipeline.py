"""The end-to-end pipeline on a coarse design: every promised file, sane physics, clean errors."""

import json
import subprocess
import sys

import pytest

import geometry
from rpud_common import ParameterError
from results.pipeline import PipelineSettings, run_pipeline
from geometry.examples import article_design


# started at the lengths this coarse variant matches to (test_fem_matching covers matching from
# 10 %-off starts): the match confirms them in a few solves instead of 16
DESIGN = geometry.filleted(article_design(), 0.0).replace({"coupler.n_slots": 0, "coupler.n_teeth": 0, "stack.ring_thickness": 0.006,
                                            "horn.length": 0.064545, "coupler.length": 0.044374})
# the whole drill's free mesh, ungraded and coarse: the stages' machinery, fast (the sector path below)
SETTINGS = PipelineSettings(mesh_size=0.008, mesher="free", grade=False, m_free_values=(0.0, 0.002, 0.008),
                            impact_rel_tol=0.05, impact_max_members=512, n_points=60)


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    return run_pipeline(DESIGN, SETTINGS, tmp_path_factory.mktemp("run"))


@pytest.fixture(scope="module")
def run(result):
    return result.folder, result.summary


def test_pipeline_result_shows_the_headline_and_saves_the_folder(result, tmp_path):
    s = result.summary
    text = repr(result)
    assert text.startswith("PipelineResult(") and len(text) < 400
    assert f"{s['working_mode']['f_r_hz']:.1f} Hz" in text and "95 % CI" in text
    assert result.to_dict() == json.loads((result.folder / "summary.json").read_text())
    copy = result.save(tmp_path / "copy")
    assert sorted(p.relative_to(copy) for p in copy.rglob("*")) == sorted(
        p.relative_to(result.folder) for p in result.folder.rglob("*"))


def test_pipeline_writes_every_promised_file(run):
    out, summary = run
    assert json.loads((out / "summary.json").read_text()) == json.loads(json.dumps(summary))
    report = (out / "report.md").read_text()
    for rel in summary["files"]["figures"].values():
        assert (out / rel).stat().st_size > 10_000          # real pictures, not empty files
        assert f"]({rel})" in report                         # and the report links them
    assert {"admittance", "tip_response", "ring_up", "impact_history", "kinetic_energy"} <= set(
        summary["files"]["figures"])
    assert len(summary["files"]["renders"]) >= 3
    assert (out / summary["files"]["vtu"]).exists()
    assert not list(out.rglob("*.part*"))                    # no half-written files left behind


def test_pipeline_numbers_are_consistent(run):
    _, s = run
    wm, h, a0 = s["working_mode"], s["harmonic"], s["A0"]
    assert s["matching"]["converged"] and wm["f_r_hz"] == pytest.approx(20e3, rel=5e-3)
    assert wm["label"] == "longitudinal" and 0.2 < wm["k_eff"] < 0.6
    # harmonic vs modal: the admittance peaks at f_r and dips at f_a (issue: 0.5 %)
    assert h["admittance_f_r_hz"] == pytest.approx(wm["f_r_hz"], rel=5e-3)
    assert h["admittance_f_a_hz"] == pytest.approx(wm["f_a_hz"], rel=5e-3)
    # ring-up settles on the harmonic amplitude (issue: 2 %)
    assert h["ring_up_steady_m"] == pytest.approx(h["tip_amplitude_m"], rel=2e-2)
    # A0 is the FE amplitude, reduced (never raised) by the impact load
    assert a0["used_m"] <= a0["unloaded_m"] * 1.0001
    # handed to the impacts rounded to 4 significant digits (reproducibility): within 5e-4
    assert a0["unloaded_m"] == pytest.approx(h["tip_amplitude_m"], rel=5e-4)
    assert a0["unloaded_m"] == float(f"{a0['unloaded_m']:.3e}")
    # the impacts run at the working resonance, handed over to 6 significant digits
    f_imp = s["impacts"]["handoff"]["freq_hz"]
    assert s["impacts"]["params"]["freq"] == f_imp == float(f"{wm['f_r_hz']:.5e}")


def test_kinetic_energy_grows_with_free_mass(run):
    """Statistically: the 95 % intervals at 2 g and 8 g are disjoint, in every sweep."""
    _, s = run
    table = {r["m_free_kg"]: r for r in s["kinetic_energy_table"]}
    assert "device_fe" not in table[0.0]                     # no free mass: no statistics to report
    for key in ("device_fe", "article_fe", "article_15um"):
        lo8 = table[0.008][key]["mean_tool_ke_after_j"]["ci95"][0]
        hi2 = table[0.002][key]["mean_tool_ke_after_j"]["ci95"][1]
        assert lo8 > hi2 > 0, key
        assert table[0.008][key]["converged"]


def test_coupled_model_beside_the_kinematic_results(run):
    """The coupled model: its figures are written, the impacts lower the tip amplitude
    below the unloaded harmonic one and the loading grows with the free mass, the ring-up history
    closes its energy balance, and the power drawn stays below the unloaded drive's."""
    out, s = run
    cm = s["coupled_model"]
    assert {"coupled_tip_envelope", "ke_three_horn_models", "coupled_drive_power"} <= set(s["files"]["figures"])
    rows = {r["m_free_kg"]: r for r in cm["rows"]}
    unloaded = s["harmonic"]["tip_amplitude_m"]
    amp = {m: r["coupled"]["tip_amplitude_m"] for m, r in rows.items()}
    assert amp[0.008]["ci95"][1] < amp[0.002]["ci95"][0] < amp[0.002]["ci95"][1] < unloaded
    assert rows[0.008]["coupled"]["drive_power_w"]["mean"] < s["harmonic"]["power_w"]
    for r in cm["history"]["energy_balance"]:
        assert abs(r["residual_j"]) <= 1e-6 * r["drive_j"]
    assert cm["reduced_transducer"]["mode_index"][cm["reduced_transducer"]["working"]] == s["working_mode"]["index"]


def test_every_fe_value_states_its_discretisation_error(run):
    """fem.errors' two-level estimate (one solve at refine 1.4) beside f_r, f_a, k_eff, the tip
    amplitude, the ellipse ratio and every A0 (their relative error: the tip amplitude's), in
    summary.json and the report."""
    out, s = run
    wm, h, a0, block = s["working_mode"], s["harmonic"], s["A0"], s["discretisation_error"]
    assert block["coarse_refine"] == pytest.approx(1.4) and block["coarse_ndof"] < s["mesh"]["ndof"]
    for q in ("f_r_hz", "f_a_hz", "k_eff"):
        assert wm[f"{q}_error"] == block["errors"][q] > 0
    assert 0 < wm["f_r_hz_error"] < 0.05 * wm["f_r_hz"]
    rel = h["tip_per_volt_m_error"] / h["tip_per_volt_m"]
    assert 0 < rel < 0.2 and h["teeth_ellipse_ratio_error"] is not None
    assert a0["used_m_error"] / a0["used_m"] == pytest.approx(rel, rel=1e-9)
    for r in s["kinetic_energy_table"][1:]:
        assert r["A0_fe_m_error"] / r["A0_fe_m"] == pytest.approx(rel, rel=1e-9)
    report = (out / "report.md").read_text()
    assert report.count("±") >= 8 and "estimated discretisation error" in report
    assert s["timings"]["discretisation_error_s"] > 0


def test_rerun_gives_identical_json(run, tmp_path):
    """Same command, same machine: every number identical (timings aside)."""
    out, first = run
    second = run_pipeline(DESIGN, SETTINGS, tmp_path / "again").summary
    a = _without_timings(json.loads((out / "summary.json").read_text()))
    b = _without_timings(json.loads((tmp_path / "again" / "summary.json").read_text()))
    assert a == b and second["A0"]["used_m"] == first["A0"]["used_m"]


def test_another_thread_count_moves_round_off_only_and_never_the_chaotic_stages(run, tmp_path):
    """The solvers' round-off depends on their thread count (measured: up to 1e-11 relative in
    the FE numbers, 4e-7 in the fitted ring-up; asserted within 1e-5). The handed-over A0 and frequency are rounded
    and the matched lengths snapped to a grid, so the chaotic impact stages see the same inputs
    and give the same statistics, bit for bit."""
    from threadpoolctl import threadpool_info, threadpool_limits

    from fem.solvers import pardiso_available

    if not pardiso_available():
        pytest.skip("SuperLU runs single-threaded: no thread-dependent round-off to test")
    _, first = run

    def mkl_threads():
        return {i["num_threads"] for i in threadpool_info() if i["internal_api"] == "mkl"}

    now = max(mkl_threads(), default=1)
    other = 1 if now > 1 else 2
    with threadpool_limits(limits=other):
        assert mkl_threads() == {other}                                 # PARDISO's threads changed
        second = run_pipeline(DESIGN, SETTINGS, tmp_path / "threads").summary
    a, b = _without_timings(first), _without_timings(second)
    assert a["matching"]["tuned"] == b["matching"]["tuned"]          # the same geometry and mesh
    assert a["mesh"] == b["mesh"]
    for key in ("impacts", "coupled_model"):
        assert a[key] == b[key]
    assert [{k: v for k, v in r.items() if not k.endswith("_error")} for r in a["kinetic_energy_table"]] == \
        [{k: v for k, v in r.items() if not k.endswith("_error")} for r in b["kinetic_energy_table"]]
    assert (a["A0"]["used_m"], a["A0"]["unloaded_m"]) == (b["A0"]["used_m"], b["A0"]["unloaded_m"])
    _assert_close(a, b, rel=1e-5)


def _assert_close(x, y, rel, path=""):
    if isinstance(x, dict):
        assert x.keys() == y.keys(), path
        for k in x:
            _assert_close(x[k], y[k], rel, f"{path}/{k}")
    elif isinstance(x, list):
        assert len(x) == len(y), path
        for i, (u, v) in enumerate(zip(x, y)):
            _assert_close(u, v, rel, f"{path}[{i}]")
    elif isinstance(x, float) and isinstance(y, float):
        assert y == pytest.approx(x, rel=rel, abs=1e-300), path
    else:
        assert x == y, path


def _without_timings(d):
    # the provenance's date and command line differ between runs by design
    if isinstance(d, dict):
        return {k: _without_timings(v) for k, v in d.items() if k not in ("timings", "seconds", "provenance")}
    if isinstance(d, list):
        return [_without_timings(v) for v in d]
    return d


def test_bad_settings_and_cli_input(tmp_path):
    with pytest.raises(ParameterError, match="voltage"):
        PipelineSettings(voltage=0.0)
    with pytest.raises(ParameterError, match="m_free_values"):
        PipelineSettings(m_free_values=(-0.001,))
    r = subprocess.run([sys.executable, "-m", "results", "--voltage", "-5", "--out", str(tmp_path / "x")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "voltage" in r.stderr
    assert not (tmp_path / "x").exists()


def test_stress_utilisation_table_in_summary_and_report(run):
    """The utilisation table at the drive voltage, in summary.json and report.md."""
    out, s = run
    st = s["stress"]
    u = st["utilisation"]
    assert u["voltage_v"] == s["harmonic"]["voltage_v"] and u["freq_hz"] == pytest.approx(s["working_mode"]["f_r_hz"])
    rows = {(r["region"], r["quantity"]): r for r in u["rows"]}
    assert rows[("horn", "von_mises")]["limit"] == 510e6 and rows[("horn", "von_mises")]["peak"] > 0
    assert {("ring_1", q) for q in ("principal_max", "principal_min", "efield")} <= set(rows)
    # every peak's error from the discretisation-error stage's coarser mesh, never null
    assert "two meshes" in u["note"] and all(r["error_estimate"] >= 0 for r in u["rows"])
    report = (out / "report.md").read_text()
    from results.report import escape_table_pipes

    # the table as written into the report: a magnitude's pipes (|E|) escaped so the row keeps its columns
    assert "## Stress and limits at the drive voltage" in report and escape_table_pipes(st["markdown"]) in report
    assert (out / st["files"]["png"]).stat().st_size > 10_000 and (out / st["files"]["vtu"]).exists()


def test_mesher_is_checked_before_anything_runs(tmp_path):
    with pytest.raises(ParameterError, match="mesher"):
        PipelineSettings(mesher="swept")
    loft = tmp_path / "loft.toml"
    article_design().replace({"horn.profile": "exponential"}).save(loft)
    r = subprocess.run([sys.executable, "-m", "results", "--mesher", "revolve", "--design", str(loft),
                        "--out", str(tmp_path / "x")], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "stepped or conical" in r.stderr
    assert not (tmp_path / "x").exists()


def test_one_point_study_equals_the_pipeline(result, tmp_path):
    """A design study submits the pipeline's own stage functions (results.stage_*) to Dask: one
    point with the pipeline's settings gives the pipeline's numbers. The FE values differ only by
    the solvers' round-off (a worker runs one BLAS thread; the thread test above measures up to
    1e-11 relative between thread counts, so 1e-9 is asserted); the hand-off to the impacts is
    rounded, so the loaded amplitude and the impact statistics are equal bit for bit."""
    from results.explore import explore
    from results.study import study_from_mapping

    s = result.summary
    DESIGN.save(tmp_path / "design.toml")
    study = study_from_mapping({
        "study": {"name": "one", "design": str(tmp_path / "design.toml"), "seed": SETTINGS.seed,
                  "stages": ["mesh", "match", "harmonic", "impact"]},
        "settings": {"voltage": SETTINGS.voltage, "q_mech": SETTINGS.q_mech, "mesh_size": SETTINGS.mesh_size,
                     "refine": SETTINGS.refine, "mesher": SETTINGS.mesher, "grade": SETTINGS.grade, "match": True,
                     "scenario": "device",
                     "rel_tol": SETTINGS.impact_rel_tol, "max_members": SETTINGS.impact_max_members},
        "parameters": {"impact.m_free": {"values": [0.008]}}})
    row = explore(study, tmp_path / "study", workers=1, figures=False).rows[0]
    assert row["status"] == "ok", row["error"]
    wm, h = s["working_mode"], s["harmonic"]
    for key in ("f_r_hz", "f_a_hz", "k_eff"):
        assert row[key] == pytest.approx(wm[key], rel=1e-9), key
    for path, value in s["matching"]["tuned"].items():
        assert row[f"tuned.{path}"] == pytest.approx(value, rel=1e-9), path
    assert row["tip_per_volt_m"] == pytest.approx(h["tip_per_volt_m"], rel=1e-9)
    assert row["teeth_ellipse_ratio"] == pytest.approx(h["teeth_ellipse_ratio"], rel=1e-9, nan_ok=True)
    assert row["power_w"] == pytest.approx(h["power_w"], rel=1e-9)
    assert row["A0_m"] == s["A0"]["per_mass"]["8 g"]
    ke = next(r for r in s["kinetic_energy_table"] if r["m_free_kg"] == 0.008)["device_fe"]
    assert row["members"] == ke["members"]
    assert (row["tool_ke_j"], row["tool_ke_j_ci95"]) == (ke["mean_tool_ke_after_j"]["mean"],
                                                         ke["mean_tool_ke_after_j"]["ci95_half_width"])
    assert (row["tool_rate_hz"], row["tool_power_w"]) == (ke["tool_impact_rate_hz"]["mean"], ke["tool_power_w"]["mean"])
