"""Mode identification: kinetic-energy shares, labels, axial effective mass, MAC, surface motion.

Every function takes mode shapes as **nodal displacement at the P2 nodes** of the tagged mesh,
an array ``(n_modes, n_nodes, 3)`` (a single ``(n_nodes, 3)`` shape is accepted too), where the
nodes are the scalar P2 DOF locations of ``mesh.to_skfem()``::

    skfem.Basis(mesh.to_skfem(), skfem.ElementTetP2()).doflocs.T   # == p2_nodes(mesh)

(vertices first, in skfem's corner numbering, then edge midpoints). This is independent of the
DOF layout of whatever solver produced the shapes.

Energy decomposition (:func:`energy_shares`)
--------------------------------------------
Kinetic energies use the consistent, density-weighted scalar P2 mass matrix ``M`` (assembled
per part with scikit-fem, densities from the material library), applied to each scalar
component: ``E(f) = f^T M f``. The displacement is split, **node by node**, into:

1. *bending* (circumferential order m = 1): per axial slab of nodes, a weighted least-squares
   fit (weights: diagonal of ``M``) of the in-plane motion with a lateral translation
   ``(t1, t2)``, a twist ``r (c0 + c1 r + c2 r^2) e_theta`` and a breathing
   ``r (d0 + d1 r + d2 r^2) e_r`` (fitted jointly, so none leaks into another on an asymmetric
   mesh), and of the axial motion with a piston plus a cross-section tilt
   ``c + a1 x1 + a2 x2``; the bending field is ``t1 e1 + t2 e2 + (a1 x1 + a2 x2) e_axis``;
2. of the rest ``u'``, the node-wise local cylindrical components about the axis
   (``e_axis``, ``e_r``, ``e_theta = e_axis x e_r``):

   - *axial*: ``u'.e_axis`` (longitudinal motion, incl. Poisson-free warping);
   - *torsional*: the axisymmetric (m = 0) part of ``u'.e_theta``, the twist fitted above
     (rigid rotation of the section and any radial variation of it);
   - *radial*: the in-plane remainder ``u'.e_r`` and ``u'.e_theta - torsional`` (breathing,
     ovalling and higher circumferential orders).

   Nodes on the axis (``r < 1e-6 * r_max``) have no tangential direction: their in-plane
   motion counts as radial (torsional = 0 there).

Shares are the four energies divided by their sum; ``lateral = bending + radial``. The sum
differs from the Cartesian kinetic energy ``u^T M u`` only by cross terms of the node-wise
projection (``closure`` reports the ratio; 1 to round-off for the synthetic fields of the tests,
a few per cent at most on real modes). Slabs are the distinct axial node levels when the mesh is
extruded/structured (<= n_nodes/4 levels), otherwise bins half a mean edge long.
"""

from __future__ import annotations

import weakref
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from geometry.common import ParameterError
from geometry.mesh import TaggedMesh

__all__ = [
    "LABELS",
    "THRESHOLDS",
    "Shares",
    "ModeShares",
    "ModeMatch",
    "p2_nodes",
    "check_shapes",
    "energy_shares",
    "classify",
    "effective_mass_axial",
    "total_mass",
    "equivalent_mass",
    "mac",
    "match_modes",
    "cylindrical_components",
    "surface_motion",
]

LABELS = ("longitudinal", "torsional", "longitudinal-torsional", "bending", "radial", "rigid")

THRESHOLDS = {
    # a mode whose kinetic energy lies >= 95 % in the six rigid-body motions is "rigid"
    "rigid": 0.95,
    # "longitudinal-torsional" when axial and torsional shares both reach 15 %
    "coupled": 0.15,
}
"""Thresholds used by :func:`classify` (energy fractions)."""

_AXIS_EPS = 1e-6


# --------------------------------------------------------------------------- context (cached per mesh)


