"""The independent axisymmetric (r, z) reference model (tests/axisym_reference.py), and the 3-D
toolkit against it.

The reference itself is checked first against exact or classical solutions:
- Pochhammer-Chree: a steel cylinder with sliding ends (u_z = 0, shear-free) carries the exact
  infinite-rod mode of wavenumber pi / L, here at k a = pi / 2 (7 % below the 1-D bar speed).
- IEEE Std 176 thickness mode: a PZT-4 disc with u_r = 0 on its rim is exactly the 1-D
  laterally clamped plate, so f_s, f_p and the admittance (lossy: c^E (1 + j/Q), eps^S
  (1 - j tan delta), the loss model of fem.harmonic; and lossless) are exact.
  The exact values are roots and closed forms evaluated to round-off; what separates the model
  from them is its discretisation error, which each test takes from the model itself: P2
  eigenvalues converge as h^4, so a level twice as coarse puts the error at |f(2h) - f(h)| / 15
  (two_level); the frequencies must lie within twice that (a pre-asymptotic ratio down to 8.5
  instead of 16), and the admittance within the frequencies' error times its sensitivity to
  f_s and f_p (d ln Y / d ln f up to 32 between f_s and f_p).
- IEEE Std 176 k33 rod (L / R = 20): 1-D theory with the Rayleigh-Love lateral-inertia factor
  (effective Poisson ratio -s13/s33 at constant field for f_s, constant D for f_p): 1e-4.
Then the default drill without slots and teeth: three graded levels (h = 2.83, 2, 1.41 mm, ratio
sqrt 2) extrapolate with observed order ~4 to the independent values (converged to 1e-7, stated
to 0.01 Hz) within 2e-5: a third of the finest level's own error (6e-5 / 8e-5), so the
extrapolation must remove most of it (finer levels 2 / 1 / 0.5 mm: order 4.03,
19 682.311 / 21 410.332 Hz).
The 3-D default meshes are compared with these converged answers (TOL_3D, TOL_SANDWICH).
"""

import math

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.special import jv

import fem
import geometry
from geometry.examples import langevin_sandwich
from geometry.materials import EPS0, get_material
from rpud_common import ParameterError

import axisym_reference as ar
from reference_designs import reference_default
from geometry.examples import article_design

AXISYM_CONVERGED = (19682.31, 21410.33)
"""f_r, f_a (Hz) of the default design without slots and teeth, converged with the independent (r, z) model."""

TOL_3D = 0.006
"""Fractional agreement of the 3-D default mesh with the converged reference on the default design
without slots and teeth (+0.45 % f_r, +0.56 % f_a on that mesh: the re-entrant flange/horn and horn-step
edges converge as h^1.1). The 0.0005 aimed for is not met by the default mesh: isotropic graded
tetrahedra reach +0.044 % / +0.055 % only at ~260k DOFs (benchmarks/bench_mesh_grading.py --study),
too slow for the suite and the default."""

TOL_SANDWICH = 0.002
"""Fractional agreement of the 3-D default mesh of the Langevin sandwich (no re-entrant edge, only
material junctions on the surface) with the reference. The reference is converged to 1e-5
(test_sandwich_reference_converges), so the tolerance is the 3-D mesh's discretisation error
alone: a bound on it (+0.055 % f_r, +0.008 % f_a on that mesh), not an accuracy of the reference."""


def no_slots():
    """The default drill without slots, teeth, fillets and bolt part, at the lengths the constants
    here were computed for (tests/reference_designs.py)."""
    return geometry.filleted(reference_default(), 0.0).replace({"coupler.n_slots": 0, "coupler.n_teeth": 0,
                                                                "stack.bolt_diameter": 0.0})


# ---------------------------------------------------------------------------- exact checks


def two_level(fine, coarse):
    """Error of a P2 eigenfrequency at h from the level at 2h: |f(2h) - f(h)| / (2^4 - 1) (h^4),
    times 2 for a pre-asymptotic ratio (the estimate holds while the ratio of errors is >= 8.5)."""
    return 2 * abs(coarse - fine) / 15


