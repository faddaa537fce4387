"""Drilling under load on the compliant model (impact.kernel_drill_compliant through
impact.drilling.drilling_sweep(horn=...)) against its references: without the rock and the weight
on bit it is the compliant free-running model (impact.kernel_compliant, the same members); with a
horn of infinite tip mass, stiff contacts and a rigid tool it is the kinematic drilling model
(impact.drill_kernel); its window energy balance closes with the rock's dissipation as an entry.
The rock law's own closed-form tests are in tests/test_drilling.py."""

import math

import numpy as np
import pytest

from impact import drill_kernel as K
from impact import kernel_compliant as KC
from impact import kernel_drill_compliant as KD
from impact.drilling import CompliantHorn, DrillParams, DrillSettings, drilling_sweep
from impact.hertz import HertzLaw
from impact.horn import ModalHorn
from impact.kernel import pack
from impact.params import ImpactParams
from impact.rod import ToolRod
from rpud_common import ParameterError

F = 19.95e3
W = 2 * np.pi * F
V0 = 225.0


def _horn3(tip_mass=0.1):
    """Three damped modes (the working one near the drive, two above with larger tip
    participation), steady start: the FE drill's wide-band horn on a small scale."""
    om = 2 * np.pi * np.array([20.3e3, 31.8e3, 55.0e3])
    s = np.array([1.0, 2.1, 1.5]) / math.sqrt(tip_mass)
    zeta = np.array([0.005, 0.004, 0.004])
    cre = 15e-6 / s[0] * abs(om[0] ** 2 - W ** 2 + 2j * zeta[0] * om[0] * W) / V0
    return ModalHorn(om, zeta, [1.0, 1.0, 1.0], s, [cre, 0.1 * cre, 0.05 * cre], [0.1 * cre, 0.0, 0.0], V0,
                     start="steady")


def _cosine_horn(tip_mass, A=15e-6):
    """An undamped mode at twice the drive whose steady tip motion is ``A cos(W t)`` (the kinematic
    horn's) with the tip mass ``tip_mass``."""
    om = 2 * W
    s = 1 / math.sqrt(tip_mass)
    return ModalHorn([om], [0.0], [1.0], [s], [0.0], [A * (om ** 2 - W ** 2) / (s * V0)], V0, start="steady")


def _laws(p: ImpactParams, k=1e10):
    return HertzLaw(k, p.e2), HertzLaw(k, p.e1)


def _one(p: DrillParams, ch: CompliantHorn, m_free, v0, *, rock_on=True, housing=None):
    """One member of the compliant drilling kernel: its window row."""
    tab, xs = ch.horn.pack(p.impact.freq)
    ip = p.impact.with_(m_free=m_free, v0=v0)
    lw = KC.pack_laws(*ch.laws, ch.residual, ch.rtol)
    mh = p.housing_mass(m_free) if housing is None else housing
    dv = KD.pack_drill(p.wob, mh, p.rock, rock_on)
    return KD.run_drill(pack(ip), lw, dv, tab, xs, p.t_from, p.t_end)[0]


def test_zero_load_is_the_compliant_free_run():
    """No rock, no weight on bit, a fixed housing: the compliant model of impact.kernel_compliant
    (closed-form flights, DOP853 contacts), member by member over 4 ms (~10 contacts). Both engines
    keep each step's error within rtol 1e-11 of mm / m/s; a contact's outcome then carries
    ~1e-11 x (its ~30 steps) and the few contacts before it amplify that by at most ~10 each:
    1e-6 of each window integral, or 1e-8 of the drive work for the net horn work (a difference
    of terms of the drive work's size, ~1e3 steps of 1e-11 each), and the same contact counts."""
    ip = ImpactParams(freq=F, spring_force=5.0)
    p = DrillParams(impact=ip, wob=0.0, t_from=0.0, t_end=0.004)
    ch = CompliantHorn(_horn3(), 2e-9, _laws(ip), rtol=1e-11)
    tab, xs = ch.horn.pack(F)
    lw = KC.pack_laws(*ch.laws, ch.residual, ch.rtol)
    for m, v0 in ((0.008, 4.0), (0.002, 3.8), (0.005, 4.2)):
        ref = KC.run_contacts(pack(ip.with_(m_free=m, v0=v0)), lw, tab, xs, 0.0, p.t_end, 10_000)[-1]
        row = _one(p, ch, m, v0, rock_on=False, housing=math.inf)
        # the kernel counts a tool contact at its touch (a blow), the reference at its separation
        assert row[K.S_BLOWS] - ref[KC.S_N_TOOL] in (0.0, 1.0)
        assert row[K.S_HORN] == ref[KC.S_N_HORN]
        assert ref[KC.S_N_TOOL] >= 2 and ref[KC.S_N_HORN] >= 2
        for mine, theirs in ((KD.K_DRIVE, KC.C_DRIVE), (KD.K_DAMP, KC.C_DAMP), (KD.K_TOOL_DAMP, KC.K_TOOL_DAMP),
                             (K.S_HORN_WORK, KC.S_HORN_WORK), (KD.K_ELEC, KC.C_ELEC)):
            assert row[mine] == pytest.approx(ref[theirs], rel=1e-6, abs=1e-8 * abs(ref[KC.C_DRIVE]))
        assert row[KD.K_LOSS] == pytest.approx(ref[KC.K_LOSS], rel=1e-6)
        assert row[K.S_PEN] == 0.0 and row[KD.K_ROCK_DISS] == 0.0


