"""The whole drill's axisymmetric response from one sector: a system every driven analysis takes.

A drill unchanged by a turn of ``alpha = 2 pi / N`` (:mod:`geometry.sector`) answers a drive
that is itself unchanged by that turn (the stack's voltage, a clamp on a whole surface) with a
field of harmonic ``k = 0``: every sector moves alike, the far cut face as the near one
rotated, ``u_far = R(alpha) u_near``, ``phi_far = phi_near``, and a node on the axis along the
axis only (:func:`fem.cyclic.cyclic_basis`). Writing the sector's vector as ``x = T q``
restricts the whole drill's equations to that field exactly, on about ``1 / N`` of its unknowns.

:class:`SectorSystem` is that restriction dressed as a :class:`fem.assembly.PiezoSystem`, so
that :func:`fem.modal.modal_analysis`, :func:`fem.harmonic.working_point`,
:func:`fem.harmonic.harmonic_sweep`, :func:`fem.transient.ring_up`,
:func:`fem.reduced.reduce_transducer`, :func:`fem.matching.match` and the surface and energy
functions of :mod:`fem.modeshape` take it unchanged:

* its vectors keep the sector's layout (``ndof`` of the sector); the unknowns ``q`` sit at the
  indices :attr:`SectorSystem.kept` (each independent DOF at its own index, an axis node's
  ``u_z``, the hot electrode), every other entry is 0. ``K``, ``M``, ``K_loss`` are
  ``T^T (N K_s) T`` scattered onto those indices, so a vector's energy, charge and power are
  the whole drill's (``N`` sectors), and :meth:`SectorSystem.free_dofs` never frees the others;
* :meth:`SectorSystem.complete` (and :meth:`~SectorSystem.displacement`,
  :meth:`~SectorSystem.potential`, which apply it) turns such a vector into the sector's field
  ``T q``; :attr:`SectorSystem.sector` is the sector's own system (scaled by ``N``) for the
  mass matrix and surfaces of :mod:`fem.modeshape`;
* :meth:`SectorSystem.whole_mesh` and :meth:`SectorSystem.whole_shapes` replicate the sector
  and its field onto the whole drill (renders, VTU).

Area-weighted surface means of a ``k = 0`` field are the same on one sector as on the whole
surface; sums over the whole drill (charge, energy, mass) carry the factor ``N``.
"""

from __future__ import annotations

import dataclasses
import logging
import time
import weakref
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Iterable

import numpy as np
import scipy.sparse as sp

from geometry.sector import replicate, sector_pairs
from rpud_common import ParameterError, check_choice

from .assembly import PiezoSystem

__all__ = ["SectorSystem", "sector_system", "sector_mesh", "axial_sector", "AXIS_MOTIONS", "PATHS", "sweepable", "default_path",
           "check_path", "path_label", "default_system", "system_label", "whole_grade"]

log = logging.getLogger(__name__)

AXIS_MOTIONS = (2, 5)
"""The rigid motions of :func:`fem.eigen.rigid_basis` a ``k = 0`` field holds: the translation
along and the rotation about the axis (the other four are ``k = 1``)."""


