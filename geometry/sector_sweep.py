"""A swept sector of an RPUD: the stack, flange and horn swept here from Gmsh's graded (r, z)
section, the coupler meshed freely by Gmsh with periodic cut faces (:mod:`geometry.sector`).

Gmsh's own structured sweep (:func:`geometry.revolve.revolved_parts`) cannot be used for a
sector: OpenCASCADE's fragment merges the cut coupler's edges with the sweep's and Gmsh then
loses the sweep's extrusion constraints ("Unknown source point -1 for extrusion", Gmsh 4.15).
So Gmsh meshes only what it must, in one model:

* the coupler sector (a free volume), its far cut face a periodic copy of the near one;
* the section faces of the stack, flange and horn in the plane theta = 0 (2-D, graded by the
  same size fields as the whole-turn sweep), fragmented with the coupler so that the section's
  bottom edge is the coupler's near top edge;
* the coupler's top face, against the first ring, is meshed here before Gmsh meshes the rest
  (``Mesh.MeshOnlyEmpty``): the section's bottom edge nodes swept through the sector's
  layers, each quadrilateral cut through its lowest-numbered corner, the rule of
  :func:`geometry.revolve.quad_triangles`, so that the coupler's tetrahedra meet the swept ones
  face to face.

The section's triangles are then swept here into prisms (a triangle touching the axis into a
pyramid or a tetrahedron), cut into tetrahedra by :func:`geometry.revolve._prism_tets` with the
same numbering, and given mid-edge nodes at their (r, theta, z) midpoints
(:func:`geometry.revolve.place_midnodes`).

Gmsh (``gmsh``) is handed in; this module does not import it.
"""

from __future__ import annotations

import math

import numpy as np

from rpud_common import ParameterError

from .design_rpud import RPUDDesign
from .mesh import Electrode, Region, TaggedMesh
from .revolve import VTK_EDGES, prism_tets, orient, place_midnodes, quad_triangles, section_face, section_outlines
from .sector import rotation, set_periodic
from .solids import make_coupler
from .tagging import boundary_surfaces, planar_at, surface_rules

__all__ = ["sector_layers", "check_sweepable", "sector_model", "premesh_interface", "sweep_section",
           "assemble_sector"]


def sector_layers(per_quarter: int, sectors: int) -> int:
    """Element layers across one of ``sectors`` sectors: no wider than the whole turn's
    ``per_quarter`` layers per quarter."""
    return max(1, math.ceil(4 * per_quarter / sectors - 1e-9))


def check_sweepable(d: RPUDDesign) -> None:
    """Raise unless the coupler's top face is the first ring's bottom face (the same annulus,
    bored: the face's grid runs between two arcs)."""
    if not (math.isclose(d.coupler.outer_diameter, d.stack.outer_diameter, abs_tol=1e-9)
            and math.isclose(d.coupler_bore, d.stack.inner_diameter, abs_tol=1e-9) and d.coupler_bore > 0):
        raise ParameterError("--sectors", "with --mesher revolve",
                             "needs the coupler and the stack to meet face to face (equal outer and inner "
                             "diameters, a bore); use --mesher free")


def sector_model(gmsh, d: RPUDDesign, sectors: int):
    """The OCC model: ``(coupler_vols, section_faces, interface)`` with ``section_faces`` region ->
    face tags (plane theta = 0) and ``interface`` the top face of the coupler's free part (z =
    :attr:`geometry.design_rpud.RPUDDesign.coupler_top`)."""
    occ = gmsh.model.occ
    coupler = make_coupler(occ, d, sectors)
    outlines = section_outlines(d)
    faces = [(2, section_face(occ, o[4])) for o in outlines]
    _out, omap = occ.fragment(coupler + faces + _far_imprints(occ, d, sectors, outlines), [])
    occ.synchronize()
    vols = sorted({t for m in omap[:len(coupler)] for dim, t in m if dim == 3})
    section: dict[str, list[int]] = {}
    for o, m in zip(outlines, omap[len(coupler):len(coupler) + len(outlines)]):     # a region of several faces
        section[o[0]] = sorted(set(section.get(o[0], []) + [t for dim, t in m if dim == 2]))
    top = [f for f in boundary_surfaces(gmsh, vols) if planar_at(gmsh, f, "z", d.coupler_top, 1e-6)]
    if len(top) != 1:      # pragma: no cover - check_sweepable keeps the coupler top one face
        raise ParameterError("design", d.name, f"the coupler's top face is {len(top)} faces")
    return vols, section, top[0], {o[0]: o[1:4] for o in outlines}


