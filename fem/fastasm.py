"""Vectorised assembly of the piezo-elastic blocks (the fast path of :mod:`fem.assembly`).

Why it is fast
--------------
* **Symmetry.** ``K_uu``, ``M`` and ``K_phiphi`` are symmetric and ``K_uphi`` comes in transposed
  pairs, so only the local node pairs ``a <= b`` of each element are computed and summed (55 of
  the 100 pairs of a P2 tetrahedron), each into the unordered global pair ``i <= j`` (the block
  transposed where the local order is the reverse of the global one).
* **One sort.** The global node pairs are numbered by ONE ``np.sort`` of the pair keys with the
  entry number packed into the low bits (numpy's sort of int64 is SIMD-vectorised, its argsort
  is several times slower); the element values are then summed with ``np.bincount`` in element
  order, without first gathering them into sorted order.
* **Straight into CSR.** The pair sums are written once into the rows of the full matrix
  (block and transposed block), then moved into the interleaved ``3 k + c`` CSR order by one
  gather of 3-value rows; the column indices come from the same gather. No ``U + U^T``, no
  BSR->CSR, no COO sorting.
* **Geometry once.** Cells whose 10-node geometry is straight (mid-edge nodes at the midpoints;
  about half of a gmsh mesh of curved parts) have a constant Jacobian: their gradient products
  are ``|J| R @ (J^-1 (x) J^-1)`` with the reference integrals ``R`` of the quadrature rule (the
  same sums, regrouped) and their masses ``|J| M_ref``, for all cells of a chunk in one GEMM.
  On curved cells the Jacobian is one matrix product of the element nodes with the reference
  gradients of the mesh's own element, inverted by cofactors, per quadrature point
  (scikit-fem's ``CellBasis`` re-evaluates it for every basis function).
* **BLAS for the constitutive law.** The gradient products ``S[(a b), (k l)] = int dN_a/dx_k
  dN_b/dx_l`` of a chunk of elements come from one batched ``matmul``; ``K_uu`` (c_ijkl),
  ``K_uphi`` (e_kij) and ``K_phiphi`` (eps_kl) are then single GEMMs with the 9x9, 9x3, 9x1
  tensor tables of the region.
* **The loss matrix from the stiffness.** ``K_loss = sum_r K_uu^r / Q_r``: the element values
  are summed once per loss level (cells are ordered by ``Q``) and weighted afterwards.

The forms it evaluates
----------------------
Exactly the weak forms of :mod:`fem.forms`, with the same quadrature rules; only the order of
the sums differs. With the gradient products ``S_ab[k, l] = int dN_a/dx_k dN_b/dx_l`` of the
local node pair ``(a, b)``:

* :data:`fem.forms.stiffness` ``S(v)^T c S(u)``, on ``v = N_a e_i``, ``u = N_b e_j``, is
  ``sum_kl S_ab[k, l] c_ikjl`` (c_ikjl = ``c[voigt(i k), voigt(j l)]``): the
  :func:`stiffness_table` times ``S``;
* :data:`fem.forms.coupling` ``S(v)^T e^T grad(phi)``, on ``v = N_a e_i``, ``phi = N_b``, is
  ``sum_kl S_ab[k, l] e_l,ik``: the :func:`coupling_table` times ``S``;
* :data:`fem.forms.permittivity` ``grad(psi)^T eps grad(phi)`` is ``sum_kl S_ab[k, l] eps_kl``;
* :data:`fem.forms.mass` ``rho v . u`` is ``rho int N_a N_b`` on the diagonal ``i = j``.

Any scikit-fem H1 element on tetrahedra works (P1 or P2 fields, straight or curved geometry).
``tests/test_fem_assembly.py`` checks the matrices against the forms assembled by
:func:`skfem.asm` (``fem.assembly.assemble(..., reference=True)``) to 1e-12 relative, on a
curved P2 rod, a straight bar and a bimorph of straight and curved cells (P1 and P2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

__all__ = ["NodePairs", "node_pairs", "assemble_blocks", "assemble_matrices", "unique_inverse"]

_CHUNK = 4000   # elements per batch: keeps the (E, 30, 30) gradient products ~30 MB


def unique_inverse(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(keys, return_inverse=True)`` for non-negative int64 ``keys``.

    The entry number is packed into the low bits of each key, so that one plain ``np.sort``
    gives both the sorted keys and the permutation (falls back to ``np.unique`` if the packed
    value would overflow 63 bits).
    """
    keys = np.asarray(keys, dtype=np.int64).ravel()
    m = len(keys)
    if m == 0:
        return keys.copy(), np.zeros(0, dtype=np.int64)
    bits = max(int(m - 1).bit_length(), 1)
    if int(keys.max()).bit_length() + bits > 63:
        uniq, inv = np.unique(keys, return_inverse=True)
        return uniq, inv.ravel()
    packed = np.sort((keys << bits) | np.arange(m, dtype=np.int64))
    order = packed & ((1 << bits) - 1)
    sk = packed >> bits
    first = np.empty(m, dtype=bool)
    first[0] = True
    np.not_equal(sk[1:], sk[:-1], out=first[1:])
    inv = np.empty(m, dtype=np.int64)
    inv[order] = np.cumsum(first) - 1
    return sk[first], inv


