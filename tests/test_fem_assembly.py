"""fem.assembly / fem.solvers: fast assembly equals plain scikit-fem, symmetry, DOF layout,
electrodes, capacitance, solver backends."""

import numpy as np
import scipy.sparse as sp
import pytest

from fem.assembly import assemble
from fem.materials import piezo_matrices, strain_charge
from fem.solvers import backend_name, factorize, pardiso_available
from rpud_common import ParameterError
from geometry.mesh import Electrode
from test_fem_util import bar, bent_bimorph, rod


def _rel(a, b):
    return abs(a - b).max() / abs(b).max()


@pytest.mark.parametrize("builder, order", [
    (lambda: rod(0.04, 0.001, 1, 6, "PZT-4", (0, 0, -1), True), 2),         # curved P2 geometry
    (lambda: bar(n=(8, 2, 1)), 2),                                          # straight tetrahedra
    (bent_bimorph, 2),             # straight + curved 10-node cells, ceramic + metal, two Q_m
    (bent_bimorph, 1),             # P1 fields on curved geometry
])
def test_fast_assembly_equals_plain_skfem(builder, order):
    """The fast path evaluates the weak forms of fem.forms: the same matrices as those forms
    assembled by skfem.asm (reference=True) to round-off (1e-12 relative)."""
    tm = builder()
    fast, ref = assemble(tm, order=order), assemble(tm, order=order, reference=True)
    assert fast.phi_scale == ref.phi_scale
    for a, b in ((fast.K, ref.K), (fast.M, ref.M), (fast.K_loss, ref.K_loss)):
        assert a.shape == b.shape
        assert _rel(a, b) < 1e-12
        assert _rel(a, a.T) < 1e-13          # symmetric to round-off


def test_layout_and_vector_interleaving():
    tm = rod(0.02, 0.001, 1, 4, "PZT-4", (0, 0, 1), True)
    s = assemble(tm)
    n = s.n_nodes
    assert s.n_u == 3 * n and s.hot_dof == s.ndof - 1 and s.ndof == 3 * n + s.n_phi + 1
    # u DOF of node k, component c is 3k + c: the same as skfem's ElementVector numbering
    ed = s.basis.element_dofs
    assert np.array_equal(s.basis_u.element_dofs, (3 * ed[:, None, :] + np.arange(3)[None, :, None]).reshape(-1, ed.shape[1]))
    x = np.zeros(s.ndof)
    x[: s.n_u] = np.arange(s.n_u)
    assert np.array_equal(s.displacement(x)[5], [15, 16, 17])
    # potential rows have no mass; M is the rigid-body mass
    assert s.M[s.n_u:].nnz == 0
    ux = np.zeros(s.ndof)
    ux[0:s.n_u:3] = 1.0
    vol = np.pi * 0.001 ** 2 * 0.02
    # curved P2 geometry, 8 arcs per circle: the P2 arc interpolation loses ~0.15 % of the area
    assert ux @ (s.M @ ux) == pytest.approx(7500 * vol, rel=3e-3)
    top = s.surface_nodes("top")
    assert np.allclose(s.nodes[top, 2], 0.02) and len(top) == 25
    assert np.array_equal(s.dofs_on("top", components=[2]), 3 * top + 2)
    # electrodes: hot nodes tied, ground eliminated, interior potential strictly inside
    assert set(s.hot_nodes) == set(top)
    assert np.all(s.nodes[s.phi_nodes, 2] > 0) and np.all(s.nodes[s.phi_nodes, 2] < 0.02)