@dataclass
class _Context:
    sk: object                      # skfem MeshTet1/MeshTet2 with tags
    basis: object                   # scalar P2 basis
    nodes: np.ndarray               # (n, 3)
    mass_parts: dict                # part -> scalar P2 mass matrix (csr, density-weighted)
    mass: sp.csr_matrix             # sum over parts
    n_vertices: int
    frames: dict = field(default_factory=dict)   # (axis_point, axis_dir) -> _Frame


@dataclass
class _Frame:
    e1: np.ndarray
    e2: np.ndarray
    d: np.ndarray
    xi: np.ndarray                  # (n,) coordinate along e1 from the axis
    eta: np.ndarray
    s: np.ndarray                   # (n,) coordinate along the axis
    r: np.ndarray
    er: np.ndarray                  # (n, 3) radial unit vectors (e1 on the axis)
    et: np.ndarray                  # (n, 3) tangential unit vectors (e2 on the axis)
    on_axis: np.ndarray             # (n,) bool
    slab: np.ndarray                # (n,) slab index
    n_slabs: int


_CACHE: "weakref.WeakKeyDictionary[TaggedMesh, _Context]" = weakref.WeakKeyDictionary()


def _context(mesh: TaggedMesh) -> _Context:
    if not isinstance(mesh, TaggedMesh):
        raise ParameterError("mesh", type(mesh).__name__, "must be a geometry.mesh.TaggedMesh")
    ctx = _CACHE.get(mesh)
    if ctx is not None:
        return ctx
    from skfem import Basis, BilinearForm, ElementTetP2

    from geometry.materials import get_material

    sk = mesh.to_skfem()
    basis = Basis(sk, ElementTetP2())

    @BilinearForm
    def _mass(u, v, w):
        return w["rho"] * u * v

    rho_region = np.array([get_material(r.material).density for r in mesh.regions])
    rho_cell = rho_region[mesh.cell_region]
    mass_parts = {}
    for part in mesh.parts:
        cells = mesh.cells_in(part=part)
        pb = Basis(sk, ElementTetP2(), elements=cells)
        rho = rho_cell[pb.tind][:, None] * np.ones((1, pb.X.shape[1]))
        mass_parts[part] = _mass.assemble(pb, rho=rho).tocsr()
    total = sum(mass_parts.values()).tocsr()
    ctx = _Context(sk=sk, basis=basis, nodes=np.ascontiguousarray(basis.doflocs.T),
                   mass_parts=mass_parts, mass=total, n_vertices=sk.p.shape[1])
    _CACHE[mesh] = ctx
    return ctx


def p2_nodes(mesh: TaggedMesh) -> np.ndarray:
    """The (n_nodes, 3) P2 node coordinates the mode shapes refer to (vertices first)."""
    return _context(mesh).nodes


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


def _frame(mesh: TaggedMesh, axis_point, axis_dir) -> _Frame:
    ctx = _context(mesh)
    p0, d = _axis(axis_point, axis_dir)
    key = (tuple(p0), tuple(d))
    if key in ctx.frames:
        return ctx.frames[key]
    helper = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = helper - (helper @ d) * d
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(d, e1)
    rel = ctx.nodes - p0
    xi, eta, s = rel @ e1, rel @ e2, rel @ d
    r = np.hypot(xi, eta)
    rmax = r.max() if r.size else 0.0
    on_axis = r <= _AXIS_EPS * max(rmax, 1e-300)
    rs = np.where(on_axis, 1.0, r)
    cos, sin = np.where(on_axis, 1.0, xi / rs), np.where(on_axis, 0.0, eta / rs)
    er = cos[:, None] * e1 + sin[:, None] * e2
    et = -sin[:, None] * e1 + cos[:, None] * e2
    # axial slabs: distinct levels for extruded meshes, else bins of half a mean edge
    span = max(np.ptp(s) if s.size else 0.0, 1e-300)
    levels, slab = np.unique(np.round((s - s.min()) / span * 1e9), return_inverse=True)
    if len(levels) > len(s) / 4:
        sk = ctx.sk
        edges = sk.p[:, sk.edges]
        h = 0.5 * np.mean(np.linalg.norm(edges[:, 0] - edges[:, 1], axis=0))
        _, slab = np.unique(np.floor((s - s.min()) / h).astype(np.int64), return_inverse=True)
    slab = slab.ravel()
    fr = _Frame(e1=e1, e2=e2, d=d, xi=xi, eta=eta, s=s, r=r, er=er, et=et, on_axis=on_axis,
                slab=slab, n_slabs=int(slab.max()) + 1 if slab.size else 0)
    ctx.frames[key] = fr
    return fr