def _pochhammer(w, k, a, c1, c2):
    """Pochhammer-Chree frequency function of the longitudinal modes (real for q^2 > 0)."""
    p, q = np.sqrt(complex(w ** 2 / c1 ** 2 - k ** 2)), np.sqrt(complex(w ** 2 / c2 ** 2 - k ** 2))
    pJ1 = p * jv(1, p * a)
    return ((2 / a) * (q * q + k * k) * pJ1 * jv(1, q * a) - (q * q - k * k) ** 2 * jv(0, p * a) * jv(1, q * a)
            - 4 * k * k * q * pJ1 * jv(0, q * a)).real


def test_pochhammer_chree_rod_with_sliding_ends(vv):
    m = get_material("steel_45")
    E, nu, rho = m.youngs_modulus, m.poisson_ratio, m.density
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    c1, c2, c0 = math.sqrt((lam + 2 * mu) / rho), math.sqrt(mu / rho), math.sqrt(E / rho)
    a, L = 0.005, 0.01
    k = math.pi / L
    # long waves: the equation reproduces Rayleigh-Love (checks the transcription)
    k_long = math.pi / 1.0
    w_long = brentq(_pochhammer, 0.7 * c0 * k_long, c0 * k_long, args=(k_long, a, c1, c2))
    assert w_long / (c0 * k_long) == pytest.approx(1 - 0.5 * nu ** 2 * (a ** 2 / 2) * k_long ** 2, abs=1e-9)
    f_exact = brentq(_pochhammer, 0.7 * c0 * k, c0 * k, args=(k, a, c1, c2)) / (2 * math.pi)
    assert f_exact < 0.95 * c0 / (2 * L)                      # far from 1-D: a real test of r, u_r / r
    sec = ar.Section((ar._rect("rod", "steel_45", 0, 0.0, a, 0.0, L),), ())
    f = []
    for h in (5e-4, 1e-3):
        res = ar.modes(ar.assemble(sec, h, 1e-3, fixed=(("z", "z", 0.0), ("z", "z", L))), f_exact, 2)
        f.append(res.f_r[np.argmin(np.abs(res.f_r - f_exact))])
    vv.record("VV-AX-01", title="Pochhammer-Chree mode of a steel cylinder with sliding ends",
              quantity="first longitudinal frequency",
              description="A steel_45 cylinder, radius 5 mm and length 10 mm, with sliding ends (u_z = 0, "
              "shear-free) carries exactly the infinite rod's longitudinal mode of wavenumber pi / L "
              "(k a = pi / 2, far from 1-D theory). The independent axisymmetric (r, z) model "
              "(tests/axisym_reference.py, P2 elements, h = 0.5 mm) is compared with the root of the "
              "Pochhammer-Chree frequency equation.",
              reference="Pochhammer-Chree frequency equation of the longitudinal modes of an infinite "
              "elastic cylinder, solved to round-off with brentq.",
              assumptions="Linear isotropic elasticity; the tolerance is the model's own discretisation "
              "error estimated from a level twice as coarse (P2: h^4), and the model must lie above the "
              "exact value.",
              target=f_exact, computed=f[0], tolerance=two_level(*f) / f_exact, unit="Hz")
    # within its own discretisation error (about 4e-7 at h = 0.5 mm), from above
    assert 0 < f[0] - f_exact <= two_level(*f)