def test_window_energy_balance_closes():
    """Drive work = modal, tool and contact losses + the rock's dissipation + the change of the
    stored energy (bodies, modes, contacts, the rock's elastic energy, the potentials of the weight
    on bit, the restoring spring and gravity), to 1e-9 of the drive work over 30 ms of drilling
    (rtol 1e-11: ~1e4 steps of local error 1e-11 of the state's scale, mostly cancelling)."""
    ip = ImpactParams(freq=F, spring_force=5.0)
    p = DrillParams(impact=ip, t_from=0.005, t_end=0.035)
    ch = CompliantHorn(_horn3(), 2e-9, _laws(ip), rtol=1e-11)
    for m in (0.002, 0.008):
        row = _one(p, ch, m, 4.0)
        assert row[K.S_BLOWS] >= 5 and row[KD.K_ROCK_DISS] > 0 and row[K.S_PEN] > 0
        assert row[K.S_STATUS] == 0
        assert abs(row[KD.K_LEDGER]) <= 1e-9 * abs(row[KD.K_DRIVE])
        # every joule the rock dissipates is work done on it (its elastic energy is bounded)
        assert row[KD.K_ROCK_DISS] <= row[K.S_ROCK_WORK] + 0.5 * 400.0 ** 2 / p.rock.k_load


def test_heavy_horn_stiff_contacts_rigid_tool_give_the_kinematic_drilling_model():
    """The kinematic drilling model (impact.drill_kernel: Newton impacts, a horn moving as
    A0 cos(W t)) with a rigid tool (a 1 mm rod of 1e13 Pa: 7e13 N/m in series with the rock's
    2.4e8) against the compliant kernel with a horn of 1e3 kg tip mass whose tip moves as the
    kinematic one, Hertz contacts of 1e13 N/m^1.5 (contacts of ~3 us, 1/17 of a drive period, the
    restitutions the same) and the same housing: blow rate, drilling rate and mean rock force
    within the two ensembles' 95 % CIs added in quadrature (the models' difference, contact time
    against the period, is below the sampling error at these sizes)."""
    ip = ImpactParams(freq=F, spring_force=5.0)
    p_kin = DrillParams(impact=ip, rod=ToolRod(length=1e-3, E=1e13, cells=2), t_from=0.01, t_end=0.06)
    p = DrillParams(impact=ip, t_from=0.01, t_end=0.06)
    st = DrillSettings(rel_tol=0.05, n_start=24, n_max=24)
    kin = drilling_sweep(p_kin, [0.008], st)[0]
    ch = CompliantHorn(_cosine_horn(1e3), 0.0, _laws(ip, 1e13), rtol=1e-9)
    comp = drilling_sweep(p, [0.008], st, horn=ch)[0]
    assert comp.model == "compliant" and kin.model == "kinematic"
    for q in ("blow_rate_hz", "drilling_rate_m_s", "mean_rock_force_n"):
        a, b = kin[q], comp[q]
        assert abs(a.mean - b.mean) <= math.hypot(a.half_width, b.half_width), q