def _far_imprints(occ, d: RPUDDesign, sectors: int, outlines) -> list:
    """Points on the far cut's top edge where the section's vertices split the near cut's: with
    a bolt the section's faces meet the coupler's closed top inside its edge, and the two cut
    faces must keep the same vertices to be meshed as periodic copies."""
    if d.bolt_thread is None:
        return []
    radii = sorted({r for o in outlines for r, z in o[4] if abs(z) < 1e-12 and r > 0})
    c, s = math.cos(2 * math.pi / sectors), math.sin(2 * math.pi / sectors)
    return [(0, occ.addPoint(r * c, r * s, 0.0)) for r in radii]


def _curve_nodes(gmsh, curve: int):
    """(tags, coords) of a meshed curve's nodes, its end points included, in parametric order."""
    tags, coords, par = gmsh.model.mesh.getNodes(1, curve, includeBoundary=True, returnParametricCoord=True)
    order = np.argsort(np.asarray(par))
    return np.asarray(tags, dtype=np.int64)[order], np.asarray(coords).reshape(-1, 3)[order]


def _cut_edge_nodes(gmsh, curves, theta: float):
    """(tags, coords) of the nodes on a face's straight edges at angle ``theta`` (one edge, or
    several where the section's vertices split it), ordered from the axis out."""
    tags, xyz = [], []
    for c in curves:
        if gmsh.model.getType(1, c) != "Line":
            continue
        t, x = _curve_nodes(gmsh, c)
        mid = x.mean(axis=0)
        if abs(math.atan2(mid[1], mid[0]) - theta) < 1e-6:
            tags.append(t)
            xyz.append(x)
    if not tags:                # pragma: no cover - the face is a sector of an annulus or disc
        raise RuntimeError("the coupler's top face is not a sector")
    t, first = np.unique(np.concatenate(tags), return_index=True)
    x = np.concatenate(xyz)[first]
    order = np.argsort(np.hypot(x[:, 0], x[:, 1]))
    return t[order], x[order]