def _thickness_disc(m, t, lossy, dv=0.0, dk=0.0):
    """Exact 1-D laterally clamped plate (IEEE Std 176 thickness mode) with the loss model
    c^E (1 + j / Q), eps^S (1 - j tan delta): f_p, f_s (lossless) and Y(f) per unit area.
    ``dv``, ``dk``: relative changes of the wave speed (moves f_p and f_s together) and of kt^2
    (moves f_s alone), for the sensitivities of Y."""
    Q, tan_d = (m.q_mech, m.tan_delta) if lossy else (math.inf, 0.0)
    eps33 = m.eps_S["eps33"] * EPS0 * (1 - 1j * tan_d)
    c33D = m.c_E["c33"] * (1 + 1j / Q) + m.e["e33"] ** 2 / eps33
    kt2 = m.e["e33"] ** 2 / (c33D * eps33) * (1 + dk)
    v = np.sqrt(c33D / m.density) * (1 + dv)

    def Y(f):
        X = 2 * math.pi * np.asarray(f) * t / (2 * v)
        return 2j * math.pi * np.asarray(f) * (eps33 / t) / (1 - kt2 * np.tan(X) / X)

    fp = (v / (2 * t)).real
    fs = brentq(lambda f: math.pi / 2 * f / fp * math.tan(math.pi / 2 * (fp - f) / fp) - kt2.real, 0.5 * fp, fp * (1 - 1e-12))
    return fs, fp, Y


@pytest.fixture(scope="module")
def disc():
    """A PZT-4 disc with u_r = 0 on its rim: exactly the 1-D thickness-mode plate. The model at
    h = 0.125 mm, its f_r / f_a, and their errors estimated from the level at 0.25 mm."""
    t, R = 0.002, 0.001
    sec = ar.Section((ar._rect("disc", "PZT-4", 1, 0.0, R, 0.0, t),),
                     (ar.ElectrodeLine("ground", 0.0, 0.0, R), ar.ElectrodeLine("hot", t, 0.0, R)))
    fs, _, _ = _thickness_disc(get_material("PZT-4"), t, lossy=False)
    models = [ar.assemble(sec, h, 1e-3, fixed=(("r", "r", R),)) for h in (1.25e-4, 2.5e-4)]
    fine, coarse = (ar.modes(m, fs, 2) for m in models)
    errors = (two_level(fine.f_r[0], coarse.f_r[0]) / fine.f_r[0], two_level(fine.f_a[0], coarse.f_a[0]) / fine.f_a[0])
    return t, R, models[0], fine, errors


def test_thickness_mode_of_a_laterally_clamped_disc_is_ieee176_exact(disc, vv):
    t, R, _model, res, (err_r, err_a) = disc
    fs, fp, _ = _thickness_disc(get_material("PZT-4"), t, lossy=False)
    common = dict(description="A PZT-4 disc 2 mm thick, radius 1 mm, electroded on both faces, with "
                  "u_r = 0 on its rim: exactly the laterally clamped plate of 1-D thickness-mode theory. "
                  "The independent axisymmetric piezoelectric model (h = 0.125 mm) is compared with the "
                  "closed form.",
                  reference="IEEE Std 176, thickness-extensional plate: f_p = v^D / (2 t), f_s the root of "
                  "(pi/2)(f/f_p) tan((pi/2)(f_p - f)/f_p) = k_t^2, from the library's stress-charge constants.",
                  assumptions="Lossless linear piezoelectricity; the tolerance is the model's own discretisation "
                  "error from a level twice as coarse (P2: h^4), and the model must lie above the exact value.")
    vv.record("VV-AX-02", title="IEEE 176 thickness mode of a clamped PZT-4 disc: resonance",
              quantity="series resonance f_s", target=fs, computed=res.f_r[0], tolerance=err_r, unit="Hz", **common)
    vv.record("VV-AX-03", title="IEEE 176 thickness mode of a clamped PZT-4 disc: anti-resonance",
              quantity="parallel resonance f_p", target=fp, computed=res.f_a[0], tolerance=err_a, unit="Hz", **common)
    # within their own discretisation error (about 3e-7 / 4e-7 relative), from above
    assert 0 < res.f_r[0] / fs - 1 <= err_r
    assert 0 < res.f_a[0] / fp - 1 <= err_a
    assert res.k_eff[0] > 0.4


