"""fem.eigen (block shift-invert Lanczos) against dense eigen-solves and against ARPACK.

Tolerances: eigenvalues of small dense pencils 1e-10 relative (scipy.linalg.eigh as the
reference, exact to round-off; block_eigs run at tol = 1e-12). On piezo meshes the block path's
f_r equal ARPACK's and its open-circuit f_a (joint path, the default: from the short circuit's
own Lanczos basis; and the seeded one) equal the from-scratch ARPACK ones to 1e-9 relative. Both
solvers run at fem.modal's tol = 1e-10: the block solver's bound on each lam is <= tol (fem.eigen:
min(rho, rho_c^2 |theta| / gap) |lam - sigma| / lam); ARPACK stops at a residual <= tol |theta|,
which for a symmetric pencil puts theta within (tol |theta|)^2 / gap, i.e. lam within
tol^2 |lam - sigma| / (g lam) relative (g = gap / |theta| >= 0.15 here: < 1e-17). So f differs by
at most 5e-11 between them; 1e-9 leaves 20x for the round-off of the Rayleigh quotients.
Mode shapes: a residual rho_c puts a cluster's subspace (modes within 1e-3, as fem.eigen groups
them: a bending pair split by the mesh is one) within an angle rho_c / g of the exact one; the
block bound allows rho_c^2 <= tol g lam / |lam - sigma|, ARPACK rho_c <= tol, so the two spans
agree to 1 - cos^2 <= (sqrt(tol lam / (|lam - sigma| g)) + tol / g)^2, below 2e-9 for the modes
here (lam / |lam - sigma| <= 18, g >= 0.15): asserted 1e-8. The single vectors of a pair are
not promised (the split is 1e-4: its rotation may reach rho_c / 1e-4).
"""

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

import geometry
from geometry import examples
from fem.assembly import assemble
from fem.eigen import block_eigs, bordered_solve, smooth_start
from fem.modal import modal_analysis
from fem.solvers import factorize
from rpud_common import ParameterError
from reference_designs import reference_default


def _cluster_cos2(V1, V2, M, f, rel=1e-3):
    """Smallest squared cosine of the principal angles between the spans of two M-orthonormal
    mode sets, cluster by cluster (modes whose f lie within ``rel`` of each other)."""
    order = np.argsort(f)
    groups = [[order[0]]]
    for i in order[1:]:
        if f[i] - f[groups[-1][-1]] <= rel * f[i]:
            groups[-1].append(i)
        else:
            groups.append([i])
    return min((np.linalg.svd(V1[:, g].T @ (M @ V2[:, g]), compute_uv=False) ** 2).min() for g in groups)


def _pencil(n=150, seed=3):
    """A sparse SPD pencil with a clustered spectrum (pairs 1e-6 apart, like bending pairs)."""
    rng = np.random.default_rng(seed)
    lam = np.sort(rng.uniform(1.0, 100.0, n))
    lam[1::2] = lam[0::2] * (1 + 1e-6)
    Qd, _ = np.linalg.qr(rng.standard_normal((n, n)))
    Mh = np.diag(rng.uniform(0.5, 2.0, n))                 # M = Mh^2, K = Mh Q diag(lam) Q^T Mh
    K = Mh @ Qd @ np.diag(lam) @ Qd.T @ Mh
    return sp.csr_matrix(0.5 * (K + K.T)), sp.csr_matrix(Mh @ Mh)


def test_block_eigs_matches_dense_eigh():
    K, M = _pencil()
    ref = sla.eigh(K.toarray(), M.toarray(), eigvals_only=True)
    sigma = 50.0
    F = factorize((K - sigma * M).tocsc(), backend="superlu")
    X = np.random.default_rng(0).standard_normal((K.shape[0], 10))
    r = block_eigs(F, K, M, sigma, X, n_wanted=8, tol=1e-12)
    want = np.sort(ref[np.argsort(np.abs(ref - sigma))[:8]])
    assert r.converged
    np.testing.assert_allclose(r.lam, want, rtol=1e-10)
    V = r.vectors
    assert np.abs(V.T @ (M @ V) - np.eye(8)).max() < 1e-9
    res = K @ V - (M @ V) * r.lam
    assert np.linalg.norm(res, axis=0).max() < 1e-6 * np.abs(r.lam).max()
    # block solves, fewer than one per vector
    assert r.n_solves < r.n_vectors


