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
pairs. A complex phase (``0 < k alpha < pi``) gives a complex Hermitian pencil, solved as it is
(PARDISO's Hermitian factorisation, complex block Lanczos): its real equivalent
``[[Re H, -Im H], [Im H, Re H]]`` would hold every mode twice (``q`` and ``i q``) and take
about twice the factorisation and Lanczos work.
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
from .modal import BLOCK_MIN, frequency_hz, own_anti_resonance
from .solvers import blas_threads, factorize

__all__ = ["first_ask", "cyclic_basis", "cyclic_modes", "CyclicModes", "harmonics", "multiplicity", "nearest_modes",
           "harmonic_shares", "harmonic_labels", "expand", "sector_images"]

log = logging.getLogger(__name__)


def harmonics(sectors: int) -> tuple[int, ...]:
    """The distinct harmonics ``0 .. floor(N / 2)`` of ``N`` sectors."""
    return tuple(range(sectors // 2 + 1))


def multiplicity(harmonic: int, sectors: int) -> int:
    """How many modes of the whole drill one mode of ``harmonic`` stands for: 2 (a pair) for a
    complex phase, else 1."""
    return 2 if 0 < harmonic < sectors / 2 else 1


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
    if k != 0:              # the axis carries no potential of a non-axisymmetric harmonic
        ap = phi[pairs.axis]
        dependent[ap[ap >= 0]] = True
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


def _pencil(T: sp.csr_matrix, K: sp.csr_matrix, M: sp.csr_matrix):
    """``(K_r, M_r, T_r)``: the reduced pencil ``T^H K T``, ``T^H M T`` and its basis, real when
    ``T`` is (``k = 0``, ``k = N / 2``), else complex Hermitian."""
    # copies: scipy's .real / .imag share T's data, and eliminate_zeros would compact it in place
    A, B = T.real.tocsr(copy=True), T.imag.tocsr(copy=True)
    B.eliminate_zeros()
    if B.nnz == 0:
        At = A.T.tocsr()
        return (At @ (K @ A)).tocsr(), (At @ (M @ A)).tocsr(), A
    Th = T.conj().T.tocsr()
    out = []
    for X in (K, M):
        H = (Th @ (X @ T)).tocsr()
        out.append((0.5 * (H + H.conj().T)).tocsr())    # Hermitian to the last bit
    return out[0], out[1], T


@dataclass
class CyclicModes:
    """Modes of one harmonic of a cyclically symmetric drill.

    ``f_hz``: resonance frequencies (short circuit), ``f_open_hz``: anti-resonances (``k = 0``:
    open circuit, paired by MAC; ``k > 0``: equal to ``f_hz``), ``vectors``: complex sector
    vectors ``x`` (``(ndof, n)``, the whole drill's mode on sector copy ``s`` is
    ``exp(i k s alpha)`` times it rotated by ``s alpha``), ``ndof``: unknowns of the reduced
    problem counted in real numbers (a complex unknown twice), ``timings`` in s.
    """

    harmonic: int
    sectors: int
    f_hz: np.ndarray
    f_open_hz: np.ndarray
    vectors: np.ndarray
    ndof: int
    rigid_hz: np.ndarray
    timings: dict = field(default_factory=dict)


def _solve(Kr, Mr, Tr, system, n_modes, sigma, backend, tol, hot: bool = False):
    """Eigenpairs of the reduced pencil nearest ``sigma`` (block shift-invert Lanczos, started
    from the smooth fields of :func:`fem.eigen.smooth_start` projected onto the harmonic).

    ``hot``: the last unknown is the hot electrode's potential; the pencil without it is the
    short circuit, and the open circuit comes from the same Lanczos run (the bordered
    Rayleigh-Ritz of :mod:`fem.modal`). Returns ``(lam, vectors, lam_open, vectors_open)`` (the
    open ones None without ``hot`` or when the joint run could not give them).
    """
    if hot:
        krow = Kr[-1].toarray().ravel()
        a_hot, alpha = krow[:-1], float(krow[-1])
        Kr, Mr, Tr = Kr[:-1, :-1].tocsr(), Mr[:-1, :-1].tocsr(), Tr[:, :-1]
    F = factorize((Kr - sigma * Mr).tocsr(), backend=backend, matching=False, hermitian=np.iscomplexobj(Kr.data))
    n = Kr.shape[0]
    b = min(max(BLOCK_MIN, n_modes // 2 + 2), max(n - 2, 1))
    x = smooth_start(system.nodes, np.arange(system.ndof), system.ndof, b, n_random=max(2, b // 4))
    start = np.asarray(Tr.conj().T @ x)
    border = None
    if hot:
        z = np.asarray(F(a_hot)).ravel()
        border = (a_hot, alpha, z)
        start = np.column_stack([start, z / np.linalg.norm(z)])
    with blas_threads(1):
        res = block_eigs(F, Kr, Mr, sigma, start, n_wanted=min(n_modes, n - 2), tol=tol, border=border)
    if hot and res.converged_open and res.lam_open is not None:
        return res.lam, res.vectors, res.lam_open, res.vectors_open
    return res.lam, res.vectors, None, None


def cyclic_modes(system: PiezoSystem, sectors: int, harmonic: int, near_hz: float, n_modes: int,
                 clamp=(), *, pairs: SectorPairs | None = None, open_circuit: bool = True,
                 rigid_hz: float | None = None, backend: str | None = None, tol: float = 1e-10) -> CyclicModes:
    """The ``n_modes`` modes of ``harmonic`` nearest ``near_hz`` (Hz; nearest in omega^2, as
    :func:`fem.modal.modal_analysis`) of the whole drill whose sector ``system`` is (see the module
    docstring).

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

    joint = harmonic == 0 and open_circuit and system.hot_dof is not None

    def run(electrical, hot=False):
        T = cyclic_basis(system, pairs, harmonic, electrical, clamp)
        Kr, Mr, Tr = _pencil(T, system.K, system.M)
        lam, vec, lam_o, vec_o = _solve(Kr, Mr, Tr, system, n_modes + extra, sigma, backend, tol, hot=hot)
        nq = T.shape[1] - int(hot)
        out = []
        for lam_, vec_, T_ in ((lam, vec, T[:, :nq]), (lam_o, vec_o, T)):
            if lam_ is None:
                out.append(None)
                continue
            order = np.argsort(lam_)
            f, q = frequency_hz(lam_[order]), vec_[:, order].astype(complex)
            out.append((f, T_ @ q))
        # real unknowns: a complex one counts twice
        return out[0], out[1], (Kr.shape[0] - int(hot)) * (2 if np.iscomplexobj(Kr.data) else 1)

    (f, x), opened, ndof = run("open" if joint else "short", hot=joint)
    rigid = np.abs(f) < rigid_hz
    f_r, x_r = f[~rigid], x[:, ~rigid]
    # nearest in omega^2, the shift-invert sense of fem.modal (not in f)
    order = np.sort(np.argsort(np.abs(f_r ** 2 - near_hz ** 2))[:n_modes])
    f_r, x_r = f_r[order], x_r[:, order]
    t1 = time.perf_counter()
    if joint:
        if opened is None:         # the joint run lost the border: the open circuit on its own
            opened = run("open")[0]
        f_o, x_o = opened
        keep = np.abs(f_o) >= rigid_hz
        f_open = own_anti_resonance(f_r, _pair_open(system, x_r, x_o[:, keep], f_o[keep]))
    else:
        f_open = f_r.copy()
    t2 = time.perf_counter()
    log.info("cyclic harmonic %d of %d sectors: %d reduced unknowns, %d modes in %.2f s", harmonic, sectors,
             ndof, len(f_r), t2 - t0)
    return CyclicModes(harmonic, sectors, f_r, f_open, x_r, ndof, f[rigid],
                       {"short_s": t1 - t0, "open_s": t2 - t1, "total_s": t2 - t0})


def first_ask(ks, n_modes: int) -> dict[int, int]:
    """Modes :func:`nearest_modes` asks each harmonic of ``ks`` for in its first round (about its
    share of ``n_modes``), so that a caller can start those solves before every mesh exists."""
    return {k: min(n_modes, -(-n_modes // (len(ks) + 1)) + 2) for k in ks}


def nearest_modes(systems, sectors: int, near_hz: float, n_modes: int, first: dict | None = None, **kw):
    """The whole drill's ``n_modes`` modes nearest ``near_hz`` (in omega^2, as
    :func:`fem.modal.modal_analysis` picks them) from its harmonics, a pair counting twice.

    ``systems``: harmonic -> the sector system it is solved on; ``kw`` go to
    :func:`cyclic_modes`. Each harmonic is asked for about its share of the modes, and for more
    where it may hold modes nearer than the last one chosen. Returns ``(results, chosen)``:
    harmonic -> :class:`CyclicModes`, and ``(harmonic, index)`` of the chosen modes, nearest first,
    their multiplicities summing to ``n_modes`` (one more when the last is a pair). ``first``:
    harmonic -> the first round's result already solved (``cyclic_modes`` with :func:`first_ask`'s
    count and the same ``kw``).
    """
    ks = sorted(systems)
    ask = first_ask(ks, n_modes)
    results = dict(first or {})
    asked = {k: ask[k] for k in results}
    while True:
        todo = [k for k in ks if asked.get(k, 0) < ask[k]]
        solved = _side_by_side(lambda k: cyclic_modes(systems[k], sectors, k, near_hz, ask[k], **kw), todo)
        for k, res in zip(todo, solved):
            results[k] = res
            asked[k] = ask[k]
        cands = sorted((abs(f * f - near_hz * near_hz), k, j) for k in ks for j, f in enumerate(results[k].f_hz))
        chosen, total = [], 0
        for _d, k, j in cands:
            chosen.append((k, j))
            total += multiplicity(k, sectors)
            if total >= n_modes:
                break
        last = cands[len(chosen) - 1][0] if cands else 0.0
        short = [k for k in ks if ask[k] < n_modes and len(results[k].f_hz) == ask[k]
                 and max(abs(results[k].f_hz ** 2 - near_hz ** 2)) <= last]
        if not short:
            return results, chosen
        for k in short:
            ask[k] = min(n_modes, 2 * ask[k])


def _side_by_side(fn, items: list) -> list:
    """``[fn(item) for item in items]``, the items in threads side by side (each harmonic is its
    own factorisation and Lanczos run: PARDISO and NumPy release the interpreter, so two cores
    overlap one's sparse products with the other's factorisation). OpenBLAS stays on one thread
    across all of them (each run limits it anyway), so no run sees another's thread count
    change: the same numbers as one after the other."""
    if len(items) < 2:
        return [fn(item) for item in items]
    from concurrent.futures import ThreadPoolExecutor

    with blas_threads(1), ThreadPoolExecutor(max_workers=len(items), thread_name_prefix="harmonic") as pool:
        return list(pool.map(fn, items))


def _pair_open(system, x_r, x_o, f_o, mac_min: float = 0.5):
    """Open-circuit frequency of each short-circuit mode: its partner by the mass-weighted MAC of
    the displacement, one to one (Hungarian assignment, as :mod:`fem.modal`; NaN below
    ``mac_min``)."""
    from scipy.optimize import linear_sum_assignment

    u = slice(0, system.n_u)
    Mu = system.M[u, u]
    a, b = x_r[u], x_o[u]
    cross = np.abs(a.conj().T @ (Mu @ b)) ** 2
    na = np.real(np.einsum("ij,ij->j", a.conj(), Mu @ a))
    nb = np.real(np.einsum("ij,ij->j", b.conj(), Mu @ b))
    mac = cross / np.outer(na, nb)
    rows, cols = linear_sum_assignment(-mac)
    out = np.full(len(a.T), np.nan)
    ok = mac[rows, cols] >= mac_min
    out[rows[ok]] = f_o[cols[ok]]
    return out


def harmonic_shares(system: PiezoSystem, x: np.ndarray) -> np.ndarray:
    """``(n, 3)`` kinetic-energy shares of sector vectors ``x`` (``(ndof, n)``, complex) in
    axial, tangential and radial motion (node-wise cylindrical projection, consistent mass)."""
    theta = np.arctan2(system.nodes[:, 1], system.nodes[:, 0])
    c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]
    u = x[: system.n_u].reshape(system.n_nodes, 3, -1)          # node, component, mode
    ur = c * u[:, 0] + s * u[:, 1]
    ut = -s * u[:, 0] + c * u[:, 1]
    zero = np.zeros_like(ur)
    fields = (np.stack([zero, zero, u[:, 2]], axis=1), np.stack([-s * ut, c * ut, zero], axis=1),
              np.stack([c * ur, s * ur, zero], axis=1))
    Mu = system.M[: system.n_u, : system.n_u]
    e = np.stack([np.real(np.einsum("ij,ij->j", f.reshape(system.n_u, -1).conj(), Mu @ f.reshape(system.n_u, -1)))
                  for f in fields], axis=1)
    return e / np.maximum(e.sum(axis=1, keepdims=True), 1e-300)


def harmonic_labels(shares: np.ndarray, harmonic: int, coupled: float = 0.15) -> list[str]:
    """Labels of :data:`fem.modeshape.LABELS` for modes of ``harmonic`` with ``shares`` (axial,
    tangential, radial): ``k = 0`` longitudinal / torsional / longitudinal-torsional / radial by
    the largest share; ``k = 1`` is bending (a cross-section that tilts moves axially too);
    ``k >= 2`` radial (lobed)."""
    if harmonic == 1:
        return ["bending"] * len(shares)
    if harmonic > 1:
        return ["radial"] * len(shares)
    out = []
    for a, t, r in shares:
        if a >= coupled and t >= coupled:
            out.append("longitudinal-torsional")
        else:
            out.append(("longitudinal", "torsional", "radial")[int(np.argmax([a, t, r]))])
    return out


def sector_images(sector_nodes: np.ndarray, nodes: np.ndarray, sectors: int) -> tuple[np.ndarray, np.ndarray]:
    """``(copy, j)``: for each of ``nodes`` (m; e.g. the P2 nodes of
    :func:`geometry.sector.replicate`'s mesh) the sector copy ``s`` it lies in (``theta`` in
    ``[s alpha, (s+1) alpha]``, 0 on the axis) and the index ``j`` into ``sector_nodes`` (the
    sector's nodes) of its image rotated back by ``-s alpha``. A node with no image within
    1e-7 of the mesh's extent raises a ParameterError."""
    from scipy.spatial import cKDTree

    nodes = np.asarray(nodes, float)
    alpha = 2 * math.pi / sectors
    theta = np.mod(np.arctan2(nodes[:, 1], nodes[:, 0]), 2 * math.pi)
    copy = np.minimum(np.floor(theta / alpha + 1e-9).astype(np.int64), sectors - 1)
    copy[np.hypot(nodes[:, 0], nodes[:, 1]) < 1e-12] = 0
    back = np.empty_like(nodes)
    for s in range(sectors):
        m = copy == s
        back[m] = nodes[m] @ rotation(s * alpha)        # rotated by -s alpha
    dist, j = cKDTree(sector_nodes).query(back)
    if dist.max() > 1e-7 * max(float(np.ptp(nodes, axis=0).max()), 1e-3):
        raise ParameterError("nodes", f"{dist.max():.3g} m from the sector's", "must be the replicated mesh's nodes")
    return copy, j


def expand(system: PiezoSystem, x: np.ndarray, harmonic: int, sectors: int, nodes: np.ndarray) -> np.ndarray:
    """The whole drill's displacement ``(n, len(nodes), 3)`` (complex) at ``nodes`` (m; e.g. the
    P2 nodes of :func:`geometry.sector.replicate`'s mesh) from sector vectors ``x``: node
    ``p`` in copy ``s`` (``theta`` in ``[s alpha, (s+1) alpha]``) moves as
    ``exp(i k s alpha) R(s alpha) u(R(-s alpha) p)``. Its real and imaginary parts are the two
    members of a pair (``k > 0``)."""
    alpha = 2 * math.pi / sectors
    copy, j = sector_images(system.nodes, nodes, sectors)
    u = x[: system.n_u].T.reshape(x.shape[1], system.n_nodes, 3)[:, j]          # (n, P, 3)
    out = np.empty(u.shape, dtype=complex)
    for s in range(sectors):
        m = copy == s
        out[:, m] = np.exp(1j * harmonic * s * alpha) * (u[:, m] @ rotation(s * alpha).T)
    return out
