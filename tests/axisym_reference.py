"""An independent axisymmetric (r, z) piezo-elastic reference model, for the tests (no tests here).

Written apart from ``geometry.builder`` and ``fem``: the (r, z) cross-section is re-derived from
the design dataclass fields (:func:`section`), meshed with Gmsh triangles graded toward the
singular points of the section (:func:`mesh_section`), and the axisymmetric piezo-elastic weak
form is assembled with plain scikit-fem forms (P2 displacement and potential):

    int_V  S(v) : c^E : S(u)  +  S(v) : e^T grad(phi)    dV  =  w^2 int_V rho v . u dV
    int_V  grad(psi) . e S(u)  -  grad(psi) . eps^S grad(phi)  dV  =  - psi_electrode Q

with ``dV = 2 pi r dr dz``, ``u = (u_r, u_z)``, the strain in Voigt order (rr, tt, zz, rz)
``S = (du_r/dr, u_r/r, du_z/dz, du_r/dz + du_z/dr)``, ``E = -grad(phi)``. Materials come from
``geometry.materials`` (stress-charge constants c^E, e, eps^S, poling along +z; a ring poled
-z has e negated: a half-turn about x flips every odd-rank tensor, even ranks keep).
Electrodes are equipotential lines: ground at 0 V, every hot electrode one shared unknown.
Short circuit (hot = 0) gives the resonances f_r, open circuit (hot floating, zero net charge,
the natural condition of its row) the anti-resonances f_a. u_r = 0 on the axis (finite u_r/r).

Limits: u_theta = 0, so torsional modes (and every non-axisymmetric mode: bending pairs, slots,
teeth, boxes, x/y poling) are outside this model; designs with them are refused.

Mesh: the element size is ``h`` in the bulk and ``h (d / l)^beta`` at a distance ``d < l`` from
a graded point (re-entrant corners, material or poling junctions on the surface), with
``beta = 0.75 < 1 - lambda / p`` (Williams' lambda = 0.5445 of a 270-degree free corner, p = 2)
so that P2 eigenvalues keep their smooth rate h^4 (Babuska grading); thin blocks are capped at
``t h / l``. Every size scales with h alone, so halving h is one refinement level
(:func:`convergence`: observed order and Richardson extrapolation).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla
from skfem import Basis, BilinearForm, ElementTriP2, ElementVector, MeshTri, MeshTri2, asm

from geometry.design import RPUDDesign, StackDesign
from geometry.materials import EPS0, get_material
from rpud_common import ParameterError

TWO_PI = 2.0 * math.pi
BETA = 0.75
"""Grading exponent of the element size toward singular points (see the module docstring)."""


# ============================================================================ cross-section


@dataclass(frozen=True)
class Block:
    """One region of the (r, z) cross-section: a polygon (m, counter-clockwise); ``arcs`` gives
    ``(i, r_c, z_c)``: edge i (vertex i to i + 1) is the circular arc about (r_c, z_c)."""

    name: str
    material: str
    poling: int                                  # +1 (+z), -1 (-z), 0 passive
    outline: tuple[tuple[float, float], ...]
    arcs: tuple[tuple[int, float, float], ...] = ()

    def arc_centre(self, i: int):
        for k, rc, zc in self.arcs:
            if k == i % len(self.outline):
                return np.array([rc, zc])
        return None


@dataclass(frozen=True)
class ElectrodeLine:
    """An electrode: the segment r0 <= r <= r1 of the plane z (m), wired ``hot`` or ``ground``."""

    role: str
    z: float
    r0: float
    r1: float


@dataclass(frozen=True)
class Section:
    blocks: tuple[Block, ...]
    electrodes: tuple[ElectrodeLine, ...]


def _rect(name, material, poling, r0, r1, z0, z1):
    return Block(name, material, poling, ((r0, z0), (r1, z0), (r1, z1), (r0, z1)))


def _trapezoid(name, material, poling, r_in, r_bottom, r_top, z0, z1):
    return Block(name, material, poling, ((r_in, z0), (r_bottom, z0), (r_top, z1), (r_in, z1)))


def section(design) -> Section:
    """The (r, z) cross-section of an axisymmetric design (RPUD without slots/teeth, or a stack)."""
    if isinstance(design, RPUDDesign):
        return _rpud_section(design)
    if isinstance(design, StackDesign):
        return _stack_section(design)
    raise ParameterError("design", type(design).__name__, "must be an RPUDDesign or a StackDesign")


def _rpud_section(d: RPUDDesign) -> Section:
    c, s, f, h = d.coupler, d.stack, d.flange, d.horn
    if c.n_slots or c.n_teeth:
        raise ParameterError("coupler.n_slots/n_teeth", (c.n_slots, c.n_teeth),
                             "must both be 0: slots and teeth are not axisymmetric")
    bore = d.bore_diameter / 2
    rc, Rc = max(c.inner_diameter / 2, bore), c.outer_diameter / 2
    blocks = [_rect("coupler", c.material, 0, rc, Rc, -c.length, 0.0)]
    if d.bolt_thread is not None:       # the coupler's bore closed around the bolt's thread
        zt = d.bolt_thread[0]
        blocks = [Block("coupler", c.material, 0, ((rc, -c.length), (Rc, -c.length), (Rc, 0.0), (0.0, 0.0), (0.0, zt),
                                                   (rc, zt)))]
    # the stack from z = 0: electrode planes 0..n alternate ground, hot, ...; with shims each
    # electrode is a copper shim whose two faces touch ceramic; a ring is poled along the field
    # of a positive hot electrode (from its hot face toward its ground face), so all expand together
    ri, ro = s.inner_diameter / 2, s.outer_diameter / 2
    roles = ["ground" if k % 2 == 0 else "hot" for k in range(s.n_rings + 1)]
    electrodes, z = [], 0.0
    for k in range(s.n_rings + 1):
        if s.electrode_shims:
            blocks.append(_rect(f"shim_{k}", s.shim_material, 0, ri, ro, z, z + s.shim_thickness))
            if k > 0:
                electrodes.append(ElectrodeLine(roles[k], z, ri, ro))
            z += s.shim_thickness
        if k < s.n_rings:
            electrodes.append(ElectrodeLine(roles[k], z, ri, ro))
            hot_on_top = roles[k + 1] == "hot"
            blocks.append(_rect(f"ring_{k + 1}", s.material, -1 if hot_on_top else +1, ri, ro, z, z + s.ring_thickness))
            z += s.ring_thickness
            if not s.electrode_shims:
                electrodes.append(ElectrodeLine(roles[k + 1], z, ri, ro))
    zf = z
    z += f.thickness
    L, R0, Rt = h.length, h.back_diameter / 2, h.tip_diameter / 2
    rf, rs = h.flange_fillet, h.step_fillet
    if rf and h.profile != "stepped":
        raise ParameterError("horn.flange_fillet", rf, "fillets are modelled here on stepped horns only")
    Rf = f.outer_diameter / 2
    if h.profile == "stepped" and (rf or rs):
        # quarter-circle fillets tangent to a plane and a cylinder: centre one radius from each;
        # the flange fillet's metal is split along the 45-degree line from the sharp corner to
        # the centre (lower half flange, upper half horn), where the arc's point is
        # corner + (1 - 1/sqrt 2) r (1, 1)
        l1 = h.step_fraction * L
        m = (1 - 1 / math.sqrt(2)) * rf
        if rf:
            blocks.append(Block("flange", f.material, 0, ((bore, zf), (Rf, zf), (Rf, z), (R0 + rf, z), (R0 + m, z + m),
                                                            (R0, z), (bore, z)), ((3, R0 + rf, z + rf),)))
            horn = [(bore, z), (R0, z), (R0 + m, z + m), (R0, z + rf)]
            arcs = [(2, R0 + rf, z + rf)]
        else:
            blocks.append(_rect("flange", f.material, 0, bore, Rf, zf, z))
            horn, arcs = [(bore, z), (R0, z)], []
        horn.append((R0, z + l1))
        if rs:
            horn += [(Rt + rs, z + l1), (Rt, z + l1 + rs)]
            arcs.append((len(horn) - 2, Rt + rs, z + l1 + rs))
        else:
            horn.append((Rt, z + l1))
        horn += [(Rt, z + L), (bore, z + L)]
        blocks.append(Block("horn", h.material, 0, tuple(horn), tuple(arcs)))
        return Section(tuple(blocks + _bolt(d)), tuple(electrodes))
    blocks.append(_rect("flange", f.material, 0, bore, Rf, zf, z))
    if h.profile == "stepped":
        l1 = h.step_fraction * L
        outline = ((bore, z), (R0, z), (R0, z + l1), (Rt, z + l1), (Rt, z + L), (bore, z + L))
    elif h.profile == "conical":
        outline = ((bore, z), (R0, z), (Rt, z + L), (bore, z + L))
    else:   # exponential r = R0 (R0/Rt)^(-s/L): a fine polyline
        sz = np.linspace(0.0, L, 49)
        rs = R0 * (R0 / Rt) ** (-sz / L)
        outline = ((bore, z), *zip(rs.tolist(), (z + sz).tolist()), (bore, z + L))
    blocks.append(Block("horn", h.material, 0, tuple(outline)))
    return Section(tuple(blocks + _bolt(d)), tuple(electrodes))


def _bolt(d: RPUDDesign) -> list:
    """The stack bolt's block (none without a bolt part): a rod in the rings' bore from the
    coupler's top to the flange, free along the rings."""
    s = d.stack
    return [_rect("bolt", s.bolt_material, 0, 0.0, s.bolt_diameter / 2, 0.0, s.length)] if s.bolt_diameter else []