def test_capacitances_of_a_k31_bar(vv):
    l, w, t = 0.04, 0.004, 0.001
    s = assemble(bar(l, w, t, n=(10, 2, 1)))
    eps33S = piezo_matrices("PZT-4").eps_S[2, 2]
    c_blocked = s.capacitance_static("blocked")
    vv.record("VV-FE-06", title="Blocked capacitance of a PZT-4 plate", quantity="static capacitance, clamped",
              description="A PZT-4 bar 40 x 4 x 1 mm with electrodes on its 40 x 4 mm faces, every displacement "
              "held (blocked); the capacitance of the assembled piezoelectric system at zero frequency.",
              reference="Parallel-plate capacitor: C = eps33^S A / t (the field of a blocked plate is uniform).",
              assumptions="Uniform field, no fringing (the electrodes cover the faces): exact up to round-off, "
              "tolerance 1e-9.",
              target=eps33S * l * w / t, computed=c_blocked, tolerance=1e-9, unit="F")
    assert c_blocked == pytest.approx(eps33S * l * w / t, rel=1e-9)   # uniform field: exact
    # free bar: eps33 between eps^S and eps^T; thin bar -> close to eps^T minus the k31 clamp in y
    _, d, epsT = strain_charge(piezo_matrices("PZT-4"))
    c_free = s.capacitance_static("free")
    assert c_free == pytest.approx(epsT[2, 2] * l * w / t, rel=0.02)
    # charge sign: the blocked capacitor at +1 V carries +C
    free = np.arange(s.n_u, s.n_u + s.n_phi)
    x = s.expand(np.zeros(len(free)), free, 1.0)
    assert s.charge(x) > 0


def test_split_for_a_driven_problem_matches_static_capacitance():
    s = assemble(bar(n=(10, 2, 1)))
    sp_ = s.split()
    A = (sp_.K + (2 * np.pi) ** 2 * sp_.M).tocsr()
    xf = factorize(A)(sp_.rhs(2.0, lossy=False))
    x = s.expand(xf, sp_.free, 2.0)
    assert s.charge(x) / 2.0 == pytest.approx(s.capacitance_static("free"), rel=1e-9)
    assert s.potential(x)[s.hot_nodes] == pytest.approx(2.0)


def test_loss_matrix_and_poling_sign():
    up = assemble(rod(0.02, 0.001, 1, 4, "PZT-4", (0, 0, 1), True))
    down = assemble(rod(0.02, 0.001, 1, 4, "PZT-4", (0, 0, -1), True))
    # flipping the poling flips the coupling block only
    Kup_u = up.K[: up.n_u, up.n_u:]
    Kup_d = down.K[: down.n_u, down.n_u:]
    assert _rel(Kup_u, -Kup_d) < 1e-13
    # K_loss = K_uu / Q  (+) tan(delta) s^2 K_phiphi
    Kuu = up.K[: up.n_u, : up.n_u]
    assert _rel(up.K_loss[: up.n_u, : up.n_u], Kuu / 500.0) < 1e-12
    assert _rel(up.K_loss[up.n_u:, up.n_u:], -0.004 * up.K[up.n_u:, up.n_u:]) < 1e-12


def test_electrode_errors():
    tm = rod(0.02, 0.001, 1, 4, "PZT-4", (0, 0, 1), True)
    with pytest.raises(ParameterError, match="ground electrode"):
        assemble(tm.replace(electrodes=(Electrode("top", "hot"),)))
    with pytest.raises(ParameterError, match="must not touch"):
        assemble(tm.replace(electrodes=(Electrode("top", "hot"), Electrode("side", "ground"))))
    with pytest.raises(ParameterError, match="poling"):
        from geometry.mesh import Region
        assemble(tm.replace(regions=(Region("rod", "rod", "PZT-4", None),)))
    with pytest.raises(ParameterError, match="surface"):
        assemble(tm).dofs_on("nowhere")


def _agreement_bound(A, b, *xs):
    """What the solutions' residuals guarantee for their difference: each x is within
    cond(A) ||A x - b|| / ||b|| (relative) of the exact solution, so two of them within the sum
    (residuals in extended precision, so that their own round-off does not enter)."""
    Ad = A.toarray()
    wide = np.clongdouble if np.iscomplexobj(Ad) else np.longdouble
    res = [np.linalg.norm((Ad.astype(wide) @ np.asarray(x, wide) - b).astype(Ad.dtype)) for x in xs]
    return np.linalg.cond(Ad) * sum(res) / np.linalg.norm(b)