def _index_dtype(*sizes):
    return np.int32 if max(sizes) < np.iinfo(np.int32).max else np.int64


def _starts(lengths):
    out = np.zeros(len(lengths), dtype=np.int64)
    np.cumsum(lengths[:-1], out=out[1:])
    return out


@dataclass(frozen=True)
class NodePairs:
    """Unordered global node pairs ``(pi[p], pj[p])``, ``pi <= pj``, sorted, and the CSR pattern
    of the full (both triangles) ``n x n`` node-pair matrix.

    ``pos_up[p]`` is the CSR position of ``(pi, pj)``, ``pos_lo[p]`` that of ``(pj, pi)`` (equal
    to ``pos_up`` on the diagonal); ``indptr``/``col`` are the pattern.
    """

    n: int
    pi: np.ndarray
    pj: np.ndarray
    pos_up: np.ndarray
    pos_lo: np.ndarray
    indptr: np.ndarray      # (n + 1,) int64
    col: np.ndarray         # (nnz,) column of each entry

    @property
    def n_pairs(self) -> int:
        return len(self.pi)

    @property
    def nnz(self) -> int:
        return int(self.indptr[-1])


def node_pairs(edofs: np.ndarray, n: int) -> tuple[NodePairs, np.ndarray, np.ndarray]:
    """Number the unordered node pairs of the elements ``edofs`` (nel, nloc).

    Returns ``(pairs, pair, flip)``, both (nel, nloc (nloc+1)/2) over the local pairs ``a <= b``
    in ``np.triu_indices`` order: the pair index, and whether the global nodes come in
    descending order (the element block is then stored transposed).
    """
    nloc = edofs.shape[1]
    ia, ib = np.triu_indices(nloc)
    ga, gb = edofs[:, ia].astype(np.int64), edofs[:, ib].astype(np.int64)
    flip = ga > gb
    keys, pair = unique_inverse(np.minimum(ga, gb) * n + np.maximum(ga, gb))
    pi, pj = keys // n, keys % n
    diag = pi == pj
    n_up = np.bincount(pi, minlength=n)
    n_lo = np.bincount(pj[~diag], minlength=n)
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(n_up + n_lo, out=indptr[1:])
    # row r: the transposed pairs (j, r), j < r, then the pairs (r, j), j >= r (diagonal first)
    pos_up = indptr[pi] + n_lo[pi] + (np.arange(len(keys)) - _starts(n_up)[pi])
    off = np.flatnonzero(~diag)
    # rank of each off-diagonal pair when sorted by (pj, pi): pairs are sorted by (pi, pj), so
    # a stable order by pj keeps pi ascending within each row
    _, rank = unique_inverse(pj[off] * len(off) + np.arange(len(off)))
    pos_lo = pos_up.copy()
    pos_lo[off] = indptr[pj[off]] + (rank - _starts(n_lo)[pj[off]])
    col = np.empty(int(indptr[-1]), dtype=np.int64)
    col[pos_lo] = pi
    col[pos_up] = pj
    return NodePairs(n, pi, pj, pos_up, pos_lo, indptr, col), pair.reshape(len(edofs), -1), flip


