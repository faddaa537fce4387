"""Block shift-invert eigen-solver for the piezo-elastic pencil ``(K, M)``.

API
---
``block_eigs(solve, K, M, sigma, start, *, n_wanted=None, targets=None, locked=None, tol=1e-10,
max_dim=None) -> BlockEigs``

Why a block method
------------------
The sparse direct solve reads the whole factor once per call whatever the number of
right-hand sides, so PARDISO solves a block of 12-24 vectors for about 4-5x less per vector
than one at a time (68.6k DOF: 55 ms for one, 220 ms for 12, 310 ms for 24). ARPACK
(``scipy.sparse.linalg.eigsh``) asks for one vector at a time; this module builds the Krylov
space of ``S = (K - sigma M)^-1 M`` a block at a time instead.

Method
------
Block Lanczos with full M-orthogonalisation (classical Gram-Schmidt twice; the block itself
orthonormalised through the eigen-decomposition of its M-Gram matrix, directions shorter than
``1e-12`` of the largest ``|theta|`` dropped), Rayleigh-Ritz on ``T = Q^T M S Q`` (explicit, symmetrised),
thick restart to the wanted Ritz vectors plus one block when the basis reaches ``max_dim``.
``M`` may be semi-definite (the massless potential DOFs): every quantity uses ``M Q`` only, and
the returned eigenvectors are ``S Q c / theta`` (in the range of ``S``, so their potential is
the statically condensed response of their displacement, as in ARPACK's mode 3).

* A complex Hermitian pencil (a cyclic harmonic ``0 < k < N / 2``) is solved as it is: the
  same steps with conjugate transposes, real Ritz values, complex vectors.
* ``locked``: M-orthonormal vectors to deflate (the rigid-body modes of a free body); the
  operator is followed by the M-orthogonal projection away from them.
* Wanted Ritz pairs: the ``n_wanted`` of largest ``|theta|`` (eigenvalues nearest ``sigma``),
  or, with ``targets`` (``(n, p)`` vectors), the Ritz vector of each target assigned by the
  mass-weighted MAC (Hungarian assignment): the partner of each target, wherever it lies.
* Convergence: the block-Lanczos residual of each wanted Ritz pair,
  ``rho = ||S y - theta y||_M / |theta|`` (for ``||y||_M = 1``), read off the last block's
  coefficients without an extra product. Converged when every wanted pair's error bound
  ``min(rho, rho_c^2 |theta| / gap) |lam - sigma| / |lam|`` is ``<= tol`` (``rho_c``: the block
  residual of the pair's cluster, Ritz values within 1e-3 relative such as a bending pair,
  which Rayleigh-Ritz separates; ``gap``: distance to the nearest Ritz value outside it; with
  ``targets`` at most ``1e-3 |theta|``, since a basis grown from a few seeds may not have seen
  a nearer eigenvalue yet; a basis grown from a random-rich start block sees the
  neighbourhood of its extreme Ritz values), i.e. the
  Rayleigh-Ritz bound in the operator's eigenvalue carried over to ``lam``; stops early (with
  a warning and ``converged = False``) when that bound stagnates at the round-off of the solve.
* Eigenvalues are the Rayleigh quotients ``y^T K y / y^T M y`` on the exact matrices, not
  ``sigma + 1/theta``: their error is of order ``rho^2`` (measured: ``<= 0.1 rho^2`` relative on
  the article's drill), and the round-off of the solve (which limits ``1/theta`` to ~1e-9 relative for modes far from
  the shift on a 68.6k-DOF drill) does not enter them.

* Joint open circuit (``border=(a, alpha, z)``): the open-circuit matrix borders ``K - sigma M``
  by the hot column ``a`` and diagonal ``alpha``; its solve is ``S_open = S + z z^T M / delta``
  on the short-circuit unknowns (``z = (K - sigma M)^-1 a``, ``delta = alpha - a^T z``). With
  ``z`` in the start block, ``S_open`` maps span Q into span Q + the next block exactly as ``S``
  does (the rank-1 part stays in span Q), so ``Q^T M S_open Q = T + g g^T / delta``
  (``g = Q^T M z``) is the Rayleigh-Ritz matrix of the open circuit in the same basis, and its
  Ritz pairs have the residual coefficients ``B c_last`` of the same Lanczos relation. One run
  converges both sets (each wanted short-circuit pair and its MAC partner among the open-circuit
  Ritz pairs) to the same bound; no extra solve. A thick restart would take ``z`` out of the
  basis, so the basis is sized for the whole run and the bordered pairs are dropped if it fills.

``BlockEigs``: ``lam`` (ascending), ``vectors`` (``(n, k)``, ``V^T M V = I``), ``residual``
(``rho`` per pair), ``n_solves`` (block solves), ``n_vectors`` (right-hand sides in all),
``dim`` (final basis size), ``converged``, ``restarts``; with ``border``: ``lam_open``,
``vectors_open`` (``(n + 1, k)``), ``residual_open``, ``converged_open``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.sparse.linalg as spla

from rpud_common import ParameterError

from .solvers import blas_threads

__all__ = ["block_eigs", "BlockEigs", "smooth_start", "bordered_solve", "arpack_eigs", "rigid_basis"]

log = logging.getLogger(__name__)

_DROP = 1e-12     # new directions shorter than this times the largest |theta| are dropped
_GAP_FLOOR = 1e-3  # with targets: largest relative gap assumed to the nearest eigenvalue
_CLUSTER = 1e-3    # Ritz values closer than this (relative) are bounded together


@dataclass(frozen=True)
class BlockEigs:
    """Result of :func:`block_eigs` (see the module docstring)."""

    lam: np.ndarray
    vectors: np.ndarray
    residual: np.ndarray
    n_solves: int
    n_vectors: int
    dim: int
    converged: bool
    restarts: int
    lam_open: np.ndarray | None = None
    vectors_open: np.ndarray | None = None
    residual_open: np.ndarray | None = None
    converged_open: bool = False


class _Basis:
    """M-orthonormal basis ``Q`` (columns ``:m`` of preallocated arrays) with ``M Q`` and ``S Q``."""

    def __init__(self, M, n, cap, locked, dtype=float):
        self.M = M
        self.L = locked
        self.ML = None if locked is None else M @ locked
        self.Q = np.empty((n, cap), order="F", dtype=dtype)
        self.MQ = np.empty((n, cap), order="F", dtype=dtype)
        self.SQ = np.empty((n, cap), order="F", dtype=dtype)
        self.m = 0
        self.floor = 0.0             # M-norm^2 below which a direction is round-off

    def _deflate(self, W):
        return W if self.L is None else W - self.L @ (_h(self.ML) @ W)

    def project(self, W, extra=None, passes=2):
        """Classical Gram-Schmidt passes (twice is enough) against the locked vectors, Q and
        ``extra``."""
        m = self.m
        for _ in range(passes):
            W = self._deflate(W)
            if m:
                W = W - self.Q[:, :m] @ (_h(self.MQ[:, :m]) @ W)
            if extra is not None:
                W = W - extra[0] @ (_h(extra[1]) @ W)
        return W

    def orthonormalise(self, W0):
        """M-orthonormal basis ``Qb`` of ``W0`` (already projected against Q and the locked
        vectors). Returns (Qb, MQb, B) with ``W0 = Qb B`` up to dropped round-off, or
        (None, None, None) when nothing independent is left.

        The Gram matrix squares the condition number, so a block whose columns differ in size
        by orders of magnitude (a converging Krylov block) is taken in levels: the directions
        within 1e-4 (M-norm squared) of the largest first, then the rest projected against
        them, and so on."""
        W = W0
        qs, mqs = [], []
        for level in range(6):
            if level:
                W = self.project(W, (np.hstack(qs), np.hstack(mqs)))
            MW = self.M @ W
            G = _h(W) @ MW
            w, U = np.linalg.eigh(0.5 * (G + _h(G)))
            wmax = float(w.max(initial=0.0))
            if wmax <= max(self.floor, 0.0) or wmax <= 0.0:
                break
            good = w > 1e-4 * wmax
            sc = U[:, good] / np.sqrt(w[good])
            qs.append(W @ sc)
            mqs.append(MW @ sc)
            rest = (~good) & (w > max(self.floor, 1e-15 * wmax))
            if not rest.any():
                break
            W = W @ U[:, rest]
        if not qs:
            return None, None, None
        Qb, MQb = np.hstack(qs), np.hstack(mqs)
        return Qb, MQb, _h(MQb) @ W0

    def append(self, Qb, MQb):
        k = Qb.shape[1]
        self.Q[:, self.m: self.m + k] = Qb
        self.MQ[:, self.m: self.m + k] = MQb
        self.m += k
        return slice(self.m - k, self.m)

    def rotate(self, C):
        """Replace the basis by ``Q C`` (thick restart)."""
        m, k = self.m, C.shape[1]
        for A in (self.Q, self.MQ, self.SQ):
            A[:, :k] = A[:, :m] @ C
        self.m = k


def _error_estimate(pick, theta_all, R_all, sigma, tol, gap_floor):
    """Relative eigenvalue error bound of each wanted Ritz pair.

    ``R_all``: the residual coefficients of every Ritz pair (``S y - theta y = Q_next R``).
    For an M-symmetric operator a Ritz value with residual ``r`` is within ``r`` of an
    eigenvalue (Bauer-Fike), and a cluster of Ritz values (within ``_CLUSTER`` relative, e.g. a
    bending pair) with block residual ``R`` is within ``||R||^2 / gap`` of eigenvalues when the
    rest of the spectrum is ``gap`` away (Rayleigh-Ritz separates the cluster's own members).
    The relative error of ``lam = sigma + 1/theta`` is that of ``theta`` times
    ``|lam - sigma| / |lam|`` (``|lam|`` floored at 1e-3 ``|sigma|``: rigid-body modes sit at 0)."""
    est = np.empty(len(pick))
    for i, j in enumerate(pick):
        t = theta_all[j]
        d = np.abs(theta_all - t)
        inside = d <= max(_CLUSTER, tol) * abs(t)
        r = np.linalg.norm(R_all[:, j])
        r_cl = np.linalg.norm(R_all[:, inside], 2) if R_all.size else 0.0
        # in a basis grown from a few seeds an eigenvalue not yet seen may be nearer than every
        # Ritz value: there the gap is capped at gap_floor |theta| (the langevin example: a
        # seeded open-circuit mode 0.4 % from a bending pair absent from the basis came out
        # 6e-9 off without the cap)
        gap = min(d[~inside].min() if (~inside).any() else np.inf, gap_floor * abs(t))
        lam = sigma + 1.0 / t
        scale = abs(1.0 / t) / max(abs(lam), 1e-3 * abs(sigma), 1e-300) / abs(t)
        est[i] = min(r, r_cl * r_cl / gap) * scale
    return est


def _hungarian_pick(mac_rows: np.ndarray) -> np.ndarray:
    from scipy.optimize import linear_sum_assignment

    rows, cols = linear_sum_assignment(-mac_rows)
    out = np.empty(mac_rows.shape[0], dtype=int)
    out[rows] = cols
    return out


def block_eigs(solve: Callable[[np.ndarray], np.ndarray], K, M, sigma: float, start: np.ndarray, *,
               n_wanted: int | None = None, targets: np.ndarray | None = None,
               locked: np.ndarray | None = None, tol: float = 1e-10,
               max_dim: int | None = None, max_solves: int = 200,
               border: tuple[np.ndarray, float, np.ndarray] | None = None) -> BlockEigs:
    """Eigenpairs of ``K x = lam M x`` near ``sigma`` by block shift-invert Lanczos.

    Parameters
    ----------
    solve : callable
        ``solve(B) = (K - sigma M)^-1 B`` for a block ``B`` of shape ``(n, b)``.
    K, M : sparse (n, n)
        The pencil (``M`` symmetric positive semi-definite, ``K`` symmetric), or a complex
        Hermitian one (a cyclic harmonic's: every transpose is the conjugate one; give a complex
        ``start`` and a complex ``solve``).
    sigma : float
        Shift, rad^2/s^2 (the ``solve`` must use the same).
    start : (n, b) array
        Start block; its width is the block size. Only its M-part matters. Complex for a
        Hermitian pencil (the basis and the vectors are then complex).
    n_wanted : int
        Number of eigenpairs nearest ``sigma`` (largest ``|theta|``) wanted.
    targets : (n, p) array, optional
        Instead of ``n_wanted``: one eigenpair per target, the Ritz vector assigned to it by
        the mass-weighted MAC.
    locked : (n, r) array, optional
        M-orthonormal vectors deflated from the operator (rigid-body modes).
    tol : float
        Relative accuracy of the eigenvalues (see the module docstring for the bound used).
    max_dim : int, optional
        Largest basis before a thick restart (default ``max(160, 8 b + 2 wanted)``).
    max_solves : int
        Largest number of block solves before giving up (``converged = False``).
    border : (a, alpha, z), optional
        Also the eigenpairs of the bordered pencil ``([[K, a], [a^T, alpha]], diag(M, 0))``
        (the open circuit: ``a`` the hot column, ``alpha`` its diagonal entry) from the same
        basis, with ``z = (K - sigma M)^-1 a`` (must lie in the span of ``start``): the joint
        Rayleigh-Ritz of the module docstring. One wanted bordered pair per wanted pair (its
        MAC partner in the basis), converged to the same bound; returned in ``lam_open``,
        ``vectors_open`` (``(n + 1, k)``, the last row the border unknown), ``residual_open``,
        ``converged_open`` (False when a thick restart would have dropped ``z``).
    """
    start = np.asarray(start, dtype=complex if np.iscomplexobj(start) else float)
    n_want, max_dim = _check_block(start, M, n_wanted, targets, max_dim)
    n, b = start.shape
    gap_floor = _GAP_FLOOR if targets is not None else np.inf
    basis = _Basis(M, n, max_dim + b, locked, start.dtype)
    tnorm2 = None if targets is None else np.abs(np.einsum("ij,ij->j", targets.conj(), M @ targets))
    if border is not None:
        if np.iscomplexobj(start):
            raise ParameterError("border", "complex start", "the joint open-circuit solve is real only")
        if targets is not None:
            raise ParameterError("border", "targets", "the joint open-circuit solve needs n_wanted")
        border = _Border(M, *border)
        # the basis must not be restarted (z would leave it): room for the whole run
        max_dim = max(max_dim, min(n, b * 12 + 2 * n_want))
    n_solves = n_vectors = restarts = 0
    T = np.zeros((0, 0), dtype=start.dtype)
    Qb, MQb, _ = basis.orthonormalise(basis.project(start))
    if Qb is None:
        raise ParameterError("start", "block", "has no part outside the locked vectors")
    converged = False
    history: list[float] = []
    while True:
        blk = basis.append(Qb, MQb)
        # ---- one block solve: Y = S Qb, projected away from the locked vectors
        Y = basis._deflate(solve(MQb))
        n_solves += 1
        n_vectors += Qb.shape[1]
        basis.SQ[:, blk] = Y
        m, m_old = basis.m, T.shape[0]
        T, col = _extend(T, basis.MQ[:, :m], Y)
        theta_all, C_all = np.linalg.eigh(T)
        # ---- the next block; its coefficients B also give the residuals (S y - theta y =
        # W_orth c_last: the earlier blocks' images already lie in the basis)
        basis.floor = (_DROP * float(np.max(np.abs(theta_all)))) ** 2
        Qn, MQn, B = basis.orthonormalise(basis.project(Y - basis.Q[:, :m] @ col, passes=1))
        pick = _wanted(theta_all, C_all, n_want, basis.MQ[:, :m], targets, tnorm2)
        theta, C = theta_all[pick], C_all[:, pick]
        R_all = np.zeros((0, m)) if B is None else B @ C_all[m_old:, :]
        rho = np.linalg.norm(R_all[:, pick], axis=0) / np.abs(theta)
        est = _error_estimate(pick, theta_all, R_all, sigma, tol, gap_floor)
        if border is not None:
            est = np.concatenate([est, border.ritz(basis, T, C, B, m_old, sigma, tol)])
        log.debug("block eigs: dim %d, %d solves, max residual %.2e, max error estimate %.2e",
                  m, n_solves, rho.max(), est.max())
        if est.max() <= tol or Qn is None:
            converged = bool(est.max() <= tol)
            break
        history.append(rho.max())
        if n_solves >= max_solves or (len(history) > 4 and history[-1] < 1e-6
                                      and history[-1] > 0.5 * history[-5]):
            break                                       # budget spent, or stagnating at round-off
        Qb, MQb = Qn, MQn
        if m + Qb.shape[1] > max_dim and border is not None:
            border = None                               # z would leave the basis: give up the border
            log.info("block eigs: basis full, the bordered pairs are dropped")
        if m + Qb.shape[1] > max_dim:
            T = _thick_restart(basis, theta_all, C_all, pick, min(max(n_want + b, m // 2), max_dim - Qb.shape[1]))
            restarts += 1
    lam, V, order = _ritz_vectors(basis.SQ[:, :basis.m] @ C, theta, K, M)
    out = {} if border is None else border.pairs(basis, K, M, converged)
    if not converged:
        log.warning("block eigs: not converged after %d block solves (error estimate %.1e > %.1e)",
                    n_solves, est.max(), tol)
    return BlockEigs(lam=lam[order], vectors=V[:, order], residual=rho[order], n_solves=n_solves,
                     n_vectors=n_vectors, dim=basis.m, converged=converged, restarts=restarts, **out)


def _h(X):
    """The conjugate transpose (a real array's transpose, the same view)."""
    return X.conj().T


def _check_block(start, M, n_wanted, targets, max_dim) -> tuple[int, int]:
    """``(n_want, max_dim)`` of a :func:`block_eigs` call, its arguments checked."""
    if start.ndim != 2 or start.shape[0] != M.shape[0]:
        raise ParameterError("start", start.shape, f"must be ({M.shape[0]}, b)")
    if (n_wanted is None) == (targets is None):
        raise ParameterError("n_wanted", n_wanted, "give exactly one of n_wanted and targets")
    n, b = start.shape
    n_want = n_wanted if targets is None else targets.shape[1]
    if n_want < 1:
        raise ParameterError("n_wanted", n_want, "must be >= 1")
    if max_dim is None:
        max_dim = max(160, 8 * b + 2 * n_want)
    return n_want, min(max_dim, n)


def _wanted(theta_all, C_all, n_want, MQ, targets, tnorm2) -> np.ndarray:
    """The wanted Ritz pairs: the ``n_want`` largest ``|theta|`` (nearest the shift), or one per
    target by the mass-weighted MAC (``MQ``: ``M Q``; ``tnorm2``: the targets' M-norms^2)."""
    if targets is None:
        return np.argsort(-np.abs(theta_all))[:n_want]
    G = _h(MQ) @ targets                               # Q^H M t
    return _hungarian_pick(np.abs(_h(G) @ C_all) ** 2 / tnorm2[:, None])


def _extend(T, MQ, Y):
    """The projected operator ``Q^T M S Q`` grown by the new block's images ``Y``, and its new
    columns (``MQ``: ``M Q`` of the grown basis)."""
    m, m_old = MQ.shape[1], T.shape[0]
    col = _h(MQ) @ Y                                   # T[:, new]
    Tn = np.empty((m, m), dtype=col.dtype)
    Tn[:m_old, :m_old] = T
    Tn[:, m_old:] = col
    Tn[m_old:, :m_old] = _h(col[:m_old])
    return 0.5 * (Tn + _h(Tn)), col


def _thick_restart(basis, theta_all, C_all, pick, keep_n):
    """Keep the wanted Ritz vectors and the best others (largest ``|theta|``), ``keep_n`` in
    all; returns the projected operator of the kept basis (diagonal)."""
    rest = np.setdiff1d(np.argsort(-np.abs(theta_all)), pick, assume_unique=True)
    keep = np.concatenate([pick, rest[: max(keep_n - len(pick), 0)]])
    basis.rotate(C_all[:, keep])
    return np.diag(theta_all[keep])


def _ritz_vectors(SQC, theta, K, M):
    """``(lam, V, order)``: M-normalised Ritz vectors ``S Q c / theta``, their Rayleigh quotients
    and the order of increasing ``lam``."""
    V = SQC / theta
    MV = M @ V
    mn = np.sqrt(np.abs(np.einsum("ij,ij->j", V.conj(), MV)))
    V = V / mn
    lam = np.einsum("ij,ij->j", V.conj(), K @ V).real  # Rayleigh quotients (V^H M V = 1)
    return lam, V, np.argsort(lam)


class _Border:
    """The open-circuit pencil ``([[K, a], [a^T, alpha]], diag(M, 0))`` solved in the basis of
    the short-circuit one (the joint Rayleigh-Ritz of the module docstring); ``z = (K - sigma
    M)^-1 a`` lies in that basis."""

    def __init__(self, M, a, alpha, z):
        self.a, self.alpha, self.z = np.asarray(a, float), float(alpha), np.asarray(z, float)
        self.delta = self.alpha - self.a @ self.z     # Schur complement of the border
        self.Mz = M @ self.z

    def ritz(self, basis, T, C, B, m_old, sigma, tol) -> np.ndarray:
        """Error estimates of the bordered pairs matched to the wanted ones (columns ``C``)."""
        # open circuit in the same basis: Q^T M S_open Q = T + g g^T / delta (g = Q^T M z);
        # z lies in span Q, so the residual of a bordered Ritz pair is again Q_next B c_last
        m = basis.m
        self.g = basis.Q[:, :m].T @ self.Mz
        self.theta_all, self.C_all = np.linalg.eigh(T + np.outer(self.g, self.g) / self.delta)
        self.pick = _hungarian_pick((C.T @ self.C_all) ** 2)
        R_o_all = np.zeros((0, m)) if B is None else B @ self.C_all[m_old:, :]
        self.rho = np.linalg.norm(R_o_all[:, self.pick], axis=0) / np.abs(self.theta_all[self.pick])
        return _error_estimate(self.pick, self.theta_all, R_o_all, sigma, tol, _GAP_FLOOR)

    def pairs(self, basis, K, M, converged) -> dict:
        """The bordered eigenpairs of the last :meth:`ritz`, as :class:`BlockEigs` fields."""
        theta_o, C_o = self.theta_all[self.pick], self.C_all[:, self.pick]
        # S_open Q c = S Q c + z (g^T c) / delta; border unknown -(g^T c) / delta
        s_o = (self.g @ C_o) / self.delta
        U = (basis.SQ[:, :basis.m] @ C_o + np.outer(self.z, s_o)) / theta_o
        h = -s_o / theta_o
        mn_o = np.sqrt(np.abs(np.einsum("ij,ij->j", U, M @ U)))
        U, h = U / mn_o, h / mn_o
        lam_o = np.einsum("ij,ij->j", U, K @ U) + 2 * h * (self.a @ U) + self.alpha * h * h
        oo = np.argsort(lam_o)
        return dict(lam_open=lam_o[oo], vectors_open=np.vstack([U, h[None, :]])[:, oo],
                    residual_open=self.rho[oo], converged_open=converged)


def smooth_start(nodes: np.ndarray, free: np.ndarray, ndof: int, b: int, n_random: int,
                 seed: int = 20000) -> np.ndarray:
    """Start block for :func:`block_eigs` on the free DOFs ``free`` of a system with ``ndof``.

    ``b - n_random`` smooth displacement fields (Legendre polynomials ``P_k`` of degree 1, 2, ...
    along the longest axis of the body: axial, the two transverse and the twist ``P_k(zeta) e_theta r``,
    the shapes of the low bending / torsion / axial modes of a slender transducer) and
    ``n_random`` random columns (fixed seed: reproducible), which make sure that no mode is
    M-orthogonal to the start (a symmetric body has modes orthogonal to every smooth field
    above). Smooth columns cut the high-frequency content a random start puts in every
    direction, so the wanted modes converge in fewer block solves. Potential entries are 0.
    """
    n_nodes = len(nodes)
    x = nodes - nodes.mean(axis=0)
    ext = np.ptp(x, axis=0)
    ax = int(np.argmax(ext))
    t1, t2 = [c for c in range(3) if c != ax]
    zeta = 2 * (x[:, ax] - x[:, ax].min()) / max(ext[ax], 1e-300) - 1
    r = max(ext[t1], ext[t2], 1e-300)
    cols = []
    k = 1
    while len(cols) < b - n_random:
        P = np.polynomial.legendre.Legendre.basis(k)(zeta)
        for kind in range(4):
            u = np.zeros((n_nodes, 3))
            if kind == 0:
                u[:, ax] = P
            elif kind < 3:
                u[:, (t1, t2)[kind - 1]] = P
            else:
                u[:, t1] = -x[:, t2] / r * P
                u[:, t2] = x[:, t1] / r * P
            full = np.zeros(ndof)
            full[: 3 * n_nodes] = u.ravel()
            cols.append(full[free])
            if len(cols) == b - n_random:
                break
        k += 1
    rnd = np.random.default_rng(seed).standard_normal((len(free), n_random))
    X = np.column_stack(cols + [rnd]) if cols else rnd
    return X / np.linalg.norm(X, axis=0)


def bordered_solve(solve: Callable[[np.ndarray], np.ndarray], a: np.ndarray, alpha: float,
                   z: np.ndarray | None = None):
    """Solves with ``[[A, a], [a^T, alpha]]`` from solves with ``A`` (one scalar Schur complement).

    The open-circuit matrix is the short-circuit one bordered by the hot-electrode row and
    column, so one factorisation serves both. Returns ``(solve_bordered, z)`` with
    ``z = A^-1 a`` (the short-circuit response to the hot column); ``solve_bordered`` accepts a
    vector ``(n + 1,)`` or a block ``(n + 1, b)``; ``z`` may be given when already known."""
    z = np.asarray(solve(a) if z is None else z).ravel()
    delta = alpha - a @ z

    def solve_open(B):
        B = np.asarray(B, dtype=float)
        vec = B.ndim == 1
        B2 = B[:, None] if vec else B
        X1 = np.asarray(solve(B2[:-1])).reshape(len(a), -1)
        y = (B2[-1] - a @ X1) / delta
        X = np.vstack([X1 - np.outer(z, y), y[None, :]])
        return X[:, 0] if vec else X

    return solve_open, z


# ------------------------------------------------ shared with fem.modal (and its ARPACK path)


def rigid_basis(system, free, M=None):
    """M-orthonormal rigid-body modes (3 translations, 3 rotations; zero potential) on ``free``
    (``M``: the mass restricted to ``free``, sliced here when not given)."""
    x0 = system.nodes.mean(axis=0)
    motions = list(getattr(system, "rigid_motions", range(6)))
    if len(motions) < 6:            # a sector's fields: rotations about the drill's axis, x = y = 0
        x0[:2] = 0.0
    r = system.nodes - x0
    R = np.zeros((system.ndof, 6))
    for c in range(3):
        R[c: system.n_u: 3, c] = 1.0
    for c in range(3):
        w = np.zeros(3)
        w[c] = 1.0
        R[: system.n_u, 3 + c] = np.cross(w, r).ravel()
    # a system restricted to some fields keeps the rigid motions they hold (fem.sector_system)
    R = R[free][:, motions]
    if M is None:
        M = system.M[free][:, free]
    G = R.T @ (M @ R)
    L = np.linalg.cholesky(G)
    return np.linalg.solve(L, R.T).T, M       # R L^-T: R^T M R = I


def deflated(solve, R, M):
    """OPinv followed by the M-orthogonal projection away from span(R)."""
    if R is None:
        return solve

    def op(b):
        y = solve(b)
        return y - R @ (R.T @ (M @ y))
    return op


def bordered_mass(Ms):
    """The short-circuit mass bordered by a zero row and column (the massless hot DOF)."""
    import scipy.sparse as sp

    return sp.bmat([[Ms, None], [None, sp.csr_matrix((1, 1))]], format="csr")


def restricted(A, free):
    """``A[free][:, free]`` as an operator, without slicing the matrix (only products needed)."""
    n = len(free)

    def matmat(X):
        X = np.asarray(X).reshape(n, -1)
        full = np.zeros((A.shape[0], X.shape[1]))
        full[free] = X
        return (A @ full)[free]

    return spla.LinearOperator((n, n), matvec=matmat, matmat=matmat, dtype=float)


def arpack_eigs(K, M, k, sigma, solve, tol, n):
    k = int(min(k, n - 2))
    op = spla.LinearOperator((n, n), matvec=solve, dtype=float)
    # a fixed start vector: ARPACK's default is random, which makes reruns differ in the last
    # digits (and the chaotic impact model downstream amplifies that)
    v0 = np.random.default_rng(20000).standard_normal(n)
    with blas_threads(1):
        vals, vecs = spla.eigsh(K, k=k, M=M, sigma=sigma, OPinv=op, which="LM", tol=tol, mode="normal",
                                v0=v0)
    order = np.argsort(vals)
    vals, vecs = vals[order], vecs[:, order]
    # mass normalisation (ARPACK returns M-orthonormal vectors; enforce against round-off)
    mnorm = np.sqrt(np.abs(np.einsum("ij,ij->j", vecs, M @ vecs)))
    vecs = vecs / np.where(mnorm > 0, mnorm, 1.0)
    return vals, vecs
