"""The mode-shape toolkit (fem.modeshape): energy shares, labels, effective mass, MAC, surface motion,
and one mass matrix (the assembled one) whoever asks.

Synthetic fields on a square steel bar (axis z through the section centre) have exact answers;
real modes come from an independent scikit-fem linear-elasticity eigen-solve (as in skfem ex21).
"""

import numpy as np
import pytest
import scipy.sparse as sp
from skfem import Basis, BilinearForm, ElementTetP2, ElementVector, MeshTet, asm
from skfem.models.elasticity import lame_parameters, linear_elasticity

from rpud_common import ParameterError
from geometry.materials import get_material
from geometry.mesh import Region, TaggedMesh
from fem.modeshape import (classify, cylindrical_components, effective_mass_axial, energy_shares, equivalent_mass,
                           mac, mass_matrix, match_modes, p2_nodes, surface_motion, surface_rows, total_mass)

A, L = 0.01, 0.12          # square side and length, m
STEEL = get_material("steel_45")


def bar(a=A, length=L, n=(2, 2, 12), two_parts=True):
    """Square bar centred on the z axis; two parts ("rod" z < L/2, "tip" above) when asked."""
    m = MeshTet.init_tensor(np.linspace(-a / 2, a / 2, n[0] + 1), np.linspace(-a / 2, a / 2, n[1] + 1),
                            np.linspace(0, length, n[2] + 1))
    f = m.facets[:, m.boundary_facets()].T
    z = m.p[2, f]
    sets = {"bottom": f[np.all(np.isclose(z, 0), axis=1)], "top": f[np.all(np.isclose(z, length), axis=1)]}
    zc = m.p[2, m.t].mean(axis=0)
    if two_parts:
        regions = (Region("rod", "rod", "steel_45"), Region("tip", "tip", "steel_45"))
        cell_region = (zc > length / 2).astype(int)
    else:
        regions = (Region("rod", "rod", "steel_45"),)
        cell_region = np.zeros(m.t.shape[1], dtype=int)
    return TaggedMesh(m.p.T, m.t.T, cell_region, regions, sets)


@pytest.fixture(scope="module")
def tm():
    return bar()


def scalar_mass(mesh):
    """Independent scalar P2 mass matrix (uniform steel density)."""
    basis = Basis(mesh.to_skfem(), ElementTetP2())
    M = BilinearForm(lambda u, v, w: STEEL.density * u * v).assemble(basis)
    return basis, M


def fields(tm):
    x, y, z = p2_nodes(tm).T
    c = np.cos(np.pi * z / L)
    zero = np.zeros_like(z)
    return {
        "axial": np.column_stack([zero, zero, c]),
        "torsion": np.column_stack([-y * c, x * c, zero]),
        # a half cosine lateral field is 98.5 % a rigid rotation about x (it would be labelled
        # "rigid"); the full cosine is the shape of a free-free bending mode
        "bending": np.column_stack([np.cos(2 * np.pi * z / L), zero, zero]),
        "rigid_axial": np.column_stack([zero, zero, np.ones_like(z)]),
    }


def test_nodes_are_the_p2_doflocs(tm):
    basis, _ = scalar_mass(tm)
    assert np.array_equal(p2_nodes(tm), basis.doflocs.T)