@pytest.mark.parametrize("lossy", [True, False])
def test_thickness_disc_admittance_is_exact(disc, lossy):
    """Y = j w C0 / (1 - kt^2 tan X / X) with complex constants. The model's Y is the exact Y of
    its own f_s and f_p, so its error is theirs (test above: within err_r, err_a) times the
    sensitivities |d ln Y / d ln f_s| and |d ln Y / d ln f_p| of the closed form at each probe
    (from 5 at 0.3 f_s to 32 midway between f_s and f_p); the rest (the static capacitance of a
    uniform field) is exact to round-off."""
    t, R, model, _res, (err_r, err_a) = disc
    m = get_material("PZT-4")
    fs, fp, Y = _thickness_disc(m, t, lossy)
    f = np.array([0.3 * fs, 0.9 * fs, 0.5 * (fs + fp), 1.15 * fp])
    y = ar.admittance(model, f, lossy=lossy)
    # d ln Y / d ln f_s at fixed f_p (through kt^2), and d ln Y / d ln f_p at fixed f_s
    d = 1e-7
    fs_k, _, Y_k = _thickness_disc(m, t, lossy, dk=d)
    fs_v, _, Y_v = _thickness_disc(m, t, lossy, dv=d)
    s_fs = np.log(Y_k(f) / Y(f)) / math.log(fs_k / fs)
    s_fp = (np.log(Y_v(f) / Y(f)) - s_fs * math.log(fs_v / fs)) / math.log1p(d)
    tol = err_r * np.abs(s_fs) + err_a * np.abs(s_fp) + 1e-12
    err = np.abs(y / (np.pi * R ** 2 * Y(f)) - 1)
    assert np.all(err <= tol), (err, tol)
    if not lossy:
        assert np.all(y.real == 0)


@pytest.mark.parametrize("poling", [1, -1])
def test_k33_rod_against_ieee176_with_rayleigh_love(poling, vv):
    m = get_material("PZT-4")
    C, e, eps = m.voigt_matrices()
    s = np.linalg.inv(C)
    d = e @ s
    epsT = eps + d @ e.T
    sD = s - d.T @ np.linalg.inv(epsT) @ d
    k33 = d[2, 2] ** 2 / (s[2, 2] * epsT[2, 2])
    L, R = 0.04, 0.002
    fp = 1 / (2 * L * math.sqrt(m.density * s[2, 2] * (1 - k33)))
    fs = brentq(lambda f: math.pi / 2 * f / fp * math.tan(math.pi / 2 * (fp - f) / fp) - k33, 0.5 * fp, fp * (1 - 1e-12))

    def rayleigh_love(nu):
        return 1 - 0.5 * nu ** 2 * (R ** 2 / 2) * (math.pi / L) ** 2

    sec = ar.Section((ar._rect("rod", "PZT-4", poling, 0.0, R, 0.0, L),),
                     (ar.ElectrodeLine("ground", 0.0, 0.0, R), ar.ElectrodeLine("hot", L, 0.0, R)))
    res = ar.modes(ar.assemble(sec, 1e-3, 1e-3), fs, 2)
    if poling == 1:
        vv.record("VV-AX-04", title="IEEE 176 k33 rod with Rayleigh-Love correction: resonance",
                  quantity="series resonance f_s",
                  description="A PZT-4 rod, length 40 mm and radius 2 mm (L / R = 20), poled and electroded "
                  "along its axis, free. The independent axisymmetric piezoelectric model (h = 1 mm) is "
                  "compared with the 1-D length-extensional resonance corrected for lateral inertia.",
                  reference="IEEE Std 176 length-extensional k33 bar, times the Rayleigh-Love factor "
                  "1 - nu^2 (R^2 / 2) (pi / L)^2 / 2 with the effective Poisson ratio -s13/s33 at constant field.",
                  assumptions="Lossless; the Rayleigh-Love factor is a first-order correction for a slender "
                  "rod: tolerance 1e-4.",
                  target=fs * rayleigh_love(-s[0, 2] / s[2, 2]), computed=res.f_r[0], tolerance=1e-4, unit="Hz")
    assert res.f_r[0] == pytest.approx(fs * rayleigh_love(-s[0, 2] / s[2, 2]), rel=1e-4)
    assert res.f_a[0] == pytest.approx(fp * rayleigh_love(-sD[0, 2] / sD[2, 2]), rel=1e-4)


