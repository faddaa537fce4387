"""Modes of a cyclically symmetric drill from one sector (:mod:`geometry.sector`).

A structure unchanged by a turn of ``alpha = 2 pi / N`` about z has modes that repeat from
sector to sector with a phase: ``x_{s+1} = exp(i k alpha) R(alpha) x_s`` for a harmonic
``k = 0 .. floor(N / 2)`` (Thomas 1979). On the sector mesh this ties every node of the far cut
face to its partner on the near cut face,

    u_far = exp(i k alpha) R u_near,    phi_far = exp(i k alpha) phi_near,

and a node on the axis to itself (``R u = exp(-i k alpha) u``: ``u_z`` alone for ``k = 0``,
``u_x + i u_y`` circular motion for ``k = 1``, at rest otherwise). Writing ``x = T q`` over the
independent unknowns ``q`` turns the sector's own ``K``, ``M`` into ``T^H K T``, ``T^H M T``:
the whole drill's eigenproblem restricted to harmonic ``k``, without approximation (tested
against the replicated mesh to 1e-9). ``k = 0`` holds the working longitudinal mode, the
torsion and every electrically driven response; the electrodes of a ``k > 0`` harmonic carry no
net potential (``V_hot = 0``: short and open circuit coincide); ``k = 1`` holds the bending
pairs. A complex phase (``0 < k alpha < pi``) is solved in real arithmetic: ``T = A + i B``
gives the real symmetric pencil of ``[[A, -B], [B, A]]``, each mode twice (its ``q`` and
``i q``), reported once.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from geometry.sector import SectorPairs, rotation, sector_pairs
from rpud_common import ParameterError, check_choice

from .assembly import PiezoSystem
from .eigen import block_eigs, smooth_start
from .solvers import blas_threads, factorize

__all__ = ["cyclic_basis", "cyclic_modes", "CyclicModes", "harmonics"]

log = logging.getLogger(__name__)


def harmonics(sectors: int) -> tuple[int, ...]:
    """The distinct harmonics ``0 .. floor(N / 2)`` of ``N`` sectors."""
    return tuple(range(sectors // 2 + 1))


def _axis_directions(k: int, sectors: int) -> list[np.ndarray]:
    """Complex displacement directions an axis node keeps in harmonic ``k``."""
    k %= sectors
    if k == 0:
        return [np.array([0.0, 0.0, 1.0], dtype=complex)]
    if k == 1:
        return [np.array([1.0, 1.0j, 0.0]) / math.sqrt(2.0)]
    if k == sectors - 1:
        return [np.array([1.0, -1.0j, 0.0]) / math.sqrt(2.0)]
    return []


def cyclic_basis(system: PiezoSystem, pairs: SectorPairs, k: int, electrical: str = "short",
                 clamp=()) -> sp.csr_matrix:
    """Complex ``T`` (``ndof x nq``) with ``x = T q`` the sector vectors of harmonic ``k``.

    ``electrical``: ``"short"`` (``V_hot = 0``) or ``"open"`` (``V_hot`` free; ``k = 0`` only,
    else the same as short). ``clamp``: facet sets whose displacement is zero.
    """
    check_choice("electrical", electrical, ("short", "open"))
    N = pairs.sectors
    if not 0 <= k <= N // 2:
        raise ParameterError("harmonic", k, f"must lie in [0, {N // 2}] for {N} sectors")
    n, ndof = system.n_nodes, system.ndof
    phase = np.exp(1j * 2 * math.pi * k / N)
    R = rotation(2 * math.pi / N)
    # scalar node -> potential unknown (-1: none; the hot electrode is the one unknown hot_dof)
    phi = np.full(n, -1, dtype=np.int64)
    phi[system.phi_nodes] = system.n_u + np.arange(system.n_phi)
    hot = system.hot_dof if (system.hot_dof is not None and electrical == "open" and k == 0) else None

    dependent = np.zeros(ndof, dtype=bool)
    dependent[(3 * pairs.far[:, None] + np.arange(3)).ravel()] = True
    dependent[(3 * pairs.axis[:, None] + np.arange(3)).ravel()] = True
    fp = phi[pairs.far]
    dependent[fp[fp >= 0]] = True
    if system.hot_dof is not None:
        dependent[system.hot_dof] = True
    for name in clamp:
        dependent[system.dofs_on(name)] = True
    indep = np.flatnonzero(~dependent)
    col = np.full(ndof, -1, dtype=np.int64)
    col[indep] = np.arange(len(indep))
    rows, cols, vals = [indep], [col[indep]], [np.ones(len(indep), dtype=complex)]
    nq = len(indep)

    # far cut: u_far = phase R u_near, phi_far = phase phi_near (a clamped near node stays at rest)
    for a in range(3):
        for b in range(3):
            if R[a, b] != 0.0:
                src = col[3 * pairs.near + b]
                ok = src >= 0
                rows.append(3 * pairs.far[ok] + a)
                cols.append(src[ok])
                vals.append(np.full(ok.sum(), phase * R[a, b]))
    npf = phi[pairs.near]
    if np.any((npf >= 0) != (fp >= 0)):
        raise ParameterError("sector mesh", "potential unknowns", "the cut faces' ceramic nodes do not pair up")
    has = npf >= 0
    rows.append(fp[has])
    cols.append(col[npf[has]])
    vals.append(np.full(has.sum(), phase))
    # axis nodes: the directions the harmonic keeps
    clamped = np.zeros(ndof, dtype=bool)
    for name in clamp:
        clamped[system.dofs_on(name)] = True
    for d in _axis_directions(k, N):
        for node in pairs.axis:
            if clamped[3 * node: 3 * node + 3].any():
                continue
            for c in range(3):
                if d[c] != 0:
                    rows.append(np.array([3 * node + c]))
                    cols.append(np.array([nq]))
                    vals.append(np.array([d[c]]))
            nq += 1
    if hot is not None:
        rows.append(np.array([hot]))
        cols.append(np.array([nq]))
        vals.append(np.array([1.0 + 0j]))
        nq += 1
    T = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(ndof, nq))
    T.sum_duplicates()
    return T


def _real_pencil(T: sp.csr_matrix, K: sp.csr_matrix, M: sp.csr_matrix):
    """``(K_r, M_r, T_r)``: the reduced real pencil and its real basis (doubled if ``T`` is complex)."""
    A, B = T.real.tocsr(), T.imag.tocsr()
    B.eliminate_zeros()
    if B.nnz == 0:
        Tr = A
    else:
        Tr = sp.bmat([[A, -B], [B, A]], format="csr")
        K, M = sp.block_diag([K, K], format="csr"), sp.block_diag([M, M], format="csr")
    Kr = (Tr.T @ K @ Tr).tocsr()
    Mr = (Tr.T @ M @ Tr).tocsr()
    return Kr, Mr, Tr


@dataclass
class CyclicModes:
    """Modes of one harmonic of a cyclically symmetric drill.

    ``f_hz``: resonance frequencies (short circuit), ``f_open_hz``: anti-resonances (``k = 0``:
    open circuit, paired by MAC; ``k > 0``: equal to ``f_hz``), ``vectors``: complex sector
    vectors ``x`` (``(ndof, n)``, the whole drill's mode on sector copy ``s`` is
    ``exp(i k s alpha)`` times it rotated by ``s alpha``), ``ndof``: unknowns of the reduced
    (real) problem, ``timings`` in s.
    """

    harmonic: int
    sectors: int
    f_hz: np.ndarray
    f_open_hz: np.ndarray
    vectors: np.ndarray
    ndof: int
    rigid_hz: np.ndarray
    timings: dict = field(default_factory=dict)


def _solve(Kr, Mr, Tr, system, n_modes, sigma, backend, tol):
    """Eigenpairs of the reduced pencil nearest ``sigma`` (block shift-invert Lanczos, started
    from the smooth fields of :func:`fem.eigen.smooth_start` projected onto the harmonic)."""
    F = factorize((Kr - sigma * Mr).tocsr(), backend=backend, matching=False)
    n = Kr.shape[0]
    b = min(max(8, n_modes // 2 + 2), max(n - 2, 1))
    x = smooth_start(system.nodes, np.arange(system.ndof), system.ndof, b, n_random=max(2, b // 4))
    if Tr.shape[0] != system.ndof:            # the doubled pencil: both halves
        x = np.vstack([x, np.roll(x, 1, axis=1)])
    start = Tr.T @ x
    with blas_threads(1):
        res = block_eigs(F, Kr, Mr, sigma, start, n_wanted=min(n_modes, n - 2), tol=tol)
    return res.lam, res.vectors


def _freq(lam):
    return np.sign(lam) * np.sqrt(np.abs(lam)) / (2 * np.pi)


def _collapse(f, vec, doubled, rel: float = 1e-7):
    """One of each degenerate pair of a doubled (real) problem (partners within ``rel``)."""
    if not doubled:
        return f, vec
    keep, i = [], 0
    while i < len(f):
        keep.append(i)
        i += 2 if i + 1 < len(f) and abs(f[i + 1] - f[i]) <= rel * max(abs(f[i]), 1.0) else 1
    return f[keep], vec[:, keep]


def cyclic_modes(system: PiezoSystem, sectors: int, harmonic: int, near_hz: float, n_modes: int,
                 clamp=(), *, pairs: SectorPairs | None = None, open_circuit: bool = True,
                 rigid_hz: float | None = None, backend: str | None = None, tol: float = 1e-10) -> CyclicModes:
    """The ``n_modes`` modes of ``harmonic`` nearest ``near_hz`` (Hz) of the whole drill whose
    sector ``system`` is (see the module docstring).

    ``open_circuit`` (``k = 0``): also the anti-resonances, paired with the resonances by the
    mass-weighted MAC of their displacement. Modes below ``rigid_hz`` (default ``max(10 Hz,
    1 % of near_hz)``) are rigid-body motion, reported apart.
    """
    t0 = time.perf_counter()
    if pairs is None:
        pairs = sector_pairs(system.nodes, sectors)
    if rigid_hz is None:
        rigid_hz = max(10.0, 0.01 * near_hz)
    sigma = (2 * np.pi * near_hz) ** 2 if near_hz > 0 else -(2 * np.pi * 1e3) ** 2
    clamp = (clamp,) if isinstance(clamp, str) else tuple(clamp)
    free_body = not clamp
    # rigid motions of the harmonic: k = 0 axial translation and spin, k = 1 the lateral ones
    extra = (2 if harmonic in (0, 1) else 0) if free_body else 0

    def run(electrical):
        T = cyclic_basis(system, pairs, harmonic, electrical, clamp)
        Kr, Mr, Tr = _real_pencil(T, system.K, system.M)
        doubled = Tr.shape[1] != T.shape[1]
        want = (n_modes + extra) * (2 if doubled else 1)
        lam, vec = _solve(Kr, Mr, Tr, system, want, sigma, backend, tol)
        order = np.argsort(lam)
        f, vec = _freq(lam[order]), vec[:, order]
        nq = T.shape[1]
        q = vec[:nq] + 1j * vec[nq:] if doubled else vec.astype(complex)
        f, q = _collapse(f, q, doubled)
        x = T @ q
        return f, x, Kr.shape[0]

    f, x, ndof = run("short")
    rigid = np.abs(f) < rigid_hz
    f_r, x_r = f[~rigid], x[:, ~rigid]
    order = np.argsort(np.abs(f_r - near_hz))[:n_modes]
    order = np.sort(order)
    f_r, x_r = f_r[order], x_r[:, order]
    t1 = time.perf_counter()
    if harmonic == 0 and open_circuit and system.hot_dof is not None:
        f_o, x_o, _ = run("open")
        keep = np.abs(f_o) >= rigid_hz
        f_o, x_o = f_o[keep], x_o[:, keep]
        f_open = _pair_open(system, x_r, x_o, f_o)
    else:
        f_open = f_r.copy()
    t2 = time.perf_counter()
    log.info("cyclic harmonic %d of %d sectors: %d reduced unknowns, %d modes in %.2f s", harmonic, sectors,
             ndof, len(f_r), t2 - t0)
    return CyclicModes(harmonic, sectors, f_r, f_open, x_r, ndof, f[rigid],
                       {"short_s": t1 - t0, "open_s": t2 - t1, "total_s": t2 - t0})


def _pair_open(system, x_r, x_o, f_o, mac_min: float = 0.5):
    """Open-circuit frequency of each short-circuit mode: the partner of greatest mass-weighted
    MAC of the displacement (NaN below ``mac_min``)."""
    u = slice(0, system.n_u)
    Mu = system.M[u, u]
    a, b = x_r[u], x_o[u]
    cross = np.abs(a.conj().T @ (Mu @ b)) ** 2
    na = np.real(np.einsum("ij,ij->j", a.conj(), Mu @ a))
    nb = np.real(np.einsum("ij,ij->j", b.conj(), Mu @ b))
    mac = cross / np.outer(na, nb)
    best = mac.argmax(axis=1)
    return np.where(mac.max(axis=1) >= mac_min, f_o[best], np.nan)