@dataclass(eq=False)
class SectorSystem(PiezoSystem):
    """A :class:`fem.assembly.PiezoSystem` restricted to the fields of harmonic ``k = 0`` of a
    sector (see the module docstring); build it with :func:`sector_system`. The attributes below
    come beside the system's own.

    Attributes
    ----------
    sector : PiezoSystem
        The sector's own system with ``K``, ``M``, ``K_loss`` and part masses times ``N``.
    tie : scipy.sparse.csr_matrix
        ``(ndof, ndof)``: ``tie @ x`` is the sector's field of a vector ``x`` of this system.
    kept : ndarray of int
        The indices that carry unknowns.
    sectors : int
        ``N``.
    label : str
        The mesh that ran, in words (printed and written by every command).
    """

    sector: PiezoSystem | None = field(default=None, repr=False)
    tie: sp.csr_matrix | None = field(default=None, repr=False)
    kept: np.ndarray | None = field(default=None, repr=False)
    sectors: int = 0
    label: str = ""
    _whole: tuple | None = field(default=None, repr=False)

    rigid_motions = AXIS_MOTIONS

    def free_dofs(self, electrical: str = "short", clamp: Iterable[str] = ()) -> np.ndarray:
        """:meth:`fem.assembly.PiezoSystem.free_dofs` among the indices that carry unknowns."""
        return np.intersect1d(super().free_dofs(electrical, clamp), self.kept, assume_unique=True)

    def complete(self, x: np.ndarray) -> np.ndarray:
        """The sector's field ``T q`` (same shape) of a vector (or columns) of this system."""
        x = np.asarray(x)
        return np.asarray(self.tie @ x)

    def displacement(self, x: np.ndarray) -> np.ndarray:
        """The sector's displacement (``(n_nodes, 3)`` or ``(k, n_nodes, 3)``) of ``x``."""
        return super().displacement(self.complete(x))

    def potential(self, x: np.ndarray) -> np.ndarray:
        """The sector's nodal potential (V) of ``x``."""
        return super().potential(self.complete(x))

    def capacitance_static(self, mechanical: str = "blocked", clamp: Iterable[str] = (),
                           backend: str | None = None) -> float:
        """The whole drill's static capacitance (F); see
        :meth:`fem.assembly.PiezoSystem.capacitance_static`."""
        from .solvers import factorize

        check_choice("mechanical", mechanical, ("blocked", "free"))
        if self.hot_dof is None:
            raise ParameterError("electrodes", "none hot", "no hot electrode")
        if mechanical == "blocked":
            free = self.kept[(self.kept >= self.n_u) & (self.kept < self.n_u + self.n_phi)]
            A = self.K[free][:, free]
        else:
            free = self.free_dofs("driven", clamp)
            A = self.K[free][:, free] + (2 * np.pi) ** 2 * self.M[free][:, free]
        col = np.asarray(self.K[:, [self.hot_dof]].toarray()).ravel()[free]
        xf = factorize(A.tocsr(), backend=backend)(-col / self.phi_scale) if len(free) else np.zeros(0)
        return float(np.real(self.charge(self.expand(xf, free, 1.0), lossy=False)))

    def whole_mesh(self):
        """``(mesh, index)`` of the whole drill replicated from the sector
        (:func:`geometry.sector.replicate`; built once)."""
        if self._whole is None:
            self._whole = replicate(self.mesh, self.sectors)
        return self._whole

    def whole_shapes(self, x: np.ndarray) -> np.ndarray:
        """The whole drill's displacement ``(k, n_whole, 3)`` (real part for a complex ``x``, e.g.
        a phasor at phase 0) at the nodes of :meth:`whole_mesh`'s system numbering, from vectors
        ``x`` (``(ndof,)`` or ``(ndof, k)``) of this system."""
        from .cyclic import expand
        from .modeshape import p2_nodes

        x = np.asarray(x)
        cols = x[:, None] if x.ndim == 1 else x
        whole, _ = self.whole_mesh()
        return np.real(expand(self.sector, self.complete(cols), 0, self.sectors, p2_nodes(whole)))