# ---------------------------------------------------------------------------- the default drill


@pytest.mark.parametrize("fillets", [False, True])
def test_section_of_the_default_drill_reads_the_design(fillets):
    bolted = no_slots().replace({"stack.bolt_diameter": 0.012})
    d = geometry.filleted(bolted) if fillets else bolted
    sec = ar.section(d)
    names = [b.name for b in sec.blocks]
    assert names == ["coupler", "ring_1", "ring_2", "ring_3", "ring_4", "flange", "horn", "bolt"]
    # closed-form volumes of the design = Pappus volumes of the section's polygons
    vol = {}
    for b in sec.blocks:
        r, z = np.asarray(b.outline).T
        # Pappus and Green: V = 2 pi int r dA = pi (closed integral of r^2 dz), counter-clockwise
        r1, z1 = np.roll(r, -1), np.roll(z, -1)
        vol[b.name] = math.pi * np.sum((z1 - z) * (r * r + r * r1 + r1 * r1) / 3)
        # a fillet's arc instead of its chord: the circular segment between them (area
        # rho^2 (t - sin t) / 2, centroid 4 rho sin^3(t/2) / (3 (t - sin t)) from the centre on the
        # bisector) lies on the side of the chord away from the centre: removed when the centre
        # lies outside the block (a concave fillet), added otherwise
        for i, rc, zc in b.arcs:
            a, e, c = np.asarray(b.outline[i]), np.asarray(b.outline[(i + 1) % len(b.outline)]), np.array([rc, zc])
            rho = np.hypot(*(a - c))
            t = 2 * math.asin(np.hypot(*(e - a)) / (2 * rho))
            mid = 0.5 * (a + e) - c
            r_seg = rc + mid[0] / np.hypot(*mid) * 4 * rho * math.sin(t / 2) ** 3 / (3 * (t - math.sin(t)))
            chord = e - a
            outside = chord[0] * (c - a)[1] - chord[1] * (c - a)[0] < 0     # centre right of the edge
            vol[b.name] += (-1 if outside else 1) * 2 * math.pi * r_seg * rho ** 2 * (t - math.sin(t)) / 2
    assert any(b.arcs for b in sec.blocks) == fillets
    table = {region: v for region, _part, _mat, v in d.region_table()}
    assert vol["coupler"] == pytest.approx(table["coupler"], rel=1e-12)
    assert vol["horn"] == pytest.approx(table["horn"], rel=1e-12)
    assert vol["flange"] == pytest.approx(table["flange_disc"], rel=1e-12)
    assert vol["bolt"] == pytest.approx(table["bolt"], rel=1e-12)
    assert [b.poling for b in sec.blocks[1:5]] == [-1, 1, -1, 1]
    assert [e.role for e in sec.electrodes] == ["ground", "hot", "hot", "ground", "ground", "hot", "hot", "ground"]
    with pytest.raises(ParameterError):
        ar.section(article_design())


@pytest.fixture(scope="module")
def reference():
    """Converged working mode of the default drill without slots and teeth (about 30k DOF in all)."""
    return ar.convergence(no_slots(), 2 * math.sqrt(2) * 1e-3, 4e-3, levels=3, ratio=math.sqrt(2))


def test_reference_converges_at_order_4_to_the_independent_values(reference):
    c = reference
    assert 3.0 < c.order_r < 5.0 and 3.0 < c.order_a < 5.0           # graded: smooth P2 rate h^4
    assert c.f_r_limit == pytest.approx(AXISYM_CONVERGED[0], rel=2e-5)
    assert c.f_a_limit == pytest.approx(AXISYM_CONVERGED[1], rel=2e-5)
    # the Richardson error estimate of the finest level brackets the independent value
    assert (abs(c.f_r[-1] - AXISYM_CONVERGED[0]) < 1.5 * c.error_r
            and abs(c.f_a[-1] - AXISYM_CONVERGED[1]) < 1.5 * c.error_a)


@pytest.fixture(scope="module")
def default_3d():
    d = no_slots()
    system = fem.assemble(geometry.build_mesh(d))
    return fem.modal_analysis(system, near_hz=d.target_frequency, n_modes=3)


