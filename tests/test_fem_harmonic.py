"""Harmonic response and ring-up against independent references.

Model: a free stack of four PZT-8 layers (10 x 10 mm, 5 mm each, alternately poled, electrodes
between them: ground at the ends and the middle, hot in between), P2 fields. References:
- static capacitance of a free stack: exactly N eps33^T A / t (stress-free uniform field);
- the modal analysis (resonance / anti-resonance of the open- and short-circuit eigenproblems);
- the direct complex solution (second method for the modal superposition);
- full-system Newmark (second method for the modal ring-up).
"""

import numpy as np
import pytest
from skfem import MeshTet

from rpud_common import ParameterError
from geometry.materials import get_material
from geometry.mesh import Electrode, Region, TaggedMesh
from fem.assembly import assemble
from fem.harmonic import LossModel, harmonic_sweep, modal_basis, working_point
from fem.materials import piezo_matrices, strain_charge
from fem.modal import modal_analysis
from fem.transient import ring_up

A_SIDE, T_LAYER, N_LAYERS = 0.01, 0.005, 4


def _stack() -> TaggedMesh:
    a, t = A_SIDE, T_LAYER
    m = MeshTet.init_tensor(np.linspace(-a / 2, a / 2, 4), np.linspace(-a / 2, a / 2, 4),
                            np.linspace(0, N_LAYERS * t, 3 * N_LAYERS + 1))
    p, cells = m.p.T, m.t.T
    layer = np.minimum((p[cells, 2].mean(axis=1) // t).astype(int), N_LAYERS - 1)
    f = m.facets.T
    sets, electrodes = {}, []
    for k in range(N_LAYERS + 1):
        sets[f"electrode_{k}"] = f[np.all(np.isclose(p[f, 2], k * t), axis=1)]
        electrodes.append(Electrode(f"electrode_{k}", "hot" if k % 2 else "ground"))
    regions = tuple(Region(f"ring_{i + 1}", "stack", "PZT-8", (0.0, 0.0, 1.0 if i % 2 == 0 else -1.0))
                    for i in range(N_LAYERS))
    return TaggedMesh(p, cells, layer, regions, sets, tuple(electrodes))


@pytest.fixture(scope="module")
def system():
    return assemble(_stack())


@pytest.fixture(scope="module")
def modes(system):
    return modal_analysis(system, 70e3, 8)


def _longitudinal(modes):
    i = int(np.argmax(modes.shares[:, 0]))
    return modes.f_r_hz[i], modes.f_a_hz[i]


TIP = ("electrode_4",)


def test_static_admittance_is_parallel_plate_capacitance(system):
    _, _, eps_T = strain_charge(piezo_matrices(get_material("PZT-8")))
    c_pp = N_LAYERS * eps_T[2, 2] * A_SIDE ** 2 / T_LAYER
    res = harmonic_sweep(system, [100.0], 1.0, loss=LossModel(np.inf, 0.0), method="direct", surfaces=TIP)
    c_fe = res.admittance[0].imag / (2 * np.pi * 100.0)
    assert res.admittance[0].real == pytest.approx(0.0, abs=1e-12)
    assert c_fe == pytest.approx(c_pp, rel=1e-3)          # issue tolerance 1 %


def test_admittance_peak_and_dip_at_resonance_and_antiresonance(system, modes):
    f_r, f_a = _longitudinal(modes)
    loss = LossModel(1000.0, 0.004)
    freqs = np.linspace(0.97 * f_r, 1.03 * f_a, 801)
    basis = modal_basis(system, f_r, 8, loss=loss, modes=modal_analysis(system, 70e3, 8, open_circuit=False))
    res = harmonic_sweep(system, freqs, 1.0, loss=loss, basis=basis, surfaces=TIP)
    assert res.f_r_hz == pytest.approx(f_r, rel=5e-3)
    assert res.f_a_hz == pytest.approx(f_a, rel=5e-3)
    # the open-circuit eigenvalue problem really is independent: f_a well above f_r (k_eff ~ 0.6)
    assert f_a / f_r > 1.1


@pytest.mark.parametrize("ratio", [0.9, 0.99, 1.0, 1.005, 1.1])
def test_modal_superposition_equals_direct_solution(system, modes, ratio):
    f_r, _ = _longitudinal(modes)
    loss = LossModel(300.0, 0.004)
    basis = modal_basis(system, f_r, 8, loss=loss)
    f = ratio * f_r
    direct = working_point(system, f, 2.0, loss=loss, surfaces=TIP)
    modal = working_point(system, f, 2.0, loss=loss, surfaces=TIP, basis=basis)
    assert modal.tip_amplitude_m == pytest.approx(direct.tip_amplitude_m, rel=5e-3)
    assert abs(modal.admittance - direct.admittance) <= 5e-3 * abs(direct.admittance)
    assert modal.power_w == pytest.approx(direct.power_w, rel=2e-2)


def test_peak_amplitude_scales_with_q_and_is_unbounded_without_loss(system, modes):
    f_r, _ = _longitudinal(modes)
    freqs = f_r * np.linspace(0.995, 1.005, 2001)
    peaks = {}
    for q in (100.0, 200.0):
        res = harmonic_sweep(system, freqs, 1.0, loss=LossModel(q, 0.0), surfaces=TIP, n_modes=8)
        peaks[q] = res.amplitude("electrode_4").max()
    assert peaks[200.0] / peaks[100.0] == pytest.approx(2.0, rel=2e-2)
    lossless = LossModel(np.inf, 0.0)
    amp = [working_point(system, f_r * (1 + eps), 1.0, loss=lossless, surfaces=TIP).tip_amplitude_m
           for eps in (1e-3, 1e-4, 1e-5)]
    # |x| ~ 1 / (2 eps) near an undamped resonance: every decade closer, ten times larger
    assert amp[1] / amp[0] == pytest.approx(10.0, rel=2e-2)
    assert amp[2] / amp[1] == pytest.approx(10.0, rel=2e-2)
    assert amp[2] > 100 * peaks[200.0]
    # exactly on the resonance a lossless model has no finite answer: refused, resonance named
    f_exact = f_r
    with pytest.raises(ParameterError, match=r"resonance .* lossless model: the response is unbounded"):
        working_point(system, f_exact, 1.0, loss=lossless, surfaces=TIP)
    basis = modal_basis(system, f_r, 8, loss=lossless, modes=modes)
    with pytest.raises(ParameterError, match="unbounded"):
        harmonic_sweep(system, [0.99 * f_exact, f_exact], 1.0, loss=lossless, surfaces=TIP, basis=basis)


def test_ring_up_settles_on_the_harmonic_amplitude(system, modes):
    f_r, _ = _longitudinal(modes)
    q = 50.0
    loss = LossModel(q, 0.004)
    tau = 2 * q / (2 * np.pi * f_r)                 # amplitude envelope time constant
    res = ring_up(system, f_r, 1.0, 12 * tau, loss=loss, surfaces=TIP, n_modes=8)
    harmonic = working_point(system, f_r, 1.0, loss=loss, surfaces=TIP)
    assert res.steady_amplitude("electrode_4") == pytest.approx(harmonic.tip_amplitude_m, rel=2e-2)
    t_env, env = res.envelope("electrode_4")
    # the envelope grows as 1 - exp(-t / tau): at one time constant about 63 % of the final value
    k = np.searchsorted(t_env, tau)
    assert env[k] / harmonic.tip_amplitude_m == pytest.approx(1 - np.exp(-1), abs=0.05)


def test_modal_ring_up_equals_full_newmark(system, modes):
    f_r, _ = _longitudinal(modes)
    loss = LossModel(50.0, 0.0)
    kw = dict(loss=loss, surfaces=TIP, steps_per_cycle=40)
    modal = ring_up(system, f_r, 1.0, 20 / f_r, prewarp=False, n_modes=8, **kw)
    direct = ring_up(system, f_r, 1.0, 20 / f_r, method="direct", **kw)
    ym, yd = modal.surfaces["electrode_4"]["axial"], direct.surfaces["electrode_4"]["axial"]
    assert np.max(np.abs(ym - yd)) <= 1e-2 * np.max(np.abs(yd))


def test_bad_input_is_a_clear_error(system):
    with pytest.raises(ParameterError, match="voltage = 0"):
        working_point(system, 50e3, 0.0, surfaces=TIP)
    with pytest.raises(ParameterError, match="freq"):
        harmonic_sweep(system, [-1.0, 5.0], 1.0, surfaces=TIP)
    with pytest.raises(ParameterError, match="surface = 'horn_tip'"):
        working_point(system, 50e3, 1.0)
    with pytest.raises(ParameterError, match="q_mech"):
        LossModel(q_mech=-5.0)
    with pytest.raises(ParameterError, match="t_end"):
        ring_up(system, 50e3, 1.0, 0.0, surfaces=TIP)


def test_tip_damper_in_modal_basis_equals_direct_solution(system, modes):
    """A viscous damper c on the tip's mean axial motion: modal rank-one term vs the direct
    solution with ``j w c a a^T`` assembled into the full system (a: the mean-axial row)."""
    import scipy.sparse as sp

    from fem.harmonic import loss_matrix, surface_functional
    from fem.solvers import factorize

    f_r, _ = _longitudinal(modes)
    loss = LossModel(300.0, 0.004)
    basis = modal_basis(system, f_r, 8, loss=loss)
    c = 10.0                                       # N s/m: comparable to the modal damping here
    modal = working_point(system, f_r, 1.0, loss=loss, surfaces=TIP, basis=basis, tip_damping=c)
    free_only = working_point(system, f_r, 1.0, loss=loss, surfaces=TIP, basis=basis)
    split = system.split(())
    L = loss_matrix(system, loss)
    a = surface_functional(system, "electrode_4").rows[0][:, split.free]
    w = 2 * np.pi * f_r
    A = (split.K - w ** 2 * split.M + 1j * L[split.free][:, split.free] + 1j * w * c * (a.T @ a)).tocsr()
    lh = np.asarray(L[:, [system.hot_dof]].toarray()).ravel()[split.free]
    xf = factorize(sp.csr_matrix(A))(-(split.k_hot + 1j * lh) / system.phi_scale)
    direct = abs((a @ xf).item())
    assert modal.tip_amplitude_m == pytest.approx(direct, rel=5e-3)
    assert modal.tip_amplitude_m < 0.8 * free_only.tip_amplitude_m      # the damper matters here
    with pytest.raises(ParameterError, match="tip_damping"):
        working_point(system, f_r, 1.0, loss=loss, surfaces=TIP, tip_damping=1.0)


def test_modal_sweep_equals_direct_across_the_whole_band(system, modes):
    """From below f_r to above f_a, anti-resonance dip included (where |Y| is smallest and the
    truncated modes' frequency dependence matters most: the second-order residual handles it)."""
    f_r, f_a = _longitudinal(modes)
    loss = LossModel(300.0, 0.004)
    basis = modal_basis(system, f_r, 8, loss=loss)
    probe = np.array([0.97 * f_r, 0.5 * (f_r + f_a), 0.99 * f_a, f_a, 1.03 * f_a])
    modal = harmonic_sweep(system, probe, 1.0, loss=loss, basis=basis, surfaces=TIP)
    direct = harmonic_sweep(system, probe, 1.0, loss=loss, method="direct", surfaces=TIP)
    # |Y| at the dip is ~800x smaller than at the peak: 2 % there, 1 % elsewhere
    rtol = np.array([1e-2, 1e-2, 1e-2, 2e-2, 1e-2])
    ym, yd = np.abs(modal.admittance), np.abs(direct.admittance)
    assert np.all(np.abs(ym - yd) <= rtol * yd)
    np.testing.assert_allclose(modal.amplitude("electrode_4"), direct.amplitude("electrode_4"), rtol=1e-2)


def test_basis_reusing_another_basis_factorisation_is_the_same_basis(system, modes):
    """The residual's factorisation of K - sigma M does not depend on the losses: a basis that
    borrows it (``reuse=``) equals one built from scratch, and its working point too."""
    f_r, _ = _longitudinal(modes)
    b1 = modal_basis(system, f_r, 8, loss=LossModel(300.0, 0.004), modes=modes)
    fresh = modal_basis(system, f_r, 8, loss=LossModel(), modes=modes)
    reused = modal_basis(system, f_r, 8, loss=LossModel(), modes=modes, reuse=b1)
    assert reused.factor is b1.factor and fresh.factor is not b1.factor
    for name in ("R", "W", "g", "R_terms"):
        np.testing.assert_allclose(getattr(reused, name), getattr(fresh, name), rtol=1e-10, atol=0)
    a = working_point(system, f_r * 1.001, 1.0, surfaces=TIP, basis=fresh)
    b = working_point(system, f_r * 1.001, 1.0, surfaces=TIP, basis=reused)
    assert b.tip_amplitude_m == pytest.approx(a.tip_amplitude_m, rel=1e-10)


def test_basis_on_modes_that_kept_their_factorisation_reuses_it(system, modes):
    """A modal analysis that keeps its factorisation of K - sigma M (the matching's final one)
    lends it to the basis's residual at the same shift: the same basis as one that factorises
    afresh to 1e-10 of each array's norm (PARDISO without/with weighted matching pivots
    differently: round-off of a shifted matrix conditioned ~ lambda / |lambda - sigma| < 1e4
    here, ~1e-12); the kept
    handle is not pickled."""
    import pickle

    f_r, _ = _longitudinal(modes)
    kept = modal_analysis(system, 70e3, 8, keep_factor=True)
    assert kept.factor is not None and modes.factor is None
    np.testing.assert_allclose(kept.f_r_hz, modes.f_r_hz, rtol=1e-12)
    reused = modal_basis(system, f_r, 8, loss=LossModel(300.0, 0.004), modes=kept)
    fresh = modal_basis(system, f_r, 8, loss=LossModel(300.0, 0.004), modes=modes)
    assert reused.sigma == fresh.sigma == kept.sigma and reused.factor is kept.factor
    for name in ("R", "W", "g", "R_terms"):          # relative to each array's norm: round-off
        a, b = getattr(reused, name), getattr(fresh, name)
        assert np.linalg.norm(a - b) <= 1e-10 * np.linalg.norm(b), name
    assert pickle.loads(pickle.dumps(kept)).factor is None


# --------------------------------------------------------------------------- wide bands


@pytest.fixture(scope="module")
def k33():
    from test_fem_util import rod

    return assemble(rod(0.04, 0.001, n_r=1, n_z=20, material="PZT-4", poling=(0, 0, 1), electrodes=True))


def test_modal_sweep_over_three_resonances_equals_direct(k33):
    """20-280 kHz spans the k33 rod's 1st, 3rd and 5th longitudinal resonances: the basis grows
    until it represents the band, and every probe (peaks and dips included) is within 1 %."""
    from scipy.signal import find_peaks

    loss = LossModel(100.0, 0.01)
    f = np.linspace(20e3, 280e3, 521)
    modal = harmonic_sweep(k33, f, 1.0, loss=loss, surfaces=("top",))
    y = np.abs(modal.admittance)
    peaks, dips = find_peaks(y)[0], find_peaks(-y)[0]
    assert len(peaks) == 3 and len(dips) == 3
    assert modal.basis_modes > 12                      # grown until the band is within reach
    checked = harmonic_sweep(k33, f, 1.0, loss=loss, surfaces=("top",), check=True)
    assert checked.check_error <= 0.01
    probe = np.unique(np.r_[peaks, dips, np.linspace(0, len(f) - 1, 6).astype(int)])
    direct = harmonic_sweep(k33, f[probe], 1.0, loss=loss, surfaces=("top",), method="direct")
    np.testing.assert_allclose(modal.admittance[probe], direct.admittance, rtol=1e-2)
    top_m, top_d = modal.surfaces["top"]["axial"][probe], direct.surfaces["top"]["axial"]
    assert np.max(np.abs(top_m - top_d)) <= 1e-2 * np.max(np.abs(top_d))


def test_a_basis_that_cannot_represent_the_band_is_refused(k33):
    loss = LossModel(100.0, 0.01)
    narrow = modal_basis(k33, 40e3, 6, loss=loss)
    with pytest.raises(ParameterError, match=r"freqs.*misses the direct solution.*narrower band"):
        harmonic_sweep(k33, np.linspace(20e3, 280e3, 53), 1.0, loss=loss, surfaces=("top",), basis=narrow,
                       check=True)


def test_anti_resonance_with_dielectric_loss_equals_direct(k33):
    """At the anti-resonance |Y| is of the order of the losses: the loss coupling to the
    truncated modes must be kept beyond first order (first order: 9 % off with tan delta 0.01)."""
    loss = LossModel(100.0, 0.01)
    basis = modal_basis(k33, 45e3, 12, loss=loss)
    probe = np.array([45e3, 48e3, 50e3, 50.5e3, 51e3])
    modal = harmonic_sweep(k33, probe, 1.0, loss=loss, surfaces=(), basis=basis, check=False)
    direct = harmonic_sweep(k33, probe, 1.0, loss=loss, surfaces=(), method="direct")
    np.testing.assert_allclose(modal.admittance, direct.admittance, rtol=3e-3)


def test_harmonic_cli_drives_the_coupled_mode_and_says_what_it_drives(tmp_path, capsys):
    """Near a k33 rod's resonance several modes lie within 40 %; the drive excites the one with
    the electromechanical coupling, and an off-resonance --freq is shown as the drive, next to
    that mode's own f_r and f_a."""
    import json

    from geometry.examples import k33_rod
    from fem.harmonic_cli import main

    design = tmp_path / "rod.toml"
    k33_rod().save(design)
    out = tmp_path / "h.json"
    argv = ["--design", str(design), "--surface", "electrode_top", "--points", "11", "--mesh-size", "0.004", "--modes", "4",
            "--json", str(out), "-q"]                  # -q: the result lines first, no inputs line
    assert main(argv) == 0
    first = json.loads(out.read_text())["working_mode"]
    assert first["k_eff"] > 0.5 and "drive" not in capsys.readouterr().out.splitlines()[0]
    assert first["f_r_hz_error"] is None                  # no --error: stated as not estimated (fem.errors)
    assert main(argv + ["--freq", "41000"]) == 0
    line = capsys.readouterr().out.splitlines()[0]
    assert line.startswith("drive 41000.0 Hz; working mode") and f"f_r {first['f_r_hz']:.1f} Hz" in line
