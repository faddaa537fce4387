"""The mode-shape toolkit: mass matrix, MAC, cylindrical projection, energy shares, labels, surface motion.

Every function takes mode shapes as **nodal displacement** ``(n_modes, n_nodes, 3)`` (a single
``(n_nodes, 3)`` shape is accepted too) at the nodes of the field, and as its first argument
``mesh`` either

* a :class:`fem.assembly.PiezoSystem`: the nodes are ``system.nodes`` (P2, or P1 for an
  ``order=1`` system) and the mass matrix is the system's own ``M`` (displacement block), the
  one the modal analysis normalises its shapes with (``Phi^T M Phi = I``); or
* a :class:`geometry.mesh.TaggedMesh`: the P2 nodes of ``mesh.to_skfem()``::

      skfem.Basis(mesh.to_skfem(), skfem.ElementTetP2()).doflocs.T   # == p2_nodes(mesh)

  (vertices first, in skfem's corner numbering, then edge midpoints), and the mass matrix that
  ``fem.assembly.assemble(mesh)`` would build (built-in material library, the same quadrature
  order).

One mass matrix
---------------
The displacement block of the assembled mass is ``M_uu = M (x) I_3`` (u DOF ``3 k + c``), with
``M`` the density-weighted scalar mass. Every energy, MAC and projection here uses that ``M``
(:func:`mass_matrix`): with a system it *is* ``system.M[0:n_u:3, 0:n_u:3]``; with a mesh it is
assembled as :mod:`fem.assembly`'s reference path does (``rho u v`` per region with the mass
quadrature order of the assembly, scikit-fem ``BilinearForm``), equal to it to round-off. The
mass of each part (``region.part``) is assembled the same way; the parts sum to ``M``.

Energy decomposition (:func:`energy_shares`)
--------------------------------------------
Kinetic energies ``E(f) = f^T M f`` are applied to each scalar component. The displacement is
split, **node by node**, into:

1. *bending* (circumferential order m = 1): per axial slab of nodes, a weighted least-squares
   fit (weights: diagonal of ``M``) of the in-plane motion with a lateral translation
   ``(t1, t2)``, a twist ``r (c0 + c1 r + c2 r^2) e_theta`` and a breathing
   ``r (d0 + d1 r + d2 r^2) e_r`` (fitted jointly, so none leaks into another on an asymmetric
   mesh), and of the axial motion with a piston plus a cross-section tilt
   ``c + a1 x1 + a2 x2``; the bending field is ``t1 e1 + t2 e2 + (a1 x1 + a2 x2) e_axis``;
2. of the rest ``u'``, the node-wise cylindrical components about the axis
   (:func:`cylindrical_components`: ``e_axis``, ``e_r``, ``e_theta = e_axis x e_r``):

   - *axial*: ``u'.e_axis`` (longitudinal motion, incl. Poisson-free warping);
   - *torsional*: the axisymmetric (m = 0) part of ``u'.e_theta``, the twist fitted above
     (rigid rotation of the section and any radial variation of it);
   - *radial*: the in-plane remainder ``u'.e_r`` and ``u'.e_theta - torsional`` (breathing,
     ovalling and higher circumferential orders).

   Nodes on the axis (``r < 1e-6 * r_max``) have no tangential direction: their in-plane
   motion counts as radial (torsional = 0 there).

Shares are the four energies divided by their sum (so they sum to 1); ``lateral = bending +
radial``. The sum differs from the Cartesian kinetic energy ``u^T M u`` only by cross terms of
the node-wise projection (``closure`` reports the ratio; 1 to round-off for the synthetic
fields of the tests, a few per cent at most on real modes). Slabs are the distinct axial node
levels when the mesh is extruded/structured (<= n_nodes/4 levels), otherwise bins half a mean
edge long.

Surface motion (:func:`surface_rows`, :func:`surface_motion`)
-------------------------------------------------------------
The displacement is interpolated at the quadrature points of a facet set (scikit-fem
``FacetBasis``) and projected there on the local cylindrical unit vectors. The area-weighted
means are linear in the nodal displacement: :func:`surface_rows` returns them as a sparse
``(3, 3 n_nodes)`` matrix (rows axial, tangential, radial), which the harmonic and transient
analyses apply to every solution (:func:`fem.harmonic.surface_functional`).
"""

from __future__ import annotations

import weakref
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from rpud_common import ParameterError
from geometry.mesh import TaggedMesh

from .assembly import PiezoSystem

__all__ = [
    "LABELS",
    "THRESHOLDS",
    "COMPONENTS",
    "Shares",
    "ModeShares",
    "ModeMatch",
    "p2_nodes",
    "mass_matrix",
    "check_shapes",
    "axis_frame",
    "energy_shares",
    "classify",
    "effective_mass_axial",
    "total_mass",
    "equivalent_mass",
    "mac",
    "match_modes",
    "cylindrical_components",
    "surface_rows",
    "surface_motion", "mesh_context"]

LABELS = ("longitudinal", "torsional", "longitudinal-torsional", "bending", "radial", "rigid")

THRESHOLDS = {
    # a mode whose kinetic energy lies >= 95 % in the six rigid-body motions is "rigid"
    "rigid": 0.95,
    # "longitudinal-torsional" when axial and torsional shares both reach 15 %
    "coupled": 0.15,
}
"""Thresholds used by :func:`classify` (energy fractions)."""

COMPONENTS = ("axial", "tangential", "radial")
"""The cylindrical components, in the order of :func:`cylindrical_components` and :func:`surface_rows`."""

_AXIS_EPS = 1e-6


# --------------------------------------------------------------------------- nodes and the mass matrix


@dataclass
class _Context:
    """What depends only on the mesh and the field's element (cached per mesh and order)."""

    mesh: TaggedMesh
    sk: object                      # skfem mesh with the facet sets as boundaries
    basis: object                   # scalar CellBasis: node numbering and DOF lookup
    nodes: np.ndarray               # (n, 3), m
    n_vertices: int
    frames: dict = field(default_factory=dict)     # axis key -> _Frame
    surfaces: dict = field(default_factory=dict)   # (surface, axis key) -> _Surface
    masses: dict = field(default_factory=dict)     # (mass order, densities) -> {part: M_part, None: M}


