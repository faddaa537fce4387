"""The bodies of revolution of an RPUD (stack, flange, horn) meshed as a revolved (r, z) section.

Where two coaxial parts of different diameter meet, the section has a 270-degree re-entrant
corner and the strain is singular along the whole circular edge. Isotropic tetrahedra graded
toward such an edge pay the edge size along its whole circumference, although the field is
smooth along it (~260k DOFs for 0.05 % on the working mode). Here the stack, the
flange and the horn are instead built as one fragmented (r, z) section of plane faces, meshed
in 2-D with the graded size field of :mod:`geometry.sizing` (elements of a few µm at the
corners), and swept around the axis in four quarter turns of ``n`` element layers each: long
elements along the edges, small across them. Gmsh sweeps them as prisms (tetrahedra and
pyramids where a triangle touches the axis); :func:`split_to_tets` cuts every prism and pyramid
into 10-node tetrahedra, each quadrilateral face along the diagonal through its lowest-numbered
vertex, which makes the cuts of neighbouring elements agree and always leaves a valid prism
cut (Dompierre et al. 1999, "How to subdivide pyramids, prisms and hexahedra into tetrahedra").
The coupler (slots, teeth: not a body of revolution) keeps its free mesh; Gmsh puts pyramids
on its face against the first ring, split the same way.

The swept elements are thin across the edges and long along them: a straight mid-edge node on
a 30-degree arc would sit outside an element a few µm thick. :func:`place_midnodes` therefore
puts every mid-edge node of a swept element at the midpoint in (r, theta, z), so each element
is the image of a straight one under the cylindrical map.

Gmsh (``gmsh.model.occ``) is handed in; this module does not import it.
"""

from __future__ import annotations

import math

import numpy as np

from rpud_common import ParameterError, check_choice

from .design_rpud import RPUDDesign
from .fillets import flange_horn_outlines

__all__ = ["can_revolve", "resolve_mesher", "MESHERS", "sectors_per_quarter", "revolved_parts", "stack_regions", "section_outlines", "section_face", "quad_triangles", "split_to_tets", "place_midnodes",
           "swept_quality", "jacobian_ratio", "straighten", "SECTORS_PER_QUARTER", "STRAIGHTEN_BELOW",
           "STRAIGHTEN_STEP", "VTK_EDGES", "prism_tets"]

SECTORS_PER_QUARTER = 3
"""Element layers per quarter turn at ``refine = 1`` (12 per circle, as the free mesh's
curvature rule); ``ceil(3 / refine)`` otherwise. On the article's drill at refine 1, 4 / 5 / 6 per
quarter (the sector cap of the section shrinking with them) move the first bending pair by
-0.056 / -0.090 / -0.117 %, torsion and the working mode by ~-0.03 % and ~-0.02 %
(benchmarks/study_swept_convergence.py --sectors)."""

STRAIGHTEN_BELOW = 0.05
"""A free 10-node element whose :func:`jacobian_ratio` falls below this after curving gets its
mid-edge nodes back on the straight edges (:func:`straighten`)."""

STRAIGHTEN_STEP = 0.125
"""Fraction of the way from arc to chord per round with which a free (unswept) build unfolds its
elements (:func:`straighten`). On the article's drill without slots and teeth at refine 1.4 (5
folded elements at the coupler's bore) the working mode and the tip amplitude per volt then lie
within 2.4e-5 / 4.2e-4 of Gmsh's high-order optimiser's, against 2.0e-4 / 3.1e-3 with whole edges."""

VTK_EDGES = ((0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3))
"""Edge order of a 10-node tetrahedron in meshio/VTK (and :class:`geometry.mesh.TaggedMesh`)."""


def can_revolve(design) -> bool:
    """True for an RPUD whose stack, flange and horn have straight (r, z) outlines (a stepped or
    conical horn; the exponential horn is a loft, meshed freely)."""
    return isinstance(design, RPUDDesign) and design.horn.profile in ("stepped", "conical")


MESHERS = ("auto", "free", "revolve")
"""``free``: every part meshed freely; ``revolve``: an RPUD's stack, flange and horn swept from a
graded (r, z) section, the coupler free; ``auto``: ``revolve`` where the design can be swept
(:func:`can_revolve`), else ``free``."""