def premesh_interface(gmsh, face: int, sectors: int, layers: int, new_tag: int):
    """Mesh the coupler's top face as the swept grid (see the module docstring).

    Must run after ``generate(1)`` with the face's two arcs transfinite (``layers`` + 1 nodes).
    Returns ``(grid, radii, next_tag)``: ``grid[i, j]`` the Gmsh node tag at the i-th node of
    the face's edge on the cut theta = 0 (from the axis side out) and layer j, ``radii[i]`` that
    node's radius (m).
    """
    alpha = 2 * math.pi / sectors
    curves = [abs(t) for _d, t in gmsh.model.getBoundary([(2, face)], oriented=False)]
    t0, x0 = _cut_edge_nodes(gmsh, curves, 0.0)
    t1, _x1 = _cut_edge_nodes(gmsh, curves, alpha)
    n = len(t0)
    if len(t1) != n:            # pragma: no cover - the far face is a periodic copy
        raise RuntimeError("the cut faces' top edges differ")
    grid = np.zeros((n, layers + 1), dtype=np.int64)
    grid[:, 0], grid[:, layers] = t0, t1
    # the arcs: their nodes by angle
    arc_nodes = {}
    for c in curves:
        if gmsh.model.getType(1, c) != "Line":
            tags, xyz = _curve_nodes(gmsh, c)
            r = float(np.hypot(xyz[0, 0], xyz[0, 1]))
            th = np.arctan2(xyz[:, 1], xyz[:, 0])
            arc_nodes[r] = tags[np.argsort(th)]
    if any(len(a) != layers + 1 for a in arc_nodes.values()):   # pragma: no cover
        raise RuntimeError("the coupler's top arcs are not transfinite")
    grid[-1] = arc_nodes[max(arc_nodes)]
    # a bored top's inner arc, or the axis node of a closed one
    grid[0] = arc_nodes[min(arc_nodes)] if len(arc_nodes) == 2 else t0[0]
    # interior nodes: the bottom edge's nodes rotated to each inner layer
    coords = []
    for j in range(1, layers):
        rot = x0[1:-1] @ rotation(j * alpha / layers).T
        grid[1:-1, j] = new_tag + np.arange(n - 2)
        new_tag += n - 2
        coords.append(rot)
    if coords:
        gmsh.model.mesh.addNodes(2, face, grid[1:-1, 1:layers].T.ravel().tolist(), np.concatenate(coords).ravel().tolist())
    quads = np.stack([grid[:-1, :-1], grid[1:, :-1], grid[1:, 1:], grid[:-1, 1:]], axis=-1).reshape(-1, 4)
    tri = np.take_along_axis(quads[:, None, :], quad_triangles(quads), axis=2).reshape(-1, 3)
    s = np.sort(tri, axis=1)
    tri = tri[np.all(s[:, 1:] != s[:, :-1], axis=1)]     # the axis' collapsed quads: their one triangle
    gmsh.model.mesh.addElementsByType(face, 2, [], tri.ravel().tolist())
    return grid, np.hypot(x0[:, 0], x0[:, 1]), new_tag


def _interface_grid(gmsh, face: int, points_rz: dict, sectors: int, layers: int, z_face: float) -> dict:
    """Section tag -> the coupler top face's node tags of its copies at layers 0 .. ``layers``
    (found by position: Gmsh renumbers nodes when it raises the order)."""
    from scipy.spatial import cKDTree

    tags, xyz, _ = gmsh.model.mesh.getNodes(2, face, includeBoundary=True)
    tags = np.asarray(tags, dtype=np.int64)
    xyz = np.asarray(xyz).reshape(-1, 3)
    tree = cKDTree(xyz)
    scale = float(np.abs(xyz).max())
    out = {}
    for t, p in points_rz.items():
        if abs(p[2] - z_face) > 1e-12 or p[0] <= 0:
            continue
        ring = np.array([rotation(j * 2 * math.pi / (sectors * layers)) @ p for j in range(layers + 1)])
        dist, k = tree.query(ring)
        if dist.max() <= 1e-9 * scale:
            out[t] = tags[k]
        elif dist.min() <= 1e-9 * scale:      # pragma: no cover - the face is the swept grid
            raise RuntimeError("the coupler's top face does not hold the swept grid")
    return out