def test_block_eigs_on_a_complex_hermitian_pencil():
    """A cyclic harmonic's pencil is complex Hermitian: the complex block Lanczos against the
    dense reference (scipy.linalg.eigh, exact to round-off; 1e-10 relative as above), through
    PARDISO's Hermitian factorisation where available and SuperLU's complex one. The pencil is
    the real clustered one turned by a complex unitary congruence U^H K U, U^H M U (the same
    spectrum, both matrices complex), so a wrong conjugation changes the answer by O(1)."""
    from fem.solvers import pardiso_available

    K, M = _pencil()
    rng = np.random.default_rng(7)
    U, _ = np.linalg.qr(rng.standard_normal(K.shape) + 1j * rng.standard_normal(K.shape))
    Kc, Mc = (sp.csr_matrix(U.conj().T @ (K @ U)), sp.csr_matrix(U.conj().T @ (M @ U)))
    Kc, Mc = (0.5 * (Kc + Kc.conj().T)).tocsr(), (0.5 * (Mc + Mc.conj().T)).tocsr()
    ref = sla.eigh(Kc.toarray(), Mc.toarray(), eigvals_only=True)
    sigma = 50.0
    want = np.sort(ref[np.argsort(np.abs(ref - sigma))[:8]])
    for backend in ("superlu", "pardiso") if pardiso_available() else ("superlu",):
        F = factorize((Kc - sigma * Mc).tocsr(), backend=backend, hermitian=True, matching=False)
        X = rng.standard_normal((K.shape[0], 10)) + 1j * rng.standard_normal((K.shape[0], 10))
        r = block_eigs(F, Kc, Mc, sigma, X, n_wanted=8, tol=1e-12)
        assert r.converged and np.iscomplexobj(r.vectors)
        np.testing.assert_allclose(r.lam, want, rtol=1e-10)
        V = r.vectors
        assert np.abs(V.conj().T @ (Mc @ V) - np.eye(8)).max() < 1e-9
        res = Kc @ V - (Mc @ V) * r.lam
        assert np.linalg.norm(res, axis=0).max() < 1e-6 * np.abs(r.lam).max()


def test_block_eigs_locked_and_targets():
    K, M = _pencil(seed=5)
    Kd, Md = K.toarray(), M.toarray()
    ref, vecs = sla.eigh(Kd, Md)
    sigma = 30.0
    F = factorize((K - sigma * M).tocsc(), backend="superlu")
    near = np.argsort(np.abs(ref - sigma))
    # deflate the two eigenvectors nearest the shift: the next eight are returned
    L = vecs[:, near[:2]]
    X = np.random.default_rng(1).standard_normal((K.shape[0], 10))
    r = block_eigs(F, K, M, sigma, X, n_wanted=8, locked=L, tol=1e-12)
    np.testing.assert_allclose(r.lam, np.sort(ref[near[2:10]]), rtol=1e-10)
    # targets: perturbed copies of three eigenvectors far from the shift find those three
    pick = near[[12, 15, 20]]
    T = vecs[:, pick] + 1e-2 * np.random.default_rng(2).standard_normal((K.shape[0], 3))
    r = block_eigs(F, K, M, sigma, T, targets=T, tol=1e-12)
    assert r.converged
    np.testing.assert_allclose(r.lam, np.sort(ref[pick]), rtol=1e-10)