def test_solver_backends_agree_real_and_complex():
    """Each backend's residual is checked (1e-8 of b: a backward-stable solve reaches ~1e-12);
    PARDISO and SuperLU then agree to what those residuals guarantee, cond(A) = 5.9e5 times them
    (~1e-6; a failed or wrong solve differs by O(1))."""
    s = assemble(rod(0.02, 0.001, 1, 4, "PZT-4", (0, 0, 1), True))
    K, M, free = s.reduce("open")
    A = (K - (2 * np.pi * 30e3) ** 2 * M).tocsr()
    b = np.random.default_rng(1).normal(size=A.shape[0])
    x_lu = factorize(A, backend="superlu")(b)
    assert np.linalg.norm(A @ x_lu - b) < 1e-8 * np.linalg.norm(b)
    L = s.K_loss[free][:, free]
    Ac = (A + 1j * L).tocsr()
    xc_lu = factorize(Ac, backend="superlu")(b)
    assert np.linalg.norm(Ac @ xc_lu - b) < 1e-8 * np.linalg.norm(b)
    if pardiso_available():
        assert backend_name() == "pardiso"
        x_p = factorize(A)(b)
        tol = _agreement_bound(A, b, x_p, x_lu)
        assert tol < 1e-4 and np.linalg.norm(x_p - x_lu) <= tol * np.linalg.norm(x_lu)
        xc_p = factorize(Ac)(b)
        tol = _agreement_bound(Ac, b, xc_p, xc_lu)
        assert tol < 1e-4 and np.linalg.norm(xc_p - xc_lu) <= tol * np.linalg.norm(xc_lu)
    with pytest.raises(ParameterError):
        factorize(A, backend="mumps")


def test_hermitian_factorisation_solves_a_cyclic_pencil():
    """A complex Hermitian matrix (a cyclic harmonic's reduced pencil, ``hermitian=True``): PARDISO's
    Hermitian factorisation against SuperLU's complex LU, each residual checked (1e-8 of b, as
    above) and the two within cond(A) times their residuals (:func:`_agreement_bound`). The
    matrix is the rod's real shifted pencil turned by a complex unitary congruence (every entry
    complex, the same condition number), so a conjugation error shows as an O(1) residual."""
    s = assemble(rod(0.02, 0.001, 1, 4, "PZT-4", (0, 0, 1), True))
    K, M, free = s.reduce("open")
    A = (K - (2 * np.pi * 30e3) ** 2 * M).tocsr()
    rng = np.random.default_rng(2)
    D = sp.diags(np.exp(1j * rng.uniform(0, 2 * np.pi, A.shape[0])))
    P = sp.random(A.shape[0], A.shape[0], density=2.0 / A.shape[0], random_state=6)
    U = sp.csr_matrix(np.linalg.qr(np.eye(A.shape[0]) + 0.3j * P.toarray())[0])     # unitary, complex
    H = D.conj() @ (U.conj().T @ (A @ U)) @ D
    H = (0.5 * (H + H.conj().T)).tocsr()
    b = rng.normal(size=A.shape[0]) + 1j * rng.normal(size=A.shape[0])
    x_lu = factorize(H, backend="superlu", hermitian=True)(b)
    assert np.linalg.norm(H @ x_lu - b) < 1e-8 * np.linalg.norm(b)
    if pardiso_available():
        F = factorize(H, hermitian=True, matching=False)
        assert F.backend == "pardiso(hermitian)"
        x_p = F(b)
        assert np.linalg.norm(H @ x_p - b) < 1e-8 * np.linalg.norm(b)
        tol = _agreement_bound(H, b, x_p, x_lu)
        assert tol < 1e-4 and np.linalg.norm(x_p - x_lu) <= tol * np.linalg.norm(x_lu)
        # a block of right-hand sides: each column solved as alone (two solves of one system: the
        # same bound)
        y = F(np.stack([b, 2j * b], axis=1))[:, 1] / 2j
        assert np.linalg.norm(y - x_p) <= _agreement_bound(H, b, y, x_p) * np.linalg.norm(x_p)