def check_shapes(mesh: TaggedMesh, shapes, name: str = "shapes", allow_complex: bool = True) -> np.ndarray:
    """Validate and return ``shapes`` as an ``(n_modes, n_nodes, 3)`` array.

    A single shape ``(n_nodes, 3)`` becomes ``(1, n_nodes, 3)``. Raises
    :class:`~geometry.common.ParameterError` for any other shape or non-finite values.
    """
    n = len(_context(mesh).nodes)
    try:
        a = np.asarray(shapes)
    except Exception:  # noqa: BLE001 - ragged input
        raise ParameterError(name, type(shapes).__name__, "must be an array") from None
    if a.ndim == 2:
        a = a[None]
    if a.ndim != 3 or a.shape[1:] != (n, 3) or a.shape[0] == 0:
        raise ParameterError(name, a.shape, f"must have shape (n_modes, {n}, 3): displacement at the "
                             f"{n} P2 nodes of the mesh")
    if not (np.issubdtype(a.dtype, np.number) and not np.issubdtype(a.dtype, np.bool_)):
        raise ParameterError(name, a.dtype, "must be numeric")
    if np.iscomplexobj(a) and not allow_complex:
        raise ParameterError(name, a.dtype, "must be real (pass .real of a complex response)")
    if not np.all(np.isfinite(a)):
        raise ParameterError(name, "non-finite", "must hold finite values only")
    return a if np.iscomplexobj(a) else a.astype(float, copy=False)


def _energy(M, f) -> np.ndarray:
    """Row-wise f^T M f for f of shape (k, n) (real part for complex f)."""
    return np.real(np.einsum("kn,kn->k", np.conj(f), (M @ f.T).T))


# --------------------------------------------------------------------------- decomposition


def _slab_fit(fr: _Frame, w: np.ndarray, y: np.ndarray, cols: np.ndarray,
              groups: Sequence[Sequence[int]]) -> list[np.ndarray]:
    """Per slab, joint weighted least-squares fit of ``y`` (k, n, c) on the model columns
    ``cols`` (n, c, q); returns the fitted contribution of each group of columns, (k, n, c) each.

    The fit is joint over all columns, so a field inside the model's span is reproduced exactly
    whatever the (mesh-dependent) weights.
    """
    k, n, c = y.shape
    out = [np.zeros(y.shape, dtype=y.dtype) for _ in groups]
    order = np.argsort(fr.slab, kind="stable")
    bounds = np.searchsorted(fr.slab[order], np.arange(fr.n_slabs + 1))
    for s in range(fr.n_slabs):
        idx = order[bounds[s]:bounds[s + 1]]
        if idx.size == 0:
            continue
        sw = np.sqrt(w[idx])[:, None, None]
        A = (cols[idx] * sw).reshape(idx.size * c, -1)                  # (m c, q)
        scale = np.linalg.norm(A, axis=0)
        keep = scale > 1e-12 * max(scale.max(initial=0.0), 1e-300)
        if not np.any(keep):
            continue
        coef = np.zeros((cols.shape[2], k), dtype=np.result_type(y, float))
        rhs = (y[:, idx, :] * sw[None, :, :, 0]).reshape(k, -1).T        # (m c, k)
        # minimum-norm least squares through a thin SVD (numpy's lstsq is ~50x slower here)
        U, S, Vt = np.linalg.svd(A[:, keep] / scale[keep], full_matrices=False)
        ok = S > 1e-10 * S[0]
        sol = Vt[ok].T @ ((U[:, ok].T @ rhs) / S[ok][:, None])
        coef[keep] = sol / scale[keep][:, None]
        for g, cols_g in enumerate(groups):
            out[g][:, idx, :] = np.einsum("ncq,qk->knc", cols[idx][:, :, cols_g], coef[cols_g])
    return out


