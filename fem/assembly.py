"""Assembly of the coupled piezo-elastic system on a :class:`geometry.mesh.TaggedMesh`.

Fields
------
* displacement ``u``: vector P2 (``ElementVector(ElementTetP2())``) on the whole mesh
  (``order=1``: P1). Node numbering = skfem's scalar P2 numbering (vertices, then edges);
  u DOF of node ``k``, component ``c`` is ``3 k + c`` (skfem interleaves the components; checked
  in the tests against ``basis_u.element_dofs``).
* electric potential ``phi``: scalar P2 on the piezoceramic cells only (nodes not touched by a
  ceramic cell carry no potential). Electrodes are equipotential: every node of every ``hot``
  electrode is tied into ONE unknown ``V_hot``; nodes of ``ground`` electrodes are fixed at 0 V
  and eliminated. A mesh with ceramic needs at least one ground electrode.

Scaling and DOF layout
----------------------
Potential unknowns are scaled, ``phi = phi_scale * phi~`` (``phi_scale`` in V/m: a power of ten
close to ``sqrt(mean diag K_uu / mean diag K_phiphi)`` over the ceramic nodes, so that the
potential block has the magnitude of the stiffness block; unscaled the blocks differ by ~20
orders of magnitude). The global vector is::

    x = [ u (n_u = 3 n_nodes) | phi~ interior (n_phi) | V~_hot (1 if any hot electrode) ]

``u_dofs``/``phi_dofs`` are slices, ``hot_dof`` an int or None. ``phi_nodes`` gives the
scalar node of each interior potential unknown.

Matrices and sign convention
----------------------------
``K = [[K_uu, s K_uphi], [s K_uphi^T, -s^2 K_phiphi]]`` (symmetric, indefinite), with
``K_uu = int B^T c_E B``, ``K_uphi = int B^T e^T grad(N)``, ``K_phiphi = int grad(N)^T eps_S grad(N)``
(positive definite), ``s = phi_scale``. The equations are ``(K - w^2 M) x = [f; -s Q]``: the
potential rows carry minus the free electrode charge; interior rows have zero charge and the hot
row carries ``-s Q_hot``. Hence :meth:`PiezoSystem.charge` returns
``Q_hot = -(K[hot] @ x) / s`` (Coulomb; positive when the hot electrode is at a positive voltage
on a blocked capacitor: ``Q = C V``).
``M`` is the consistent mass with zero rows/columns for the potential.
``K_loss`` is the hysteretic imaginary part: ``sum_region K_uu^region / Q_region`` plus
``+tan(delta) s^2 K_phiphi`` in the potential block, so that ``K + j K_loss`` represents
``c (1 + j/Q)`` and ``eps (1 - j tan(delta))`` (time factor ``exp(+j w t)``; both dissipate).

Electrical/mechanical boundary conditions
-----------------------------------------
``free_dofs(electrical="short"|"open", clamp=())``: ``short`` removes ``V_hot`` (all electrodes
at 0 V: resonance), ``open`` keeps it free (zero net charge is the natural condition:
anti-resonance). ``clamp`` names facet sets whose u DOFs are fixed. Free-free is the default.
``split(clamp=())`` prepares a driven problem (harmonic/transient): it returns the reduced
matrices without the hot DOF and the load columns ``K[:, hot]``, ``K_loss[:, hot]``; for a
voltage ``V`` the right-hand side is ``-(k_hot + j l_hot) V / s`` (see :class:`Split`).

Quadrature
----------
Minimal exact orders on straight (affine) tetrahedra: stiffness/coupling/permittivity order
``2p - 2`` (2 for P2: 4 points), mass ``2p`` (4 for P2). On curved (10-node) geometry the
integrands are rational: stiffness order 4 and mass order 5 (all-positive 14-point rule).
Override with ``intorder=(k, m)``.

Fast path
---------
:mod:`fem.fastasm`: element matrices of whole chunks of cells with numpy/BLAS, only for the
local node pairs ``a <= b`` (the blocks are symmetric), summed per unordered node pair with
``np.bincount`` and written straight into the final CSR arrays; straight cells of a curved mesh
skip the per-point quadrature (constant Jacobian). ``assemble(..., reference=True)`` builds the
same matrices from the weak forms of :mod:`fem.forms` with scikit-fem's ``asm`` (the baseline of
the tests and the benchmark); they agree to round-off.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Iterable, Mapping

import numpy as np
import scipy.sparse as sp

from rpud_common import ParameterError, check_choice
from geometry.mesh import TaggedMesh

from .fastasm import assemble_matrices
from .materials import elastic_matrix, piezo_matrices, resolve

__all__ = ["assemble", "PiezoSystem", "Split", "RegionData", "default_intorder", "region_data", "submatrix"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RegionData:
    """Constitutive data of one region in mesh coordinates."""

    name: str
    material: str
    piezo: bool
    density: float
    q_mech: float
    tan_delta: float
    c: np.ndarray
    e: np.ndarray | None
    eps: np.ndarray | None


def _library(tm: TaggedMesh, library) -> dict:
    """Where the mesh's material names resolve: its own records (``tm.library``: built-in
    overlaid with the records the design resolved), overlaid with an explicit ``library``."""
    lib = tm.library
    if library is None:
        return lib
    for name, rec in tm.materials.items():
        if name in library and library[name] != rec:
            log.warning("material %s: the library given to assemble differs from the mesh's record; "
                        "the given one is used", name)
    return {**lib, **library}


def region_data(tm: TaggedMesh, library) -> list[RegionData]:
    """The constitutive data of every region of ``tm`` in mesh coordinates (poled ceramics rotated)."""
    out = []
    library = _library(tm, library)
    for r in tm.regions:
        m = resolve(r.material, library)
        if m.is_piezo:
            if r.poling is None:
                raise ParameterError(f"regions.{r.name}.poling", None,
                                     "a piezoceramic region needs a poling direction")
            pc = piezo_matrices(m, r.poling)
            out.append(RegionData(r.name, m.name, True, m.density, m.q_mech, m.tan_delta,
                                  pc.c_E, pc.e, pc.eps_S))
        else:
            out.append(RegionData(r.name, m.name, False, m.density, m.q_mech, 0.0,
                                  elastic_matrix(m), None, None))
    return out


@dataclass
class _Blocks:
    """Unscaled blocks numbered by scalar nodes (u: 3 k + c)."""

    Kuu: sp.csr_matrix
    Luu: sp.csr_matrix
    Muu: sp.csr_matrix
    Kup: sp.csr_matrix   # (3n, n)
    Kpp: sp.csr_matrix   # (n, n)
    Lpp: sp.csr_matrix   # tan_delta-weighted Kpp


def _blocks_reference(mesh, elem, qk, qm, rdata, cell_region) -> _Blocks:
    """The same blocks from the weak forms of :mod:`fem.forms`, assembled by :func:`skfem.asm`
    region by region (the baseline the fast path is tested against)."""
    from skfem import Basis, ElementVector, asm

    from .forms import coupling, mass, permittivity, stiffness

    n = Basis(mesh, elem, intorder=1).N
    Kuu = sp.csr_matrix((3 * n, 3 * n))
    Luu, Muu = Kuu.copy(), Kuu.copy()
    Kup = sp.csr_matrix((3 * n, n))
    Kpp = sp.csr_matrix((n, n))
    Lpp = Kpp.copy()
    for ri, rd in enumerate(rdata):
        cells = np.flatnonzero(cell_region == ri)
        if len(cells) == 0:
            continue
        bu = Basis(mesh, ElementVector(elem), elements=cells, intorder=qk)
        bum = Basis(mesh, ElementVector(elem), elements=cells, intorder=qm)
        K = asm(stiffness, bu, c=rd.c)
        Kuu = Kuu + K
        if np.isfinite(rd.q_mech):
            Luu = Luu + K / rd.q_mech
        Muu = Muu + asm(mass, bum, rho=rd.density)
        if rd.piezo:
            bp = Basis(mesh, elem, elements=cells, intorder=qk)
            Kup = Kup + asm(coupling, bp, bu, e=rd.e)
            Kp = asm(permittivity, bp, eps=rd.eps)
            Kpp = Kpp + Kp
            Lpp = Lpp + rd.tan_delta * Kp
    return _Blocks(Kuu.tocsr(), Luu.tocsr(), Muu.tocsr(), Kup.tocsr(), Kpp.tocsr(), Lpp.tocsr())


@dataclass(repr=False)
class Split:
    """A driven problem with ``V_hot`` prescribed (harmonic / transient analyses).

    ``free``: global indices of the unknowns kept (u without clamped DOFs, interior potential);
    ``K``, ``M``, ``K_loss``: the matrices on ``free``; ``k_hot = K[free, hot]`` and
    ``l_hot = K_loss[free, hot]`` (dense vectors). For a hot-electrode voltage ``V`` (volts,
    complex amplitude allowed) solve ``(K + j K_loss - w^2 M) x_f = f_f - (k_hot + j l_hot) V / s``
    with ``s = phi_scale`` (use :meth:`rhs`), then :meth:`PiezoSystem.expand` rebuilds ``x``.
    """

    free: np.ndarray
    K: sp.csr_matrix
    M: sp.csr_matrix
    K_loss: sp.csr_matrix
    k_hot: np.ndarray
    l_hot: np.ndarray
    phi_scale: float

    def __repr__(self) -> str:
        return f"Split({len(self.free)} free DOFs, {self.K.nnz} stiffness entries; phi_scale {self.phi_scale:g} V/m)"

    def rhs(self, volts: complex = 1.0, lossy: bool = True) -> np.ndarray:
        """Load vector on ``free`` for the hot electrode at ``volts`` (no mechanical load)."""
        col = self.k_hot + (1j * self.l_hot if lossy else 0.0)
        out = -col * (volts / self.phi_scale)
        return out if np.iscomplexobj(out) and np.any(np.imag(out)) else np.real(out)


@dataclass(eq=False, repr=False)
class PiezoSystem:
    """The assembled coupled system (see the module docstring for layout and conventions)."""

    mesh: TaggedMesh
    skmesh: object
    basis: object          # scalar CellBasis (P2), the node numbering
    nodes: np.ndarray      # (n_nodes, 3) coordinates of the scalar nodes
    K: sp.csr_matrix
    M: sp.csr_matrix
    K_loss: sp.csr_matrix
    n_u: int
    n_phi: int
    hot_dof: int | None
    phi_scale: float
    phi_nodes: np.ndarray  # scalar node of each interior potential unknown
    hot_nodes: np.ndarray
    ground_nodes: np.ndarray
    regions: list[RegionData]
    order: int
    intorder: tuple[int, int]
    timings: dict = field(default_factory=dict)
    _basis_u: object = None
    materials: dict = field(default_factory=dict)
    """name -> :class:`geometry.materials.Material`: the records assembled (JSON: ``materials_block``)."""
    part_mass: dict | None = None
    """part -> scalar ``n x n`` mass (kg) of that part's cells, from the same element masses as
    ``M`` (fast path only; :func:`fem.modeshape.mass_matrix` builds it otherwise)."""

    def __repr__(self) -> str:
        # the sizes and the regions: the generated repr would print every matrix and array
        named = [f"{r.name} ({r.material})" for r in self.regions]
        regions = ", ".join(named[:4]) + (f", ... ({len(named)} in all)" if len(named) > 4 else "")
        phi = f"{self.n_phi} phi" + (" + V_hot" if self.hot_dof is not None else "")
        return (f"PiezoSystem({self.ndof} DOFs: {self.n_u} u, {phi}; P{self.order} fields on "
                f"{len(self.mesh.cells)} cells; regions {regions}; phi_scale {self.phi_scale:g} V/m)")

    def materials_block(self) -> dict:
        """``{name: record}`` of the constants assembled (layout of ``materials.toml``)."""
        return {n: m.to_record() for n, m in sorted(self.materials.items())}

    @property
    def basis_u(self):
        """Vector P2 ``CellBasis`` (``ElementVector``) on the whole mesh, built on first use;
        its DOF ``3 k + c`` is node ``k`` component ``c`` (same numbering as ``K``, ``M``)."""
        if self._basis_u is None:
            from skfem import CellBasis, ElementVector

            self._basis_u = CellBasis(self.skmesh, ElementVector(self.basis.elem), intorder=self.intorder[0])
        return self._basis_u

    # ------------------------------------------------------------------ layout
    @property
    def n_nodes(self) -> int:
        return len(self.nodes)

    @property
    def ndof(self) -> int:
        return self.K.shape[0]

    @property
    def u_dofs(self) -> slice:
        return slice(0, self.n_u)

    @property
    def phi_dofs(self) -> slice:
        return slice(self.n_u, self.n_u + self.n_phi)

    @property
    def has_piezo(self) -> bool:
        return any(r.piezo for r in self.regions)

    def displacement(self, x: np.ndarray) -> np.ndarray:
        """u part of ``x`` as (n_nodes, 3) (or (k, n_nodes, 3) for x of shape (ndof, k))."""
        x = np.asarray(x)
        if x.ndim == 2:
            return x[: self.n_u].T.reshape(x.shape[1], self.n_nodes, 3)
        return x[: self.n_u].reshape(self.n_nodes, 3)

    def potential(self, x: np.ndarray) -> np.ndarray:
        """Nodal potential in volts (n_nodes,), NaN where there is no ceramic."""
        x = np.asarray(x)
        out = np.full(self.n_nodes, np.nan, dtype=np.result_type(x.dtype, float))
        out[self.ground_nodes] = 0.0
        out[self.phi_nodes] = x[self.phi_dofs] * self.phi_scale
        if self.hot_dof is not None:
            out[self.hot_nodes] = x[self.hot_dof] * self.phi_scale
        return out

    def expand(self, x_free: np.ndarray, free: np.ndarray, v_hot: complex = 0.0) -> np.ndarray:
        """Full vector from the values on ``free`` and the hot-electrode voltage (volts)."""
        x_free = np.asarray(x_free)
        dtype = np.result_type(x_free.dtype, np.asarray(v_hot).dtype, float)
        shape = (self.ndof,) + x_free.shape[1:]
        x = np.zeros(shape, dtype=dtype)
        x[free] = x_free
        if self.hot_dof is not None and self.hot_dof not in set(np.asarray(free).tolist()):
            x[self.hot_dof] = v_hot / self.phi_scale
        return x

    def surface_nodes(self, name: str) -> np.ndarray:
        """Sorted scalar (P2) node indices on the facet set ``name``."""
        facets = self.skmesh.boundaries.get(name) if self.skmesh.boundaries else None
        if facets is None:
            self.mesh.facets(name)  # raises the clear ParameterError
        return np.unique(self.basis.get_dofs(facets=facets).all())

    def dofs_on(self, name: str, components: Iterable[int] = (0, 1, 2)) -> np.ndarray:
        """Global u DOF indices on the facet set ``name`` for the given components (0=x,1=y,2=z)."""
        comps = np.asarray(list(components), dtype=np.int64)
        if comps.size == 0 or comps.min() < 0 or comps.max() > 2:
            raise ParameterError("components", tuple(comps), "must be a subset of (0, 1, 2)")
        nodes = self.surface_nodes(name)
        return np.sort((3 * nodes[:, None] + comps[None, :]).ravel())

    # ------------------------------------------------------------------ BCs
    def free_dofs(self, electrical: str = "short", clamp: Iterable[str] = ()) -> np.ndarray:
        """Indices kept for an electrical state (``short``: V_hot = 0 removed; ``open``: V_hot
        free) and clamped facet sets (all u components fixed)."""
        check_choice("electrical", electrical, ("short", "open", "driven"))
        keep = np.ones(self.ndof, dtype=bool)
        if self.hot_dof is not None and electrical in ("short", "driven"):
            keep[self.hot_dof] = False
        for name in (clamp if not isinstance(clamp, str) else (clamp,)):
            keep[self.dofs_on(name)] = False
        return np.flatnonzero(keep)

    def reduce(self, electrical: str = "short", clamp: Iterable[str] = ()):
        """``(K_r, M_r, free)``: the matrices restricted to :meth:`free_dofs`."""
        free = self.free_dofs(electrical, clamp)
        return submatrix(self.K, free), submatrix(self.M, free), free

    def split(self, clamp: Iterable[str] = ()) -> Split:
        """The driven problem (hot voltage prescribed); see :class:`Split`."""
        if self.hot_dof is None:
            raise ParameterError("electrodes", "none hot", "a driven problem needs a hot electrode")
        free = self.free_dofs("driven", clamp)
        kh = np.asarray(self.K[:, [self.hot_dof]].toarray()).ravel()[free]
        lh = np.asarray(self.K_loss[:, [self.hot_dof]].toarray()).ravel()[free]
        return Split(free, submatrix(self.K, free), submatrix(self.M, free), submatrix(self.K_loss, free), kh, lh,
                     self.phi_scale)

    # ------------------------------------------------------------------ electrical
    def charge(self, x: np.ndarray, lossy: bool | None = None) -> complex:
        """Free charge on the hot electrode (C) for a solution ``x`` (``-(K[hot] x)/s``; with
        ``lossy`` (default: when x is complex) the row of ``K + j K_loss`` is used)."""
        if self.hot_dof is None:
            raise ParameterError("electrodes", "none hot", "no hot electrode to carry a charge")
        x = np.asarray(x)
        if lossy is None:
            lossy = np.iscomplexobj(x)
        row = self.K[self.hot_dof] @ x
        if lossy:
            row = row + 1j * (self.K_loss[self.hot_dof] @ x)
        q = -row / self.phi_scale
        return q.item() if np.ndim(q) == 0 or np.size(q) == 1 else q

    def capacitance_static(self, mechanical: str = "blocked", clamp: Iterable[str] = (),
                           backend: str | None = None) -> float:
        """Static capacitance (F) between hot and ground electrodes.

        ``mechanical="blocked"``: u = 0 (clamped capacitance C^S, purely dielectric).
        ``mechanical="free"``: the coupled static capacitance of the free (or ``clamp``-ed) body,
        i.e. the low-frequency limit of I/(j w V) below the first resonance (rigid-body modes are
        not excited by the self-equilibrated piezo forces; a tiny mass shift (1 Hz)^2 regularises
        the free-free stiffness, relative error ~ (1 Hz / f_1)^2).
        """
        from .solvers import factorize

        check_choice("mechanical", mechanical, ("blocked", "free"))
        if self.hot_dof is None:
            raise ParameterError("electrodes", "none hot", "no hot electrode")
        if mechanical == "blocked":
            free = np.arange(self.n_u, self.n_u + self.n_phi)
            A = submatrix(self.K, free)
        else:
            free = self.free_dofs("driven", clamp)
            A = (submatrix(self.K, free) + (2 * np.pi) ** 2 * submatrix(self.M, free)).tocsr()
        col = np.asarray(self.K[:, [self.hot_dof]].toarray()).ravel()[free]
        v = 1.0 / self.phi_scale
        xf = factorize(A, backend=backend)(-col * v) if len(free) else np.zeros(0)
        x = self.expand(xf, free, 1.0)
        return float(np.real(self.charge(x, lossy=False)))


def _pad(A, extra):
    """``A`` (csr) with ``extra`` empty rows and columns appended, without copying the data."""
    A = A.tocsr()
    n = A.shape[0] + extra
    indptr = np.concatenate([A.indptr, np.full(extra, A.indptr[-1], dtype=A.indptr.dtype)])
    return sp.csr_matrix((A.data, A.indices, indptr), shape=(n, n))


def _stack_diagonal(A, B):
    """``[[A, 0], [0, B]]`` (csr) by concatenating the CSR arrays."""
    A, B = A.tocsr(), B.tocsr()
    n = A.shape[0] + B.shape[0]
    idx = np.int64 if n >= np.iinfo(np.int32).max or A.nnz + B.nnz >= np.iinfo(np.int32).max else np.int32
    return sp.csr_matrix((np.concatenate([A.data, B.data]),
                          np.concatenate([A.indices.astype(idx, copy=False), B.indices.astype(idx) + A.shape[1]]),
                          np.concatenate([A.indptr.astype(idx, copy=False), B.indptr[1:].astype(idx) + A.nnz])),
                         shape=(n, n))


def submatrix(A, idx):
    """``A[idx][:, idx]`` as CSR."""
    return A[idx][:, idx].tocsr()


def _electrode_nodes(tm: TaggedMesh, basis, skmesh, role) -> np.ndarray:
    out = [np.zeros(0, dtype=np.int64)]
    for el in tm.electrodes:
        if el.role == role:
            out.append(np.asarray(basis.get_dofs(facets=skmesh.boundaries[el.name]).all(), dtype=np.int64))
    return np.unique(np.concatenate(out))


def _potential_nodes(mesh: TaggedMesh, bk, skmesh, rdata) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(hot, ground, interior)`` scalar nodes of the ceramic: those on hot electrodes (tied
    into one unknown), on ground electrodes (0 V, eliminated) and the rest (free potential)."""
    piezo_regions = [i for i, r in enumerate(rdata) if r.piezo]
    if not piezo_regions:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty, empty
    pcells = np.flatnonzero(np.isin(mesh.cell_region, piezo_regions))
    pnodes = np.unique(bk.element_dofs[:, pcells])
    hot = np.intersect1d(_electrode_nodes(mesh, bk, skmesh, "hot"), pnodes)
    ground = np.intersect1d(_electrode_nodes(mesh, bk, skmesh, "ground"), pnodes)
    if len(ground) == 0:
        raise ParameterError("electrodes", [e.name for e in mesh.electrodes],
                             "a mesh with piezoceramic needs a ground electrode touching it")
    both = np.intersect1d(hot, ground)
    if len(both):
        raise ParameterError("electrodes", f"{len(both)} shared nodes",
                             "hot and ground electrodes must not touch")
    return hot, ground, np.setdiff1d(pnodes, np.union1d(hot, ground))