def _tie(system: PiezoSystem, sectors: int, pairs) -> tuple[sp.csr_matrix, np.ndarray]:
    """``(tie, kept)``: :func:`fem.cyclic.cyclic_basis` of ``k = 0`` (open circuit: the hot
    electrode free) with each column placed at the index of the unknown it stands for."""
    from .cyclic import cyclic_basis

    T = cyclic_basis(system, pairs, 0, "open").tocoo()
    dependent = np.zeros(system.ndof, dtype=bool)
    dependent[(3 * pairs.far[:, None] + np.arange(3)).ravel()] = True
    dependent[(3 * pairs.axis[:, None] + np.arange(3)).ravel()] = True
    phi = np.full(system.n_nodes, -1, dtype=np.int64)
    phi[system.phi_nodes] = system.n_u + np.arange(system.n_phi)
    fp = phi[pairs.far]
    dependent[fp[fp >= 0]] = True
    if system.hot_dof is not None:
        dependent[system.hot_dof] = True
    # the column order of cyclic_basis: independent DOFs, an axis node's u_z each, the hot electrode
    kept = np.concatenate([np.flatnonzero(~dependent), 3 * pairs.axis + 2,
                           [system.hot_dof] if system.hot_dof is not None else []]).astype(np.int64)
    if len(kept) != T.shape[1]:
        raise ParameterError("sector mesh", f"{T.shape[1]} unknowns", "do not match the k = 0 basis's layout")
    tie = sp.csr_matrix((np.real(T.data), (T.row, kept[T.col])), shape=(system.ndof, system.ndof))
    return tie, np.sort(kept)


def _restriction(tie: sp.csr_matrix):
    """``A -> T^T A T`` for the symmetric matrices of the sector (``T``: ``tie``).

    Most rows of ``T`` are rows of the identity (a DOF that is its own unknown); only the far
    cut, the axis and the hot electrode (``X``, ~10 % of the DOFs) are combinations. With
    ``T = D + E`` (``D`` those identity rows, ``E`` the rest), ``T^T A T = D A D + E^T A D +
    (E^T A D)^T + E^T A E``: ``D A D`` is ``A`` with the rows and columns of ``X`` dropped (no
    product), and the products run over the ``X`` rows of ``A`` only. Two general sparse
    products and a transposed sum over the whole matrix cost ~3x more. ``A`` is symmetric to
    its assembly's round-off, so ``D A E`` is taken as ``(E^T A D)^T``; the ``E`` terms are
    exactly symmetric, the ``D A D`` block is ``A``'s own.
    """
    n = tie.shape[0]
    tie = tie.tocsr()
    tie.sort_indices()
    ident = np.zeros(n, dtype=bool)
    single = np.flatnonzero(np.diff(tie.indptr) == 1)
    first = tie.indptr[single]
    ident[single] = (tie.indices[first] == single) & (tie.data[first] == 1.0)
    X = np.flatnonzero(~ident)
    EX = tie[X]
    EXt = EX.T.tocsr()

    def restrict(A):
        A = sp.csr_matrix(A)
        A.sum_duplicates()
        keep = np.repeat(ident, np.diff(A.indptr)) & ident[A.indices]
        indptr = np.concatenate([[0], np.cumsum(keep)])[A.indptr].astype(A.indptr.dtype)
        DAD = sp.csr_matrix((A.data[keep], A.indices[keep], indptr), shape=A.shape)
        G = A[X]                                # the X rows, (|X|, n)
        GD = sp.csr_matrix((np.where(ident[G.indices], G.data, 0.0), G.indices, G.indptr), shape=G.shape)
        HD = (EXt @ GD).tocsr()                 # E^T A D
        HE = (EXt @ (G[:, X] @ EX)).tocsr()     # E^T A E
        B = (DAD + (HD + HD.T + (HE + HE.T) * 0.5)).tocsr()
        B.eliminate_zeros()
        B.sort_indices()
        return B

    return restrict