def resolve_mesher(design, mesher: str) -> str:
    """``"free"`` or ``"revolve"`` for ``design`` (``auto`` resolved), or a ParameterError."""
    check_choice("--mesher", mesher, MESHERS)
    if mesher == "auto":
        return "revolve" if can_revolve(design) else "free"
    if mesher == "revolve" and not can_revolve(design):
        raise ParameterError("--mesher", mesher, "needs an RPUD design with a stepped or conical horn "
                             "(its stack, flange and horn swept from their section); use free or auto")
    return mesher


def sectors_per_quarter(refine: float) -> int:
    """Element layers per quarter turn at refinement ``refine``."""
    return max(1, math.ceil(SECTORS_PER_QUARTER / refine - 1e-9))


def section_face(occ, outline):
    """A plane face in y = 0 (x = r) of an (r, z) outline; its ``arcs`` (edge index -> centre,
    :class:`geometry.fillets.Outline`) as circular arcs."""
    pts = [occ.addPoint(r, 0.0, z) for r, z in outline]
    arcs = getattr(outline, "arcs", {})
    lines = []
    for i in range(len(pts)):
        j = (i + 1) % len(pts)
        if i in arcs:
            c = occ.addPoint(arcs[i][0], 0.0, arcs[i][1])
            lines.append(occ.addCircleArc(pts[i], c, pts[j]))
        else:
            lines.append(occ.addLine(pts[i], pts[j]))
    return occ.addPlaneSurface([occ.addCurveLoop(lines)])


def stack_regions(d: RPUDDesign) -> list[tuple[str, str, str, object, float, float]]:
    """(region, part, material, poling, z0, z1) of the stack's rings and shims (m)."""
    s = d.stack
    out = []
    for region, kind, z0, z1 in d.stack_layers():
        if kind == "ring":
            out.append((region, "stack", s.material, d.ring_poling(int(region.split("_")[1])), z0, z1))
        else:
            out.append((region, "electrodes", s.shim_material, None, z0, z1))
    return out


def section_outlines(d: RPUDDesign) -> list[tuple[str, str, str, object, tuple]]:
    """(region, part, material, poling, outline) of the stack, flange and horn: (r, z) polygons
    (m), counter-clockwise, in the order of :func:`geometry.solids.make_rpud`; the flange's and
    the horn's with their fillet arcs (:func:`geometry.fillets.flange_horn_outlines`; a stepped or
    conical horn). A bolt part is one outline per stack layer (one region): a plane across the
    stack at an electrode (where the matching cuts the drill) then cuts no element of it. A
    threaded bolt (:attr:`geometry.design_rpud.StackRings.threaded`) runs on into the coupler's
    thread zone (a ring of the coupler, region ``coupler``, bonded to it) and through the flange
    into the horn, one outline per part it passes."""
    s, f, h = d.stack, d.flange, d.horn
    ri, ro = s.inner_diameter / 2, s.outer_diameter / 2
    out = [(*meta, ((ri, z0), (ro, z0), (ro, z1), (ri, z1))) for *meta, z0, z1 in stack_regions(d)]
    if s.bolt_diameter:        # one piece per stack layer: its faces meet every electrode plane
        rb = s.bolt_diameter / 2
        spans = [(z0, z1) for _r, _kind, z0, z1 in d.stack_layers()]
        zone = d.thread_zone
        if zone is not None:
            zf, e = s.length, s.bolt_engagement
            spans = [zone] + spans + [(zf, zf + f.thickness), (zf + f.thickness, zf + e)]
            rc, rbore = d.coupler.outer_diameter / 2, d.coupler_bore / 2
            out.append(("coupler", "coupler", d.coupler.material, None,
                        ((rb, zone[0]), (rbore, zone[0]), (rc, zone[0]), (rc, zone[1]), (ri, zone[1]), (rb, zone[1]))))
        out += [("bolt", "bolt", s.bolt_material, None, ((0.0, z0), (rb, z0), (rb, z1), (0.0, z1)))
                for z0, z1 in spans]
    flange, horn = flange_horn_outlines(d)
    out.append(("flange_disc", "flange", f.material, None, flange))
    out.append(("horn", "horn", h.material, None, horn))
    return out