def _compose(blocks: _Blocks, n: int, interior: np.ndarray, hot: np.ndarray):
    """``(K, M, K_loss, phi_scale)``: the blocks on the unknowns ``[u | phi~ interior | V~_hot]``
    with the potential scaled (module docstring)."""
    n_phi = len(interior)
    nr = n_phi + int(len(hot) > 0)
    rows = np.concatenate([interior, hot])
    cols = np.concatenate([np.arange(n_phi), np.full(len(hot), n_phi)])
    T = sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, nr))
    if nr:
        scaled = interior if n_phi else hot
        dk = blocks.Kuu.diagonal().reshape(n, 3)[scaled].mean()
        dp = blocks.Kpp.diagonal()[scaled].mean()
        phi_scale = float(10.0 ** np.round(np.log10(np.sqrt(dk / dp))))
    else:
        phi_scale = 1.0
    s = phi_scale
    Kup = (blocks.Kup @ T) * s
    Kpp = (T.T @ blocks.Kpp @ T) * (s * s)
    Lpp = (T.T @ blocks.Lpp @ T) * (s * s)
    if nr:
        # the u-u blocks, padded without a copy, plus the (ceramic-only, small) potential blocks
        K = _pad(blocks.Kuu, nr) + sp.bmat([[None, Kup], [Kup.T, -Kpp]], format="csr")
        M = _pad(blocks.Muu, nr)
        L = _stack_diagonal(blocks.Luu, Lpp)
    else:
        # the fast path's Kuu and Luu share their index arrays: give L its own
        K, M, L = blocks.Kuu.tocsr(), blocks.Muu.tocsr(), blocks.Luu.tocsr().copy()
    for A in (K, M, L):
        A.sum_duplicates()
        A.sort_indices()
    return K, M, L, phi_scale