def test_sweep_is_reproducible_and_carries_the_model_status():
    ip = ImpactParams(freq=F, spring_force=5.0)
    p = DrillParams(impact=ip, t_from=0.005, t_end=0.02)
    ch = CompliantHorn(_horn3(), 2e-9, _laws(ip), rtol=1e-9)
    st = DrillSettings(n_start=4, n_max=4)
    a = drilling_sweep(p, [0.004], st, horn=ch)[0]
    b = drilling_sweep(p, [0.004], st, horn=ch)[0]
    assert np.array_equal(a.raw, b.raw, equal_nan=True)
    assert "uncalibrated" in repr(a) and "compliant" in repr(a)
    rec = a.to_dict()
    assert rec["model"] == "compliant" and math.isfinite(rec["ledger_rel"]["mean"])


def test_pipeline_stage_drills_on_the_fe_horn_beside_the_kinematic_comparison():
    """results.drilling.drilling_stage with a horn: the compliant rows for the positive masses, the
    kinematic sweep as the comparison (JSON, report, figure), each with its model, assumptions and
    calibration status beside the numbers; JSON without NaN."""
    import json

    from impact.drilling_plots import plot_depth_vs_mass
    from results.drilling import drilling_stage, report_lines

    base = ImpactParams(A0=15e-6, freq=F)
    ch = CompliantHorn(_horn3(), 2e-9, (_laws(base),))
    out = drilling_stage(base, [0.0, 0.004], {0.004: 14e-6}, 7.0, 20260, settings=DrillSettings(n_start=4, n_max=4),
                         window=(0.005, 0.02), horn=(ch, [0.004]), horn_members=4)
    doc = out["json"]
    assert doc["model"] == "compliant" and [r["m_free_kg"] for r in doc["rows"]] == [0.004]
    assert doc["comparison"]["model"] == "kinematic" and len(doc["comparison"]["rows"]) == 2
    assert "uncalibrated" in doc["model_status"]["calibration"] and "rigid tool" in doc["model_status"]["assumptions"]
    assert "uncalibrated" in doc["comparison"]["model_status"]["calibration"]
    json.dumps(doc, allow_nan=False)
    lines = report_lines(doc)
    assert any(ln.startswith("**Model (compliant):**") and "uncalibrated" in ln for ln in lines)
    assert any(ln.startswith("Comparison, the kinematic model") for ln in lines)
    assert sum(1 for ln in lines if ln.startswith("| ") and ln[2].isdigit()) == 3
    ax = plot_depth_vs_mass(out["result"])
    text = " ".join(t.get_text().replace("\n", " ") for t in ax.texts)
    assert "compliant" in text and "NOT credible" in text
    assert len(ax.get_legend().get_texts()) == 2
    # the pipeline's no-load axis for a compliant drilling run: that model's own no-load energies
    ax = plot_depth_vs_mass(out["result"], no_load_ke=([0.004], [6.8e-3], [0.3e-3], "no-load, compliant model"))
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert len(legend) == 3 and legend[-1] == "no-load, compliant model"
    twin = [a for a in ax.figure.axes if a is not ax][0]
    assert np.allclose(twin.lines[0].get_ydata(), [6.8])


def test_bad_inputs_are_refused():
    ip = ImpactParams(freq=F)
    p = DrillParams(impact=ip, t_end=0.03)
    with pytest.raises(ParameterError, match="laws"):
        drilling_sweep(p, [0.002, 0.004], horn=CompliantHorn(_horn3(), 0.0, (_laws(ip),) * 3))
    with pytest.raises(ParameterError, match="rtol"):
        CompliantHorn(_horn3(), 0.0, _laws(ip), rtol=1e-3)
    with pytest.raises(ParameterError, match="A0_values"):
        drilling_sweep(p, [0.002], A0_values=[1e-5], horn=CompliantHorn(_horn3(), 0.0, _laws(ip)))
    with pytest.raises(ParameterError, match="m_free"):
        drilling_sweep(p, [0.0], horn=CompliantHorn(_horn3(), 0.0, _laws(ip)))


def test_cli_fem_horn_refuses_bad_input_before_the_fe_build(tmp_path):
    """``python -m impact --load rock --horn fem``: a bad value is one line naming it, exit 2, no file,
    before the FE horn is built."""
    import subprocess
    import sys

    out = tmp_path / "d.json"
    for args, name in ((["--m-free", "0"], "m_free"), (["--members", "1"], "--members")):
        r = subprocess.run([sys.executable, "-m", "impact", "--load", "rock", "--horn", "fem", *args, "--json", str(out)],
                           capture_output=True, text=True, timeout=120)
        assert r.returncode == 2 and name in r.stderr and len(r.stderr.strip().splitlines()) == 1
        assert "Traceback" not in r.stderr and not out.exists()