def test_3d_default_mesh_against_the_reference(reference, default_3d):
    w = default_3d.working
    assert default_3d.labels[w] == "longitudinal"
    err_r = default_3d.f_r_hz[w] / reference.f_r_limit - 1
    err_a = default_3d.f_a_hz[w] / reference.f_a_limit - 1
    # the 3-D mesh is stiff (too high), not merely different
    assert 0 < err_r < TOL_3D and 0 < err_a < TOL_3D


# ---------------------------------------------------------------------------- a generic stack


@pytest.fixture(scope="module")
def sandwich():
    d = langevin_sandwich()
    ref = ar.convergence(d, 2 * math.sqrt(2) * 1e-3, 4e-3, levels=3, near_hz=d.target_frequency, ratio=math.sqrt(2))
    system = fem.assemble(geometry.build_mesh(d))
    modes3d = fem.modal_analysis(system, near_hz=d.target_frequency, n_modes=2)
    return d, ref, system, modes3d


def test_sandwich_reference_converges(sandwich):
    _d, ref, _s, _m = sandwich
    assert ref.order_r > 3.0 and ref.order_a > 3.0
    assert ref.error_r < 1e-5 * ref.f_r_limit and ref.error_a < 1e-5 * ref.f_a_limit


def test_sandwich_3d_against_the_reference(sandwich):
    _d, ref, _s, m = sandwich
    w = m.working
    assert m.labels[w] == "longitudinal"
    assert m.f_r_hz[w] == pytest.approx(ref.f_r_limit, rel=TOL_SANDWICH)
    assert m.f_a_hz[w] == pytest.approx(ref.f_a_limit, rel=TOL_SANDWICH)


@pytest.fixture(scope="module")
def sandwich_bending_torsion(sandwich):
    """The sandwich's first bending pair and first torsion: the (r, z) harmonics at three levels,
    the 3-D toolkit on its default mesh and refined by 0.7."""
    d, _ref, system, _m = sandwich
    sec = ar.section(d)
    bend = [ar.harmonic_modes(sec, h, 4e-3, 1, 8e3, 1)[0][0] for h in (4e-3, 2e-3, 1e-3)]
    tors = [ar.harmonic_modes(sec, h, 4e-3, 0, 15e3, 1)[0][0] for h in (4e-3, 2e-3, 1e-3)]
    three_d = []
    for s in (system, fem.assemble(geometry.build_mesh(d, refine=0.7))):
        m = fem.modal_analysis(s, near_hz=8e3, n_modes=4)
        f = np.asarray(m.f_r_hz)
        b = np.sort(f[[k for k, lab in enumerate(m.labels) if lab == "bending"]])
        t = np.sort(f[[k for k, lab in enumerate(m.labels) if lab == "torsional"]])
        three_d.append((b[:2].mean(), t[0], s.ndof))
    return bend, tors, three_d


def test_torsion_harmonic_of_a_free_free_cylinder_is_exact(vv):
    """u_theta = r cos(k pi z / L) is an exact torsional mode of a free-free cylinder: f = k c_s / (2 L)."""
    m = get_material("steel_45")
    L, R = 0.1, 0.01
    sec = ar.Section((ar._rect("rod", "steel_45", 0, 0.0, R, 0.0, L),), ())
    c_s = math.sqrt(m.youngs_modulus / (2 * (1 + m.poisson_ratio)) / m.density)
    exact = np.array([k * c_s / (2 * L) for k in (1, 2, 3)])
    coarse, _ = ar.harmonic_modes(sec, 4e-3, 2e-3, 0, exact[1], 3)
    fine, _ = ar.harmonic_modes(sec, 2e-3, 2e-3, 0, exact[1], 3)
    err_c, err_f = np.sort(coarse) / exact - 1, np.sort(fine) / exact - 1
    vv.record("VV-AX-05", title="First torsional mode of a free-free steel cylinder",
              quantity="first torsional frequency",
              description="A steel_45 cylinder, length 100 mm and radius 10 mm, free at both ends. The "
              "independent axisymmetric model's torsional (n = 0, u_theta) harmonic at h = 2 mm is compared "
              "with the exact first torsional mode.",
              reference="u_theta = r cos(pi z / L) is an exact mode: f = c_s / (2 L), c_s = sqrt(G / rho).",
              assumptions="Linear isotropic elasticity; the tolerance is the model's own discretisation error "
              "from a level twice as coarse (P2: h^4).",
              target=exact[0], computed=np.sort(fine)[0], tolerance=float(two_level(err_f, err_c)[0]), unit="Hz")
    # from above, at the P2 rate h^4 (16x): the exact value is then within the fine level's own
    # error estimate (two_level), and a wrong limit (an error not falling with h) fails
    assert np.all(err_f > 0) and np.all(err_c / err_f > 10)
    assert np.all(err_f <= two_level(err_f, err_c))