class VectorLayout:
    """The CSR arrays of the symmetric ``3n x 3n`` matrices of a vector field interleaved as
    ``3 k + c`` whose node blocks are given on the pairs of a :class:`NodePairs`.

    CSR row ``3 r + c`` lists, for each entry ``(r, s)`` of the node pattern in order, row ``c``
    of the node block ``(r, s)``: three values at columns ``3 s + d``. The whole data array is
    one gather of such runs of three from ``[blocks; blocks^T]`` (the transposed blocks serve
    the entries below the diagonal); the column indices are shared by every such matrix.
    """

    def __init__(self, pairs: NodePairs):
        n, P, nnz = pairs.n, pairs.n_pairs, pairs.nnz
        length = np.diff(pairs.indptr)
        runs = np.repeat(length, 3)                        # row (r, c) holds length[r] runs
        entry = np.arange(3 * nnz) + np.repeat(np.repeat(pairs.indptr[:-1], 3) - _starts(runs), runs)
        comp = np.repeat(np.tile(np.arange(3), n), runs)
        owner = np.empty(nnz, dtype=np.int64)            # pair p, or P + p for a transposed block
        owner[pairs.pos_lo] = P + np.arange(P)
        owner[pairs.pos_up] = np.arange(P)               # written last: the diagonal is upper
        self.n = n
        self._run = 3 * owner[entry] + comp
        self._pair = owner[entry] % P
        idx = _index_dtype(9 * nnz, 3 * n)
        col3 = 3 * pairs.col[entry].astype(idx)
        self._indices = np.empty(9 * nnz, dtype=idx)
        for d in range(3):            # strided writes: much faster than broadcasting over (N, 3)
            np.add(col3, d, out=self._indices[d::3])
        self._indptr = self._row_starts(pairs, 3).astype(idx)
        idx1 = _index_dtype(3 * nnz, 3 * n)
        self._indices1 = (col3 + comp).astype(idx1)
        self._indptr1 = self._row_starts(pairs, 1).astype(idx1)

    @staticmethod
    def _row_starts(pairs, width):
        """Start of CSR row ``3 r + c`` when every node-pattern entry holds ``width`` values."""
        length = np.diff(pairs.indptr)
        ptr = 3 * width * pairs.indptr[:-1, None] + width * np.arange(3)[None, :] * length[:, None]
        return np.append(ptr.ravel(), 3 * width * pairs.nnz)

    def blocks(self, upper: np.ndarray) -> sp.csr_matrix:
        """The symmetric matrix whose ``(pi, pj)`` node block is ``upper[p]`` (P, 3, 3); shares
        its index arrays with the other matrices of this layout."""
        both = np.concatenate([upper, upper.swapaxes(1, 2)]).reshape(-1, 3)
        data = np.take(both, self._run, axis=0).ravel()
        return _csr(data, self._indices, self._indptr, 3 * self.n)

    def diagonal_blocks(self, upper: np.ndarray) -> sp.csr_matrix:
        """The symmetric matrix whose ``(pi, pj)`` node block is ``upper[p] * I`` (a mass)."""
        return _csr(np.take(upper, self._pair), self._indices1, self._indptr1, 3 * self.n)


def _csr(data, indices, indptr, n):
    A = sp.csr_matrix((data, indices, indptr), shape=(n, n))
    A.has_sorted_indices = True       # by construction: the node pattern is sorted
    return A


# ---------------------------------------------------------------------- constitutive tables
def _voigt_index():
    V = np.zeros((3, 3), dtype=int)
    for n, (i, j) in enumerate(((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))):
        V[i, j] = V[j, i] = n
    return V


def stiffness_table(c: np.ndarray) -> np.ndarray:
    """Voigt (6,6) stiffness -> (9, 9) table ``T[(k l), (i j)] = c_ikjl``: the node block is
    ``K_ab[i, j] = sum_kl S_ab[k, l] T[(k l), (i j)]``."""
    V = _voigt_index()
    i, j, k, l = np.meshgrid(*(np.arange(3),) * 4, indexing="ij")
    T = np.empty((3, 3, 3, 3))
    T[k, l, i, j] = c[V[i, k], V[j, l]]
    return T.reshape(9, 9)