_CONTEXTS: "weakref.WeakKeyDictionary[TaggedMesh, dict]" = weakref.WeakKeyDictionary()
_SYSTEM_MASS: "weakref.WeakKeyDictionary[PiezoSystem, sp.csr_matrix]" = weakref.WeakKeyDictionary()


def _mesh_of(mesh) -> TaggedMesh:
    if isinstance(mesh, PiezoSystem):
        return mesh.mesh
    if isinstance(mesh, TaggedMesh):
        return mesh
    raise ParameterError("mesh", type(mesh).__name__,
                         "must be a geometry.mesh.TaggedMesh or a fem.assembly.PiezoSystem")


def mesh_context(mesh) -> _Context:
    """The context of a mesh (P2) or of a system (its own order, its own node numbering)."""
    tm = _mesh_of(mesh)
    order = mesh.order if isinstance(mesh, PiezoSystem) else 2
    per_order = _CONTEXTS.setdefault(tm, {})
    ctx = per_order.get(order)
    if ctx is not None:
        return ctx
    if isinstance(mesh, PiezoSystem):
        sk, basis = mesh.skmesh, mesh.basis
    else:
        from skfem import CellBasis, ElementTetP2

        sk = tm.to_skfem()
        # as in fem.assembly: the basis gives the node numbering; its quadrature is never used
        basis = CellBasis(sk, ElementTetP2(), intorder=1)
    ctx = _Context(mesh=tm, sk=sk, basis=basis, nodes=np.ascontiguousarray(basis.doflocs.T),
                   n_vertices=sk.p.shape[1])
    per_order[order] = ctx
    return ctx


def _part_masses(ctx: _Context, mass_order: int, densities: Sequence[float]) -> dict:
    """Scalar mass of each part: ``rho u v`` per region with the assembly's mass quadrature
    (the reference path of :mod:`fem.assembly`, which the fast path matches to round-off)."""
    from skfem import Basis, BilinearForm

    @BilinearForm
    def unit_mass(u, v, w):
        return u * v

    tm, n = ctx.mesh, len(ctx.nodes)
    parts = {p: sp.csr_matrix((n, n)) for p in tm.parts}
    for ri, region in enumerate(tm.regions):
        cells = np.flatnonzero(tm.cell_region == ri)
        if len(cells):
            basis = Basis(ctx.sk, ctx.basis.elem, elements=cells, intorder=mass_order)
            parts[region.part] = parts[region.part] + densities[ri] * unit_mass.assemble(basis)
    return {p: M.tocsr() for p, M in parts.items()}


def _masses(mesh) -> dict:
    """``{part: M_part, ..., None: sum of the parts}`` for the densities and mass quadrature of
    the system (or of ``fem.assembly.assemble(mesh)`` with the built-in library)."""
    ctx = mesh_context(mesh)
    if isinstance(mesh, PiezoSystem):
        key = (mesh.intorder[1], tuple(r.density for r in mesh.regions))
    else:
        from .assembly import default_intorder, region_data

        key = (default_intorder(2, ctx.mesh.order == 2)[1],
               tuple(r.density for r in region_data(ctx.mesh, None)))
    if key not in ctx.masses:
        own = mesh.part_mass if isinstance(mesh, PiezoSystem) else None
        parts = dict(own) if own is not None else _part_masses(ctx, *key)
        ctx.masses[key] = {**parts, None: sum(parts.values()).tocsr()}
    return ctx.masses[key]


def mass_matrix(mesh, part: str | None = None) -> sp.csr_matrix:
    """The scalar mass matrix ``M`` (kg) every function of this module uses.

    Parameters
    ----------
    mesh : TaggedMesh or PiezoSystem
        With a system: ``system.M[0:n_u:3, 0:n_u:3]``, the system's own matrix (its
        displacement block is ``M (x) I_3``). With a mesh: the same matrix as
        ``fem.assembly.assemble(mesh)`` builds, to round-off (built-in material library).
    part : str, optional
        The mass of one part's cells only (``region.part``); the parts sum to ``M``.
    """
    if part is not None:
        masses = _masses(mesh)
        if part not in masses:
            raise ParameterError("part", part, "unknown; known: " + ", ".join(p for p in masses if p))
        return masses[part]
    if not isinstance(mesh, PiezoSystem):
        return _masses(mesh)[None]
    M = _SYSTEM_MASS.get(mesh)
    if M is None:
        # THE matrix of the system: its displacement block is M (x) I_3 (u DOF 3 k + c); a
        # fem.sector_system.SectorSystem's shapes are its sector's fields, whose mass that is
        own = getattr(mesh, "sector", None) or mesh
        M = _SYSTEM_MASS[mesh] = own.M[0:own.n_u:3, 0:own.n_u:3].tocsr()
    return M


def p2_nodes(mesh) -> np.ndarray:
    """The (n_nodes, 3) node coordinates (m) the mode shapes refer to (vertices first): the P2
    nodes of a mesh, or ``system.nodes`` of a system."""
    return mesh_context(mesh).nodes