def sector_system(system: PiezoSystem, sectors: int, *, label: str = "") -> SectorSystem:
    """The ``k = 0`` restriction (:class:`SectorSystem`) of the assembled sector ``system``
    (a sector mesh of ``sectors`` identical sectors, :mod:`geometry.sector`).

    Parameters
    ----------
    system : PiezoSystem
        The sector, as :func:`fem.assembly.assemble` returns it.
    sectors : int
        ``N``: the sector spans ``2 pi / N``.
    label : str
        The mesh in words (default: "sector 1/N").
    """
    if isinstance(system, SectorSystem):
        raise ParameterError("system", "a SectorSystem", "must be the sector's own assembled system")
    if isinstance(sectors, bool) or not isinstance(sectors, (int, np.integer)) or sectors < 2:
        raise ParameterError("sectors", sectors, "must be an integer >= 2")
    t0 = time.perf_counter()
    pairs = sector_pairs(system.nodes, int(sectors))
    tie, kept = _tie(system, int(sectors), pairs)
    n = float(sectors)
    scaled = dataclasses.replace(
        system, K=(n * system.K).tocsr(), M=(n * system.M).tocsr(), K_loss=(n * system.K_loss).tocsr(),
        part_mass=None if system.part_mass is None else {p: (n * m).tocsr() for p, m in system.part_mass.items()})
    restrict = _restriction(tie)
    # the three restrictions share nothing they write and run in scipy's and NumPy's compiled
    # loops, which release the interpreter: two threads (each result is the one computed alone)
    with ThreadPoolExecutor(max_workers=2, thread_name_prefix="restrict") as pool:
        K, M, K_loss = pool.map(restrict, (scaled.K, scaled.M, scaled.K_loss))
    fields = {f.name: getattr(scaled, f.name) for f in dataclasses.fields(PiezoSystem)}
    fields.update(K=K, M=M, K_loss=K_loss, _basis_u=None,
                  timings={**system.timings, "sector_restriction_s": time.perf_counter() - t0})
    out = SectorSystem(**fields, sector=scaled, tie=tie, kept=kept, sectors=int(sectors),
                       label=label or f"sector 1/{int(sectors)}")
    log.info("k = 0 sector system: %d of %d sector DOFs carry unknowns (%d sectors), %.2f s", len(kept),
             system.ndof, sectors, time.perf_counter() - t0)
    return out


def sector_mesh(design, *, refine: float = 1.0, grade: bool = False, mesh_size: float | None = None,
                sectors: int | None = None):
    """The swept sector mesh of the ``k = 0`` rule (:data:`geometry.sector.AXIAL_RULE`, scaled by
    ``refine``) of ``design``, not assembled: ``(mesh, sectors)``, ``sectors`` default the
    coupler's symmetry order (6 for a body of revolution). Raises a ParameterError for a design
    that cannot be swept as a sector."""
    import geometry
    from geometry.sector import AXIAL_RULE, symmetry_order

    if sectors is None:
        sectors = symmetry_order(design) or 6
    rule_refine, meshing = AXIAL_RULE
    mesh = geometry.build_mesh(design, mesh_size=mesh_size, order=2, refine=rule_refine * refine, grade=grade,
                               mesher="revolve", sectors=sectors, sector_meshing=meshing.scaled(refine))
    return mesh, sectors


def axial_sector(design, *, refine: float = 1.0, grade: bool = False, mesh_size: float | None = None,
                 sectors: int | None = None) -> SectorSystem:
    """Mesh ``design`` as the swept sector of the ``k = 0`` rule (:func:`sector_mesh`), assemble
    it and restrict it (:func:`sector_system`). ``sectors``: default the coupler's symmetry order
    (6 for a body of revolution). Raises a ParameterError for a design that cannot be swept as a
    sector."""
    from .assembly import assemble

    mesh, sectors = sector_mesh(design, refine=refine, grade=grade, mesh_size=mesh_size, sectors=sectors)
    return sector_system(assemble(mesh, order=2), sectors,
                         label=path_label(design, "sector", refine=refine, grade=grade, mesh_size=mesh_size))


PATHS = ("sector", "whole")
"""The FE paths: ``sector``, the ``k = 0`` swept sector (:func:`axial_sector`); ``whole``, the
whole drill (swept (r, z) section where the design has one, else free), graded toward its
re-entrant edges."""