def _decompose(mesh: TaggedMesh, u: np.ndarray, axis_point, axis_dir) -> dict[str, list[np.ndarray]]:
    """Split (k, n, 3) shapes into scalar nodal fields per category (lists of (k, n) arrays)."""
    ctx = _context(mesh)
    fr = _frame(mesh, axis_point, axis_dir)
    w = ctx.mass.diagonal()
    w = np.where(w > 0, w, 0.0)
    u1, u2, ua = u @ fr.e1, u @ fr.e2, u @ fr.d           # (k, n) each
    n = len(fr.s)
    one, zero = np.ones(n), np.zeros(n)
    rmax = max(fr.r.max(initial=0.0), 1e-300)
    rho = fr.r / rmax
    cos, sin = fr.er @ fr.e1, fr.er @ fr.e2
    # in-plane model per slab: translation (m = 1), twist r (c0 + c1 r + c2 r^2) e_theta (m = 0),
    # breathing r (d0 + d1 r + d2 r^2) e_r (m = 0)
    cols = [np.column_stack([one, zero]), np.column_stack([zero, one])]
    for p in (1, 2, 3):
        cols.append(np.column_stack([-sin, cos]) * rho[:, None] ** p)
    for p in (1, 2, 3):
        cols.append(np.column_stack([cos, sin]) * rho[:, None] ** p)
    trans, twist = _slab_fit(fr, w, np.stack([u1, u2], axis=-1), np.stack(cols, axis=-1),
                             [[0, 1], [2, 3, 4]])
    # axial model per slab: piston + tilt (m = 1 of the axial motion, the section rotation)
    (tilt,) = _slab_fit(fr, w, ua[:, :, None], np.stack([one, fr.xi, fr.eta], axis=-1)[:, None, :], [[1, 2]])
    tilt = tilt[:, :, 0]
    b1, b2 = trans[:, :, 0], trans[:, :, 1]
    v1, v2, va = u1 - b1, u2 - b2, ua - tilt
    vr = v1 * cos + v2 * sin
    vt = -v1 * sin + v2 * cos
    tors = -twist[:, :, 0] * sin + twist[:, :, 1] * cos
    tors[:, fr.on_axis] = 0.0
    return {"axial": [va], "torsional": [tors], "bending": [b1, b2, tilt], "radial": [vr, vt - tors]}


@dataclass(frozen=True)
class Shares:
    """Kinetic-energy fractions per mode (each an ``(n_modes,)`` array summing to 1)."""

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
        ``u^T M u`` in kg m^2 per unit^2 of shape (kinetic energy / omega^2 * 2).
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


def _rigid_fraction(ctx: _Context, u: np.ndarray) -> np.ndarray:
    """Energy fraction of each shape in span{3 translations, 3 rotations} (mass metric)."""
    M = ctx.mass
    x = ctx.nodes - ctx.nodes.mean(axis=0)
    n = len(x)
    R = np.zeros((6, n, 3))
    for c in range(3):
        R[c, :, c] = 1.0
    for c in range(3):
        axis = np.zeros(3)
        axis[c] = 1.0
        R[3 + c] = np.cross(axis, x) / max(np.abs(x).max(), 1e-300)

    def inner(a, b):  # a (p, n, 3), b (q, n, 3) -> (p, q)
        Mb = np.stack([(M @ b[:, :, c].T).T for c in range(3)], axis=-1)
        return np.einsum("pnc,qnc->pq", np.conj(a), Mb)

    G = np.real(inner(R, R))
    C = inner(R, u)                               # (6, k)
    E = np.real(np.einsum("knc,knc->k", np.conj(u), np.stack([(M @ u[:, :, c].T).T for c in range(3)], -1)))
    proj = np.real(np.einsum("pk,pk->k", np.conj(C), np.linalg.solve(G, C)))
    return np.where(E > 0, proj / np.where(E > 0, E, 1.0), 0.0)