def check_shapes(mesh, shapes, name: str = "shapes", allow_complex: bool = True) -> np.ndarray:
    """Validate and return ``shapes`` as an ``(n_modes, n_nodes, 3)`` array.

    A single shape ``(n_nodes, 3)`` becomes ``(1, n_nodes, 3)``. Raises
    :class:`~rpud_common.errors.ParameterError` for any other shape or non-finite values.
    """
    n = len(mesh_context(mesh).nodes)
    try:
        a = np.asarray(shapes)
    except Exception:  # noqa: BLE001 - ragged input
        raise ParameterError(name, type(shapes).__name__, "must be an array") from None
    if a.ndim == 2:
        a = a[None]
    if a.ndim != 3 or a.shape[1:] != (n, 3) or a.shape[0] == 0:
        raise ParameterError(name, a.shape, f"must have shape (n_modes, {n}, 3): displacement at the "
                             f"{n} nodes of the field (p2_nodes)")
    if not (np.issubdtype(a.dtype, np.number) and not np.issubdtype(a.dtype, np.bool_)):
        raise ParameterError(name, a.dtype, "must be numeric")
    if np.iscomplexobj(a) and not allow_complex:
        raise ParameterError(name, a.dtype, "must be real (pass .real of a complex response)")
    if not np.all(np.isfinite(a)):
        raise ParameterError(name, "non-finite", "must hold finite values only")
    return a if np.iscomplexobj(a) else a.astype(float, copy=False)


def _apply(M, u: np.ndarray) -> np.ndarray:
    """``M`` applied to every component of ``u`` (k, n, c); ``M = None`` is the identity."""
    if M is None:
        return u
    k, n, c = u.shape
    return (M @ u.transpose(1, 0, 2).reshape(n, k * c)).reshape(n, k, c).transpose(1, 0, 2)