def revolved_parts(occ, d: RPUDDesign, n_per_quarter: int):
    """OCC solids of the stack, flange and horn, swept from one fragmented (r, z) section.

    Returns ``(region, part, material, poling, dimtags)`` per region, like
    :func:`geometry.solids.make_rpud`. The volumes carry Gmsh's structured-sweep constraint
    (``n_per_quarter`` prism layers per quarter turn); they must come out of the model's
    conformal fragment unchanged, which they do since their faces are not split by it.
    """
    outlines = section_outlines(d)
    faces = [(2, section_face(occ, o[4])) for o in outlines]
    _out, fmap = occ.fragment(faces, [])
    # the sweep: every face of the fragmented section together, so that shared edges sweep to
    # shared faces; a full turn in four quarters (a swept mesh needs an angle below pi)
    current = [dt for m in fmap for dt in m]
    owner = [i for i, m in enumerate(fmap) for _ in m]
    vols: list[list[tuple[int, int]]] = [[] for _ in outlines]
    for _q in range(4):
        ext = occ.revolve(current, 0, 0, 0, 0, 0, 1, math.pi / 2, numElements=[n_per_quarter], recombine=True)
        k = [j for j, dt in enumerate(ext) if dt[0] == 3]
        if len(k) != len(current):     # pragma: no cover - OCC's sweep output is one volume per face
            raise RuntimeError("unexpected OpenCASCADE sweep output")
        for i, j in zip(owner, k):
            vols[i].append(ext[j])
        current = [ext[j - 1] for j in k]      # each volume follows its top face
    return [(o[0], o[1], o[2], o[3], v) for o, v in zip(outlines, vols)]


# ============================================================================ mesh post-processing


def _pair_table(ref: np.ndarray, n_corners: int) -> dict[tuple[int, int], int]:
    """(corner i, corner j) -> local node whose reference point is their midpoint (edges and,
    for quadrilateral faces, both diagonals -> the face node)."""
    out = {}
    for i in range(n_corners):
        for j in range(i + 1, n_corners):
            mid = 0.5 * (ref[i] + ref[j])
            hit = np.flatnonzero(np.all(np.abs(ref[n_corners:] - mid) < 1e-9, axis=1))
            if len(hit):
                out[(i, j)] = out[(j, i)] = n_corners + int(hit[0])
    return out


def prism_tets(tags: np.ndarray) -> np.ndarray:
    """Corner-local tetrahedra (n, 3, 4) of prisms with global corner tags ``tags`` (n, 6):
    bottom 0 1 2, top 3 4 5. The face (x, y) is cut through its lowest-tagged vertex; x goes
    before y when that vertex is t_x or b_y, and the three precedences (never cyclic) give the
    staircase (b_p b_q b_r t_p) (t_p b_q b_r t_q) (t_p t_q b_r t_r)."""
    n = len(tags)
    before = {}
    for x, y in ((0, 1), (1, 2), (0, 2)):
        quad = np.stack([tags[:, x], tags[:, y], tags[:, 3 + x], tags[:, 3 + y]], axis=1)
        m = np.argmin(quad, axis=1)
        before[(x, y)] = (m == 2) | (m == 1)           # t_x or b_y
    wins = np.zeros((n, 3), dtype=np.int64)
    for (x, y), xy in before.items():
        wins[:, x] += xy
        wins[:, y] += ~xy
    order = np.argsort(-wins, axis=1, kind="stable")
    if not np.array_equal(np.sort(wins, axis=1), np.tile([0, 1, 2], (n, 1))):  # pragma: no cover
        raise RuntimeError("cyclic prism cut")
    p, q, r = order[:, 0], order[:, 1], order[:, 2]
    return np.stack([np.stack([p, q, r, 3 + p], 1), np.stack([3 + p, q, r, 3 + q], 1),
                     np.stack([3 + p, 3 + q, r, 3 + r], 1)], axis=1)


def quad_triangles(quads: np.ndarray) -> np.ndarray:
    """Corner-local triangles (n, 2, 3) of quadrilaterals with global corner tags ``quads``
    (n, 4, cyclic order), cut through the lowest-tagged corner: the one rule of every cut here
    (prisms, pyramids, and the swept faces' facet triangles)."""
    even = (np.argmin(quads, axis=1) % 2 == 0)[:, None, None]
    return np.where(even, np.array([[0, 1, 2], [0, 2, 3]])[None], np.array([[1, 2, 3], [1, 3, 0]])[None])