def sweep_section(points_rz: dict, triangles: np.ndarray, sectors: int, layers: int, first_tag: int,
                  fixed: dict | None = None, rank: dict | None = None):
    """Swept prisms of a section mesh, cut into 4-node tetrahedra.

    Parameters
    ----------
    points_rz : dict
        Gmsh tag -> (x, 0, z) position of every section node (plane theta = 0).
    triangles : (m, 3) int
        Section triangles (Gmsh tags).
    first_tag : int
        First tag for the swept nodes (layers 1 ..).
    fixed : dict, optional
        Section tag -> its tags at layers 0 .. ``layers`` where they exist already (the
        coupler's top face, :func:`premesh_interface`).
    rank : dict, optional
        Tag -> the number that orders it in the prisms' cuts instead of the tag itself (the
        coupler's top face was cut by its tags before Gmsh renumbered them; every other node
        ranks after those, by its tag).

    Returns
    -------
    (tags, coords, tets, source) : the new node tags and positions (m), the tetrahedra (node
    tags) and the section triangle each came from.
    """
    alpha = 2 * math.pi / sectors
    base = np.array(sorted(points_rz), dtype=np.int64)
    xyz = np.array([points_rz[t] for t in base])
    on_axis = np.abs(xyz[:, 0]) <= 1e-12
    fixed = fixed or {}
    pos = {int(t): i for i, t in enumerate(base)}
    is_fixed = np.zeros(len(base), dtype=bool)
    is_fixed[[pos[t] for t in fixed]] = True
    copies = np.zeros((layers + 1, len(base)), dtype=np.int64)
    copies[0] = base
    new_tags, new_xyz = [], []
    tag = first_tag
    off = np.flatnonzero(~on_axis & ~is_fixed)
    for j in range(1, layers + 1):
        copies[j, on_axis] = base[on_axis]
        for t, row in fixed.items():
            copies[j, pos[t]] = row[j]
        copies[j, off] = tag + np.arange(len(off))
        tag += len(off)
        new_tags.append(copies[j, off])
        new_xyz.append(xyz[off] @ rotation(j * alpha / layers).T)
    idx = np.vectorize(pos.__getitem__)(triangles)
    tets, source = [], []
    rows = np.repeat(np.arange(len(idx)), 3)
    if rank:
        top = max(rank.values()) + 1
        order = np.vectorize(lambda t: rank.get(int(t), top + int(t)), otypes=[np.int64])
    for j in range(layers):
        prism = np.concatenate([copies[j][idx], copies[j + 1][idx]], axis=1)
        local = prism_tets(order(prism) if rank else prism)
        tets.append(np.take_along_axis(prism[rows], local.reshape(-1, 4), axis=1))
        source.append(rows)
    tets, source = np.concatenate(tets), np.concatenate(source)
    s = np.sort(tets, axis=1)
    keep = np.all(s[:, 1:] != s[:, :-1], axis=1)       # a prism on the axis collapses: drop the flat ones
    return np.concatenate(new_tags), np.concatenate(new_xyz), tets[keep], source[keep]


def _edge_breaks(design: RPUDDesign, axis: str, value: float) -> np.ndarray:
    """Sorted radii (m) of the section's vertices on the plane ``axis = value``: where its
    fragmented edges, and so the swept faces, begin and end."""
    ax = {"x": 0, "z": 1}.get(axis)
    if ax is None:      # pragma: no cover - the RPUD's rules are z planes
        raise ParameterError("surface rule", axis, "a swept sector tags z planes only")
    pts = [pt for o in section_outlines(design) for pt in o[4]]
    return np.array(sorted({round(r, 12) for r, z in pts if abs(z - value) < 1e-9}))


def add_midnodes(points: np.ndarray, cells4: np.ndarray, known: dict) -> tuple[np.ndarray, np.ndarray]:
    """10-node cells from 4-node ``cells4``: each edge's mid node from ``known`` (sorted corner
    pair -> node index) or a new node (appended to ``points``; placed by the caller)."""
    ends = np.asarray(VTK_EDGES)
    a, b = cells4[:, ends[:, 0]], cells4[:, ends[:, 1]]
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    mids = np.empty_like(lo)
    extra = []
    n = len(points)
    for idx in np.ndindex(lo.shape):
        key = (int(lo[idx]), int(hi[idx]))
        m = known.get(key)
        if m is None:
            m = known[key] = n + len(extra)
            extra.append(0.5 * (points[key[0]] + points[key[1]]))
        mids[idx] = m
    if extra:
        points = np.vstack([points, np.asarray(extra)])
    return points, np.concatenate([cells4, mids], axis=1)