def default_intorder(p: int, curved: bool) -> tuple[int, int]:
    """(stiffness, mass) quadrature orders for fields of order ``p`` (module docstring, Quadrature)."""
    if curved:
        return (2 * p, 2 * p + 1)
    return (2 * p - 2, 2 * p)


def assemble(mesh: TaggedMesh, *, order: int = 2, library: Mapping | None = None,
             intorder: tuple[int, int] | None = None, reference: bool = False) -> PiezoSystem:
    """Assemble the coupled system of ``mesh`` (see the module docstring).

    Parameters
    ----------
    mesh : TaggedMesh
    order : 1 or 2
        Polynomial order of the displacement and potential fields.
    library : mapping of material records, optional
        Default: the mesh's own records (``mesh.library``: what the design resolved, built-in
        records for names it does not carry); a given library overrides them by name.
    intorder : (stiffness, mass) quadrature orders, optional
        ``"skfem"`` (with ``reference=True``): scikit-fem's own default rules.
    reference : bool
        Assemble the weak forms of :mod:`fem.forms` with scikit-fem's ``asm`` (slow baseline)
        instead of the fast path (:mod:`fem.fastasm`); both give the same matrices to round-off.

    Returns
    -------
    PiezoSystem
        ``K`` (N/m; potential rows scaled by ``phi_scale``), ``M`` (kg), ``K_loss`` and the DOF
        layout ``[u | phi~ interior | V~_hot]``.

    Examples
    --------
    A PZT-4 rod poled along its length, electrodes on both ends:

    >>> from geometry import build_mesh
    >>> from geometry.examples import k33_rod
    >>> system = assemble(build_mesh(k33_rod(), mesh_size=0.01, order=1))
    >>> system
    PiezoSystem(12895 DOFs: 9726 u, 3168 phi + V_hot; P2 fields on 1507 cells; regions rod (PZT-4); phi_scale 1e+10 V/m)

    Its blocked capacitance is the parallel-plate value ``eps33^S A / L`` of the meshed section
    (the mass gives the volume; the faceted section varies along the rod by ~1e-5):

    >>> area = system.M.sum() / 3 / 7500.0 / 0.04          # m^2 (density 7500 kg/m^3, L = 40 mm)
    >>> eps33 = system.regions[0].eps[2, 2]                 # F/m, poled along z
    >>> round(float(system.capacitance_static() / (eps33 * area / 0.04)), 4)
    1.0
    """
    from skfem import CellBasis, ElementTetP1, ElementTetP2

    if order not in (1, 2):
        raise ParameterError("order", order, "must be 1 or 2")
    t0 = time.perf_counter()
    rdata = region_data(mesh, library)
    lib = _library(mesh, library)
    used = {r.material: resolve(r.material, lib) for r in mesh.regions}
    skmesh = mesh.to_skfem()
    elem = ElementTetP2() if order == 2 else ElementTetP1()
    if intorder == "skfem":      # scikit-fem's default rules (plain-assembly baseline only)
        if not reference:
            raise ParameterError("intorder", intorder, "'skfem' is for reference=True only")
        qk = qm = None
    else:
        qk, qm = intorder or default_intorder(order, mesh.order == 2)
    # the node numbering (kept by the PiezoSystem); its one-point quadrature is never used
    bk = CellBasis(skmesh, elem, intorder=1)
    t1 = time.perf_counter()
    part_mass = None
    if reference:
        blocks = _blocks_reference(skmesh, elem, qk, qm, rdata, mesh.cell_region)
    else:
        parts = {p: [ri for ri, r in enumerate(mesh.regions) if r.part == p] for p in mesh.parts}
        mats = assemble_matrices(bk, qk, qm, rdata, mesh.cell_region, groups=parts)
        part_mass = mats.pop("M_groups")
        blocks = _Blocks(**mats)
    t2 = time.perf_counter()
    n = bk.N
    n_u = 3 * n

    hot, ground, interior = _potential_nodes(mesh, bk, skmesh, rdata)
    n_phi = len(interior)
    has_hot = len(hot) > 0
    K, M, L, phi_scale = _compose(blocks, n, interior, hot)
    t3 = time.perf_counter()
    timings = {"setup_s": t1 - t0, "element_matrices_s": t2 - t1, "reduction_s": t3 - t2,
               "assembly_s": t3 - t0}
    log.info("assembled %d DOFs (%d u, %d phi%s) in %.2f s (%s)", K.shape[0], n_u, n_phi,
             " + V_hot" if has_hot else "", t3 - t0, "reference skfem" if reference else "fast")
    return PiezoSystem(
        mesh=mesh, skmesh=skmesh, basis=bk, nodes=bk.doflocs.T.copy(),
        K=K, M=M, K_loss=L, n_u=n_u, n_phi=n_phi, hot_dof=(n_u + n_phi) if has_hot else None,
        phi_scale=phi_scale, phi_nodes=interior, hot_nodes=hot, ground_nodes=ground,
        regions=rdata, order=order, intorder=(qk, qm), timings=timings, materials=used, part_mass=part_mass)