def _gram(M, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a_p^H (M (x) I) b_q`` for fields a (p, n, c), b (q, n, c): the one inner product."""
    return np.einsum("pnc,qnc->pq", np.conj(a), _apply(M, b))


def _energy(M, u: np.ndarray) -> np.ndarray:
    """``u_k^H (M (x) I) u_k`` per field of u (k, n, c), real."""
    return np.real(np.einsum("knc,knc->k", np.conj(u), _apply(M, u)))


def _ratio(num, den, empty=0.0):
    return np.where(den > 0, num / np.where(den > 0, den, 1.0), empty)


# --------------------------------------------------------------------------- cylindrical frame


def _axis(axis_point, axis_dir) -> tuple[np.ndarray, np.ndarray]:
    p = np.asarray(axis_point, dtype=float).ravel()
    if p.size == 2:
        p = np.r_[p, 0.0]
    if p.size != 3 or not np.all(np.isfinite(p)):
        raise ParameterError("axis_point", axis_point, "must be 2 or 3 finite coordinates in m")
    d = np.asarray(axis_dir, dtype=float).ravel()
    if d.size != 3 or not np.all(np.isfinite(d)) or np.linalg.norm(d) == 0:
        raise ParameterError("axis_dir", axis_dir, "must be a non-zero 3-vector")
    return p, d / np.linalg.norm(d)


def axis_frame(axis_dir=(0.0, 0.0, 1.0)) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Right-handed orthonormal ``(e1, e2, d)`` with ``d`` along the axis; ``e1`` is the x (or,
    for an axis near x, the y) direction made perpendicular to ``d`` (for the z axis: x, y, z)."""
    _, d = _axis((0.0, 0.0), axis_dir)
    helper = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = helper - (helper @ d) * d
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(d, e1), d


@dataclass
class _Frame:
    e1: np.ndarray
    e2: np.ndarray
    d: np.ndarray
    xi: np.ndarray                  # (n,) coordinate along e1 from the axis, m
    eta: np.ndarray
    s: np.ndarray                   # (n,) coordinate along the axis, m
    r: np.ndarray
    er: np.ndarray                  # (n, 3) radial unit vectors (e1 on the axis)
    et: np.ndarray                  # (n, 3) tangential unit vectors (e2 on the axis)
    on_axis: np.ndarray             # (n,) bool
    slab: np.ndarray                # (n,) slab index
    n_slabs: int


def _unit_vectors(x: np.ndarray, p0, e1, e2, r_max: float):
    """Radial and tangential unit vectors at points ``x`` (..., 3): ``(xi, eta, r, er, et,
    on_axis)``; on the axis (r <= 1e-6 r_max) ``er = e1``, ``et = e2``."""
    rel = x - p0
    xi, eta = rel @ e1, rel @ e2
    r = np.hypot(xi, eta)
    on_axis = r <= _AXIS_EPS * max(r_max, 1e-300)
    rs = np.where(on_axis, 1.0, r)
    cos, sin = np.where(on_axis, 1.0, xi / rs), np.where(on_axis, 0.0, eta / rs)
    er = cos[..., None] * e1 + sin[..., None] * e2
    et = -sin[..., None] * e1 + cos[..., None] * e2
    return xi, eta, r, er, et, on_axis


def _key(axis_point, axis_dir) -> tuple:
    p0, d = _axis(axis_point, axis_dir)
    return tuple(p0), tuple(d)


def _frame(mesh, axis_point, axis_dir) -> _Frame:
    ctx = mesh_context(mesh)
    key = _key(axis_point, axis_dir)
    if key in ctx.frames:
        return ctx.frames[key]
    p0 = np.array(key[0])
    e1, e2, d = axis_frame(key[1])
    r_max = float(np.hypot((ctx.nodes - p0) @ e1, (ctx.nodes - p0) @ e2).max(initial=0.0))
    xi, eta, r, er, et, on_axis = _unit_vectors(ctx.nodes, p0, e1, e2, r_max)
    s = (ctx.nodes - p0) @ d
    # axial slabs: distinct levels for extruded meshes, else bins of half a mean edge; on a mesh
    # swept in part (a free coupler on a swept drill) the nodes of thinly populated levels go to
    # bins too: a slab of a node or two cannot carry the fit (the minimum-norm solution would call
    # its axial motion a tilt, i.e. bending)
    span = max(np.ptp(s) if s.size else 0.0, 1e-300)
    levels, slab = np.unique(np.round((s - s.min()) / span * 1e9), return_inverse=True)
    slab = slab.ravel()
    sparse = np.bincount(slab)[slab] < MIN_SLAB_NODES
    if len(levels) > len(s) / 4 or sparse.any():
        edges = ctx.sk.p[:, ctx.sk.edges]
        h = 0.5 * np.mean(np.linalg.norm(edges[:, 0] - edges[:, 1], axis=0))
        bins = np.floor((s - s.min()) / h).astype(np.int64)
        if len(levels) > len(s) / 4:
            slab = bins
        else:
            slab = np.where(sparse, len(levels) + bins, slab)
        _, slab = np.unique(slab, return_inverse=True)
    slab = slab.ravel()
    fr = _Frame(e1=e1, e2=e2, d=d, xi=xi, eta=eta, s=s, r=r, er=er, et=et, on_axis=on_axis,
                slab=slab, n_slabs=int(slab.max()) + 1 if slab.size else 0)
    ctx.frames[key] = fr
    return fr


MIN_SLAB_NODES = 8
"""Fewest nodes of an axial level that makes it a slab of its own (the in-plane fit has 8 columns
over 2 components a node, at least 4 nodes; twice that keeps it overdetermined)."""


def _project(fr: _Frame, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Node-wise ``(u.e_axis, u.e_theta, u.e_r)`` of u (k, n, 3), on the axis along (e2, e1)."""
    return u @ fr.d, np.einsum("knc,nc->kn", u, fr.et), np.einsum("knc,nc->kn", u, fr.er)


def cylindrical_components(mesh, shapes, *, axis_point=(0.0, 0.0), axis_dir=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Node-wise (axial, tangential, radial) components, ``(n_modes, n_nodes, 3)``, in the
    shapes' units.

    On the axis (r < 1e-6 r_max) the tangential component is 0 and the radial one is the
    in-plane motion along ``e1`` of :func:`axis_frame`.
    """
    u = check_shapes(mesh, shapes)
    fr = _frame(mesh, axis_point, axis_dir)
    ua, ut, ur = _project(fr, u)
    ut[:, fr.on_axis] = 0.0
    return np.stack([ua, ut, ur], axis=-1)


# --------------------------------------------------------------------------- decomposition


def _slab_fit(fr: _Frame, w: np.ndarray, y: np.ndarray, cols: np.ndarray,
              groups: Sequence[Sequence[int]]) -> list[np.ndarray]:
    """Per slab, joint weighted least-squares fit of ``y`` (k, n, c) on the model columns
    ``cols`` (n, c, q); returns the fitted contribution of each group of columns, (k, n, c) each.

    The fit is joint over all columns, so a field inside the model's span is reproduced exactly
    whatever the (mesh-dependent) weights.
    """
    k, n, c = y.shape
    q = cols.shape[2]
    out = [np.zeros(y.shape, dtype=y.dtype) for _ in groups]
    counts = np.bincount(fr.slab, minlength=fr.n_slabs)
    order = np.argsort(fr.slab, kind="stable")
    bounds = np.concatenate([[0], np.cumsum(counts)])
    dtype = np.result_type(y, float)
    # slabs of one node count are fitted together (swept meshes have thousands of levels: a
    # Python loop over them took 3 s); minimum-norm least squares through a batched thin SVD
    for m in np.unique(counts[counts > 0]):
        slabs = np.flatnonzero(counts == m)
        idx = order[bounds[slabs][:, None] + np.arange(m)]              # (B, m)
        sw = np.sqrt(w[idx])[:, :, None, None]                            # (B, m, 1, 1)
        A = (cols[idx] * sw).reshape(len(slabs), m * c, q)                # (B, m c, q)
        scale = np.linalg.norm(A, axis=1)                                 # (B, q)
        keep = scale > 1e-12 * np.maximum(scale.max(axis=1, initial=0.0), 1e-300)[:, None]
        rhs = (y[:, idx, :] * sw[None, :, :, :, 0]).reshape(k, len(slabs), m * c).transpose(1, 2, 0)
        patterns, which = np.unique(keep, axis=0, return_inverse=True)
        which = which.ravel()
        for p, pat in enumerate(patterns):
            if not pat.any():
                continue
            b = np.flatnonzero(which == p)
            As = A[b][:, :, pat] / scale[b][:, None, pat]
            U, S, Vt = np.linalg.svd(As, full_matrices=False)
            ok = S > 1e-10 * S[:, :1]
            Sinv = np.where(ok, 1.0 / np.where(ok, S, 1.0), 0.0)
            sol = np.einsum("bji,bj,bjk->bik", Vt, Sinv, np.einsum("bmj,bmk->bjk", U, rhs[b]))
            coef = np.zeros((len(b), q, k), dtype=dtype)
            coef[:, pat] = sol / scale[b][:, pat, None]
            ib = idx[b]
            for g, cols_g in enumerate(groups):
                out[g][:, ib.ravel(), :] = np.einsum("bncq,bqk->kbnc", cols[ib][:, :, :, cols_g],
                                                    coef[:, cols_g]).reshape(k, -1, c)
    return out


def _decompose(fr: _Frame, w: np.ndarray, u: np.ndarray, axisymmetric: bool = False) -> dict[str, np.ndarray]:
    """Split (k, n, 3) shapes into scalar nodal fields per category, (k, n, c) each (the
    category's energy is the sum over its c fields); ``w`` are the slab-fit weights.

    ``axisymmetric``: the shapes are one sector's of fields unchanged by the drill's symmetry
    (:mod:`fem.sector_system`), which hold no m = 1 motion: no translation or tilt is fitted (on
    a sector they would not be orthogonal to the twist and the breathing)."""
    u1, u2, ua = u @ fr.e1, u @ fr.e2, u @ fr.d           # (k, n) each
    n = len(fr.s)
    one, zero = np.ones(n), np.zeros(n)
    rho = fr.r / max(fr.r.max(initial=0.0), 1e-300)
    cos, sin = fr.er @ fr.e1, fr.er @ fr.e2
    # in-plane model per slab: translation (m = 1), twist r (c0 + c1 r + c2 r^2) e_theta (m = 0),
    # breathing r (d0 + d1 r + d2 r^2) e_r (m = 0)
    cols = [] if axisymmetric else [np.column_stack([one, zero]), np.column_stack([zero, one])]
    for p in (1, 2, 3):
        cols.append(np.column_stack([-sin, cos]) * rho[:, None] ** p)
    for p in (1, 2, 3):
        cols.append(np.column_stack([cos, sin]) * rho[:, None] ** p)
    m1 = 0 if axisymmetric else 2
    trans, twist = _slab_fit(fr, w, np.stack([u1, u2], axis=-1), np.stack(cols, axis=-1),
                             [list(range(m1)), [m1, m1 + 1, m1 + 2]])
    if axisymmetric:
        tilt = np.zeros(ua.shape + (1,), dtype=np.result_type(ua, float))
    else:
        # axial model per slab: piston + tilt (m = 1 of the axial motion, the section rotation)
        (tilt,) = _slab_fit(fr, w, ua[:, :, None], np.stack([one, fr.xi, fr.eta], axis=-1)[:, None, :], [[1, 2]])
    bending = trans[:, :, 0, None] * fr.e1 + trans[:, :, 1, None] * fr.e2 + tilt * fr.d
    va, vt, vr = _project(fr, u - bending)
    tors = -twist[:, :, 0] * sin + twist[:, :, 1] * cos
    tors[:, fr.on_axis] = 0.0
    return {"axial": va[..., None], "torsional": tors[..., None],
            "bending": np.stack([trans[:, :, 0], trans[:, :, 1], tilt[:, :, 0]], axis=-1),
            "radial": np.stack([vr, vt - tors], axis=-1)}


@dataclass(frozen=True)
class Shares:
    """Kinetic-energy fractions per mode (each an ``(n_modes,)`` array; the four sum to 1)."""

    axial: np.ndarray
    torsional: np.ndarray
    bending: np.ndarray
    radial: np.ndarray

    @property
    def lateral(self) -> np.ndarray:
        """Bending + radial: everything that is neither axial nor torsional."""
        return self.bending + self.radial

    def as_dict(self, i: int) -> dict[str, float]:
        return {k: float(getattr(self, k)[i]) for k in ("axial", "torsional", "bending", "radial", "lateral")}

    def table(self, names: Sequence[str] = ("axial", "torsional", "lateral")) -> np.ndarray:
        """``(n_modes, len(names))`` array of the named shares (default axial, torsional, lateral)."""
        return np.column_stack([getattr(self, k) for k in names])


@dataclass(frozen=True)
class ModeShares:
    """Result of :func:`energy_shares`.

    Attributes
    ----------
    overall : Shares
        Shares over the whole mesh.
    parts : dict of str to Shares
        Shares within each part (``TaggedMesh`` ``region.part``), normalised per part.
    part_energy : dict of str to (n_modes,) array
        Fraction of the mode's kinetic energy that lies in each part (sums to 1).
    rigid : (n_modes,) array
        Fraction of the kinetic energy in the six rigid-body motions (mass-orthogonal projection).
    closure : (n_modes,) array
        Sum of the component energies over the Cartesian kinetic energy ``u^T M u``.
    energy : (n_modes,) array
        ``u^T M u`` in kg m^2 per unit^2 of shape (kinetic energy / omega^2 * 2); 1 for the
        mass-normalised shapes of :func:`fem.modal.modal_analysis` with their system.
    """

    overall: Shares
    parts: dict
    part_energy: dict
    rigid: np.ndarray
    closure: np.ndarray
    energy: np.ndarray

    def __len__(self) -> int:
        return len(self.rigid)

    # convenience accessors for the overall shares
    @property
    def axial(self) -> np.ndarray:
        return self.overall.axial

    @property
    def torsional(self) -> np.ndarray:
        return self.overall.torsional

    @property
    def bending(self) -> np.ndarray:
        return self.overall.bending

    @property
    def radial(self) -> np.ndarray:
        return self.overall.radial

    @property
    def lateral(self) -> np.ndarray:
        return self.overall.lateral

    def records(self) -> list[dict]:
        """One JSON-friendly dict per mode (overall, per part, rigid fraction, label)."""
        labels = classify(self)
        out = []
        for i in range(len(self)):
            out.append({
                "label": labels[i],
                **self.overall.as_dict(i),
                "rigid": float(self.rigid[i]),
                "parts": {p: {**s.as_dict(i), "energy": float(self.part_energy[p][i])}
                          for p, s in self.parts.items()},
            })
        return out


def _rigid_modes(nodes: np.ndarray, axisymmetric: bool = False) -> np.ndarray:
    """The six rigid-body fields (3 translations, 3 rotations about the centroid), (6, n, 3);
    ``axisymmetric``: the two a sector's axisymmetric fields hold (along and about the z axis)."""
    x = nodes - nodes.mean(axis=0)
    if axisymmetric:
        x[:, :2] = nodes[:, :2]
    R = np.zeros((6, len(x), 3))
    for c in range(3):
        R[c, :, c] = 1.0
        R[3 + c] = np.cross(np.eye(3)[c], x) / max(np.abs(x).max(), 1e-300)
    return R[[2, 5]] if axisymmetric else R


def _rigid_fraction(M, nodes: np.ndarray, u: np.ndarray, axisymmetric: bool = False) -> np.ndarray:
    """Energy fraction of each shape in span{3 translations, 3 rotations} (mass metric)."""
    R = _rigid_modes(nodes, axisymmetric)
    C = _gram(M, R, u)                                   # (6, k)
    proj = np.real(np.einsum("pk,pk->k", np.conj(C), np.linalg.solve(np.real(_gram(M, R, R)), C)))
    return _ratio(proj, _energy(M, u))


def energy_shares(mesh, shapes, *, axis_point=(0.0, 0.0), axis_dir=(0.0, 0.0, 1.0)) -> ModeShares:
    """Kinetic-energy shares of each mode in axial, torsional, bending and radial motion.

    Parameters
    ----------
    mesh : TaggedMesh or PiezoSystem
        A system contributes its own mass matrix (see :func:`mass_matrix`).
    shapes : (n_modes, n_nodes, 3) or (n_nodes, 3) array
        Displacement at the nodes (:func:`p2_nodes`); any normalisation; real or complex.
    axis_point : 2 or 3 floats, m
        A point of the drill axis (``(x, y)`` in the z = 0 plane, or a 3D point).
    axis_dir : 3 floats
        Direction of the drill axis.

    Returns
    -------
    ModeShares
        Overall and per-part shares, part energy fractions, rigid-body fraction. See the module
        docstring for the decomposition (node-wise cylindrical projection, m = 1 slab fit for
        bending, m = 0 fit of the tangential motion for torsion).
    """
    u = check_shapes(mesh, shapes)
    M = mass_matrix(mesh)
    parts = {p: Mp for p, Mp in _masses(mesh).items() if p is not None}
    axisymmetric = getattr(mesh, "sector", None) is not None           # fem.sector_system
    fields = _decompose(_frame(mesh, axis_point, axis_dir), np.maximum(M.diagonal(), 0.0), u, axisymmetric)

    def shares_in(Mp):
        E = {c: _energy(Mp, f) for c, f in fields.items()}
        tot = sum(E.values())
        return Shares(**{c: _ratio(E[c], tot) for c in E}), tot

    overall, tot = shares_in(M)
    cart = _energy(M, u)
    return ModeShares(overall=overall, parts={p: shares_in(Mp)[0] for p, Mp in parts.items()},
                      part_energy={p: _ratio(_energy(Mp, u), cart) for p, Mp in parts.items()},
                      rigid=_rigid_fraction(M, mesh_context(mesh).nodes, u, axisymmetric),
                      closure=_ratio(tot, cart, empty=1.0), energy=cart)


def classify(shares: ModeShares | Shares, *, part: str | None = None,
             rigid: float = THRESHOLDS["rigid"], coupled: float = THRESHOLDS["coupled"]) -> list[str]:
    """One label per mode from :data:`LABELS`.

    Rules, in order (energy fractions):

    1. ``rigid`` if the rigid-body fraction is >= ``rigid`` (0.95) — whole-mesh shares only;
    2. ``longitudinal-torsional`` if axial >= ``coupled`` and torsional >= ``coupled`` (0.15);
    3. otherwise the largest of axial (``longitudinal``), torsional (``torsional``) and lateral
       (bending + radial); a lateral mode is ``bending`` if bending >= radial, else ``radial``.

    ``part`` labels the motion within one part (e.g. ``"coupler"``) instead of the whole.
    """
    rigid_frac = None
    if isinstance(shares, ModeShares):
        if part is not None:
            if part not in shares.parts:
                raise ParameterError("part", part, "unknown; known: " + ", ".join(shares.parts))
            s = shares.parts[part]
        else:
            s = shares.overall
            rigid_frac = shares.rigid
    elif isinstance(shares, Shares):
        s = shares
    else:
        raise ParameterError("shares", type(shares).__name__, "must be ModeShares or Shares")
    labels = []
    for i in range(len(s.axial)):
        a, t, b, r = s.axial[i], s.torsional[i], s.bending[i], s.radial[i]
        if rigid_frac is not None and rigid_frac[i] >= rigid:
            labels.append("rigid")
        elif a >= coupled and t >= coupled:
            labels.append("longitudinal-torsional")
        elif b + r > max(a, t):
            labels.append("bending" if b >= r else "radial")
        else:
            labels.append("longitudinal" if a >= t else "torsional")
    return labels


# --------------------------------------------------------------------------- effective mass, MAC


def total_mass(mesh) -> float:
    """Mass in kg from the mass matrix: ``1^T M 1`` (the kinetic energy x 2 of a unit rigid
    translation)."""
    M = mass_matrix(mesh)
    one = np.ones(M.shape[0])
    return float(one @ (M @ one))


def effective_mass_axial(mesh, shapes, *, axis_dir=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Effective modal mass along the axis, kg: ``(phi^T M r)^2 / (phi^T M phi)`` for the unit
    rigid translation ``r`` along ``axis_dir``; sums to the total mass over a complete basis.

    Meaningful for a supported structure (e.g. clamped at the flange). In a free-free model the
    elastic modes are mass-orthogonal to the rigid translation, so their effective mass is 0
    and the whole mass sits in the rigid modes; use :func:`equivalent_mass` there.
    """
    u = check_shapes(mesh, shapes)
    _, d = _axis((0.0, 0.0), axis_dir)
    M = mass_matrix(mesh)
    r = np.broadcast_to(d, u.shape[1:])[None]
    return _ratio(np.abs(_gram(M, r, u)[0]) ** 2, _energy(M, u))


def equivalent_mass(mesh, shapes, surface: str, *, axis_point=(0.0, 0.0),
                    axis_dir=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Modal mass referred to the mean axial motion of a surface, kg:
    ``(phi^T M phi) / w^2`` with ``w`` the area-weighted mean axial displacement on ``surface``
    (e.g. ``"horn_tip"``). This is the lumped mass that, moving like the surface, carries the
    mode's kinetic energy; for a uniform free-free rod's first longitudinal mode it is half the
    rod's mass. ``inf`` when the surface has no net axial motion.

    Unlike :func:`effective_mass_axial` it is non-zero for the elastic modes of a free-free
    structure (which are mass-orthogonal to the rigid translation).
    """
    u = check_shapes(mesh, shapes)
    rows, _ = surface_rows(mesh, surface, axis_point=axis_point, axis_dir=axis_dir)
    w = np.abs(u.reshape(len(u), -1) @ rows[0].toarray().ravel())
    den = _energy(mass_matrix(mesh), u)
    return np.where(w > 0, den / np.where(w > 0, w, 1.0) ** 2, np.inf)


def mac(shapes_a, shapes_b, *, mesh=None) -> np.ndarray:
    """Modal assurance criterion ``|a^H W b|^2 / ((a^H W a)(b^H W b))``, shape ``(na, nb)``.

    ``W`` is the identity (plain MAC) or, with ``mesh`` (a TaggedMesh or a PiezoSystem), the
    mass matrix of :func:`mass_matrix` applied per component (mass-weighted MAC; the shapes
    must then be at that field's nodes). Both sets must have the same nodes; see
    :func:`match_modes` for shapes on different meshes.
    """
    if mesh is not None:
        a = check_shapes(mesh, shapes_a, "shapes_a")
        b = check_shapes(mesh, shapes_b, "shapes_b")
        M = mass_matrix(mesh)
    else:
        a, b = np.asarray(shapes_a), np.asarray(shapes_b)
        a = a[None] if a.ndim == 2 else a
        b = b[None] if b.ndim == 2 else b
        if a.ndim != 3 or b.ndim != 3 or a.shape[1:] != b.shape[1:] or a.shape[2] != 3:
            raise ParameterError("shapes", (np.shape(shapes_a), np.shape(shapes_b)),
                                 "must both be (n_modes, n_nodes, 3) on the same nodes")
        M = None
    return _ratio(np.abs(_gram(M, a, b)) ** 2, np.outer(_energy(M, a), _energy(M, b)))


@dataclass(frozen=True)
class ModeMatch:
    """Result of :func:`match_modes`.

    Attributes
    ----------
    index : (na,) int array
        For each mode of design A, the matched mode of design B, or -1 if none reaches
        ``min_mac``.
    mac : (na,) array
        MAC of each matched pair (0 where unmatched).
    matrix : (na, nb) array
        The full MAC matrix.
    method : str
        ``"same-nodes"`` or ``"nearest"`` (normalised-coordinate interpolation).
    """

    index: np.ndarray
    mac: np.ndarray
    matrix: np.ndarray
    method: str


def _normalised(nodes: np.ndarray, p0: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Nodes in axis-aligned coordinates scaled to [0, 1] along the axis and r_max = 1 across."""
    e1, e2, d = axis_frame(d)
    rel = nodes - p0
    x, y, s = rel @ e1, rel @ e2, rel @ d
    rmax = max(np.hypot(x, y).max(), 1e-300)
    return np.column_stack([x / rmax, y / rmax, (s - s.min()) / max(np.ptp(s), 1e-300)])


def match_modes(mesh_a, shapes_a, mesh_b, shapes_b, *,
                method: str = "auto", min_mac: float = 0.5, k_neighbours: int = 4,
                axis_point=(0.0, 0.0), axis_dir=(0.0, 0.0, 1.0)) -> ModeMatch:
    """Match the modes of design A to those of design B by shape (one-to-one, max total MAC).

    ``mesh_a``, ``mesh_b``: TaggedMesh or PiezoSystem each. ``method``:

    - ``"same-nodes"``: the meshes share topology (e.g. a morphed mesh: same cells, moved
      points); the mass-weighted MAC on mesh A is used directly;
    - ``"nearest"``: the meshes differ; B's shapes are interpolated onto A's nodes in
      *normalised coordinates* (axial coordinate scaled to [0, 1], transverse coordinates by
      the largest radius) by inverse-distance weighting of the ``k_neighbours`` nearest B
      nodes (scipy cKDTree), then the mass-weighted MAC on mesh A is used. Shapes are compared
      in the same normalised sense, so a 10 % longer horn still matches mode by mode;
    - ``"auto"``: ``"same-nodes"`` if both meshes have identical cells, else ``"nearest"``.

    The assignment maximises the summed MAC (Hungarian algorithm); pairs below ``min_mac`` are
    reported as unmatched (-1).
    """
    from scipy.optimize import linear_sum_assignment
    from scipy.spatial import cKDTree

    if method not in ("auto", "same-nodes", "nearest"):
        raise ParameterError("method", method, "must be 'auto', 'same-nodes' or 'nearest'")
    a = check_shapes(mesh_a, shapes_a, "shapes_a")
    b = check_shapes(mesh_b, shapes_b, "shapes_b")
    ta, tb = _mesh_of(mesh_a), _mesh_of(mesh_b)
    same = ta.cells.shape == tb.cells.shape and np.array_equal(ta.cells, tb.cells)
    if method == "auto":
        method = "same-nodes" if same else "nearest"
    if method == "same-nodes":
        if a.shape[1] != b.shape[1]:
            raise ParameterError("method", "same-nodes", "needs meshes with the same nodes; use 'nearest'")
        b_on_a = b
    else:
        p0, d = _axis(axis_point, axis_dir)
        xa = _normalised(p2_nodes(mesh_a), p0, d)
        xb = _normalised(p2_nodes(mesh_b), p0, d)
        k = int(min(max(k_neighbours, 1), len(xb)))
        dist, idx = cKDTree(xb).query(xa, k=k)
        dist, idx = dist.reshape(len(xa), k), idx.reshape(len(xa), k)
        wts = 1.0 / np.maximum(dist, 1e-12)
        exact = dist[:, 0] < 1e-12
        wts[exact] = 0.0
        wts[exact, 0] = 1.0
        wts /= wts.sum(axis=1, keepdims=True)
        b_on_a = np.einsum("nk,mnkc->mnc", wts, b[:, idx, :])
    matrix = mac(a, b_on_a, mesh=mesh_a)
    rows, cols = linear_sum_assignment(-matrix)
    index = np.full(len(a), -1, dtype=np.int64)
    value = np.zeros(len(a))
    for i, j in zip(rows, cols):
        if matrix[i, j] >= min_mac:
            index[i], value[i] = j, matrix[i, j]
    return ModeMatch(index=index, mac=value, matrix=matrix, method=method)


# --------------------------------------------------------------------------- surface motion


@dataclass(frozen=True)
class _Surface:
    basis: object                   # vector FacetBasis on the surface
    directions: np.ndarray          # (3 components, 3 xyz, n_facets, n_qp): e_axis, e_theta, e_r
    dx: np.ndarray                  # (n_facets, n_qp) quadrature weights, m^2
    area: float                     # m^2
    rows: sp.csr_matrix             # (3, 3 n_nodes): the area-weighted means
    n_nodes: int


def _surface(mesh, surface: str, axis_point, axis_dir) -> _Surface:
    ctx = mesh_context(mesh)
    if not isinstance(surface, str) or surface not in ctx.mesh.facet_sets:
        raise ParameterError("surface", surface, "unknown; known: " + ", ".join(sorted(ctx.mesh.facet_sets)))
    key = (surface, _key(axis_point, axis_dir))
    if key in ctx.surfaces:
        return ctx.surfaces[key]
    from skfem import ElementVector, LinearForm
    from skfem.helpers import dot

    from .facets import facet_basis

    facets = ctx.sk.boundaries[surface]
    if len(facets) == 0:
        raise ParameterError("surface", surface, "is empty")
    fb = facet_basis(ctx.sk, ElementVector(ctx.basis.elem), facets)
    fr = _frame(mesh, axis_point, axis_dir)
    x = np.moveaxis(np.asarray(fb.global_coordinates()), 0, -1)            # (nf, nq, 3)
    p0, _ = _axis(axis_point, axis_dir)
    *_, er, et, on_axis = _unit_vectors(x, p0, fr.e1, fr.e2, fr.r.max(initial=0.0))
    et = np.where(on_axis[..., None], 0.0, et)          # no tangential direction on the axis
    ea = np.broadcast_to(fr.d, et.shape)
    directions = np.moveaxis(np.stack([ea, et, er]), -1, 1)                # (3, 3, nf, nq)

    @LinearForm
    def mean_along(v, w):
        return dot(w["e"], v)

    dx = np.asarray(fb.dx)
    area = float(dx.sum())
    rows = sp.csr_matrix(np.stack([mean_along.assemble(fb, e=e) for e in directions]) / area)
    n_nodes = int(len(np.unique(ctx.basis.get_dofs(facets).all())))
    out = _Surface(basis=fb, directions=directions, dx=dx, area=area, rows=rows, n_nodes=n_nodes)
    ctx.surfaces[key] = out
    return out


def surface_rows(mesh, surface: str, *, axis_point=(0.0, 0.0), axis_dir=(0.0, 0.0, 1.0)) -> tuple[sp.csr_matrix, float]:
    """The area-weighted mean (axial, tangential, radial) displacement on a facet set as a
    linear map: ``(rows, area)``.

    ``rows`` is a sparse ``(3, 3 n_nodes)`` matrix on the nodal displacement flattened as
    ``u.ravel()`` (node ``k``, component ``c`` at ``3 k + c``: the u DOFs of a system):
    ``rows @ u.ravel()`` gives ``(1/A) integral u.e_c dA`` in the displacement's units, the
    displacement interpolated and projected on the cylindrical unit vectors at the surface's
    quadrature points (tangential 0 on the axis). ``area`` ``A`` in m^2.
    """
    s = _surface(mesh, surface, axis_point, axis_dir)
    return s.rows, s.area


def surface_motion(mesh, shape, surface: str, *, axis_point=(0.0, 0.0),
                   axis_dir=(0.0, 0.0, 1.0)) -> dict:
    """Area-weighted motion of one mode on a facet set (e.g. ``"teeth_tops"``, ``"horn_tip"``).

    The displacement is interpolated at the quadrature points of the surface (scikit-fem
    ``FacetBasis``), projected there on the local cylindrical unit vectors, and integrated
    (the means are :func:`surface_rows` applied to the shape).

    Returns a dict (lengths in the shape's units; m for a physical response):

    ``axial``, ``tangential``, ``radial``
        Mean amplitude ``(1/A) * integral |u_c| dA`` of each component.
    ``axial_mean``, ``tangential_mean``, ``radial_mean``
        Signed mean ``(1/A) * integral u_c dA`` (net piston motion, net rotation x r, ...);
        for complex shapes the modulus of the complex mean.
    ``axial_rms``, ``tangential_rms``, ``radial_rms``, ``max_magnitude``
        Root-mean-square of each component over the surface, and the largest displacement
        magnitude at its quadrature points.
    ``ellipse_ratio``
        ``tangential / axial`` (mean amplitudes), the aspect of the tooth-top ellipse; ``inf``
        if the surface has no axial motion.
    ``phase_deg``
        For complex shapes, the phase of the tangential mean relative to the axial mean
        (degrees; 0 or 180 for a real mode shape, whose "ellipse" degenerates to a line).
    ``area``, ``n_nodes``, ``surface``
        Surface area (m^2), nodes on the surface, and the facet set's name.
    """
    u = check_shapes(mesh, shape, "shape")
    if u.shape[0] != 1:
        raise ParameterError("shape", np.shape(shape), "must be one mode, (n_nodes, 3)")
    s = _surface(mesh, surface, axis_point, axis_dir)
    U = np.asarray(s.basis.interpolate(u[0].ravel()))                      # (3, nf, nq)
    means = s.rows @ u[0].ravel()
    out = {"surface": surface, "area": s.area}
    for name, e, mean in zip(COMPONENTS, s.directions, means):
        f = np.einsum("cfq,cfq->fq", e, U)
        out[name] = float((np.abs(f) * s.dx).sum() / s.area)
        out[f"{name}_mean"] = complex(mean)
        out[f"{name}_rms"] = float(np.sqrt((np.abs(f) ** 2 * s.dx).sum() / s.area))
    am, tm = out["axial_mean"], out["tangential_mean"]
    out["phase_deg"] = float(np.degrees(np.angle(tm / am))) if abs(am) > 0 and abs(tm) > 0 else 0.0
    for name in COMPONENTS:
        v = out[f"{name}_mean"]
        out[f"{name}_mean"] = float(v.real) if not np.iscomplexobj(u) else float(abs(v))
    out["max_magnitude"] = float(np.sqrt((np.abs(U) ** 2).sum(axis=0)).max())
    out["ellipse_ratio"] = out["tangential"] / out["axial"] if out["axial"] > 0 else float("inf")
    out["n_nodes"] = s.n_nodes
    return out