def _check_interface(design: RPUDDesign, points: np.ndarray, cells: np.ndarray) -> None:
    """Raise if the coupler's free part and the section do not meet face to face (a boundary
    triangle inside their common annulus, or a face-bonded bolt's disc, at the free part's top)."""
    local = np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]])
    faces, counts = np.unique(np.sort(cells[:, :4][:, local].reshape(-1, 3), axis=1), axis=0, return_counts=True)
    p = points[faces[counts == 1]]
    r = np.hypot(p[:, :, 0], p[:, :, 1])
    bonded = ((r > design.coupler_bore / 2 + 1e-9) & (r < design.coupler.outer_diameter / 2 - 1e-9)
              | (design.bolt_thread is not None) & (r < design.stack.bolt_diameter / 2 - 1e-9))
    inside = np.all((np.abs(p[:, :, 2] - design.coupler_top) < 1e-12) & bonded, axis=1)
    if inside.any():    # pragma: no cover - the cuts follow one order on both sides
        raise RuntimeError(f"{int(inside.sum())} faces of the coupler's top do not match the first ring's "
                           "or the bolt's")


def assemble_sector(design: RPUDDesign, coords: np.ndarray, coupler_cells: np.ndarray, swept: dict,
                    region_meta: dict, coupler_facets: dict) -> tuple[TaggedMesh, np.ndarray]:
    """The sector's TaggedMesh from the coupler's 10-node cells (indices into ``coords``) and the
    swept 4-node cells per region (``swept``: region -> cells), with the swept regions' facet
    sets found by :func:`geometry.tagging.surface_rules`. Returns ``(mesh, swept_mask)``."""
    known = {}
    ends = np.asarray(VTK_EDGES)
    for k, (i, j) in enumerate(ends):
        a, b = coupler_cells[:, i], coupler_cells[:, j]
        for lo, hi, m in zip(np.minimum(a, b).tolist(), np.maximum(a, b).tolist(), coupler_cells[:, 4 + k].tolist()):
            known[(lo, hi)] = m
    regions = [Region("coupler", "coupler", design.coupler.material, None)]
    cells, cell_region = [coupler_cells], [np.zeros(len(coupler_cells), dtype=np.int64)]
    points = coords
    swept_mask = [np.zeros(len(coupler_cells), dtype=bool)]
    for region, c4 in swept.items():
        part, material, poling = region_meta[region]
        if region != "coupler":     # a threaded bolt's thread zone is the coupler's
            regions.append(Region(region, part, material, None if poling is None else tuple(float(x) for x in poling)))
        points, c10 = add_midnodes(points, c4, known)
        cells.append(c10)
        cell_region.append(np.full(len(c10), [r.name for r in regions].index(region), dtype=np.int64))
        swept_mask.append(np.ones(len(c10), dtype=bool))
    cells = np.concatenate(cells)
    cell_region = np.concatenate(cell_region)
    swept_mask = np.concatenate(swept_mask)
    points = place_midnodes(points, cells[swept_mask])
    cells = orient(cells, points)
    facet_sets = dict(coupler_facets)
    local = np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]])
    names = [r.name for r in regions]
    for name, region, axis, value, rmin in surface_rules(design):
        if region == "coupler":
            continue
        c = cells[cell_region == names.index(region), :4]
        tri = c[:, local].reshape(-1, 3)
        p = points[tri]
        ax = "xyz".index(axis)
        on = np.all(np.abs(p[:, :, ax] - value) < 1e-9, axis=1)
        if rmin > 0:
            # per face, as geometry.tagging: a face is the sweep of one section edge on the plane,
            # kept when it reaches beyond rmin (its triangles share the interval of their centroid)
            rc = np.hypot(p[:, :, 0], p[:, :, 1]).mean(axis=1)    # mean corner radius: not the chord's
            ends = _edge_breaks(design, axis, value)
            upper = ends[np.minimum(np.searchsorted(ends, rc), len(ends) - 1)]
            on &= upper >= rmin
        if on.any():
            facet_sets[name] = np.concatenate([facet_sets.get(name, np.zeros((0, 3), dtype=np.int64)), tri[on]])
    missing = sorted({r[0] for r in surface_rules(design)} - set(facet_sets))
    if missing:
        raise ParameterError("design", design.name, f"no surface found for {', '.join(missing)}")
    _check_interface(design, points, cells)
    used = np.unique(cells)
    renum = np.full(len(points), -1, dtype=np.int64)
    renum[used] = np.arange(len(used))
    roles = design.electrode_roles()
    electrodes = tuple(Electrode(n, roles[n]) for n in sorted(roles, key=lambda s: int(s.split("_")[1])))
    tm = TaggedMesh(points[used], renum[cells], cell_region, tuple(regions),
                    {k: renum[v] for k, v in facet_sets.items()}, electrodes, design.used_materials())
    return tm, swept_mask