def coupling_table(e: np.ndarray) -> np.ndarray:
    """Voigt (3,6) piezo stress constants -> (9, 3) table ``T[(k l), i] = e_l,ik``:
    ``K_uphi[(a i), b] = sum_kl S_ab[k, l] T[(k l), i]``."""
    V = _voigt_index()
    k, l, i = np.meshgrid(*(np.arange(3),) * 3, indexing="ij")
    T = np.empty((3, 3, 3))
    T[k, l, i] = e[l, V[i, k]]
    return T.reshape(9, 3)


_SWAP = np.array([0, 3, 6, 1, 4, 7, 2, 5, 8])     # (k, l) -> (l, k) in a row-major 3x3


# ---------------------------------------------------------------------- element kernels
def _jacobian(mesh, X, cells):
    """``J[e, i, j, q] = dx_i/dX_j`` (E, 3, 3, nq) of the (straight or curved) geometry of
    ``cells`` at the reference points ``X``: the mesh's own element interpolates its nodes."""
    gelem = mesh.elem()
    nodes = mesh.dofs.element_dofs[:, cells]                            # (ng, E)
    ng, nq = len(nodes), X.shape[1]
    dG = np.stack([gelem.lbasis(X, a)[1] for a in range(ng)])           # (ng, j, q)
    xn = mesh.doflocs.T[nodes.T].transpose(0, 2, 1)                     # (E, i, ng)
    return np.matmul(xn, dG.reshape(ng, 3 * nq)).reshape(len(cells), 3, 3, nq)


def _det(J):
    return (J[:, 0, 0] * (J[:, 1, 1] * J[:, 2, 2] - J[:, 1, 2] * J[:, 2, 1])
            - J[:, 0, 1] * (J[:, 1, 0] * J[:, 2, 2] - J[:, 1, 2] * J[:, 2, 0])
            + J[:, 0, 2] * (J[:, 1, 0] * J[:, 2, 1] - J[:, 1, 1] * J[:, 2, 0]))


def _inverse(J):
    """``(J^-1, det J)`` of a stack (E, 3, 3, q), by cofactors."""
    (a, b, c), (d, e, f), (g, h, i) = J.transpose(1, 2, 0, 3)
    inv = np.empty_like(J)
    inv[:, 0, 0], inv[:, 0, 1], inv[:, 0, 2] = e * i - f * h, c * h - b * i, b * f - c * e
    inv[:, 1, 0], inv[:, 1, 1], inv[:, 1, 2] = f * g - d * i, a * i - c * g, c * d - a * f
    inv[:, 2, 0], inv[:, 2, 1], inv[:, 2, 2] = d * h - e * g, b * g - a * h, a * e - b * d
    det = a * inv[:, 0, 0] + b * inv[:, 1, 0] + c * inv[:, 2, 0]
    inv /= det[:, None, None, :]
    return inv, det


def _affine_cells(mesh, tol=1e-13):
    """Cells whose geometry is affine: all of a straight mesh; of a quadratic one, those whose
    mid-edge nodes sit at the edge midpoints (to ``tol`` times the longest edge)."""
    nodes = mesh.dofs.element_dofs
    edges = np.asarray(mesh.elem.refdom.edges)
    if len(nodes) == 4:
        return np.ones(nodes.shape[1], dtype=bool)
    if len(nodes) != 4 + len(edges):
        return np.zeros(nodes.shape[1], dtype=bool)
    x = mesh.doflocs.T[nodes]                                            # (ng, E, 3)
    mid = x[4:] - 0.5 * (x[edges[:, 0]] + x[edges[:, 1]])
    h = np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=2).max(axis=0)
    return np.abs(mid).max(axis=(0, 2)) <= tol * h


def _vertex_jacobian(mesh, cells):
    """Constant ``J[e, i, j] = dx_i/dX_j`` of affine cells: edges from vertex 0 (RefTet)."""
    x = mesh.doflocs.T[mesh.dofs.element_dofs[:4, cells]]               # (4, E, 3)
    return (x[1:] - x[0]).transpose(1, 2, 0)