def energy_shares(mesh: TaggedMesh, shapes, *, axis_point=(0.0, 0.0), axis_dir=(0.0, 0.0, 1.0)) -> ModeShares:
    """Kinetic-energy shares of each mode in axial, torsional, bending and radial motion.

    Parameters
    ----------
    mesh : TaggedMesh
    shapes : (n_modes, n_nodes, 3) or (n_nodes, 3) array
        Displacement at the P2 nodes (:func:`p2_nodes`); any normalisation; real or complex.
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
    ctx = _context(mesh)
    fields = _decompose(mesh, u, axis_point, axis_dir)
    cats = ("axial", "torsional", "bending", "radial")

    def shares_for(M):
        E = {c: sum(_energy(M, f) for f in fields[c]) for c in cats}
        tot = sum(E.values())
        safe = np.where(tot > 0, tot, 1.0)
        return Shares(**{c: np.where(tot > 0, E[c] / safe, 0.0) for c in cats}), tot

    overall, tot = shares_for(ctx.mass)
    cart = sum(_energy(ctx.mass, u[:, :, c]) for c in range(3))
    parts, part_e = {}, {}
    for p, Mp in ctx.mass_parts.items():
        parts[p], _ = shares_for(Mp)
        ep = sum(_energy(Mp, u[:, :, c]) for c in range(3))
        part_e[p] = np.where(cart > 0, ep / np.where(cart > 0, cart, 1.0), 0.0)
    closure = np.where(cart > 0, tot / np.where(cart > 0, cart, 1.0), 1.0)
    return ModeShares(overall=overall, parts=parts, part_energy=part_e, rigid=_rigid_fraction(ctx, u),
                      closure=closure, energy=cart)


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


def total_mass(mesh: TaggedMesh) -> float:
    """Mass of the mesh in kg from the consistent P2 mass matrix (1^T M 1)."""
    M = _context(mesh).mass
    one = np.ones(M.shape[0])
    return float(one @ (M @ one))


def effective_mass_axial(mesh: TaggedMesh, shapes, *, axis_dir=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Effective modal mass along the axis, kg: ``(phi^T M r)^2 / (phi^T M phi)`` for the unit
    rigid translation ``r`` along ``axis_dir``; sums to the total mass over a complete basis.

    Meaningful for a supported structure (e.g. clamped at the flange). In a free-free model the
    elastic modes are mass-orthogonal to the rigid translation, so their effective mass is 0
    and the whole mass sits in the rigid modes; use :func:`equivalent_mass` there.
    """
    u = check_shapes(mesh, shapes)
    _, d = _axis((0.0, 0.0), axis_dir)
    M = _context(mesh).mass
    one = np.ones(M.shape[0])
    Mone = M @ one
    num = np.abs((u @ d) @ Mone) ** 2
    den = sum(_energy(M, u[:, :, c]) for c in range(3))
    return np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)