def test_harmonics_reject_other_orders():
    with pytest.raises(ParameterError, match="n"):
        ar.harmonic_modes(ar.section(langevin_sandwich()), 4e-3, 4e-3, 2, 8e3)


def test_sandwich_bending_and_torsion_harmonics_against_the_3d_toolkit(sandwich_bending_torsion):
    """A second numerical method: the 3-D piezo model (P2 tetrahedra, every component and the
    potential free in theta) converges from above onto the (r, z) harmonics. Measured: bending
    +0.12 % / +0.06 %, torsion +0.032 % / +0.010 % on the default mesh / refine 0.7; the
    order-2 extrapolation of the two 3-D levels (h from the DOFs) lands within 1.5e-4 / 1.7e-4."""
    bend, tors, three_d = sandwich_bending_torsion
    for series in (bend, tors):
        p, limit = ar.richardson(series)
        assert p > 3.0 and abs(series[-1] / limit - 1) < 1e-5
    for k, (ref, tol_fine, tol_extrap) in enumerate(((bend[-1], 1e-3, 3e-4), (tors[-1], 3e-4, 3e-4))):
        (q1, *_), (q2, *_) = three_d[0][k:k + 1], three_d[1][k:k + 1]
        e1, e2 = q1 / ref - 1, q2 / ref - 1
        assert 0 < e2 < e1 and e2 < tol_fine, (k, e1, e2)
        h1, h2 = (float(n) ** (-1 / 3) for *_, n in three_d)
        extrap = q2 + (q2 - q1) / ((h1 / h2) ** 2 - 1)
        assert abs(extrap / ref - 1) < tol_extrap, (k, extrap, ref)


def test_default_design_bending_and_torsion_references_converge():
    """The references the swept 3-D mesh is measured against (tests/test_revolve.py)."""
    sec = ar.section(no_slots())
    hs = (2e-3, 2e-3 / math.sqrt(2), 1e-3)
    bend = np.array([np.sort(ar.harmonic_modes(sec, h, 4e-3, 1, 8e3, 2)[0]) for h in hs])
    tors = [ar.harmonic_modes(sec, h, 4e-3, 0, 15e3, 1)[0][0] for h in hs]
    for series, ref in ((bend[:, 0], ar.BENDING_19[0]), (bend[:, 1], ar.BENDING_19[1]), (tors, ar.TORSION_19)):
        p, limit = ar.richardson(series, math.sqrt(2))
        assert 3.0 < p < 5.5 and limit == pytest.approx(ref, rel=2e-5), (p, limit, ref)


def test_sandwich_lossless_admittance_vanishes_at_the_anti_resonance(sandwich):
    d, _ref, _system, _m = sandwich
    model = ar.assemble(ar.section(d), 2e-3, 4e-3)
    res = ar.modes(model, d.target_frequency, 3)
    fa = res.f_a[res.working]
    B = lambda f: ar.admittance(model, [f], lossy=False)[0].imag
    assert brentq(B, fa * (1 - 1e-3), fa * (1 + 1e-3), xtol=1e-6) == pytest.approx(fa, rel=1e-8)