def test_upper_triangle_keeps_every_diagonal_entry_and_saddle_points_solve():
    from fem.solvers import _upper

    rng = np.random.default_rng(3)
    R = sp.random(200, 200, density=0.03, random_state=4)
    A = (R + R.T).tocsr()
    A.setdiag(0.0)
    A.eliminate_zeros()                     # no diagonal stored at all
    U = _upper(A.copy())
    assert abs(U - sp.triu(A)).max() == 0
    rows = np.repeat(np.arange(200), np.diff(U.indptr))
    assert np.array_equal(np.sort(U.indices[U.indices == rows]), np.arange(200))   # stored, as 0
    assert U.has_sorted_indices
    # a saddle point [[I, B], [B^T, 0]] with an empty (2, 2) diagonal: PARDISO against SuperLU
    B = sp.random(40, 10, density=0.3, random_state=5) + sp.eye(40, 10)
    S = sp.bmat([[sp.eye(40), B], [B.T, None]], format="csr")
    b = rng.normal(size=50)
    x = factorize(S, backend="superlu")(b)
    assert np.linalg.norm(S @ x - b) < 1e-10 * np.linalg.norm(b)
    if pardiso_available():
        x_p = factorize(S)(b)
        tol = _agreement_bound(S, b, x_p, x)                    # cond(S) times their residuals
        assert tol < 1e-6 and np.linalg.norm(x_p - x) <= tol * np.linalg.norm(x)


def test_unique_inverse_matches_numpy_including_the_fallback():
    from fem.fastasm import unique_inverse

    rng = np.random.default_rng(1)
    for keys in (rng.integers(0, 50, 1000), rng.integers(0, 2 ** 60, 1000),   # packed / fallback
                 np.zeros(0, dtype=np.int64), np.array([7])):
        u, inv = unique_inverse(keys)
        u0, inv0 = np.unique(keys, return_inverse=True)
        assert np.array_equal(u, u0) and np.array_equal(inv, inv0.ravel())


def test_node_pair_pattern_and_block_layout_match_scipy():
    import scipy.sparse as sp

    from fem.fastasm import VectorLayout, node_pairs

    rng = np.random.default_rng(2)
    n, nel, nloc = 30, 40, 4
    edofs = np.array([rng.choice(n, nloc, replace=False) for _ in range(nel)])
    pairs, pair, flip = node_pairs(edofs, n)
    ia, ib = np.triu_indices(nloc)
    assert np.array_equal(pairs.pi[pair], np.minimum(edofs[:, ia], edofs[:, ib]))
    assert np.array_equal(pairs.pj[pair], np.maximum(edofs[:, ia], edofs[:, ib]))
    assert np.array_equal(flip, edofs[:, ia] > edofs[:, ib])
    rows, cols = np.repeat(edofs, nloc, axis=1).ravel(), np.tile(edofs, (1, nloc)).ravel()
    ref = sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
    ref.sort_indices()
    assert np.array_equal(pairs.indptr, ref.indptr) and np.array_equal(pairs.col, ref.indices)
    # random upper blocks -> the symmetric matrix with B and B^T, and a scalar "mass"
    B = rng.normal(size=(pairs.n_pairs, 3, 3))
    B[pairs.pi == pairs.pj] += B[pairs.pi == pairs.pj].transpose(0, 2, 1)
    dense = np.zeros((3 * n, 3 * n))
    for p, (i, j) in enumerate(zip(pairs.pi, pairs.pj)):
        dense[3 * i:3 * i + 3, 3 * j:3 * j + 3] = B[p]
        dense[3 * j:3 * j + 3, 3 * i:3 * i + 3] = B[p].T
    layout = VectorLayout(pairs)
    A = layout.blocks(B)
    assert np.array_equal(A.toarray(), dense)
    C = A.copy()
    C.has_sorted_indices = False
    C.sort_indices()
    assert np.array_equal(C.indices, A.indices)           # rows really are sorted
    m = rng.normal(size=pairs.n_pairs)
    Mm = layout.diagonal_blocks(m).toarray()
    S = sp.csr_matrix((m, (pairs.pi, pairs.pj)), shape=(n, n)).toarray()
    S = S + np.triu(S, 1).T
    assert np.array_equal(Mm, np.kron(S, np.eye(3)))