def _pyramid_tets(tags: np.ndarray) -> np.ndarray:
    """Corner-local tetrahedra (n, 2, 4) of pyramids (base 0 1 2 3, apex 4): the base's
    :func:`quad_triangles` joined to the apex."""
    tri = quad_triangles(tags[:, :4])
    return np.concatenate([tri, np.full(tri.shape[:2] + (1,), 4)], axis=2)


def split_to_tets(etype_props: dict, elements: dict) -> dict[int, np.ndarray]:
    """10-node (or 4-node) tetrahedra, VTK node order, of a Gmsh mesh with prisms and pyramids.

    Parameters
    ----------
    etype_props : dict
        Gmsh element type -> (number of corners, reference coordinates (n_nodes, 3)).
    elements : dict
        Gmsh element type -> global node tags (n_elements, n_nodes).

    Returns
    -------
    dict
        Gmsh element type -> (n_tets, 4 or 10) global node tags.
    """
    out = {}
    for etype, nodes in elements.items():
        n_corners, ref = etype_props[etype]
        corners = nodes[:, :n_corners]
        if n_corners == 4:
            local = np.tile(np.arange(4), (len(nodes), 1, 1))
        elif n_corners == 6:
            local = prism_tets(corners)
        elif n_corners == 5:
            local = _pyramid_tets(corners)
        else:  # pragma: no cover - the builder asks for 3-D elements only
            raise RuntimeError(f"unexpected element with {n_corners} corners")
        n_el, n_tet = local.shape[:2]
        rows = np.repeat(np.arange(n_el), n_tet)
        loc = local.reshape(-1, 4)
        tet = [nodes[rows, loc[:, i]] for i in range(4)]
        if nodes.shape[1] > n_corners:
            pairs = _pair_table(ref, n_corners)
            lut = np.full((n_corners, n_corners), -1, dtype=np.int64)
            for (i, j), k in pairs.items():
                lut[i, j] = k
            for i, j in VTK_EDGES:
                k = lut[loc[:, i], loc[:, j]]
                if (k < 0).any():  # pragma: no cover - every tetrahedron edge is an edge or a diagonal
                    raise RuntimeError("tetrahedron edge without a mid node")
                tet.append(nodes[rows, k])
        out[etype] = np.stack(tet, axis=1)
    return out


def orient(cells: np.ndarray, points: np.ndarray) -> np.ndarray:
    """The tetrahedra with positive volume (corners 1 and 2 swapped where negative)."""
    p = points[cells[:, :4]]
    vol = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0])
    flip = vol < 0
    if cells.shape[1] == 4:
        perm = [0, 2, 1, 3]
    else:   # edges (01 12 02 03 13 23) -> (02 21 01 03 23 13)
        perm = [0, 2, 1, 3, 6, 5, 4, 7, 9, 8]
    out = cells.copy()
    out[flip] = cells[flip][:, perm]
    return out


def place_midnodes(points: np.ndarray, cells: np.ndarray, tol: float = 1e-12) -> np.ndarray:
    """Points with every mid-edge node of ``cells`` (10-node, VTK order) at the midpoint of its
    edge in (r, theta, z), m (edges with an end on the axis keep the straight midpoint)."""
    out = points.copy()
    for k, (i, j) in enumerate(VTK_EDGES):
        a, b, m = points[cells[:, i]], points[cells[:, j]], cells[:, 4 + k]
        ra, rb = np.hypot(a[:, 0], a[:, 1]), np.hypot(b[:, 0], b[:, 1])
        ok = (ra > tol) & (rb > tol)
        ta, tb = np.arctan2(a[:, 1], a[:, 0]), np.arctan2(b[:, 1], b[:, 0])
        tm = ta + 0.5 * ((tb - ta + np.pi) % (2 * np.pi) - np.pi)
        rm = 0.5 * (ra + rb)
        mid = np.column_stack([rm * np.cos(tm), rm * np.sin(tm), 0.5 * (a[:, 2] + b[:, 2])])
        out[m[ok]] = mid[ok]
    return out


