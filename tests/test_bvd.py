"""Butterworth-Van Dyke fit of an admittance sweep (fem.bvd) against known circuits and the FE model.

References:
- a synthetic admittance of known R, L, C, C0, tan delta (the circuit itself: exact without
  noise; with 1 % noise the 95 % CIs must cover the truth in ~95 % of the realisations and their
  width must match the scatter of the estimates);
- the FE admittance of a k33 rod with a known hysteretic loss: the BVD Q_m of its resonance is the
  mode's quality factor 1 / eta from its energies (the modal loss factor phi^T L phi / lambda,
  a second route that never looks at the admittance curve).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import binom

from rpud_common import ParameterError
from fem.bvd import NAMES, AdmittanceData, bvd_admittance, fit_bvd, fit_resonance, read_admittance

# a 20 kHz resonator: Q_m 251, k_eff 0.335 (the drill's order of magnitude)
R, L, C0, TD = 50.0, 0.1, 5e-9, 0.004
FS = 20e3
C = 1.0 / ((2 * np.pi * FS) ** 2 * L)
TRUTH = {"R_ohm": R, "L_h": L, "C_f": C, "C0_f": C0, "tan_delta": TD, "f_s_hz": FS,
         "f_p_hz": FS * math.sqrt(1 + C / C0), "q_m": 2 * math.pi * FS * L / R, "k_eff": math.sqrt(C / (C + C0))}
F = np.linspace(19e3, 22e3, 301)


def test_noise_free_circuit_is_recovered_exactly():
    fit = fit_resonance(F, bvd_admittance(F, R, L, C, C0, TD))
    for k in NAMES:
        assert fit.values[k] == pytest.approx(TRUTH[k], rel=1e-6), k
    assert fit.rms_residual < 1e-9


def test_one_percent_noise_is_covered_by_the_confidence_intervals():
    """60 realisations of 1 % complex noise (relative, as an analyser's reading error). If the
    95 % CIs are right, the count covering the truth is Binomial(60, 0.95): below 51 with
    probability 4e-4, so >= 51 per parameter. Coverage alone passes an interval far too wide: the
    mean half-width / 1.96 must also match the estimates' scatter within 0.7-1.4 (the sample
    standard deviation of 60 values is uncertain by 1/sqrt(118) = 9 %, so this is > 3 sigma)."""
    assert binom.cdf(50, 60, 0.95) < 1e-3
    rng = np.random.default_rng(20260)
    y0 = bvd_admittance(F, R, L, C, C0, TD)
    est = {k: [] for k in NAMES}
    half = {k: [] for k in NAMES}
    for _ in range(60):
        y = y0 * (1 + 0.01 * (rng.standard_normal(F.size) + 1j * rng.standard_normal(F.size)) / math.sqrt(2))
        fit = fit_resonance(F, y)
        for k in NAMES:
            est[k].append(fit.values[k])
            half[k].append(fit.ci95[k])
    for k in NAMES:
        e, h = np.array(est[k]), np.array(half[k])
        covered = int(np.sum(np.abs(e - TRUTH[k]) <= h))
        assert covered >= 51, (k, covered)
        ratio = np.mean(h) / 1.96 / np.std(e, ddof=1)
        assert 0.7 <= ratio <= 1.4, (k, ratio)


def _write(path, header, rows):
    path.write_text(header + "\n" + "\n".join(",".join(f"{v:.12g}" for v in r) for r in rows) + "\n")
    return path


def test_csv_in_both_layouts_and_units_reads_back_the_circuit(tmp_path):
    y = bvd_admittance(F, R, L, C, C0, TD)
    z = 1 / y
    a = read_admittance(_write(tmp_path / "z.csv", "# analyser export\nFrequency (kHz),|Z| (kohm),Phase (deg)",
                               np.c_[F / 1e3, np.abs(z) / 1e3, np.degrees(np.angle(z))]))
    b = read_admittance(_write(tmp_path / "gb.csv", "f_hz,G (mS),B (mS)", np.c_[F, y.real * 1e3, y.imag * 1e3]))
    for d in (a, b):
        np.testing.assert_allclose(d.freqs_hz, F, rtol=1e-11)
        np.testing.assert_allclose(d.admittance, y, rtol=1e-10)
    (fit,) = fit_bvd(a)
    assert fit.values["q_m"] == pytest.approx(TRUTH["q_m"], rel=1e-6)


def test_two_resonances_are_fitted_each_in_its_window():
    f = np.linspace(15e3, 35e3, 2001)
    c2 = 1.0 / ((2 * np.pi * 30e3) ** 2 * 0.05)
    y = bvd_admittance(f, R, L, C, C0, TD) + 1.0 / (80.0 * 30e3 / f + 1j * 2 * np.pi * f * 0.05
                                                     + 1.0 / (1j * 2 * np.pi * f * c2))
    fits = fit_bvd(AdmittanceData(f, y, "two"))
    assert [round(ft.values["f_s_hz"] / 1e3) for ft in fits] == [20, 30]
    # each window sees the other branch as a background the constant-C0 circuit cannot follow: its
    # susceptance is ~10 % of w C0 there and changes by about its own size across the window (~20 %
    # wide), absorbed into C0 and R: a bias of order 10 % x 20 % = 2 % on Q_m, hence 3 %
    assert fits[0].values["f_s_hz"] == pytest.approx(FS, rel=1e-3)
    assert fits[1].values["f_s_hz"] == pytest.approx(30e3, rel=1e-3)
    assert fits[0].values["q_m"] == pytest.approx(TRUTH["q_m"], rel=0.03)
    assert fits[1].values["q_m"] == pytest.approx(2 * math.pi * 30e3 * 0.05 / 80.0, rel=0.03)


@pytest.mark.parametrize("header, rows, message", [
    ("frequency,|Z|", [[1e3 * (i + 1), 10.0] for i in range(20)], "needs frequency and either"),
    ("frequency,voltage,phase", [[1.0, 1.0, 1.0]] * 20, "not a known column"),
    ("frequency (GHz),G,B", [[1.0, 1.0, 1.0]] * 20, "unit 'ghz' not known"),
    ("frequency,G,B", [[1e3 * (i + 1), 1e-3, 1e-3] for i in range(5)], "at least 12"),
    ("frequency,G,B", [[1e3 * (20 - i), 1e-3, 1e-3] for i in range(20)], "strictly increasing"),
    ("frequency,G,B", [[1e3 * (i + 1), -1e-3 if i == 7 else 1e-3, 1e-3] for i in range(20)], "line 9: a passive"),
    ("frequency,|Z|,phase", [[1e3 * (i + 1), 10.0, 120.0] for i in range(20)], "within \\+-90 deg"),
])
def test_malformed_files_are_refused_naming_the_problem(tmp_path, header, rows, message):
    with pytest.raises(ParameterError, match=message):
        read_admittance(_write(tmp_path / "bad.csv", header, rows))


def test_text_and_missing_files_are_refused(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("frequency,G,B\n" + "1000,abc,1\n" * 20)
    with pytest.raises(ParameterError, match="line 2: not a number"):
        read_admittance(p)
    with pytest.raises(ParameterError, match="not a readable file"):
        read_admittance(tmp_path / "none.csv")
    with pytest.raises(ParameterError, match="no peak inside"):
        fit_bvd(AdmittanceData(F, 1j * F * 1e-9 + F * 1e-12, "ramp"))


@pytest.fixture(scope="module")
def k33():
    from test_fem_util import rod
    from fem.assembly import assemble
    from fem.modal import modal_analysis

    system = assemble(rod(0.04, 0.001, n_r=1, n_z=20, material="PZT-4", poling=(0, 0, 1), electrodes=True))
    modes = modal_analysis(system, 40e3, 6)
    return system, modes, int(np.nanargmax(modes.k_eff))


@pytest.mark.parametrize("tan_delta", [0.0, 0.004])
def test_fe_admittance_of_a_k33_rod_gives_its_modal_q(k33, tan_delta):
    """The FE admittance (modal sweep, f_s - 3 % .. f_p + 3 %) of a k33 rod with q_mech 100: the
    fitted Q_m equals the mode's 1 / eta within 1 % (the reference's accuracy: the neighbour modes,
    30 % and more away, load the window by ~(f / f_n)^2 k_n^2 ~ 1e-3; the truncation of the modal
    sweep is 0.04 %). Then the losses calibrated from the fit (q_mech for which the FE mode has the
    fitted Q_m) give back the q_mech put in within the same 1 %, and tan delta no larger than the
    one put in (the fitted C0 holds the clamped capacitance, the only one with dielectric loss,
    plus the other modes' static share, which has none)."""
    from fem.bvd import calibrated_losses
    from fem.harmonic import LossModel, harmonic_sweep, modal_basis

    system, modes, w = k33
    loss = LossModel(100.0, tan_delta)
    basis = modal_basis(system, modes.f_r_hz[w], loss=loss, modes=modes)
    f = np.linspace(modes.f_r_hz[w] * 0.97, modes.f_a_hz[w] * 1.03, 400)
    res = harmonic_sweep(system, f, 1.0, loss=loss, basis=basis, surfaces=())
    (fit,) = fit_bvd(AdmittanceData(f, res.admittance, "k33 FE"))
    assert fit.values["f_s_hz"] == pytest.approx(modes.f_r_hz[w], rel=1e-4)
    assert fit.values["k_eff"] == pytest.approx(modes.k_eff[w], rel=0.01)
    assert fit.values["q_m"] == pytest.approx(1.0 / basis.eta[w], rel=0.01)
    cal = calibrated_losses(system, modes, w, fit)
    assert cal.q_mech == pytest.approx(100.0, rel=0.01)
    assert cal.origin == "measured" and cal.tan_delta <= tan_delta + 3 * fit.ci95["tan_delta"]


def test_harmonic_command_takes_its_losses_from_a_measured_sweep(tmp_path, capsys):
    """The command's own admittance sweep at q_mech 250 written as an analyser CSV (G, B) and read
    back with --admittance: the losses it then uses are q_mech 250 within 1 % (the fit's accuracy
    above) and their origin and source are printed and written."""
    import json

    from geometry.examples import k33_rod
    from fem.harmonic_cli import main

    design = tmp_path / "rod.toml"
    k33_rod().save(design)
    common = ["--design", str(design), "--surface", "electrode_top", "--mesh-size", "0.004", "--modes", "4", "-q"]
    assert main(common + ["--q-mech", "250", "--tan-delta", "0.004", "--points", "400",
                          "--json", str(tmp_path / "a.json")]) == 0
    sw = json.loads((tmp_path / "a.json").read_text())["sweep"]
    rows = np.c_[sw["freqs_hz"], sw["admittance_s"]["re"], sw["admittance_s"]["im"]]
    _write(tmp_path / "meas.csv", "frequency (Hz),G (S),B (S)", rows)
    capsys.readouterr()
    assert main(common + ["--admittance", str(tmp_path / "meas.csv"), "--points", "11",
                          "--json", str(tmp_path / "b.json")]) == 0
    out = capsys.readouterr().out
    assert "admittance fit (" in out and "Q_mech" in out and "(measured)" in out
    losses = json.loads((tmp_path / "b.json").read_text())["losses"]
    assert losses["origin"] == "measured" and "BVD fit" in losses["source"]
    assert losses["q_mech"] == pytest.approx(250.0, rel=0.01)


@pytest.mark.parametrize("module", ["fem.harmonic_cli", "results.__main__", "results.coupled_cli"])
def test_every_drive_command_refuses_a_bad_sweep_before_any_solve(module):
    import importlib

    from test_cli_fuzz import run_clean

    main = importlib.import_module(module).main
    extra = ["--horn", "fem"] if module == "results.coupled_cli" else []

    def setup(root):
        (root / "bad.csv").write_text("frequency,G\n" + "1,1\n" * 20)

    assert "needs frequency and either" in run_clean(main, extra + ["--admittance", "bad.csv"], setup)
    assert "not a readable file" in run_clean(main, extra + ["--admittance", "none.csv"])
    assert "drop --q-mech" in run_clean(main, extra + ["--admittance", "bad.csv", "--q-mech", "50"], setup)


def test_a_window_the_circuit_cannot_follow_is_flagged():
    """A second, strong resonance inside the window (no conductance peak of its own: it sits on the
    first one's anti-resonance side) is not a BVD circuit: the misfit is flagged, not hidden."""
    f = np.linspace(19e3, 22e3, 301)
    c2 = 1.0 / ((2 * np.pi * 21.5e3) ** 2 * 0.02)
    y = bvd_admittance(f, R, L, C, C0, TD) + 0.3 / (5.0 + 1j * 2 * np.pi * f * 0.02 + 1.0 / (1j * 2 * np.pi * f * c2))
    fit = fit_resonance(f, y)
    assert fit.misfit and "MISFIT" in fit.text()
    assert not fit_resonance(F, bvd_admittance(F, R, L, C, C0, TD)).misfit