class _Kernels:
    """Gradient products ``S`` and element masses of a chunk of cells for the local pairs
    ``a <= b``, with the quadrature rules (orders ``qk``, ``qm``) of ``elem``."""

    def __init__(self, elem, mesh, qk, qm):
        from skfem.quadrature import get_quadrature

        self.mesh = mesh
        self.Xk, self.Wk = get_quadrature(elem.refdom, qk)
        self.Xm, self.Wm = get_quadrature(elem.refdom, qm)
        nloc = len(elem.doflocs)
        self.nloc = nloc
        self.ia, self.ib = np.triu_indices(nloc)
        self.dref = np.stack([elem.lbasis(self.Xk, a)[1] for a in range(nloc)])    # (a, i, q)
        vals = np.stack([elem.lbasis(self.Xm, a)[0] for a in range(nloc)])        # (a, qm)
        self.pair_vals = (vals[self.ia] * vals[self.ib]).T                          # (qm, pairs)
        # reference integrals for affine cells: R[p, (i j)] = sum_q w dN_a/dX_i dN_b/dX_j
        d = self.dref
        self.R = np.einsum("q,aiq,bjq->abij", self.Wk, d, d)[self.ia, self.ib].reshape(-1, 9)
        self.Mref = self.Wm @ self.pair_vals                                        # (pairs,)
        k9, l9 = np.divmod(np.arange(9), 3)
        self.sel = (((3 * self.ia[:, None] + k9) * 3 * nloc) + 3 * self.ib[:, None] + l9).ravel()

    def affine(self, cells):
        """``(S, mass)`` in (pair, cell) order: S (pairs*E, 9), mass (pairs*E,) per density."""
        inv, det = _inverse(_vertex_jacobian(self.mesh, cells)[..., None])
        inv, w = inv[..., 0], np.abs(det[:, 0])
        E = len(cells)
        T = np.einsum("eik,ejl,e->ijekl", inv, inv, w).reshape(9, E * 9)
        return (self.R @ T).reshape(-1, 9), np.outer(self.Mref, w).ravel()

    def curved(self, cells):
        """``(S, mass)`` in (cell, pair) order, by quadrature on the curved geometry."""
        E, nloc = len(cells), self.nloc
        dxm = np.abs(_det(_jacobian(self.mesh, self.Xm, cells))) * self.Wm          # (E, qm)
        inv, det = _inverse(_jacobian(self.mesh, self.Xk, cells))                   # (E, i, j, q)
        # dN_a/dx_j = sum_i dN_a/dX_i (J^-1)_ij
        g = sum(self.dref[None, :, i, None, :] * inv[:, None, i] for i in range(3))
        g = g.reshape(E, 3 * nloc, -1)
        gw = g * (np.abs(det) * self.Wk)[:, None, :]
        S = np.take(np.matmul(gw, g.transpose(0, 2, 1)).reshape(E, -1), self.sel, axis=1)
        return S.reshape(-1, 9), (dxm @ self.pair_vals).ravel()


def assemble_blocks(basis, qk, qm, regions, cell_region):
    """Node-pair sums of the element matrices of every region.

    Parameters
    ----------
    basis : skfem CellBasis
        Supplies the element and its DOF numbering (``element_dofs``); its quadrature is not
        used. The geometry is that of ``basis.mesh`` (straight or curved).
    qk, qm : int
        Quadrature orders of the stiffness-like terms and of the mass.
    regions : list of fem.assembly.RegionData
    cell_region : (nel,) region index of each cell

    Returns
    -------
    pairs : NodePairs
    sums : dict of arrays over the pairs, SI units
        ``kuu`` and ``luu`` (P, 3, 3): the block of ``(pi, pj)`` (N/m) and its loss part
        (``/ Q_m`` per region); ``muu`` (P,) kg; over the ceramic only ``kup_up`` (P, 3) (u at pi,
        potential at pj) and ``kup_dn`` (P, 3) (u at pj, potential at pi) in C/m, ``kpp`` (P,)
        and ``lpp`` (``tan delta``-weighted) in F; ``piezo_pairs``: the pairs in the ceramic;
        ``muu_region``: ``{region index: (P,) kg}``, the mass of each region's cells alone.
    """
    mesh = basis.mesh
    edofs = basis.element_dofs.T                                       # (nel, nloc)
    nel = len(edofs)
    kern = _Kernels(basis.elem, mesh, qk, qm)
    npl = len(kern.ia)
    pairs, pair, flip = node_pairs(edofs, basis.N)

    piezo = np.array([r.piezo for r in regions], dtype=bool)[cell_region]
    inv_q = np.array([1.0 / r.q_mech if np.isfinite(r.q_mech) else 0.0 for r in regions])[cell_region]
    curved = ~_affine_cells(mesh)
    # ceramic first (its entries are a prefix), then by loss level (the loss sums run over
    # contiguous ranges), region, and geometry (affine and curved cells in separate chunks)
    order = np.lexsort((curved, cell_region, inv_q, ~piezo))
    key = np.stack([cell_region[order], curved[order]])
    runs = np.concatenate([[0], np.flatnonzero(np.any(np.diff(key, axis=1), axis=0)) + 1, [nel]])

    ev = _element_values(kern, regions, cell_region, order, runs, curved, pair, flip, int(piezo.sum()))
    return pairs, _pair_sums(ev, pairs.n_pairs, npl, inv_q[order], cell_region[order])