def equivalent_mass(mesh: TaggedMesh, shapes, surface: str, *, axis_point=(0.0, 0.0),
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
    M = _context(mesh).mass
    den = sum(_energy(M, u[:, :, c]) for c in range(3))
    out = np.empty(len(u))
    for i in range(len(u)):
        w = surface_motion(mesh, u[i], surface, axis_point=axis_point, axis_dir=axis_dir)["axial_mean"]
        out[i] = den[i] / w**2 if w != 0 else np.inf
    return out


def mac(shapes_a, shapes_b, *, mesh: TaggedMesh | None = None) -> np.ndarray:
    """Modal assurance criterion ``|a^H W b|^2 / ((a^H W a)(b^H W b))``, shape ``(na, nb)``.

    ``W`` is the identity (plain MAC) or, with ``mesh``, the consistent mass matrix applied per
    component (mass-weighted MAC; then the shapes must be at that mesh's P2 nodes). Both sets must
    have the same nodes; see :func:`match_modes` for shapes on different meshes.
    """
    if mesh is not None:
        a = check_shapes(mesh, shapes_a, "shapes_a")
        b = check_shapes(mesh, shapes_b, "shapes_b")
    else:
        a, b = np.asarray(shapes_a), np.asarray(shapes_b)
        a = a[None] if a.ndim == 2 else a
        b = b[None] if b.ndim == 2 else b
        if a.ndim != 3 or b.ndim != 3 or a.shape[1:] != b.shape[1:] or a.shape[2] != 3:
            raise ParameterError("shapes", (np.shape(shapes_a), np.shape(shapes_b)),
                                 "must both be (n_modes, n_nodes, 3) on the same nodes")
    na = a.reshape(len(a), -1)
    if mesh is not None:
        M = _context(mesh).mass
        Wb = np.stack([(M @ b[:, :, c].T).T for c in range(3)], axis=-1).reshape(len(b), -1)
    else:
        Wb = b.reshape(len(b), -1)
    nb = b.reshape(len(b), -1)
    Wa = (np.stack([(M @ a[:, :, c].T).T for c in range(3)], axis=-1).reshape(len(a), -1)
          if mesh is not None else na)
    cross = np.conj(na) @ Wb.T
    ea = np.real(np.einsum("kn,kn->k", np.conj(na), Wa))
    eb = np.real(np.einsum("kn,kn->k", np.conj(nb), Wb))
    den = np.outer(ea, eb)
    return np.where(den > 0, np.abs(cross) ** 2 / np.where(den > 0, den, 1.0), 0.0)


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
    helper = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = helper - (helper @ d) * d
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(d, e1)
    rel = nodes - p0
    x, y, s = rel @ e1, rel @ e2, rel @ d
    rmax = max(np.hypot(x, y).max(), 1e-300)
    return np.column_stack([x / rmax, y / rmax, (s - s.min()) / max(np.ptp(s), 1e-300)])


def match_modes(mesh_a: TaggedMesh, shapes_a, mesh_b: TaggedMesh, shapes_b, *,
                method: str = "auto", min_mac: float = 0.5, k_neighbours: int = 4,
                axis_point=(0.0, 0.0), axis_dir=(0.0, 0.0, 1.0)) -> ModeMatch:
    """Match the modes of design A to those of design B by shape (one-to-one, max total MAC).

    ``method``:

    - ``"same-nodes"``: the meshes share topology (e.g. a morphed mesh: same cells, moved
      points); the mass-weighted MAC on mesh A is used directly;
    - ``"nearest"``: the meshes differ; B's shapes are interpolated onto A's P2 nodes in
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
    same = mesh_a.cells.shape == mesh_b.cells.shape and np.array_equal(mesh_a.cells, mesh_b.cells)
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


def cylindrical_components(mesh: TaggedMesh, shapes, *, axis_point=(0.0, 0.0),
                           axis_dir=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Node-wise (axial, tangential, radial) components, ``(n_modes, n_nodes, 3)``.

    On the axis (r < 1e-6 r_max) the tangential component is 0 and the radial one is the
    in-plane motion along the frame's first transverse unit vector.
    """
    u = check_shapes(mesh, shapes)
    fr = _frame(mesh, axis_point, axis_dir)
    ua = u @ fr.d
    ut = np.einsum("knc,nc->kn", u, fr.et)
    ur = np.einsum("knc,nc->kn", u, fr.er)
    ut[:, fr.on_axis] = 0.0
    return np.stack([ua, ut, ur], axis=-1)


def surface_motion(mesh: TaggedMesh, shape, surface: str, *, axis_point=(0.0, 0.0),
                   axis_dir=(0.0, 0.0, 1.0)) -> dict:
    """Area-weighted motion of one mode on a facet set (e.g. ``"teeth_tops"``, ``"horn_tip"``).

    The P2 displacement is interpolated at the quadrature points of the surface (scikit-fem
    ``FacetBasis``), projected there on the local cylindrical unit vectors, and integrated.

    Returns a dict (lengths in the shape's units; m for a physical response):

    ``axial``, ``tangential``, ``radial``
        Mean amplitude ``(1/A) * integral |u_c| dA`` of each component.
    ``axial_mean``, ``tangential_mean``, ``radial_mean``
        Signed mean ``(1/A) * integral u_c dA`` (net piston motion, net rotation x r, ...);
        for complex shapes the modulus of the complex mean.
    ``axial_rms``, ``tangential_rms``, ``radial_rms``, ``max_magnitude``
    ``ellipse_ratio``
        ``tangential / axial`` (mean amplitudes), the aspect of the tooth-top ellipse; ``inf``
        if the surface has no axial motion.
    ``phase_deg``
        For complex shapes, the phase of the tangential mean relative to the axial mean
        (degrees; 0 or 180 for a real mode shape, whose "ellipse" degenerates to a line).
    ``area`` (m^2), ``n_nodes`` (P2 nodes on the surface), ``surface``.
    """
    from skfem import ElementTetP2, FacetBasis

    u = check_shapes(mesh, shape, "shape")
    if u.shape[0] != 1:
        raise ParameterError("shape", np.shape(shape), "must be one mode, (n_nodes, 3)")
    u = u[0]
    if not isinstance(surface, str) or surface not in mesh.facet_sets:
        raise ParameterError("surface", surface, "unknown; known: " + ", ".join(sorted(mesh.facet_sets)))
    ctx = _context(mesh)
    facets = ctx.sk.boundaries[surface]
    if len(facets) == 0:
        raise ParameterError("surface", surface, "is empty")
    fb = FacetBasis(ctx.sk, ElementTetP2(), facets=facets)
    p0, d = _axis(axis_point, axis_dir)
    comps = [np.asarray(fb.interpolate(u[:, c])) for c in range(3)]   # (nf, nq) each
    x = np.asarray(fb.global_coordinates())                        # (3, nf, nq)
    rel = np.moveaxis(x, 0, -1) - p0
    fr = _frame(mesh, axis_point, axis_dir)
    xi, eta = rel @ fr.e1, rel @ fr.e2
    r = np.hypot(xi, eta)
    on_axis = r <= _AXIS_EPS * max(fr.r.max(initial=0.0), 1e-300)
    rs = np.where(on_axis, 1.0, r)
    cos, sin = np.where(on_axis, 1.0, xi / rs), np.where(on_axis, 0.0, eta / rs)
    U = np.stack(comps, axis=-1)                              # (nf, nq, 3)
    ua = U @ d
    u1, u2 = U @ fr.e1, U @ fr.e2
    ur = u1 * cos + u2 * sin
    ut = np.where(on_axis, 0.0, -u1 * sin + u2 * cos)
    dx = fb.dx
    area = float(dx.sum())
    out = {"surface": surface, "area": area}
    for name, f in (("axial", ua), ("tangential", ut), ("radial", ur)):
        out[name] = float((np.abs(f) * dx).sum() / area)
        out[f"{name}_mean"] = complex((f * dx).sum() / area)
        out[f"{name}_rms"] = float(np.sqrt((np.abs(f) ** 2 * dx).sum() / area))
    am, tm = out["axial_mean"], out["tangential_mean"]
    out["phase_deg"] = float(np.degrees(np.angle(tm / am))) if abs(am) > 0 and abs(tm) > 0 else 0.0
    for name in ("axial", "tangential", "radial"):
        v = out[f"{name}_mean"]
        out[f"{name}_mean"] = float(v.real) if not np.iscomplexobj(u) else float(abs(v))
    out["max_magnitude"] = float(np.sqrt((np.abs(U) ** 2).sum(axis=-1)).max())
    out["ellipse_ratio"] = out["tangential"] / out["axial"] if out["axial"] > 0 else float("inf")
    out["n_nodes"] = int(len(np.unique(ctx.basis.get_dofs(facets).all())))
    return out