def _stack_section(d: StackDesign) -> Section:
    blocks, ext, z = [], {}, 0.0
    for seg in d.segments:
        z0 = z if seg.start is None else float(seg.start)
        z1 = z = z0 + seg.length
        if seg.kind == "box" or seg.poling not in ("none", "+z", "-z"):
            raise ParameterError(f"segments.{seg.name}", seg.kind if seg.kind == "box" else seg.poling,
                                 "is not axisymmetric (boxes and x/y poling are outside an (r, z) model)")
        pol = {"none": 0, "+z": 1, "-z": -1}[seg.poling]
        r_top = (seg.end_diameter if seg.kind == "cone" else seg.outer_diameter) / 2
        blocks.append(_trapezoid(seg.name, seg.material, pol, seg.inner_diameter / 2, seg.outer_diameter / 2,
                                 r_top, z0, z1))
        ext[seg.name] = (seg, z0, z1, r_top)
    electrodes = []
    for e in d.electrodes:
        seg, z0, z1, r_top = ext[e.segment]
        if e.face not in ("bottom", "top"):
            raise ParameterError(f"electrodes.{e.name}.face", e.face, "side faces are not axisymmetric")
        bottom = e.face == "bottom"
        electrodes.append(ElectrodeLine(e.role, z0 if bottom else z1, seg.inner_diameter / 2,
                                        seg.outer_diameter / 2 if bottom else r_top))
    return Section(tuple(blocks), tuple(electrodes))


# ============================================================================ graded mesh


def _leaving(block, i, j):
    """Direction in which the edge between neighbouring vertices i and j leaves vertex i (its
    tangent there if the edge is an arc)."""
    n = len(block.outline)
    pts = np.asarray(block.outline)
    d = pts[j] - pts[i]
    c = block.arc_centre(i if j == (i + 1) % n else j)
    if c is None:
        return d
    t = np.array([-(pts[i] - c)[1], (pts[i] - c)[0]])
    return t if t @ d > 0 else -t


def _angle_at(block, p, tol):
    """Interior angle (rad) of a block at point p: vertex angle (between the edges' tangents),
    pi on an edge, 2 pi inside, 0 outside (arcs taken as their chords for the last two: no other
    block's vertex lies between a fillet's arc and its chord)."""
    pts = np.asarray(block.outline)
    n = len(pts)
    for i in range(n):
        if np.hypot(*(pts[i] - p)) < tol:
            a, b = _leaving(block, i, (i - 1) % n), _leaving(block, i, (i + 1) % n)
            # counter-clockwise outline: the interior lies left of each edge
            return (math.atan2(a[1], a[0]) - math.atan2(b[1], b[0])) % TWO_PI
    for i in range(n):
        a, b = pts[i], pts[(i + 1) % n]
        t = np.dot(p - a, b - a) / np.dot(b - a, b - a)
        if 0 < t < 1 and np.hypot(*(a + t * (b - a) - p)) < tol:
            return math.pi
    # ray casting for inside/outside
    inside = False
    for i in range(n):
        (r1, z1), (r2, z2) = pts[i], pts[(i + 1) % n]
        if (z1 > p[1]) != (z2 > p[1]) and p[0] < r1 + (p[1] - z1) * (r2 - r1) / (z2 - z1):
            inside = not inside
    return TWO_PI if inside else 0.0


def singular_points(sec: Section, tol: float = 1e-9) -> np.ndarray:
    """(k, 2) points off the axis where the fields may be singular: re-entrant corners of the body
    (total interior angle above 180 degrees by more than 0.1 rad, so a fine polyline is smooth)
    and points where different materials or polings meet."""
    pts = {tuple(np.round(v, 12)) for b in sec.blocks for v in b.outline}
    out = []
    for p in sorted(pts):
        if p[0] < tol:
            continue
        p = np.array(p)
        angles = [(_angle_at(b, p, tol), (b.material, b.poling)) for b in sec.blocks]
        total = sum(a for a, _ in angles)
        kinds = {k for a, k in angles if a > 0}
        if (math.pi + 0.1 < total < TWO_PI - 0.1) or len(kinds) > 1:
            out.append(p)
    return np.array(out).reshape(-1, 2)