def _p2_gradients(xi: np.ndarray) -> np.ndarray:
    """Gradients (n_points, 10, 3) of the 10-node tetrahedron's shape functions (VTK order)."""
    lam = np.column_stack([1 - xi.sum(axis=1), xi])
    dlam = np.array([[-1.0, -1, -1], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    g = np.empty((len(xi), 10, 3))
    for i in range(4):
        g[:, i] = (4 * lam[:, i:i + 1] - 1) * dlam[i]
    for k, (i, j) in enumerate(VTK_EDGES):
        g[:, 4 + k] = 4 * (lam[:, j:j + 1] * dlam[i] + lam[:, i:i + 1] * dlam[j])
    return g


_NODES_REF = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [.5, 0, 0], [.5, .5, 0], [0, .5, 0],
                       [0, 0, .5], [.5, 0, .5], [0, .5, .5]], dtype=float)


def jacobian_ratio(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Per 10-node tetrahedron: the smallest det J at its ten nodes over the det J of its
    straight (corner) tetrahedron; <= 0 means the curved element is folded."""
    g = _p2_gradients(_NODES_REF)
    x = points[cells]                                            # (n, 10, 3)
    jac = np.einsum("nka,pkb->npab", x, g)
    det = np.linalg.det(jac)
    lin = np.linalg.det(np.stack([x[:, 1] - x[:, 0], x[:, 2] - x[:, 0], x[:, 3] - x[:, 0]], axis=2))
    return det.min(axis=1) / lin


def swept_quality(tm, swept: np.ndarray) -> dict[str, float]:
    """Quality of the final mesh ``tm`` whose swept elements are flagged by ``swept``: their
    count and smallest :func:`jacobian_ratio`, and the folded elements of the whole mesh
    (10-node meshes; 4-node: the count only)."""
    out = {"swept_elements": int(swept.sum())}
    if tm.cells.shape[1] == 10:
        ratio = jacobian_ratio(tm.points, tm.cells)
        out["swept_min_jacobian"] = float(ratio[swept].min())
        out["n_inverted"] = int(np.sum(ratio <= 0))
    return out


def straighten(points: np.ndarray, cells: np.ndarray, free: np.ndarray, below: float = STRAIGHTEN_BELOW,
               rounds: int | None = None, step: float = 1.0) -> tuple[np.ndarray, int]:
    """Points with the mid-edge nodes of folded free elements moved toward (``step`` = 1: onto)
    their straight edges, and how many elements were moved.

    A flat free tetrahedron against a coarse curved edge folds when its edge is bent onto the
    arc (seen: the coupler's bore next to the swept first ring, 12 sectors per circle); Gmsh's
    high-order optimiser repairs such elements too, but it stalls on the pyramids against the
    swept face and is not deterministic. Straightening keeps the element on its chord: a
    geometric error of one sagitta (0.26 mm on a 7.5 mm bore at 12 per circle) on a few elements
    of a free surface. With ``step`` < 1 each round moves the mid-edge nodes of the elements still
    below ``below`` a further ``step`` of the way from the arc to the chord, so an element keeps
    as much of its curvature as it can. ``rounds`` (default ``1 / step + 4``, 5 for whole edges)
    bounds the passes; at least ``1 / step`` allow full straightening.
    """
    if rounds is None:
        rounds = int(round(1 / step)) + 4
    pts = points.copy()
    share = np.zeros(len(cells))            # how far each element pulls its edges to the chord
    node_share = np.zeros(len(points))      # per mid-edge node: the largest pull on its edge, so
    moved = np.zeros(len(cells), dtype=bool)  # that a neighbour never curves a straightened edge back
    for _ in range(rounds):
        bad = free & (jacobian_ratio(pts, cells) < below) & (share < 1.0)
        if not bad.any():
            break
        share[bad] = np.minimum(1.0, share[bad] + step)
        c = cells[bad]
        for k, (i, j) in enumerate(VTK_EDGES):
            m = c[:, 4 + k]
            np.maximum.at(node_share, m, share[bad])
            mid = 0.5 * (pts[c[:, i]] + pts[c[:, j]])
            pts[m] = mid + (1.0 - node_share[m])[:, None] * (points[m] - mid)
        moved |= bad
    return pts, int(moved.sum())