@dataclass
class _ElementValues:
    """Element-matrix entries of the local pairs ``a <= b``, in the sorted cell order: ``ke``
    (9, m) the stiffness blocks, ``me`` (m,) masses, ``pe`` (m,) the global pair of each entry;
    over the ceramic prefix ``kupe`` (6, mp) the coupling (up, down), ``kppe`` (mp,) the
    permittivity and ``tand`` (mp,) its loss tangent."""

    ke: np.ndarray
    me: np.ndarray
    pe: np.ndarray
    kupe: np.ndarray
    kppe: np.ndarray
    tand: np.ndarray


def _element_values(kern, regions, cell_region, order, runs, curved, pair, flip, n_piezo) -> _ElementValues:
    """The forms' element values, chunk by chunk of one region and one geometry kind."""
    nel, npl = len(order), len(kern.ia)
    m = nel * npl
    ke = np.empty((9, m))
    me = np.empty(m)
    pe = np.empty(m, dtype=np.int64)          # pair of each entry
    mp = n_piezo * npl
    kupe = np.empty((6, mp))
    kppe = np.empty(mp)
    tand = np.empty(mp)
    for start, stop in zip(runs[:-1], runs[1:]):
        rd = regions[cell_region[order[start]]]
        C4 = stiffness_table(rd.c).T
        if rd.piezo:
            T3 = coupling_table(rd.e)
            E3, E3t, eps = T3.T, T3[_SWAP].T, rd.eps.reshape(9)
            tand[start * npl:stop * npl] = rd.tan_delta
        for s0 in range(start, stop, _CHUNK):
            s1 = min(s0 + _CHUNK, stop)
            cells = order[s0:s1]
            r = slice(s0 * npl, s1 * npl)
            if curved[cells[0]]:
                S, mass = kern.curved(cells)                     # entries (cell, pair)
                pe[r], fl = pair[cells].ravel(), flip[cells].ravel()
            else:
                S, mass = kern.affine(cells)                     # entries (pair, cell)
                pe[r], fl = pair[cells].T.ravel(), flip[cells].T.ravel()
            S[fl] = S[fl][:, _SWAP]                              # blocks of (lower, higher) node
            me[r] = rd.density * mass
            np.matmul(C4, S.T, out=ke[:, r])
            if rd.piezo:
                np.matmul(E3, S.T, out=kupe[:3, r])
                np.matmul(E3t, S.T, out=kupe[3:, r])
                kppe[r] = S @ eps
    return _ElementValues(ke, me, pe, kupe, kppe, tand)