def test_bordered_solve_matches_direct():
    K, M = _pencil(n=60)
    A = (K - 10 * M).toarray()
    a = np.random.default_rng(4).standard_normal(60)
    alpha = -3.0
    F = factorize(sp.csc_matrix(A), backend="superlu")
    solve, z = bordered_solve(F, a, alpha)
    Ab = np.block([[A, a[:, None]], [a[None, :], np.array([[alpha]])]])
    B = np.random.default_rng(5).standard_normal((61, 3))
    np.testing.assert_allclose(solve(B), np.linalg.solve(Ab, B), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(solve(B[:, 0]), np.linalg.solve(Ab, B[:, 0]), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(z, np.linalg.solve(A, a), rtol=1e-9)


def test_block_eigs_bad_input():
    K, M = _pencil(n=40)
    F = factorize((K - 10 * M).tocsc(), backend="superlu")
    with pytest.raises(ParameterError):
        block_eigs(F, K, M, 10.0, np.ones((40, 2)))                       # neither n_wanted nor targets
    with pytest.raises(ParameterError):
        block_eigs(F, K, M, 10.0, np.ones((39, 2)), n_wanted=2)


@pytest.fixture(scope="module")
def k33():
    return assemble(geometry.build_mesh(examples.k33_rod(), mesh_size=0.002))


@pytest.fixture(scope="module")
def langevin():
    return assemble(geometry.build_mesh(examples.langevin_sandwich(), mesh_size=0.006))


@pytest.mark.parametrize("case", ["k33", "langevin"])
def test_block_modal_equals_arpack(case, request):
    s = request.getfixturevalue(case)
    near = 40e3 if case == "k33" else 25e3
    old = modal_analysis(s, near, 10, eigen="arpack", open_circuit="scratch")
    new = modal_analysis(s, near, 10)                                # block SC, joint OC
    # short circuit: unchanged by the block solver
    np.testing.assert_allclose(new.f_r_hz, old.f_r_hz, rtol=1e-9)
    assert _cluster_cos2(old.vectors, new.vectors, s.M, np.asarray(new.f_r_hz)) > 1 - 1e-8
    # open circuit: the joint path equals the from-scratch one, also in which modes have no
    # anti-resonance of their own (NaN: fem.modal.own_anti_resonance; the Langevin's bending pair
    # just below the working mode's anti-resonance)
    np.testing.assert_array_equal(np.isnan(new.f_a_hz), np.isnan(old.f_a_hz))
    np.testing.assert_allclose(new.f_a_hz, old.f_a_hz, rtol=1e-9)
    # k_eff^2 = 1 - (f_r/f_a)^2 carries the 1e-9 (k_eff itself is a square root: near 0 it
    # magnifies round-off)
    np.testing.assert_allclose(new.k_eff ** 2, old.k_eff ** 2, atol=4e-9)
    assert (new.k_eff > 0.05).any()                                  # the coupled modes are there
    assert new.labels == old.labels


def test_block_modal_rigid_modes(k33):
    s = k33
    # near 0 Hz the six rigid-body modes are computed and reported, not paired
    old = modal_analysis(s, 0.0, 4, eigen="arpack")
    new = modal_analysis(s, 0.0, 4)
    assert len(new.rigid_hz) == len(old.rigid_hz) == 6
    np.testing.assert_allclose(new.f_r_hz, old.f_r_hz, rtol=1e-9)
    np.testing.assert_allclose(new.f_a_hz, old.f_a_hz, rtol=1e-9)


def test_clamped_factor_reuse_and_choices(k33):
    s = k33
    name = next(iter(s.mesh.facet_sets))
    # a clamped body: nothing deflated
    old = modal_analysis(s, 40e3, 4, clamp=[name], eigen="arpack")
    new = modal_analysis(s, 40e3, 4, clamp=[name])
    np.testing.assert_allclose(new.f_r_hz, old.f_r_hz, rtol=1e-9)
    np.testing.assert_allclose(new.f_a_hz, old.f_a_hz, rtol=1e-9)
    # an existing factorisation is used as it is
    sigma = (2 * np.pi * 40e3) ** 2
    K, M, free = s.reduce("short", [name])
    F = factorize((K - sigma * M).tocsr(), matching=False)          # as modal_analysis factorises
    again = modal_analysis(s, 40e3, 4, clamp=[name], factor=F)
    np.testing.assert_array_equal(again.f_r_hz, new.f_r_hz)
    np.testing.assert_array_equal(again.f_a_hz, new.f_a_hz)
    assert again.timings["factorisation_s"] == 0.0
    with pytest.raises(ParameterError):
        modal_analysis(s, 40e3, 4, factor=F)                          # free body: other DOFs
    with pytest.raises(ParameterError):
        modal_analysis(s, 40e3, 4, eigen="lanczos")
    with pytest.raises(ParameterError):
        modal_analysis(s, 40e3, 4, open_circuit="fast")


def test_smooth_start_columns(langevin):
    s = langevin
    free = s.free_dofs("short")
    X = smooth_start(s.nodes, free, s.ndof, 10, n_random=3)
    assert X.shape == (len(free), 10)
    np.testing.assert_allclose(np.linalg.norm(X, axis=0), 1.0)
    assert np.linalg.matrix_rank(X) == 10
    np.testing.assert_array_equal(X, smooth_start(s.nodes, free, s.ndof, 10, n_random=3))  # reproducible


def test_matching_reuse_gives_identical_results():
    """The final modal analysis of a match reuses the last stage's system and factorisation;
    the outcome is bit-identical to assembling and factorising again."""
    from fem.matching import MatchSettings, match

    # a coarse plain-coupler drill started near its matched coupler length (3 evaluations; the horn
    # length of tests/reference_designs.py, for which 41.6 mm is that start)
    d = geometry.filleted(reference_default(), 0.0).replace(
        {"coupler.n_slots": 0, "coupler.n_teeth": 0, "stack.ring_thickness": 0.006, "coupler.length": 0.0416})
    mesh = geometry.build_mesh(d, mesh_size=0.008)
    runs = [match(d, MatchSettings(tune=("coupler.length",), xtol=5e-4, mesh_size=0.008, reuse=reuse),
                  mesh=mesh) for reuse in (True, False)]
    a, b = runs
    assert a.tuned == b.tuned and a.matched_hz == b.matched_hz
    np.testing.assert_array_equal(a.modal.f_r_hz, b.modal.f_r_hz)
    np.testing.assert_array_equal(a.modal.f_a_hz, b.modal.f_a_hz)
    assert a.modal.timings["factorisation_s"] == 0.0 < b.modal.timings["factorisation_s"]
    assert a.converged and a.matched_hz == pytest.approx(20e3, rel=5e-3)


def test_joint_open_circuit_runs_alone_and_equals_seeded(langevin, caplog):
    """The joint path pairs every mode itself (no seeded or scratch fallback, no extra block
    solve) and agrees with the seeded path to 1e-9; the open-circuit vectors are M-normalised
    eigenvectors of the bordered pencil."""
    import logging

    s = langevin
    with caplog.at_level(logging.INFO, logger="fem.modal"):
        joint = modal_analysis(s, 25e3, 10, open_circuit="joint")
    text = caplog.text
    assert "open_from_short_run" in text and "seeded solve" not in text and "open_block_solves" not in text
    seeded = modal_analysis(s, 25e3, 10, open_circuit="seeded")
    np.testing.assert_allclose(joint.f_a_hz, seeded.f_a_hz, rtol=1e-9)
    np.testing.assert_allclose(joint.f_r_hz, seeded.f_r_hz, rtol=1e-9)
    # residual of the bordered pencil: K_o x = lam M_o x on the open-circuit unknowns
    free_o = np.append(s.free_dofs("short"), s.hot_dof)
    Ko, Mo = s.K[free_o][:, free_o], s.M[free_o][:, free_o]
    own = np.isfinite(joint.f_a_hz)          # modes with an anti-resonance of their own
    assert own.any()
    x = joint.vectors_open[free_o][:, own]
    lam = (2 * np.pi * joint.f_a_hz[own]) ** 2
    r = Ko @ x - (Mo @ x) * lam
    assert np.linalg.norm(r, axis=0).max() < 1e-5 * np.linalg.norm(Ko @ x, axis=0).max()
    with pytest.raises(ParameterError):
        modal_analysis(s, 25e3, 4, eigen="arpack", open_circuit="joint")


def test_factorisation_without_matching_solves_saddle_points():
    """modal_analysis factorises without PARDISO's weighted matching (factorize(matching=False));
    a saddle-point matrix with zero diagonal entries is still solved to round-off (PARDISO's
    2x2 pivots; a perturbed pivot would trigger a refactorisation with the matching)."""
    from fem.solvers import pardiso_available

    rng = np.random.default_rng(1)
    n, m = 60, 20
    A = sp.random(n, n, density=0.1, random_state=2)
    A = A @ A.T + sp.identity(n)
    B = sp.random(n, m, density=0.2, random_state=3) + sp.eye(n, m)
    C = sp.diags([np.full(m - 1, 1e-3), np.full(m - 1, 1e-3)], [-1, 1]).tolil()
    C[m - 1, m - 1] = 1.0                                        # zero diagonal but the last entry
    S = sp.bmat([[A, B], [B.T, C]]).tocsr()
    b = rng.standard_normal(n + m)
    for matching in (True, False):
        F = factorize(S, matching=matching)
        x = F(b)
        assert np.linalg.norm(S @ x - b) < 1e-12 * np.linalg.norm(b)
        if pardiso_available():
            assert F.perturbed == 0


def test_matching_warm_start_same_modes_fewer_solves(langevin, caplog):
    """A matching trial started from the previous trial's modes (fem.matching's ``warm``) finds
    the same modes as the smooth start: both meet block_eigs' tolerance 1e-12 on the eigenvalue,
    so their frequencies agree within ~1e-12 (asserted 1e-10), in fewer block solves. The stiffer
    copy (K x 1.004, +0.2 % in f) stands in for a morphed trial length."""
    import dataclasses
    import logging
    import re

    from fem.matching import _modes

    s = langevin
    t = dataclasses.replace(s, K=(1.004 * s.K).tocsr())
    free = s.free_dofs("short")
    _, prev = _modes(s, free, 25e3, 4)

    def solves(**kw):
        caplog.clear()
        with caplog.at_level(logging.DEBUG, logger="fem.matching"):
            f, _ = _modes(t, free, 25e3, 4, **kw)
        return f, int(re.search(r"(\d+) block solves", caplog.text).group(1))

    f_cold, n_cold = solves()
    f_warm, n_warm = solves(warm=prev)
    np.testing.assert_allclose(f_warm, f_cold, rtol=1e-10)
    assert n_warm < n_cold