def mesh_section(sec: Section, h: float, grade_radius: float, splits: int = 0) -> tuple[MeshTri, np.ndarray]:
    """Triangles of the cross-section, graded toward :func:`singular_points`.

    Parameters
    ----------
    h : float
        Bulk element size, m.
    grade_radius : float
        l, m: the size is ``h (d / l)^BETA`` within ``d < l`` of a singular point, floored where
        it reaches d, ``<= t h / l`` in a block of thickness t, and ``<= h c / l`` at a distance
        c from a fillet arc's centre (``h rho / l`` on an arc of radius rho).

    splits : int
        Then split every triangle into four this many times (Gmsh's uniform refinement, new
        boundary nodes on the curves): nested meshes, whose errors follow the asymptotic rate
        more closely than independent meshes at h / 2^k.

    Returns
    -------
    (MeshTri, (n_elements,) block index of each triangle)
    """
    import gmsh

    sing = singular_points(sec)
    floor = h * (h / grade_radius) ** (BETA / (1 - BETA))
    gmsh.initialize(interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("axisym")
        occ = gmsh.model.occ
        surfaces = []
        for b in sec.blocks:
            pts = [occ.addPoint(r, z, 0.0) for r, z in b.outline]
            lines = []
            for i in range(len(pts)):
                c = b.arc_centre(i)
                j = (i + 1) % len(pts)
                lines.append(occ.addLine(pts[i], pts[j]) if c is None
                             else occ.addCircleArc(pts[i], occ.addPoint(c[0], c[1], 0.0), pts[j]))
            surfaces.append(occ.addPlaneSurface([occ.addCurveLoop(lines)]))
        if len(surfaces) > 1:
            _, pieces = occ.fragment([(2, s) for s in surfaces], [])
        else:
            pieces = [[(2, surfaces[0])]]
        occ.synchronize()
        field = gmsh.model.mesh.field
        sizes = []
        if len(sing):
            vertices = [t for _, t in gmsh.model.getEntities(0)]
            xyz = np.array([gmsh.model.getValue(0, t, []) for t in vertices])
            near = [t for t, q in zip(vertices, xyz) if np.min(np.hypot(*(sing - q[:2]).T)) < 1e-9]
            dist = field.add("Distance")
            field.setNumbers(dist, "PointsList", near)
            graded = field.add("MathEval")
            field.setString(graded, "F", f"{h!r} * (F{dist} / {grade_radius!r})^{BETA!r}")
            sizes.append(graded)
        for b in sec.blocks:    # fillets: h rho / l on the arc, growing as h / l per m away from it
            for _i, rc, zc in b.arcs:
                arc = field.add("MathEval")
                field.setString(arc, "F", f"{h / grade_radius!r} * Sqrt((x - {rc!r})^2 + (y - {zc!r})^2)")
                sizes.append(arc)
        for b in sec.blocks:    # thin blocks: at most t h / l
            o = np.asarray(b.outline)
            lo, hi = o.min(axis=0), o.max(axis=0)
            cap = (hi - lo).min() * h / grade_radius
            if cap < h:
                box = field.add("Box")
                for key, v in (("VIn", cap), ("VOut", h), ("XMin", lo[0]), ("XMax", hi[0]),
                               ("YMin", lo[1]), ("YMax", hi[1]), ("ZMin", -1.0), ("ZMax", 1.0)):
                    field.setNumber(box, key, v)
                sizes.append(box)
        if sizes:
            fmin = field.add("Min")
            field.setNumbers(fmin, "FieldsList", sizes)
            field.setAsBackgroundMesh(fmin)
        for name, value in (("MeshSizeFromPoints", 0), ("MeshSizeFromCurvature", 0),
                            ("MeshSizeExtendFromBoundary", 0), ("Algorithm", 6),
                            ("MeshSizeMin", floor), ("MeshSizeMax", h)):
            gmsh.option.setNumber(f"Mesh.{name}", value)
        gmsh.model.mesh.generate(2)
        for _ in range(splits):
            gmsh.model.mesh.refine()
        # arcs: 6-node triangles with their mid-edge nodes on the arcs (isoparametric P2): on
        # straight chords every node of the boundary would be a small re-entrant corner
        curved = any(b.arcs for b in sec.blocks)
        if curved:
            gmsh.model.mesh.setOrder(2)
        npe = 6 if curved else 3
        tags, coords, _ = gmsh.model.mesh.getNodes()
        index = np.zeros(int(tags.max()) + 1, dtype=np.int64)
        index[tags.astype(np.int64)] = np.arange(len(tags))
        tris, owner = [], []
        for k, dimtags in enumerate(pieces):
            for _, tag in dimtags:
                _, _, nodes = gmsh.model.mesh.getElements(2, tag)
                t = index[np.asarray(nodes[0], dtype=np.int64)].reshape(-1, npe)
                tris.append(t)
                owner.append(np.full(len(t), k))
    finally:
        gmsh.finalize()
    p = coords.reshape(-1, 3)[:, :2]
    t = np.vstack(tris)
    used = np.unique(t)                       # drop geometry-only nodes
    renum = np.full(len(p), -1)
    renum[used] = np.arange(len(used))
    if curved:
        return MeshTri2(p[used].T.copy(), renum[t].T.copy()), np.concatenate(owner)
    return MeshTri(p[used].T.copy(), renum[t].T.copy()), np.concatenate(owner)


# ============================================================================ materials


def constants(material: str, poling: int):
    """Axisymmetric constants: (c (4, 4) Pa in rr tt zz rz, e (2, 4) C/m^2 rows r z, eps (2, 2) F/m, rho)."""
    m = get_material(material)
    if not m.is_piezo:
        E, nu = m.youngs_modulus, m.poisson_ratio
        lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
        c = np.array([[lam + 2 * mu, lam, lam, 0], [lam, lam + 2 * mu, lam, 0],
                      [lam, lam, lam + 2 * mu, 0], [0, 0, 0, mu]])
        return c, np.zeros((2, 4)), np.zeros((2, 2)), m.density
    k = m.c_E
    c = np.array([[k["c11"], k["c12"], k["c13"], 0], [k["c12"], k["c11"], k["c13"], 0],
                  [k["c13"], k["c13"], k["c33"], 0], [0, 0, 0, k["c44"]]])
    e = poling * np.array([[0, 0, 0, m.e["e15"]], [m.e["e31"], m.e["e31"], m.e["e33"], 0]])
    eps = EPS0 * np.diag([m.eps_S["eps11"], m.eps_S["eps33"]])
    return c, e, eps, m.density


# ============================================================================ weak forms


def strain(u, r):
    """Voigt strain (rr, tt, zz, rz) of an axisymmetric displacement (u_r, u_z)."""
    return [u.grad[0][0], u.value[0] / r, u.grad[1][1], u.grad[0][1] + u.grad[1][0]]


def _dot(A, a, b):
    return sum(A[i, j] * a[i] * b[j] for i in range(A.shape[0]) for j in range(A.shape[1]) if A[i, j] != 0)


def elastic_form(c):
    @BilinearForm
    def form(u, v, w):
        r = w.x[0]
        return _dot(c, strain(v, r), strain(u, r)) * TWO_PI * r
    return form


def coupling_form(e):
    # S(v) : e^T grad(phi) = grad(phi) . e S(v)
    @BilinearForm
    def form(phi, v, w):
        r = w.x[0]
        return _dot(e, phi.grad, strain(v, r)) * TWO_PI * r
    return form


def permittivity_form(eps):
    @BilinearForm
    def form(phi, psi, w):
        return _dot(eps, psi.grad, phi.grad) * TWO_PI * w.x[0]
    return form


def mass_form(rho):
    @BilinearForm
    def form(u, v, w):
        return rho * (u.value[0] * v.value[0] + u.value[1] * v.value[1]) * TWO_PI * w.x[0]
    return form


# ============================================================================ the model


@dataclass(eq=False)
class Model:
    """Assembled axisymmetric system; the potential unknowns are scaled, phi = scale * phi~."""

    mesh: MeshTri
    owner: np.ndarray
    sec: Section
    Kuu: list            # per block
    Kup: sp.csr_matrix
    Kpp: list            # per block (permittivity)
    M: sp.csr_matrix
    u_free: np.ndarray   # u DOFs not on the axis (u_r = 0 there)
    p_free: np.ndarray   # interior potential DOFs (in ceramic, off the electrodes)
    p_hot: np.ndarray    # potential DOFs of the hot electrodes (one shared unknown)
    scale: float

    @property
    def n_dof(self) -> int:
        return len(self.u_free) + len(self.p_free) + (1 if len(self.p_hot) else 0)

    def matrices(self, electrical: str, loss: bool = False, q_mech: float | None = None):
        """(K, L, M, n_u) on the reduced unknowns [u | phi~ | V~_hot if open]; L the hysteretic
        loss matrix (c (1 + j / Q) per block, eps (1 - j tan delta)); ``q_mech`` replaces every
        block's Q (as ``fem.harmonic.LossModel(q_mech=...)``)."""
        nu = len(self.u_free)
        cols = [sp.identity(self.Kup.shape[1], format="csr")[:, self.p_free] * self.scale]
        if electrical == "open" and len(self.p_hot):
            tie = np.zeros((self.Kup.shape[1], 1))
            tie[self.p_hot] = self.scale
            cols.append(sp.csr_matrix(tie))
        P = sp.hstack(cols).tocsr()
        Su = sp.identity(self.M.shape[0], format="csr")[:, self.u_free]

        def system(Kuu, Kpp, Kup):
            if P.shape[1] == 0:         # passive: no potential unknowns
                return (Su.T @ Kuu @ Su).tocsr()
            return sp.bmat([[Su.T @ Kuu @ Su, Su.T @ Kup @ P], [P.T @ Kup.T @ Su, -(P.T @ Kpp @ P)]]).tocsr()

        K = system(sum(self.Kuu), sum(self.Kpp), self.Kup)
        Mr = sp.block_diag([Su.T @ self.M @ Su, sp.csr_matrix((P.shape[1], P.shape[1]))]).tocsr()[:K.shape[0], :K.shape[0]]
        L = None
        if loss:
            Lu = sum(k / (q_mech or get_material(b.material).q_mech) for k, b in zip(self.Kuu, self.sec.blocks))
            Lp = sum(k * get_material(b.material).tan_delta for k, b in zip(self.Kpp, self.sec.blocks))
            L = system(Lu, -Lp, 0 * self.Kup)
        return K, L, Mr, nu


def _electrode_dofs(mesh, pb, line: ElectrodeLine, tol: float) -> np.ndarray:
    """Potential DOFs of ``pb`` on an electrode line (its facets on the plane z, r0 <= r <= r1)."""
    f = mesh.facets_satisfying(lambda x: (np.abs(x[1] - line.z) < tol) & (x[0] > line.r0 - tol) & (x[0] < line.r1 + tol))
    return pb.get_dofs(f).all()


def _potential_scale(stiffness_diag_mean: float, permittivity_diag_mean: float) -> float:
    """Power of ten that brings the potential block to the magnitude of the stiffness block
    (unscaled they differ by ~20 orders of magnitude)."""
    return 10.0 ** round(math.log10(math.sqrt(stiffness_diag_mean / permittivity_diag_mean)))


def assemble(sec: Section, h: float, grade_radius: float, fixed=(), splits: int = 0) -> Model:
    """Mesh the section and assemble the axisymmetric piezo-elastic matrices (P2, P2).

    ``fixed``: extra displacement constraints ``(component "r"/"z", line "r"/"z", value m)``,
    e.g. ``("z", "z", 0.0)``: u_z = 0 on the plane z = 0 (u_r stays free: a sliding end).
    """
    mesh, owner = mesh_section(sec, h, grade_radius, splits)
    ub = Basis(mesh, ElementVector(ElementTriP2()), intorder=6)
    pb = Basis(mesh, ElementTriP2(), intorder=6)
    Kuu, Kpp, Kup, M = [], [], 0, 0
    for k, b in enumerate(sec.blocks):
        c, e, eps, rho = constants(b.material, b.poling)
        el = np.nonzero(owner == k)[0]
        ubk = Basis(mesh, ub.elem, elements=el, intorder=6)
        pbk = Basis(mesh, pb.elem, elements=el, intorder=6)
        Kuu.append(asm(elastic_form(c), ubk))
        M = M + asm(mass_form(rho), ubk)
        if b.poling:
            Kup = Kup + asm(coupling_form(e), pbk, ubk)
            Kpp.append(asm(permittivity_form(eps), pbk))
        else:
            Kpp.append(sp.csr_matrix((pb.N, pb.N)))
    if not sp.issparse(Kup):
        Kup = sp.csr_matrix((ub.N, pb.N))
    tol = 1e-9 * (1 + np.abs(mesh.p).max())
    u_fixed = [np.array([], dtype=int)]
    for comp, line, value in (("r", "r", 0.0), *fixed):     # u_r = 0 on the axis
        f = mesh.facets_satisfying(lambda x: np.abs(x["rz".index(line)] - value) < tol)
        if len(f):
            u_fixed.append(ub.get_dofs(f).all("u^" + str("rz".index(comp) + 1)))
    u_fixed = np.concatenate(u_fixed)
    u_free = np.setdiff1d(np.arange(ub.N), u_fixed)
    piezo = np.isin(owner, [k for k, b in enumerate(sec.blocks) if b.poling])
    p_all = np.unique(pb.element_dofs[:, piezo]) if piezo.any() else np.array([], dtype=int)
    on = {"hot": [], "ground": []}
    for el in sec.electrodes:
        on[el.role].append(_electrode_dofs(mesh, pb, el, tol))
    hot = np.unique(np.concatenate(on["hot"])) if on["hot"] else np.array([], dtype=int)
    ground = np.unique(np.concatenate(on["ground"])) if on["ground"] else np.array([], dtype=int)
    if len(p_all) and not len(ground):
        raise ParameterError("electrodes", [], "a piezoceramic needs a ground electrode")
    p_free = np.setdiff1d(p_all, np.concatenate([hot, ground]))
    scale = 1.0
    if len(p_all):
        scale = _potential_scale(sum(Kuu).diagonal()[u_free].mean(), sum(Kpp).diagonal()[p_all].mean())
    return Model(mesh, owner, sec, Kuu, sp.csr_matrix(Kup), Kpp, sp.csr_matrix(M), u_free, p_free, hot, scale)


# ============================================================================ modes


def _eigs(op, Muu, sigma, k):
    """k eigenpairs nearest sigma, given op(b) = (K - sigma M)^-1 [b; 0] restricted to u."""
    nu = Muu.shape[0]
    OP = sla.LinearOperator((nu, nu), matvec=op, dtype=float)
    lam, vec = sla.eigsh(Muu, k=k, M=Muu, sigma=sigma, OPinv=OP, tol=1e-12)
    order = np.argsort(lam)
    return lam[order], vec[:, order]


def _eigenpairs(model: Model, sigma: float, k: int):
    """Short- and open-circuit eigenpairs of K x = w^2 M x nearest sigma, (lam, vectors on u) each.

    One factorisation: the potential is condensed inside the solve ((K - sigma M)^-1 with zero
    charge on every potential row), and the open-circuit matrix is the short-circuit one
    bordered by the hot electrode's row, solved through its Schur complement."""
    K, _, M, nu = model.matrices("open")
    n = K.shape[0] - (1 if len(model.p_hot) else 0)          # short-circuit unknowns
    A = (K - sigma * M).tocsc()
    lu = sla.splu(A[:n, :n].tocsc(), permc_spec="MMD_AT_PLUS_A")
    Muu = M[:nu, :nu]

    def short(b):
        rhs = np.zeros(n)
        rhs[:nu] = b
        return lu.solve(rhs)

    out = [_eigs(lambda b: short(b)[:nu], Muu, sigma, k)]
    if n < K.shape[0]:
        border = A[:n, [n]].toarray().ravel()
        w = lu.solve(border)
        schur = A[n, n] - border @ w

        def open_(b):
            x = short(b)
            return (x - w * (-(border @ x) / schur))[:nu]

        out.append(_eigs(open_, Muu, sigma, k + 2))
    else:
        out.append(out[0])
    return out, Muu


@dataclass
class Modes:
    """Modes near a target: f_r (Hz, short circuit), f_a (Hz, open circuit, paired by MAC), k_eff."""

    f_r: np.ndarray
    f_a: np.ndarray
    k_eff: np.ndarray
    n_dof: int

    @property
    def working(self) -> int:
        """The strongly coupled mode nearest the target: the largest k_eff."""
        return int(np.argmax(self.k_eff))


def modes(model: Model, near_hz: float, n_modes: int = 4) -> Modes:
    """Short- and open-circuit modes nearest ``near_hz`` (the rigid axial translation dropped),
    paired by the mass-weighted MAC of their displacements."""
    sigma = (TWO_PI * near_hz) ** 2
    pairs, Muu = _eigenpairs(model, sigma, n_modes + 1)
    (ls, vs), (lo, vo) = [(lam[lam > 0.01 * sigma], vec[:, lam > 0.01 * sigma]) for lam, vec in pairs]
    ls, vs = ls[:n_modes], vs[:, :n_modes]
    mac = (vs.T @ (Muu @ vo)) ** 2          # both sets M-orthonormal
    pair = np.argmax(mac, axis=1)
    f_r = np.sqrt(ls) / TWO_PI
    f_a = np.sqrt(lo[pair]) / TWO_PI
    k_eff = np.sqrt(np.clip(1 - (f_r / f_a) ** 2, 0, None))
    return Modes(f_r, f_a, k_eff, model.n_dof)


# ============================================================================ admittance


def _driven(model: Model, f: float, K, L, M):
    """Solution at ``f`` (Hz) with the hot electrodes at 1 V, from the open-circuit matrices
    ``K, L, M`` of ``model.matrices("open", loss=True)``: (x on the reduced unknowns, charge Q)."""
    n = K.shape[0]
    hot, free = n - 1, np.arange(n - 1)
    w = TWO_PI * f
    A, B = (K - w ** 2 * M).tocsr(), L.tocsr()
    # (A + j B) x = b as the real system [[A, -B], [B, A]] (complex SuperLU is ~40x slower here)
    Aff, Bff = A[free][:, free], B[free][:, free]
    lu = sla.splu(sp.bmat([[Aff, -Bff], [Bff, Aff]]).tocsc(), permc_spec="MMD_AT_PLUS_A")
    v_hot = 1.0 / model.scale
    xr = lu.solve(-np.concatenate([A[free][:, hot].toarray().ravel(), B[free][:, hot].toarray().ravel()]) * v_hot)
    x = np.zeros(n, complex)
    x[free] = xr[:n - 1] + 1j * xr[n - 1:]
    x[hot] = v_hot
    return x, -((A[hot] + 1j * B[hot]) @ x)[0] / model.scale


def tip_per_volt(model: Model, freq_hz: float, q_mech: float | None = None) -> float:
    """|mean axial displacement| of the top face (the horn tip, z = z_max) per volt at ``freq_hz``,
    m/V: area-weighted as ``fem.harmonic`` (``int u_z 2 pi r dr / int 2 pi r dr``)."""
    from skfem import FacetBasis, Functional

    K, L, M, _nu = model.matrices("open", loss=True, q_mech=q_mech)
    x, _ = _driven(model, freq_hz, K, L, M)
    ub = Basis(model.mesh, ElementVector(ElementTriP2()), intorder=6)
    u = np.zeros(ub.N, complex)
    u[model.u_free] = x[:len(model.u_free)]
    z_top = model.mesh.p[1].max()
    facets = model.mesh.facets_satisfying(lambda p: np.abs(p[1] - z_top) < 1e-9 * (1 + z_top))
    fb = FacetBasis(model.mesh, ub.elem, facets=facets, intorder=6)

    @Functional
    def uz(w):
        return w["u"].value[1] * TWO_PI * w.x[0]

    @Functional
    def area(w):
        return TWO_PI * w.x[0]

    a = area.assemble(fb)
    mean = (uz.assemble(fb, u=fb.interpolate(u.real)) + 1j * uz.assemble(fb, u=fb.interpolate(u.imag))) / a
    return float(abs(mean))


def admittance(model: Model, freqs_hz, lossy: bool = True) -> np.ndarray:
    """Y(f) = j w Q / V (S) of the hot electrodes against ground, by direct solves.

    Loss model as ``fem.harmonic``: c (1 + j / Q_mech) per material, eps (1 - j tan delta),
    time factor exp(+j w t); ``lossy=False`` drops both (then Y is purely imaginary). The hot
    electrode is driven at V = 1; its row gives the charge, Q = -(row . x) / scale.
    """
    K, L, M, _nu = model.matrices("open", loss=True)
    L = L if lossy else 0 * L
    freqs = np.atleast_1d(np.asarray(freqs_hz, float))
    return np.array([1j * TWO_PI * f * _driven(model, f, K, L, M)[1] for f in freqs])


# ============================================================================ convergence


@dataclass
class Convergence:
    """f_r, f_a of the working mode on graded refinement levels and their Richardson limits."""

    h: np.ndarray
    n_dof: np.ndarray
    f_r: np.ndarray
    f_a: np.ndarray
    order_r: float
    order_a: float
    f_r_limit: float
    f_a_limit: float

    @property
    def error_r(self) -> float:
        """Estimated error of the finest level: |limit - finest| (Hz)."""
        return abs(self.f_r_limit - self.f_r[-1])

    @property
    def error_a(self) -> float:
        return abs(self.f_a_limit - self.f_a[-1])


def richardson(values, ratio: float = 2.0) -> tuple[float, float]:
    """(observed order, extrapolated limit) from the last three values of a sequence refined by ``ratio``."""
    a, b, c = values[-3:]
    p = math.log(abs((a - b) / (c - b if c != b else 1e-300))) / math.log(ratio) if a != b else math.inf
    return p, c + (c - b) / (ratio ** p - 1)


def convergence(design, h0: float, grade_radius: float, levels: int = 3, near_hz: float | None = None,
                n_modes: int = 3, ratio: float = 2.0) -> Convergence:
    """Working-mode f_r, f_a at sizes h0, h0/ratio, ... (``levels`` of them, grading radius fixed)
    with the observed order and Richardson extrapolation of the last three."""
    sec = section(design)
    near = design.target_frequency if near_hz is None else near_hz
    hs, dofs, fr, fa = [], [], [], []
    for k in range(levels):
        h = h0 / ratio ** k
        res = modes(assemble(sec, h, grade_radius), near, n_modes)
        w = res.working
        hs.append(h), dofs.append(res.n_dof), fr.append(res.f_r[w]), fa.append(res.f_a[w])
    pr, lr = richardson(fr, ratio)
    pa, la = richardson(fa, ratio)
    return Convergence(np.array(hs), np.array(dofs), np.array(fr), np.array(fa), pr, pa, lr, la)


# ============================================================================ one Fourier harmonic (bending, torsion)
#
# The same section carries the non-axisymmetric modes of an axisymmetric body one circumferential
# harmonic at a time (the body's symmetry decouples them exactly). Harmonic n >= 1 ("cos" family):
#     u_r = U_r cos n t,  u_t = U_t sin n t,  u_z = U_z cos n t,  phi = Phi cos n t,
# strains grouped by their angular factor,
#     cos: (rr, tt, zz, rz) = (U_r,r, (U_r + n U_t) / r, U_z,z, U_r,z + U_z,r)
#     sin: (tz, rt)         = (U_t,z - n U_z / r, U_t,r - (U_t + n U_r) / r)
# and grad(phi) = (Phi,r cos, -n Phi / r sin, Phi,z cos); every product integrates over t to pi.
# A transversely isotropic ceramic poled along z has the same constants in (r, t, z) as in (x, y, z),
# and no constant couples a cos group to a sin group. n = 1 carries the bending pairs (each pair is
# one mode here), n = 0 with u_t alone the torsional modes (no field: E_t = 0, so plain elasticity).
# An electrode is an equipotential surface: for n >= 1 its potential, constant in t, is 0, so short
# and open circuit coincide. On the axis (r = 0) finite energy needs U_z = Phi = 0 and U_r + U_t = 0
# (n = 1), U_t = 0 (n = 0).


BENDING_19 = (5161.55, 10512.14)
"""First and second bending pairs (Hz) of the default design without slots and teeth: harmonic n = 1
of this model, graded levels h = 2 ... 0.5 mm (ratio sqrt 2, up to 163k unknowns), observed
order 3.8-4.4, Richardson limits 5161.553 / 10512.135 Hz (spread of the last three limits 0.05 /
0.01 Hz)."""

TORSION_19 = 15286.155
"""First torsional mode (Hz) of the same design: harmonic n = 0 with u_theta alone, same levels,
order 4.6-5.0, limit 15286.155 (spread 0.003 Hz)."""


def _shear_constants(material: str, poling: int):
    """(c44, c66 Pa, e15 C/m^2 signed by poling, eps11 F/m) of a material."""
    m = get_material(material)
    if not m.is_piezo:
        mu = m.youngs_modulus / (2 * (1 + m.poisson_ratio))
        return mu, mu, 0.0, 0.0
    k = m.c_E
    return k["c44"], k.get("c66", (k["c11"] - k["c12"]) / 2), poling * m.e["e15"], EPS0 * m.eps_S["eps11"]


def _harmonic_forms(n: int, c, e, eps, c44, c66, e15, eps11, rho):
    """Bilinear forms (elastic, coupling, permittivity, mass) of harmonic n >= 1, per unit angle pi."""

    def cos_strain(u, r):
        return [u.grad[0][0], (u.value[0] + n * u.value[1]) / r, u.grad[2][1], u.grad[0][1] + u.grad[2][0]]

    def sin_strain(u, r):
        return [u.grad[1][1] - n * u.value[2] / r, u.grad[1][0] - (u.value[1] + n * u.value[0]) / r]

    def grad_cos(p):
        return [p.grad[0], p.grad[1]]

    @BilinearForm
    def elastic(u, v, w):
        r = w.x[0]
        ss, sv = sin_strain(u, r), sin_strain(v, r)
        return (_dot(c, cos_strain(v, r), cos_strain(u, r)) + c44 * sv[0] * ss[0] + c66 * sv[1] * ss[1]) * math.pi * r

    @BilinearForm
    def coupling(phi, v, w):
        r = w.x[0]
        return (_dot(e, grad_cos(phi), cos_strain(v, r)) + e15 * (-n * phi.value / r) * sin_strain(v, r)[0]) * math.pi * r

    @BilinearForm
    def permittivity(phi, psi, w):
        r = w.x[0]
        return (_dot(eps, grad_cos(psi), grad_cos(phi)) + eps11 * (n / r) ** 2 * psi.value * phi.value) * math.pi * r

    @BilinearForm
    def mass(u, v, w):
        return rho * (u.value[0] * v.value[0] + u.value[1] * v.value[1] + u.value[2] * v.value[2]) * math.pi * w.x[0]

    return elastic, coupling, permittivity, mass


def _torsion_forms(c44, c66, rho):
    """Bilinear forms (elastic, mass) of the torsional family (n = 0, u_t = U_t only), angle 2 pi."""

    @BilinearForm
    def elastic(u, v, w):
        r = w.x[0]
        return (c44 * v.grad[1] * u.grad[1] + c66 * (v.grad[0] - v.value / r) * (u.grad[0] - u.value / r)) * TWO_PI * r

    @BilinearForm
    def mass(u, v, w):
        return rho * u.value * v.value * TWO_PI * w.x[0]

    return elastic, mass


def harmonic_modes(sec: Section, h: float, grade_radius: float, n: int, near_hz: float,
                   n_modes: int = 3) -> tuple[np.ndarray, int]:
    """Natural frequencies (Hz) of circumferential harmonic ``n`` nearest ``near_hz``.

    ``n = 1``: the bending pairs (each listed once), short circuit (= open circuit, see above);
    ``n = 0``: the torsional modes. Rigid-body modes (zero frequency) are dropped.

    Returns
    -------
    (the ``n_modes`` frequencies nearest ``near_hz``, ascending (Hz), number of unknowns)
    """
    if n not in (0, 1):
        raise ParameterError("n", n, "must be 0 (torsion) or 1 (bending)")
    mesh, owner = mesh_section(sec, h, grade_radius)
    tol = 1e-9 * (1 + np.abs(mesh.p).max())
    axis = mesh.facets_satisfying(lambda x: np.abs(x[0]) < tol)
    if n == 0:
        ub = Basis(mesh, ElementTriP2(), intorder=6)
        K, M = 0, 0
        for k, b in enumerate(sec.blocks):
            c44, c66, _, _ = _shear_constants(b.material, b.poling)
            el, ms = _torsion_forms(c44, c66, get_material(b.material).density)
            bk = Basis(mesh, ub.elem, elements=np.nonzero(owner == k)[0], intorder=6)
            K, M = K + asm(el, bk), M + asm(ms, bk)
        free = np.setdiff1d(np.arange(ub.N), ub.get_dofs(axis).all() if len(axis) else [])
        T = sp.identity(ub.N, format="csr")[:, free]
        A, Mr, nu = (T.T @ K @ T).tocsc(), (T.T @ M @ T).tocsr(), len(free)
    else:
        ub = Basis(mesh, ElementVector(ElementTriP2(), dim=3), intorder=6)
        pb = Basis(mesh, ElementTriP2(), intorder=6)
        Kuu, Kup, Kpp, M = 0, 0, 0, 0
        for k, b in enumerate(sec.blocks):
            c, e, eps, rho = constants(b.material, b.poling)
            el, cp, pm, ms = _harmonic_forms(n, c, e, eps, *_shear_constants(b.material, b.poling), rho)
            ix = np.nonzero(owner == k)[0]
            ubk = Basis(mesh, ub.elem, elements=ix, intorder=6)
            Kuu, M = Kuu + asm(el, ubk), M + asm(ms, ubk)
            if b.poling:
                pbk = Basis(mesh, pb.elem, elements=ix, intorder=6)
                Kup, Kpp = Kup + asm(cp, pbk, ubk), Kpp + asm(pm, pbk)
        # reduced unknowns: u off the axis, U_r on the axis (U_t = -U_r there), Phi in the ceramic off the electrodes
        fixed = [np.array([], dtype=int)]
        tie = np.array([], dtype=int), np.array([], dtype=int)
        if len(axis):
            ad = ub.get_dofs(axis)
            fixed += [ad.all("u^2"), ad.all("u^3")]
            tie = ad.all("u^1"), ad.all("u^2")
        u_free = np.setdiff1d(np.arange(ub.N), np.concatenate(fixed))
        rows = np.concatenate([u_free, tie[1]])
        cols = np.concatenate([np.arange(len(u_free)), np.searchsorted(u_free, tie[0])])
        vals = np.concatenate([np.ones(len(u_free)), -np.ones(len(tie[1]))])
        Tu = sp.csr_matrix((vals, (rows, cols)), shape=(ub.N, len(u_free)))
        nu = len(u_free)
        piezo = np.isin(owner, [k for k, b in enumerate(sec.blocks) if b.poling])
        if piezo.any():
            p_all = np.unique(pb.element_dofs[:, piezo])
            on = [pb.get_dofs(axis).all() if len(axis) else np.array([], dtype=int)]    # Phi = 0 on the axis
            on += [_electrode_dofs(mesh, pb, ln, tol) for ln in sec.electrodes]
            p_free = np.setdiff1d(p_all, np.concatenate(on))
            scale = _potential_scale((Tu.T @ Kuu @ Tu).diagonal().mean(), Kpp.diagonal()[p_all].mean())
            Tp = sp.identity(pb.N, format="csr")[:, p_free] * scale
            A = sp.bmat([[Tu.T @ Kuu @ Tu, Tu.T @ Kup @ Tp], [Tp.T @ Kup.T @ Tu, -(Tp.T @ Kpp @ Tp)]]).tocsc()
        else:
            A = (Tu.T @ Kuu @ Tu).tocsc()
        Mr = (Tu.T @ M @ Tu).tocsr()
    sigma = (TWO_PI * near_hz) ** 2
    Mfull = sp.block_diag([Mr, sp.csr_matrix((A.shape[0] - nu, A.shape[0] - nu))]).tocsc()
    lu = sla.splu((A - sigma * Mfull).tocsc(), permc_spec="MMD_AT_PLUS_A")

    def op(b):
        rhs = np.zeros(A.shape[0])
        rhs[:nu] = b
        return lu.solve(rhs)[:nu]

    lam, _ = _eigs(op, Mr, sigma, n_modes + 2)
    lam = lam[lam > 1e-4 * sigma]
    f = np.sqrt(lam) / TWO_PI
    return np.sort(f[np.argsort(np.abs(f - near_hz))][:n_modes]), A.shape[0]


# ============================================================================ stress at the fillets
#
# The working mode's stress: the P2 displacement's gradient evaluated in every triangle at its six
# nodes, the Voigt stress (rr, tt, zz, rz) = c S of a metal there, averaged over the triangles of one
# block sharing a node, and the von Mises value sqrt(((s_rr - s_tt)^2 + (s_tt - s_zz)^2 +
# (s_zz - s_rr)^2) / 2 + 3 s_rz^2). The peak over the nodes on each fillet arc, per unit axial
# displacement of the tip on the axis (the mode's scale drops out).


def working_shape(model: Model, near_hz: float, n_modes: int = 3):
    """(f_r Hz, displacement on the full P2 vector basis) of the working mode (largest k_eff),
    scaled to a unit axial displacement of the tip's centre (r = 0, top plane)."""
    sigma = (TWO_PI * near_hz) ** 2
    pairs, Muu = _eigenpairs(model, sigma, n_modes + 1)
    (ls, vs), (lo, vo) = [(lam[lam > 0.01 * sigma], vec[:, lam > 0.01 * sigma]) for lam, vec in pairs]
    ls, vs = ls[:n_modes], vs[:, :n_modes]
    mac = (vs.T @ (Muu @ vo)) ** 2
    f_r, f_a = np.sqrt(ls) / TWO_PI, np.sqrt(lo[np.argmax(mac, axis=1)]) / TWO_PI
    w = int(np.argmax(1 - (f_r / f_a) ** 2))
    ub = Basis(model.mesh, ElementVector(ElementTriP2()), intorder=6)
    u = np.zeros(ub.N)
    u[model.u_free] = vs[:, w]
    p = model.mesh.p[:, :ub.nodal_dofs.shape[1]]          # the vertices (a curved mesh lists them first)
    top = np.flatnonzero((np.abs(p[0]) < 1e-12) & (np.abs(p[1] - p[1].max()) < 1e-12))
    uz_tip = u[ub.nodal_dofs[1, top[0]]]
    return float(f_r[w]), u / uz_tip


def von_mises_rz(s):
    """Von Mises stress of axisymmetric Voigt stresses (..., 4) in (rr, tt, zz, rz), Pa."""
    rr, tt, zz, rz = np.moveaxis(np.asarray(s), -1, 0)
    return np.sqrt(0.5 * ((rr - tt) ** 2 + (tt - zz) ** 2 + (zz - rr) ** 2) + 3 * rz ** 2)


def nodal_stress(model: Model, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per block: (P2 node positions (2, n), node-averaged Voigt stress (n, 4) Pa of the metal
    blocks, NaN at nodes outside the block) as ``(positions, stress (n_blocks, n, 4))`` and the
    scalar P2 basis' element nodes."""
    mesh = model.mesh
    elem = ElementTriP2()
    X = np.asarray(elem.doflocs, float).T
    qb = Basis(mesh, ElementVector(elem), quadrature=(X, np.full(X.shape[1], 1.0 / X.shape[1])))
    pb = Basis(mesh, elem, intorder=2)
    f = qb.interpolate(u)
    r = np.maximum(qb.global_coordinates().value[0], 1e-300)
    S = np.stack([f.grad[0][0], f.value[0] / r, f.grad[1][1], f.grad[0][1] + f.grad[1][0]], axis=-1)
    nodes = np.asarray(pb.element_dofs).T                 # (nel, 6): the triangle's nodes, doflocs order
    out = np.full((len(model.sec.blocks), pb.N, 4), np.nan)
    for k, b in enumerate(model.sec.blocks):
        if b.poling:
            continue
        c = constants(b.material, 0)[0]
        el = np.flatnonzero(model.owner == k)
        sig = np.einsum("ij,enj->eni", c, S[el])
        count = np.bincount(nodes[el].ravel(), minlength=pb.N)
        for i in range(4):
            tot = np.bincount(nodes[el].ravel(), weights=sig[..., i].ravel(), minlength=pb.N)
            out[k, count > 0, i] = tot[count > 0] / count[count > 0]
    return pb.doflocs, out, nodes


def fillet_peaks(sec: Section, h: float, grade_radius: float, near_hz: float, splits: int = 0) -> tuple[float, dict]:
    """(f_r Hz, {block name + arc index: peak von Mises on that fillet arc per metre of axial tip
    displacement, Pa/m}) of the working mode on one mesh (:func:`mesh_section`'s arguments)."""
    model = assemble(sec, h, grade_radius, splits=splits)
    f_r, u = working_shape(model, near_hz)
    xy, stress, _nodes = nodal_stress(model, u)
    out = {}
    for k, b in enumerate(sec.blocks):
        for i, rc, zc in b.arcs:
            a, e = np.asarray(b.outline[i]), np.asarray(b.outline[(i + 1) % len(b.outline)])
            rho = math.hypot(*(a - (rc, zc)))
            d = np.hypot(xy[0] - rc, xy[1] - zc)
            # on the circle, between the arc's end points (inside the corner's box)
            lo, hi = np.minimum(a, e) - 1e-12, np.maximum(a, e) + 1e-12
            on = ((np.abs(d - rho) < 1e-9 * (1 + rho)) & (xy[0] >= lo[0]) & (xy[0] <= hi[0])
                  & (xy[1] >= lo[1]) & (xy[1] <= hi[1]) & np.isfinite(stress[k, :, 0]))
            angle = np.arctan2(xy[1][on] - zc, xy[0][on] - rc)
            out[f"{b.name}.{i}"] = arc_peak(angle, von_mises_rz(stress[k, on]))
    return f_r, out


def arc_peak(angle: np.ndarray, value: np.ndarray) -> float:
    """Largest value along an arc from node samples: the parabola through the best node and its
    two neighbours in angle (its vertex if it lies between them, else the best node). Taking the
    best node alone would leave an O(h^2) sampling error that hides the field's own rate."""
    o = np.argsort(angle)
    a, v = angle[o], value[o]
    j = int(np.argmax(v))
    if j == 0 or j == len(v) - 1:
        return float(v[j])
    (a0, a1, a2), (v0, v1, v2) = a[j - 1:j + 2], v[j - 1:j + 2]
    coef = np.polyfit([a0 - a1, 0.0, a2 - a1], [v0, v1, v2], 2)
    if coef[0] >= 0:
        return float(v1)
    x = -coef[1] / (2 * coef[0])
    return float(np.polyval(coef, np.clip(x, a0 - a1, a2 - a1)))
