"""fem.modal against 1-D theory and IEEE Std 176; orthogonality; pairing; CLI errors.

Tolerances: elastic rod 0.5 % (Rayleigh-Love corrected longitudinal, plain torsion);
piezo resonators 0.5 % against IEEE 176 formulas evaluated here from the library's
stress-charge constants, 1 % against the worked numbers of references.md (those were computed
from the rounded strain-charge datasheet, which differs from the stress-charge set by ~0.9 %
in f_p of the k33 rod).
"""

import numpy as np
import pytest
from scipy.optimize import brentq

from fem.assembly import assemble
from fem.materials import piezo_matrices, strain_charge
from fem.modal import modal_analysis
from fem.modal_cli import main
from rpud_common import run_cli
from test_fem_util import bar, rod

E, NU, RHO = 209e9, 0.269, 7890.0


@pytest.fixture(scope="module")
def steel_rod():
    L, R = 0.1, 0.0025                       # L/R = 40
    return L, R, assemble(rod(L, R, n_r=2, n_z=40))


def test_steel_rod_longitudinal_and_torsional(steel_rod, vv):
    L, R, s = steel_rod
    res = modal_analysis(s, 21e3, 6)
    c = np.sqrt(E / RHO)
    f_long = c / (2 * L) * (1 - 0.5 * NU ** 2 * (R ** 2 / 2) * (np.pi / L) ** 2)   # Rayleigh-Love
    f_tors = np.sqrt(E / (2 * (1 + NU)) / RHO) / (2 * L)
    i_l = int(np.argmax(res.shares[:, 0]))
    i_t = int(np.argmax(res.shares[:, 1]))
    assert res.shares[i_l, 0] > 0.95 and res.shares[i_t, 1] > 0.95
    vv.record("VV-FE-01", title="Free-free steel rod: first longitudinal mode", quantity="frequency",
              description="A steel rod (E = 209 GPa, nu = 0.269, rho = 7890 kg/m^3), length 100 mm, radius "
              "2.5 mm (L / R = 40), meshed by rod(L, R, n_r=2, n_z=40) of tests/test_fem_util.py, "
              "assembled by fem.assembly and solved by fem.modal_analysis. "
              "Free at both ends; the mode with the largest longitudinal share.",
              reference="1-D bar f = c / (2 L), c = sqrt(E / rho), with the Rayleigh-Love lateral-inertia "
              "factor 1 - nu^2 (R^2 / 2) (pi / L)^2 / 2.",
              assumptions="Linear isotropic elasticity; slender rod (Rayleigh-Love's lateral-inertia correction); "
              "tolerance 0.5 % covers the 3-D mesh's discretisation error.",
              target=f_long, computed=res.f_r_hz[i_l], tolerance=0.005, unit="Hz")
    vv.record("VV-FE-02", title="Free-free steel rod: first torsional mode", quantity="frequency",
              description="A steel rod (E = 209 GPa, nu = 0.269, rho = 7890 kg/m^3), length 100 mm, radius "
              "2.5 mm (L / R = 40), meshed by rod(L, R, n_r=2, n_z=40) of tests/test_fem_util.py, "
              "assembled by fem.assembly and solved by fem.modal_analysis. "
              "Free at both ends; the mode with the largest torsional share.",
              reference="Exact torsion of a circular rod: f = c_s / (2 L), c_s = sqrt(G / rho), G = E / (2 (1 + nu)).",
              assumptions="Linear isotropic elasticity; tolerance 0.5 % covers the 3-D mesh's discretisation error.",
              target=f_tors, computed=res.f_r_hz[i_t], tolerance=0.005, unit="Hz")
    assert res.f_r_hz[i_l] == pytest.approx(f_long, rel=0.005)
    assert res.f_r_hz[i_t] == pytest.approx(f_tors, rel=0.005)
    assert res.labels[i_l] == "longitudinal" and res.labels[i_t] == "torsional"
    # no electrodes: anti-resonance = resonance, k_eff = 0
    assert np.allclose(res.f_a_hz, res.f_r_hz) and np.all(res.k_eff == 0)
    # energy orthogonality of the computed modes
    V = res.vectors
    assert np.abs(V.T @ (s.M @ V) - np.eye(V.shape[1])).max() < 1e-8
    KV = V.T @ (s.K @ V)
    lam = (2 * np.pi * res.f_r_hz) ** 2
    assert np.abs(KV - np.diag(lam)).max() < 1e-8 * lam.max()
    # shapes are the displacement part, (n_modes, n_nodes, 3)
    assert res.shapes.shape == (6, s.n_nodes, 3)