def _pair_sums(ev: _ElementValues, P: int, npl: int, iq: np.ndarray, reg: np.ndarray) -> dict:
    """The element values summed per global node pair (the ``sums`` of :func:`assemble_blocks`);
    ``iq`` and ``reg``: 1/Q and the region of each cell in the sorted order."""
    ke, me, pe, kupe, kppe, tand = ev.ke, ev.me, ev.pe, ev.kupe, ev.kppe, ev.tand
    ev.ke = None                      # the largest array: freed once summed (below)
    nel, mp = len(iq), len(kppe)

    def total(w, idx=pe):
        return np.bincount(idx, weights=w, minlength=P)

    # K_uu and K_loss = sum over loss levels of K_uu(level) / Q(level), from one pass
    kuu, luu = np.zeros((P, 9)), np.zeros((P, 9))
    levels = np.concatenate([[0], np.flatnonzero(np.diff(iq)) + 1, [nel]])
    part = np.empty((P, 9))
    for a, b in zip(levels[:-1], levels[1:]):
        r = slice(a * npl, b * npl)
        for c in range(9):
            part[:, c] = total(ke[c, r], pe[r])
        kuu += part
        luu += iq[a] * part
    del ke
    pp = pe[:mp]
    # the cells of one region are one contiguous run of the sorted order
    starts = np.append(np.flatnonzero(np.concatenate([[True], reg[1:] != reg[:-1]])), nel)
    muu_region = {int(reg[a]): total(me[a * npl:b * npl], pe[a * npl:b * npl])
                  for a, b in zip(starts[:-1], starts[1:])}
    return {
        "muu_region": muu_region,
        "kuu": kuu.reshape(P, 3, 3), "luu": luu.reshape(P, 3, 3), "muu": total(me),
        "kup_up": np.stack([total(kupe[c], pp) for c in range(3)], axis=1),
        "kup_dn": np.stack([total(kupe[c], pp) for c in range(3, 6)], axis=1),
        "kpp": total(kppe, pp), "lpp": total(kppe * tand, pp),
        "piezo_pairs": np.flatnonzero(np.bincount(pp, minlength=P)),
    }


def coupling_matrix(pairs: NodePairs, up: np.ndarray, dn: np.ndarray, which: np.ndarray) -> sp.csr_matrix:
    """``K_uphi`` (3n x n) from the pair sums (u at pi, potential at pj: ``up`` (P, 3); u at pj,
    potential at pi: ``dn``), restricted to the pairs ``which``."""
    pi, pj = pairs.pi[which], pairs.pj[which]
    off = pi != pj
    c = np.arange(3)[None, :]
    rows = np.concatenate([(3 * pi[:, None] + c).ravel(), (3 * pj[off, None] + c).ravel()])
    cols = np.concatenate([np.repeat(pj, 3), np.repeat(pi[off], 3)])
    vals = np.concatenate([up[which].ravel(), dn[which][off].ravel()])
    return sp.csr_matrix((vals, (rows, cols)), shape=(3 * pairs.n, pairs.n))


def scalar_matrix(pairs: NodePairs, values: np.ndarray, which: np.ndarray) -> sp.csr_matrix:
    """The symmetric ``n x n`` matrix of the pair sums ``values`` on the pairs ``which``."""
    pi, pj, v = pairs.pi[which], pairs.pj[which], values[which]
    off = pi != pj
    rows = np.concatenate([pi, pj[off]])
    cols = np.concatenate([pj, pi[off]])
    return sp.csr_matrix((np.concatenate([v, v[off]]), (rows, cols)), shape=(pairs.n, pairs.n))


def assemble_matrices(basis, qk, qm, regions, cell_region, groups=None) -> dict:
    """:func:`assemble_blocks` written out as sparse matrices on the scalar node numbering
    (u DOF of node ``k``, component ``c``: ``3 k + c``): ``Kuu``, ``Luu``, ``Muu`` (3n x 3n),
    ``Kup`` (3n x n), ``Kpp``, ``Lpp`` (n x n); with ``groups`` (``{name: region indices}``)
    also ``M_groups``: ``{name: scalar n x n mass of those regions' cells}`` (kg)."""
    pairs, t = assemble_blocks(basis, qk, qm, regions, cell_region)
    layout = VectorLayout(pairs)
    w = t["piezo_pairs"]
    out = {"Kuu": layout.blocks(t["kuu"]), "Luu": layout.blocks(t["luu"]),
           "Muu": layout.diagonal_blocks(t["muu"]),
           "Kup": coupling_matrix(pairs, t["kup_up"], t["kup_dn"], w),
           "Kpp": scalar_matrix(pairs, t["kpp"], w), "Lpp": scalar_matrix(pairs, t["lpp"], w)}
    if groups is not None:
        out["M_groups"] = {}
        for name, members in groups.items():
            m = sum((t["muu_region"][r] for r in members if r in t["muu_region"]), np.zeros(pairs.n_pairs))
            out["M_groups"][name] = scalar_matrix(pairs, m, np.flatnonzero(m))
    return out