def sweepable(design) -> bool:
    """The design can be swept as a sector: an RPUD with a stepped or conical horn, its coupler
    and stack face to face and bored, its coupler at least 3-fold symmetric (or without slots
    and teeth)."""
    from geometry.design_rpud import RPUDDesign
    from geometry.revolve import can_revolve
    from geometry.sector import symmetry_order
    from geometry.sector_sweep import check_sweepable

    if not isinstance(design, RPUDDesign) or not can_revolve(design):
        return False
    try:
        check_sweepable(design)
    except ParameterError:
        return False
    order = symmetry_order(design)
    return order == 0 or order >= 3


def default_path(design, order: int = 2) -> str:
    """The path every command and the library take for ``design`` by default: ``sector`` where
    it can be swept (:func:`sweepable`, order 2), else ``whole``."""
    return "sector" if order == 2 and sweepable(design) else "whole"


def check_path(design, path: str | None, order: int = 2) -> str:
    """``path`` resolved (None or ``auto``: :func:`default_path`), or a ParameterError naming
    why the design cannot take it."""
    if path in (None, "auto"):
        return default_path(design, order)
    check_choice("path", path, PATHS)
    if path == "sector" and default_path(design, order) != "sector":
        raise ParameterError("path", path, "needs an RPUD design that can be swept as a sector (stepped or conical "
                             "horn, coupler and stack face to face, bored) and order 2; use the whole drill")
    return path


def path_label(design, path: str, *, refine: float = 1.0, grade: bool = False, mesh_size: float | None = None,
               order: int = 2) -> str:
    """The mesh a path runs, in words (what every output prints and writes as its ``mesh``)."""
    from geometry.revolve import resolve_mesher
    from geometry.sector import symmetry_order

    size = f", mesh size {mesh_size:g} m" if mesh_size else ""
    if path == "sector":
        return (f"swept sector 1/{symmetry_order(design) or 6} (k = 0), refine {refine:g}"
                + (", graded" if grade else "") + size)
    mesher = resolve_mesher(design, "auto")
    kind = "swept (r, z) section, coupler free" if mesher == "revolve" else "free"
    return (f"whole drill, {kind}, order {order}, refine {refine:g}" + (", graded" if grade else ", ungraded")
            + size)


def whole_grade(design) -> bool:
    """Whether the whole-drill path grades ``design`` when not told: toward its re-entrant edges,
    except on a CAD drawing, whose re-entrant edges are not known (the mesher refuses grading it)."""
    from geometry.design_cad import CadDesign

    return not isinstance(design, CadDesign)


def default_system(design, *, refine: float = 1.0, grade: bool | None = None, mesh_size: float | None = None,
                   order: int = 2, path: str | None = None) -> PiezoSystem:
    """The system of ``design`` on its default path (:func:`default_path`; or ``path``): a
    :class:`SectorSystem` on the sector path, else the whole drill, swept where it can be,
    graded (``grade`` None: graded on the whole path, the sector's own rule on the sector path).
    :func:`system_label` says which ran."""
    import geometry
    from geometry.revolve import resolve_mesher

    from .assembly import assemble

    path = check_path(design, path, order)
    if path == "sector":
        return axial_sector(design, refine=refine, grade=bool(grade), mesh_size=mesh_size)
    grade = whole_grade(design) if grade is None else bool(grade)
    mesh = geometry.build_mesh(design, mesh_size=mesh_size, order=order, refine=refine, grade=grade,
                               mesher=resolve_mesher(design, "auto"))
    system = assemble(mesh, order=order)
    _LABELS[system] = path_label(design, "whole", refine=refine, grade=grade, mesh_size=mesh_size, order=order)
    return system


_LABELS: "weakref.WeakKeyDictionary[PiezoSystem, str]" = weakref.WeakKeyDictionary()


def system_label(system: PiezoSystem) -> str:
    """The mesh ``system`` was built on, in words (:func:`default_system`'s or a
    :class:`SectorSystem`'s label; a system assembled elsewhere: its DOFs only)."""
    if isinstance(system, SectorSystem):
        return system.label
    return _LABELS.get(system, f"whole drill, {system.ndof} DOFs")