def test_clamped_free_rod_quarter_wave(steel_rod, vv):
    L, R, s = steel_rod
    c = np.sqrt(E / RHO)
    res = modal_analysis(s, c / (4 * L), 3, clamp=["bottom"])
    i = int(np.argmax(res.shares[:, 0]))
    assert len(res.rigid_hz) == 0
    vv.record("VV-FE-03", title="Clamped-free steel rod: quarter-wave mode", quantity="frequency",
              description="A steel rod (E = 209 GPa, nu = 0.269, rho = 7890 kg/m^3), length 100 mm, radius "
              "2.5 mm (L / R = 40), meshed by rod(L, R, n_r=2, n_z=40) of tests/test_fem_util.py, "
              "assembled by fem.assembly and solved by fem.modal_analysis. "
              "Every degree of freedom of the bottom face clamped.",
              reference="1-D quarter-wave bar: f = c / (4 L), c = sqrt(E / rho).",
              assumptions="Linear isotropic elasticity; the clamp also stops the face's lateral contraction and "
              "lateral inertia is neglected in the reference: tolerance 0.5 %.",
              target=c / (4 * L), computed=res.f_r_hz[i], tolerance=0.005, unit="Hz")
    assert res.f_r_hz[i] == pytest.approx(c / (4 * L), rel=0.005)
    tip = s.displacement(res.vectors[:, i])
    assert np.abs(tip[s.surface_nodes("bottom")]).max() == 0.0


def test_free_body_has_six_rigid_modes():
    s = assemble(rod(0.05, 0.0025, n_r=1, n_z=10))
    res = modal_analysis(s, 0.0, 2)
    assert len(res.rigid_hz) == 6
    assert np.all(np.abs(res.rigid_hz) < 1.0)             # Hz
    assert np.all(res.f_r_hz > 1000.0)


def _ieee():
    s, d, eT = strain_charge(piezo_matrices("PZT-4"))
    rho, l = 7500.0, 0.04
    k33 = d[2, 2] ** 2 / (s[2, 2] * eT[2, 2])
    fp = 1 / (2 * l * np.sqrt(rho * s[2, 2] * (1 - k33)))
    fs = brentq(lambda f: np.pi / 2 * f / fp * np.tan(np.pi / 2 * (fp - f) / fp) - k33, 0.5 * fp, fp * (1 - 1e-12))
    k31 = d[2, 0] ** 2 / (s[0, 0] * eT[2, 2])
    fs1 = 1 / (2 * l * np.sqrt(rho * s[0, 0]))
    fp1 = brentq(lambda f: np.pi / 2 * f / fs1 * np.tan(np.pi / 2 * (f - fs1) / fs1) - k31 / (1 - k31),
                 fs1 * (1 + 1e-12), 1.5 * fs1)
    return (fs, fp), (fs1, fp1)


def test_k33_rod_against_ieee176(vv):
    (fs, fp), _ = _ieee()
    s = assemble(rod(0.04, 0.001, n_r=1, n_z=20, material="PZT-4", poling=(0, 0, 1), electrodes=True))
    res = modal_analysis(s, 40e3, 3)
    i = int(np.argmax(res.k_eff))
    vv.record("VV-FE-04", title="3-D piezoelectric k33 rod against IEEE 176: anti-resonance",
              quantity="parallel resonance f_p",
              description="A PZT-4 rod, length 40 mm and radius 1 mm, poled along its axis with electrodes on "
              "its end faces, free; the 3-D coupled piezo-elastic model (fem.assembly, fem.modal_analysis) "
              "at the mode of largest effective coupling.",
              reference="IEEE Std 176 length-extensional k33 bar: f_p = 1 / (2 L sqrt(rho s33^E (1 - k33^2))), "
              "from the library's stress-charge constants converted to strain-charge form.",
              assumptions="Lossless; 1-D theory (no lateral inertia) for a rod of L / R = 40: tolerance 0.5 %.",
              target=fp, computed=res.f_a_hz[i], tolerance=0.005, unit="Hz")
    assert res.f_r_hz[i] == pytest.approx(fs, rel=0.005)
    assert res.f_a_hz[i] == pytest.approx(fp, rel=0.005)
    assert res.f_r_hz[i] == pytest.approx(38352, rel=0.01)    # references.md worked numbers
    assert res.f_a_hz[i] == pytest.approx(50271, rel=0.01)
    assert res.mac[i] > 0.99
    k33_ieee = np.sqrt(1 - (fs / fp) ** 2)
    assert res.k_eff[i] == pytest.approx(k33_ieee, rel=0.01)