def mesh_swept_sector(gmsh, d: RPUDDesign, sizes: dict, refine: float, grade: bool, order: int, sectors: int,
                      per_quarter: int, algorithm3d: int, snap: float, meshing=None):
    """Build and mesh the swept sector in the current (empty) Gmsh model (see the module docstring).

    ``meshing``: a :class:`geometry.sector.SectorMeshing` (coupler refined further, notch
    grading, layer angle); ``grade`` grades the notch edges at its fraction or the default.

    Returns ``(mesh, swept_mask)``; coordinates rounded to multiples of ``snap`` (m). Order 2 only.
    """
    from .revolve import split_to_tets
    from .sizing import CURVATURE_ELEMENTS, apply_fields

    from .sector import SectorMeshing

    meshing = meshing or SectorMeshing()
    check_sweepable(d)
    layers = sector_layers(per_quarter, sectors)
    if meshing.layer_deg is not None:
        layers = max(1, math.ceil(360.0 / sectors / meshing.layer_deg - 1e-9))
    coupler_refine = meshing.coupler_refine
    grade = grade or meshing.notch_fraction is not None
    vols, section, top, meta = sector_model(gmsh, d, sectors)
    set_periodic(gmsh, vols, sectors)
    if coupler_refine != 1.0:
        sizes = {k: v * coupler_refine if k == "coupler" or k.startswith("@") else v for k, v in sizes.items()}
    if meshing.slot_refine != 1.0 and "@slots" in sizes:
        sizes = {**sizes, "@slots": sizes["@slots"] * meshing.slot_refine}
    apply_fields(gmsh, d, sizes, {"coupler": vols}, refine, grade=grade, revolve=True, region_faces=section,
                 notch_fraction=meshing.notch_fraction, junction_fraction=meshing.junction_fraction,
                 notch_classes=meshing.notch_classes)
    if coupler_refine != 1.0:
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", CURVATURE_ELEMENTS / (refine * coupler_refine))
    gmsh.option.setNumber("Mesh.Algorithm", 6)
    gmsh.option.setNumber("Mesh.Algorithm3D", algorithm3d)
    gmsh.option.setNumber("Mesh.Optimize", 1)
    gmsh.option.setNumber("Mesh.ElementOrder", 1)
    for _d, c in gmsh.model.getBoundary([(2, top)], oriented=False):
        if gmsh.model.getType(1, abs(c)) != "Line":
            gmsh.model.mesh.setTransfiniteCurve(abs(c), layers + 1)
    gmsh.model.mesh.generate(1)
    next_tag = int(gmsh.model.mesh.getMaxNodeTag()) + 1
    grid, radii, _ = premesh_interface(gmsh, top, sectors, layers, next_tag)
    gmsh.option.setNumber("Mesh.MeshOnlyEmpty", 1)
    gmsh.model.mesh.generate(2)
    gmsh.model.mesh.generate(3)
    if order != 2:      # pragma: no cover - build() refuses it (the sweep builds 10-node cells)
        raise ParameterError("order", order, "must be 2 for a swept sector")
    gmsh.model.mesh.setOrder(2)
    node_tags, xyz, _ = gmsh.model.mesh.getNodes()
    node_tags = np.asarray(node_tags, dtype=np.int64)
    xyz = np.asarray(xyz).reshape(-1, 3)
    next_tag = int(node_tags.max()) + 1      # setOrder renumbers: the swept nodes come after all
    # the section: its corner nodes and triangles
    tri = []
    for region, faces in section.items():
        for f in faces:
            types, _et, en = gmsh.model.mesh.getElements(2, f)
            for t, nodes in zip(types, en):
                npe = gmsh.model.mesh.getElementProperties(int(t))[3]
                tri.append((region, np.asarray(nodes, dtype=np.int64).reshape(-1, npe)[:, :3]))
    where = dict(zip(node_tags.tolist(), range(len(node_tags))))
    corner_tags = np.unique(np.concatenate([t for _r, t in tri]))
    points_rz = {int(t): xyz[where[int(t)]] for t in corner_tags}
    fixed = _interface_grid(gmsh, top, points_rz, sectors, layers, d.coupler_top)
    # the top face was cut by its tags before setOrder renumbered them: the prisms below it are
    # cut in that order too (rows of the grid: the top face's edge nodes outward, found by radius)
    rank = {}
    for t, copies in fixed.items():
        i = int(np.argmin(np.abs(radii - float(np.hypot(*points_rz[t][:2])))))
        if abs(radii[i] - float(np.hypot(*points_rz[t][:2]))) > 1e-9 * radii[-1]:   # pragma: no cover
            raise RuntimeError("the coupler's top face lost nodes")
        rank.update({int(copies[j]): int(grid[i, j]) for j in range(layers + 1)})
    all_tri = np.concatenate([t for _r, t in tri])
    owner = np.concatenate([np.full(len(t), k) for k, (_r, t) in enumerate(tri)])
    new_tags, new_xyz, tets, source = sweep_section(points_rz, all_tri, sectors, layers, next_tag, fixed, rank)
    tags_all = np.concatenate([node_tags, new_tags])
    coords = np.round(np.concatenate([xyz, new_xyz]) / snap) * snap
    index = np.full(int(tags_all.max()) + 1, -1, dtype=np.int64)
    index[tags_all] = np.arange(len(tags_all))
    # the coupler's 10-node cells (VTK order) and its facet sets
    props, by_type = {}, {}
    for v in vols:
        types, et, en = gmsh.model.mesh.getElements(3, v)
        for t, e, nodes in zip(types, et, en):
            t = int(t)
            p = gmsh.model.mesh.getElementProperties(t)
            props[t] = (int(p[5]), np.asarray(p[4]).reshape(-1, 3))
            arr = index[np.asarray(nodes, dtype=np.int64).reshape(len(e), -1)]
            by_type[t] = np.concatenate([by_type[t], arr]) if t in by_type else arr
    coupler_cells = np.concatenate(list(split_to_tets(props, by_type).values()))
    coupler_facets = {}
    for name, region, axis, value, _rmin in surface_rules(d):
        if region != "coupler":
            continue
        for f in boundary_surfaces(gmsh, vols):
            if planar_at(gmsh, f, axis, value, 1e-6):
                for t, e, nodes in zip(*gmsh.model.mesh.getElements(2, f)):
                    conn = index[np.asarray(nodes, dtype=np.int64).reshape(len(e), -1)[:, :3]]
                    coupler_facets[name] = np.concatenate([coupler_facets.get(name, np.zeros((0, 3), np.int64)), conn])
    regions = [r for r, _t in tri]
    swept = {}
    for region in section:
        mine = np.flatnonzero(np.isin(owner[source], [k for k, r in enumerate(regions) if r == region]))
        swept[region] = index[tets[mine]]
    tm, swept_mask = assemble_sector(d, coords, coupler_cells, swept, meta, coupler_facets)
    return tm, swept_mask