def test_pure_axial_torsional_bending_fields(tm):
    f = fields(tm)
    s = energy_shares(tm, np.stack([f["axial"], f["torsion"], f["bending"]]))
    np.testing.assert_allclose(s.axial, [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(s.torsional, [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(s.bending, [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(s.radial, 0, atol=1e-12)
    # node-wise projection: exact for Cartesian-aligned fields, O(h^2) for the twist (2 x 2 mesh)
    assert np.all(np.abs(s.closure - 1) <= [1e-12, 0.03, 1e-12])
    assert classify(s) == ["longitudinal", "torsional", "bending"]
    for part in ("rod", "tip"):
        np.testing.assert_allclose(s.parts[part].axial, [1, 0, 0], atol=1e-12)
        assert classify(s, part=part) == ["longitudinal", "torsional", "bending"]
    # the fields are symmetric about z = L/2: equal energy in both halves
    np.testing.assert_allclose(s.part_energy["rod"], 0.5, rtol=1e-9)
    np.testing.assert_allclose(s.part_energy["rod"] + s.part_energy["tip"], 1, atol=1e-12)
    np.testing.assert_allclose(s.rigid, 0, atol=1e-9)


def test_fifty_fifty_axial_torsion_is_longitudinal_torsional(tm):
    f = fields(tm)
    _, M = scalar_mass(tm)
    x, y, z = p2_nodes(tm).T
    ea = f["axial"][:, 2] @ M @ f["axial"][:, 2]
    ut = np.hypot(x, y) * np.cos(np.pi * z / L)                   # u_theta of the torsion field
    et = ut @ M @ ut
    beta = np.sqrt(ea / et)                                        # equal energies
    s = energy_shares(tm, f["axial"] + beta * f["torsion"])
    assert s.axial[0] == pytest.approx(0.5, abs=1e-12)
    assert s.torsional[0] == pytest.approx(0.5, abs=1e-12)
    assert classify(s) == ["longitudinal-torsional"]
    # unequal mix: torsional energy 0.09 ea -> share 0.09 / 1.09
    s2 = energy_shares(tm, f["axial"] + 0.3 * beta * f["torsion"])
    assert s2.torsional[0] == pytest.approx(0.09 / 1.09, rel=1e-10)
    assert classify(s2) == ["longitudinal"]                       # 8.3 % torsion < 15 %


def test_rigid_axial_translation_effective_mass_is_total_mass(tm):
    f = fields(tm)
    mass = STEEL.density * A * A * L
    assert total_mass(tm) == pytest.approx(mass, rel=1e-12)
    meff = effective_mass_axial(tm, np.stack([7.0 * f["rigid_axial"], f["torsion"], f["bending"]]))
    assert meff[0] == pytest.approx(mass, rel=1e-12)
    np.testing.assert_allclose(meff[1:], 0, atol=1e-12 * mass)
    s = energy_shares(tm, f["rigid_axial"])
    assert s.rigid[0] == pytest.approx(1, abs=1e-12) and classify(s) == ["rigid"]


def test_mac_self_and_orthogonal(tm):
    f = fields(tm)
    shapes = np.stack([f["axial"], f["torsion"], f["bending"]])
    for kw in ({}, {"mesh": tm}):
        m = mac(shapes, -3.0 * shapes, **kw)
        np.testing.assert_allclose(np.diag(m), 1, atol=1e-12)
        np.testing.assert_allclose(m - np.diag(np.diag(m)), 0, atol=1e-7)   # mesh asymmetry: ~6e-9


def test_match_modes_across_designs():
    t1, t2 = bar(), bar(length=1.1 * L, n=(2, 2, 15))             # different mesh and length
    t3 = t1.replace(points=t1.points * [1, 1, 1.1])                  # morphed: same topology

    def shapes(t):
        x, y, z = p2_nodes(t).T
        lz = np.ptp(z)
        c1, c2 = np.cos(np.pi * z / lz), np.cos(2 * np.pi * z / lz)
        zero = np.zeros_like(z)
        return np.stack([np.column_stack([zero, zero, c1]), np.column_stack([-y * c1, x * c1, zero]),
                         np.column_stack([c1, zero, zero]), np.column_stack([zero, zero, c2])])

    a = shapes(t1)
    perm = [2, 3, 0, 1]
    for other, method in ((t2, "nearest"), (t3, "same-nodes")):
        b = shapes(other)[perm]
        res = match_modes(t1, a, other, b)
        assert res.method == method
        assert list(res.index) == [perm.index(i) for i in range(4)]
        assert np.all(res.mac > 0.95)


def test_surface_motion_and_ellipse_ratio(tm):
    f = fields(tm)
    x, y, z = p2_nodes(tm).T
    u = 2.0 * f["axial"] + f["torsion"] * 1e2
    out = surface_motion(tm, u, "top")
    assert out["area"] == pytest.approx(A * A, rel=1e-12)
    assert out["n_nodes"] == 25
    # top: cos(pi) = -1: axial -2 everywhere; tangential = -100 r
    assert out["axial"] == pytest.approx(2.0, rel=1e-12)
    assert out["axial_mean"] == pytest.approx(-2.0, rel=1e-12)
    # mean r over a square of side a: a * (sqrt(2) + asinh(1)) / 6
    mean_r = A * (np.sqrt(2) + np.arcsinh(1)) / 6
    assert out["tangential"] == pytest.approx(100 * mean_r, rel=2e-3)   # P2 interpolation of r
    assert out["radial"] == pytest.approx(0, abs=1e-12)
    assert out["ellipse_ratio"] == pytest.approx(50 * mean_r, rel=2e-3)
    assert out["phase_deg"] == pytest.approx(0.0, abs=1e-9)
    comps = cylindrical_components(tm, u)
    assert comps.shape == (1, len(z), 3)
    np.testing.assert_allclose(comps[0, :, 2], 0, atol=1e-12)


def test_bad_input_is_a_parameter_error(tm):
    f = fields(tm)
    with pytest.raises(ParameterError, match="surface = 'teeth_tops'"):
        surface_motion(tm, f["axial"], "teeth_tops")
    with pytest.raises(ParameterError, match="shapes"):
        energy_shares(tm, f["axial"][:-1])
    with pytest.raises(ParameterError, match="shapes"):
        effective_mass_axial(tm, np.zeros((2, len(f["axial"]), 2)))
    with pytest.raises(ParameterError, match="non-finite|finite"):
        energy_shares(tm, f["axial"] * np.nan)
    with pytest.raises(ParameterError, match="part = 'horn'"):
        classify(energy_shares(tm, f["axial"]), part="horn")


# --------------------------------------------------------------------------- real modes


@pytest.fixture(scope="module")
def free_bar_modes():
    """Free-free steel square bar, P2 linear elasticity, 18 lowest modes (shift-invert)."""
    from scipy.sparse.linalg import eigsh

    t = bar(n=(3, 3, 30), two_parts=False)
    mesh = t.to_skfem()
    ev = ElementVector(ElementTetP2())
    basis = Basis(mesh, ev)
    lam, mu = lame_parameters(STEEL.youngs_modulus, STEEL.poisson_ratio)
    K = asm(linear_elasticity(lam, mu), basis)
    M = asm(BilinearForm(lambda u, v, w: STEEL.density * (u[0] * v[0] + u[1] * v[1] + u[2] * v[2])), basis)
    sigma = -(2 * np.pi * 100.0) ** 2
    w2, X = eigsh(K, k=18, M=M, sigma=sigma, which="LM")
    order = np.argsort(w2)
    w2, X = w2[order], X[:, order]
    freqs = np.sqrt(np.abs(w2)) / (2 * np.pi)
    # ElementVector interleaves the components per scalar DOF: node i -> dofs 3i, 3i+1, 3i+2
    nodal = basis.nodal_dofs  # (3, n_vertices) for checking the layout
    assert np.array_equal(nodal[:, 1], [3, 4, 5])
    shapes = X.T.reshape(len(freqs), -1, 3)
    return t, freqs, shapes


def test_free_bar_first_longitudinal_and_torsional_modes(free_bar_modes):
    t, freqs, shapes = free_bar_modes
    s = energy_shares(t, shapes)
    labels = classify(s)
    assert labels[:6] == ["rigid"] * 6
    assert freqs[5] < 1.0 < 1000.0 < freqs[6]
    E, nu, rho = STEEL.youngs_modulus, STEEL.poisson_ratio, STEEL.density
    f_long = np.sqrt(E / rho) / (2 * L)
    G = E / (2 * (1 + nu))
    f_tors = np.sqrt(G * 0.1406 * A**4 / (rho * A**4 / 6)) / (2 * L)
    i_long = labels.index("longitudinal")
    i_tors = labels.index("torsional")
    # tolerances: 1 % longitudinal (Rayleigh lateral-inertia correction ~0.1 %, mesh),
    # 2 % torsional (K_t = 0.1406 a^4 is the Saint-Venant value; 3 x 3 P2 across: +0.5 %)
    assert freqs[i_long] == pytest.approx(f_long, rel=0.01)
    assert freqs[i_tors] == pytest.approx(f_tors, rel=0.02)
    assert s.axial[i_long] > 0.9 and s.torsional[i_tors] > 0.9
    # every other elastic mode below the longitudinal one is bending (two planes)
    others = [lab for i, lab in enumerate(labels[6:i_long], start=6) if i != i_tors]
    assert others and set(others) == {"bending"}
    meff = effective_mass_axial(t, shapes)
    m = total_mass(t)
    # free-free: the rigid modes carry the whole axial effective mass, elastic modes none
    assert meff[:6].sum() == pytest.approx(m, rel=1e-8)
    assert np.all(meff[6:] < 1e-8 * m)
    # uniform rod, u = cos(pi z / L): modal mass m/2 referred to the end's axial motion
    assert equivalent_mass(t, shapes[i_long], "top")[0] == pytest.approx(m / 2, rel=0.02)
    assert equivalent_mass(t, shapes[i_tors], "top")[0] > 1e3 * m
    # mode sets of the same solve match themselves one-to-one (degenerate bending pairs aside)
    res = match_modes(t, shapes[[i_long, i_tors]], t, shapes)
    assert list(res.index) == [i_long, i_tors]


def test_shares_follow_a_rotated_and_shifted_axis(tm):
    """Same bar and fields, rigidly rotated and moved: identical shares with axis_point/axis_dir."""
    f = fields(tm)
    shapes = np.stack([f["axial"] + 250 * f["torsion"], f["bending"] + 0.2 * f["axial"]])
    ref = energy_shares(tm, shapes)
    c, s_ = np.cos(0.7), np.sin(0.7)
    Rz = np.array([[c, -s_, 0], [s_, c, 0], [0, 0, 1]])
    Ry = np.array([[c, 0, s_], [0, 1, 0], [-s_, 0, c]])
    R = Ry @ Rz
    p0 = np.array([0.3, -0.1, 0.05])
    moved = tm.replace(points=tm.points @ R.T + p0)
    got = energy_shares(moved, shapes @ R.T, axis_point=p0, axis_dir=R @ [0, 0, 1])
    for name in ("axial", "torsional", "bending", "radial"):
        np.testing.assert_allclose(getattr(got, name), getattr(ref, name), atol=1e-9)
    assert classify(got) == classify(ref) == ["longitudinal-torsional", "bending"]
    np.testing.assert_allclose(effective_mass_axial(moved, shapes @ R.T, axis_dir=R @ [0, 0, 1]),
                               effective_mass_axial(tm, shapes), rtol=1e-9, atol=1e-15)


def test_unstructured_nodes_use_axial_bins(tm):
    """Jittered nodes (no common axial levels): slab bins, shares still close to exact."""
    from fem.modeshape import _frame

    rng = np.random.default_rng(1)
    pts = tm.points.copy()
    inner = (pts[:, 2] > 0) & (pts[:, 2] < L)
    pts[inner, 2] += rng.uniform(-0.2, 0.2, inner.sum()) * (L / 12)
    jit = tm.replace(points=pts)
    assert _frame(jit, (0, 0), (0, 0, 1)).n_slabs < len(p2_nodes(jit)) / 4
    f = fields(jit)
    s = energy_shares(jit, np.stack([f["axial"], f["torsion"], f["bending"]]))
    np.testing.assert_allclose(s.axial, [1, 0, 0], atol=1e-3)   # bins: tilt fit leaks ~1e-4
    np.testing.assert_allclose(s.torsional, [0, 1, 0], atol=1e-3)
    np.testing.assert_allclose(s.bending, [0, 0, 1], atol=5e-3)
    assert classify(s) == ["longitudinal", "torsional", "bending"]


# --------------------------------------------------------------------------- one mass matrix, one formula


@pytest.fixture(scope="module")
def sandwich_modes():
    """A curved (10-node) Langevin sandwich with three parts and electrodes, modes near 25 kHz
    (the working longitudinal mode at 24.6 kHz among bending and torsional neighbours)."""
    from fem.assembly import assemble
    from fem.modal import modal_analysis
    from test_fem_util import sandwich

    system = assemble(sandwich())
    return system, modal_analysis(system, 25e3, 6)


def _table(s):
    return np.column_stack([s.axial, s.torsional, s.bending, s.radial])


def test_the_mass_is_the_assembled_one(sandwich_modes):
    from skfem import Basis, Functional

    system, res = sandwich_modes
    tm, n_u = system.mesh, system.n_u
    M = mass_matrix(system)
    # the system's own matrix: its displacement block is M (x) I_3, entry for entry
    assert abs(sp.kron(M, sp.eye(3)) - system.M[:n_u, :n_u]).max() == 0
    # a mesh alone gets the same matrix (the assembly's densities and curved-cell quadrature;
    # the former scalar P2 matrix of this module was 0.35 % off on curved cells), and the
    # parts sum to it
    scale = abs(M).max()
    assert abs(mass_matrix(tm) - M).max() < 1e-12 * scale
    assert abs(sum(mass_matrix(tm, part=p) for p in tm.parts) - M).max() < 1e-12 * scale
    # the system's part masses (summed from the fast assembly's element masses) are the same
    assert system.part_mass is not None
    for p in tm.parts:
        assert abs(mass_matrix(system, part=p) - mass_matrix(tm, part=p)).max() < 1e-12 * scale
    # rho V of a rigid translation: through the assembled 3n x 3n matrix, and volume by volume
    t = np.zeros(system.ndof)
    t[2:n_u:3] = 1.0
    sk = tm.to_skfem()
    volume = Functional(lambda w: 1.0 + 0.0 * w.x[0])
    rho_v = sum(r.density * volume.assemble(Basis(sk, system.basis.elem, intorder=5,
                                                  elements=np.flatnonzero(tm.cell_region == i)))
                for i, r in enumerate(system.regions))
    assert t @ (system.M @ t) == pytest.approx(rho_v, rel=1e-12)
    assert total_mass(system) == pytest.approx(rho_v, rel=1e-12)
    assert total_mass(tm) == pytest.approx(rho_v, rel=1e-12)
    # Phi^T M Phi = I holds in the shares: the modal shapes carry unit energy
    np.testing.assert_allclose(res.mode_shares.energy, 1.0, rtol=0, atol=1e-12)


def test_shares_are_the_same_whoever_asks(sandwich_modes, monkeypatch):
    import fem.matching
    import fem.modal

    system, res = sandwich_modes
    direct = energy_shares(system, res.shapes)
    # the working-mode pick (fem.modal.working_mode, which matching uses): the shares it looks at
    seen = []
    ask = fem.modal.energy_shares
    monkeypatch.setattr(fem.modal, "energy_shares", lambda *a, **k: seen.append(ask(*a, **k)) or seen[-1])
    w = fem.matching.working_mode(system, res.f_r_hz, res.vectors, 25e3)
    assert len(seen) == 1
    for other in (res.mode_shares, seen[0], energy_shares(system.mesh, res.shapes)):
        np.testing.assert_allclose(_table(other), _table(direct), rtol=0, atol=1e-12)
        np.testing.assert_allclose(other.rigid, direct.rigid, rtol=0, atol=1e-12)
        for p in system.mesh.parts:
            np.testing.assert_allclose(_table(other.parts[p]), _table(direct.parts[p]), rtol=0, atol=1e-12)
            np.testing.assert_allclose(other.part_energy[p], direct.part_energy[p], rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.shares, direct.overall.table(), rtol=0, atol=1e-12)
    assert res.labels == classify(direct)
    assert res.labels[w] == "longitudinal" and w == int(np.argmax(direct.axial))
    # the shares sum to 1, overall and in every part
    np.testing.assert_allclose(_table(direct).sum(axis=1), 1.0, rtol=0, atol=1e-12)
    for p in system.mesh.parts:
        np.testing.assert_allclose(_table(direct.parts[p]).sum(axis=1), 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(sum(direct.part_energy.values()), 1.0, rtol=0, atol=1e-12)
    # the open-circuit pairing MAC is this module's mac on the same matrix
    paired = system.displacement(np.nan_to_num(res.vectors_open))
    np.testing.assert_allclose(np.diag(mac(res.shapes, paired, mesh=system)), res.mac, rtol=0, atol=1e-12)


def test_surface_means_are_one_linear_map(sandwich_modes):
    """surface_motion's signed means, surface_rows and the harmonic surface functional agree."""
    from fem.harmonic import surface_functional

    system, res = sandwich_modes
    i = res.labels.index("longitudinal")
    rows, area = surface_rows(system, "tip")
    func = surface_functional(system, "tip")
    out = surface_motion(system, res.shapes[i], "tip")
    vals = rows @ res.shapes[i].ravel()
    assert func.area == area == out["area"]
    for k, c in enumerate(("axial", "tangential", "radial")):
        assert out[f"{c}_mean"] == vals[k] == func(res.vectors[:, i])[c]
    assert out["axial"] == pytest.approx(abs(vals[0]), rel=1e-9)   # a piston: one sign on the tip


@pytest.mark.parametrize("which", ["steel", "k33"])
def test_shares_of_gmsh_rods_mean_what_their_names_say(which):
    """Bending modes of a rod must not show a torsional share (a split like 14/44/42 for a k33
    rod's first bending pair would misname the mode), checked on the unstructured Gmsh meshes the
    CLIs use: first bending pair torsional < 5 %, first torsional mode > 90 % torsional, first
    longitudinal mode > 90 % axial."""
    import geometry
    from fem.assembly import assemble
    from fem.modal import modal_analysis
    from geometry import examples

    if which == "steel":
        d, h, near = examples.slender_rod(length=0.1, diameter=0.01), 0.003, 15e3   # L/R = 20
    else:
        d, h, near = examples.k33_rod(length=0.02), 0.001, 60e3                     # the rod
    system = assemble(geometry.build_mesh(d, mesh_size=h))
    res = modal_analysis(system, near, 10)
    sh = res.mode_shares
    labels = res.labels
    bend = [i for i, lab in enumerate(labels) if lab == "bending"][:2]
    tors = labels.index("torsional")
    long_ = labels.index("longitudinal")
    assert len(bend) == 2 and abs(res.f_r_hz[bend[1]] / res.f_r_hz[bend[0]] - 1) < 1e-2   # a pair
    assert max(sh.torsional[bend]) < 0.05 and min(sh.lateral[bend]) > 0.9
    assert sh.torsional[tors] > 0.9
    assert sh.axial[long_] > 0.9