def test_k31_bar_against_ieee176(vv):
    _, (fs, fp) = _ieee()
    s = assemble(bar(0.04, 0.004, 0.001, n=(40, 4, 1)))
    res = modal_analysis(s, 42e3, 4)
    i = int(np.argmax(res.k_eff))
    vv.record("VV-FE-05", title="3-D piezoelectric k31 bar against IEEE 176: resonance",
              quantity="series resonance f_s",
              description="A PZT-4 bar 40 x 4 x 1 mm, poled through its thickness with electrodes on its large "
              "faces, free; the 3-D coupled piezo-elastic model at the mode of largest effective coupling.",
              reference="IEEE Std 176 length-extensional k31 bar: f_s = 1 / (2 L sqrt(rho s11^E)).",
              assumptions="Lossless; 1-D theory for a thin, narrow bar: tolerance 0.5 %.",
              target=fs, computed=res.f_r_hz[i], tolerance=0.005, unit="Hz")
    assert res.f_r_hz[i] == pytest.approx(fs, rel=0.005)
    assert res.f_a_hz[i] == pytest.approx(fp, rel=0.005)
    assert res.f_r_hz[i] == pytest.approx(41155, rel=0.01)
    assert res.f_a_hz[i] == pytest.approx(43059, rel=0.01)
    js = res.to_dict()
    assert js["ndof"] == s.ndof and len(js["modes"]) == 4 and "eigen_s" in js["timings"]


def test_cli_bad_input_is_one_line_exit_2(tmp_path, capsys):
    out = tmp_path / "modes.json"
    assert run_cli(main, ["--design", str(tmp_path / "none.toml"), "--near", "-5", "--json", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--near" in err[0]
    assert run_cli(main, ["--design", str(tmp_path / "none.toml"), "--near", "20000", "--modes", "0",
                          "--json", str(out)]) == 2
    assert run_cli(main, ["--design", str(tmp_path / "none.toml"), "--near", "20000",
                          "--json", str(out)]) == 2
    assert not out.exists()


def test_blas_threads_limits_openblas_only_inside_the_block():
    from threadpoolctl import threadpool_info, threadpool_limits

    from fem.solvers import blas_threads

    def openblas():
        return [i["num_threads"] for i in threadpool_info() if i["internal_api"] == "openblas"]

    # two threads outside, whatever the environment asks (make test runs single-threaded)
    with threadpool_limits(limits=2, user_api="blas"):
        before = openblas()
        assert before and set(before) == {2}, "numpy/scipy bundle OpenBLAS on every supported platform"
        with blas_threads(1):
            assert openblas() == [1] * len(before)
        assert openblas() == before


def test_blas_threads_limits_mkl_too_when_asked():
    """``blas_threads(1, mkl=True)``: PARDISO's MKL on one thread in the calling thread inside the
    block, its own count again after it (the command line's worker threads each set it)."""
    from threadpoolctl import threadpool_info, threadpool_limits

    from fem.solvers import blas_threads, pardiso_available

    if not pardiso_available():
        pytest.skip("no MKL here")

    def mkl():
        return [i["num_threads"] for i in threadpool_info() if i["internal_api"] == "mkl"]

    with threadpool_limits(limits=2, user_api="blas"):
        before = mkl()
        assert before and set(before) == {2}
        with blas_threads(1, mkl=True):
            assert mkl() == [1] * len(before)
        assert mkl() == before
        with blas_threads(1):
            assert mkl() == before
