"""Thin layers of a stack (bonds, shims, insulators) meshed as structured extrusions.

A free Delaunay mesh needs elements about as small as the thinnest piece, and the size spreads
into the neighbours' shared faces: a 0.275 mm bond on a 55 mm disc asks for millions of
tetrahedra. A *layer* is meshed instead as the extrusion of its bottom face's 2-D mesh through
its thickness, one or two elements deep (:data:`LAYER_ELEMENTS`, :data:`LAYER_ELEMENTS_EDGE`),
each prism split into three tetrahedra
(no new element types: the solver sees ordinary, here flat, 10-node tetrahedra). Its in-plane
size is that of the thick neighbours it is bonded to, whose deformation it follows.

Which segments are layers (:func:`layer_plan`): cylinders and boxes of a
:class:`~geometry.design_stack.StackDesign` thinner than :data:`LAYER_RATIO` times their in-plane
size. Layers that touch each other form a *run*; every layer of a run is imprinted with the
outlines (circles, rectangles) of every member of the run and of the thick segments at its two
ends, so that its bottom and top faces have the same edges and the conformal fragment of the
whole model leaves the extruded volumes unchanged (Gmsh refuses an extrusion whose top face
was split afterwards).

Accuracy (``tests/test_thin_layers.py``): the coupled longitudinal mode of a 3 mm aluminium /
0.25 mm epoxy / PZT-4 rod is within 0.06 % of a free mesh with two elements through the bond
(5x the elements); the thickness mode of the 55 mm sandwich with two 0.275 mm bonds moves by
0.01 % under one uniform refinement; a 50 um epoxy layer in a steel rod lowers its longitudinal
mode as the constrained-layer spring k = M A / t predicts, within 0.03 %.

Limit: a layer with no thick neighbour (a free thin plate) keeps its own wavelength-rule size,
which suits in-plane waves, not flexure; give ``--mesh-size`` for its bending modes (a 40 mm x
0.3 mm aluminium disc, first flexural mode vs Kirchhoff: +106 % at the 2 kHz default size,
+0.6 % at 4 mm, +0.2 % at 2 mm, one element through the thickness).

Everything here is plain geometry bookkeeping except :func:`make_layer`, which takes Gmsh's
OpenCASCADE kernel as an argument (gmsh is never imported here).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .design_base import DesignBase
from .design_stack import Segment, StackDesign

__all__ = ["Layer", "layer_plan", "make_layer", "rim_fields", "edge_fraction", "layer_element_estimate",
           "LAYER_RATIO", "LAYER_ELEMENTS", "LAYER_ELEMENTS_EDGE", "LAYER_KINDS", "RIM_SIZE", "RIM_GROWTH",
           "RIM_FRACTION"]

LAYER_RATIO = 0.5
"""A cylinder or box segment shorter (along z) than this fraction of its in-plane element size
is meshed as a layer. Thicker segments keep the free mesh with its thin-part cap (two elements
through the thickness), so the meshes of the existing designs do not change."""

LAYER_ELEMENTS = 1
"""Elements (prism layers, each split into three tetrahedra) through a layer's thickness: one
quadratic element holds a strain that varies linearly through the layer, all a bond between
stiff neighbours shows away from its edges (55 mm sandwich: 1 or 2 change its thickness mode by
4e-6)."""

LAYER_ELEMENTS_EDGE = 2
"""Elements through the thickness of a layer whose edge zone is large (:data:`RIM_FRACTION`):
the free edge bulges (3 mm stack: 2 instead of 1 moves the coupled mode by 0.06 %)."""

LAYER_KINDS = ("cylinder", "box")
"""Segment kinds that can be layers (prismatic along z)."""

RIM_SIZE = 1.0
"""In-plane element size at a layer's edges (its rim and the imprinted outlines), in layer
thicknesses: a compliant bond bulges at a free edge over a zone about one thickness wide."""

RIM_GROWTH = 1.0
"""Growth of the element size with the distance from a layer's edge (size / distance)."""

RIM_FRACTION = 0.05
"""A layer's edges are refined when the edge zone (perimeter x thickness) exceeds this fraction
of its area (a 4 mm disc with a 0.25 mm bond: 0.25; a 55 mm disc with 0.275 mm: 0.02, where
the zone changes the resonance by ~0.01 % and refining it would triple the mesh)."""

_TOL = 1e-12


@dataclass(frozen=True)
class Layer:
    """How one segment is meshed as a layer.

    Attributes
    ----------
    name : str
        Segment (and region) name.
    n_elements : int
        Element layers through the thickness.
    size : float
        In-plane element size, m.
    rim : float or None
        In-plane element size at the layer's edges, m (None: not refined, see
        :data:`RIM_FRACTION`).
    outlines : tuple of (str, float)
        ``(segment, z)``: the cross-sections (at height ``z``, m) whose outlines are imprinted
        on the layer's faces.
    """

    name: str
    n_elements: int
    size: float
    rim: float | None
    outlines: tuple[tuple[str, float], ...]


def edge_fraction(seg: Segment) -> float:
    """Perimeter x thickness / area of a layer's cross-section (its free-edge zone)."""
    if seg.kind == "box":
        return 2 * (seg.thickness + seg.width) * seg.length / (seg.thickness * seg.width)
    d, b = seg.outer_diameter, seg.inner_diameter
    return math.pi * (d + b) * seg.length / (math.pi / 4 * (d * d - b * b))


def _runs(segments, ext, layered: set[str]) -> list[list[int]]:
    """Index lists of maximal runs of touching layered segments (segments are in z order)."""
    runs: list[list[int]] = []
    for i, seg in enumerate(segments):
        if seg.name not in layered:
            continue
        if runs and runs[-1][-1] == i - 1 and abs(ext[segments[i - 1].name][1] - ext[seg.name][0]) < _TOL:
            runs[-1].append(i)
        else:
            runs.append([i])
    return runs


def _end_neighbours(segments, ext, run: list[int]) -> list[tuple[int, float]]:
    """Thick segments touching the two ends of a run: ``(index, z of the shared plane)``."""
    out = []
    lo, hi = run[0], run[-1]
    if lo > 0 and abs(ext[segments[lo - 1].name][1] - ext[segments[lo].name][0]) < _TOL:
        out.append((lo - 1, ext[segments[lo].name][0]))
    if hi + 1 < len(segments) and abs(ext[segments[hi + 1].name][0] - ext[segments[hi].name][1]) < _TOL:
        out.append((hi + 1, ext[segments[hi].name][1]))
    return out


def layer_plan(design: DesignBase, own: dict[str, float], capped: dict[str, float],
               refine: float = 1.0) -> dict[str, Layer]:
    """The segments of ``design`` meshed as layers.

    Parameters
    ----------
    design : DesignBase
        Only a :class:`StackDesign` has layers (an RPUD's shims keep their sizes).
    own : dict
        Region -> element size of its own material (wavelength rule or ``--mesh-size``), m.
    capped : dict
        Region -> size after the thin-part caps (what a free mesh would use), m.
    refine : float
        Uniform refinement: every size times this, the element layers through the thickness
        divided by it. Which segments are layers is decided at factor 1, so that a refinement
        study compares like with like.

    Returns
    -------
    dict
        Segment name -> :class:`Layer`; the layer's in-plane size is the smallest capped size
        of the thick segments at the ends of its run (its own size if it has none).
    """
    if not isinstance(design, StackDesign):
        return {}
    segs = design.segments
    ext = design.segment_extents()
    layered = {s.name for s in segs if s.kind in LAYER_KINDS and s.length < LAYER_RATIO * own[s.name]}
    # a layer that is thick compared with its neighbours' size is meshed freely after all; that
    # changes the runs, so iterate (each pass only removes layers)
    while True:
        plan: dict[str, Layer] = {}
        thick = set()
        for run in _runs(segs, ext, layered):
            ends = _end_neighbours(segs, ext, run)
            size = min((capped[segs[i].name] for i, _z in ends), default=min(own[segs[i].name] for i in run))
            outlines = tuple((segs[i].name, ext[segs[i].name][0]) for i in run)
            outlines += tuple((segs[i].name, z) for i, z in ends)
            for i in run:
                seg = segs[i]
                if seg.length >= LAYER_RATIO * size:
                    thick.add(seg.name)
                edge = RIM_SIZE * seg.length < size and edge_fraction(seg) > RIM_FRACTION
                n_elements = math.ceil((LAYER_ELEMENTS_EDGE if edge else LAYER_ELEMENTS) / refine - 1e-9)
                rim = RIM_SIZE * seg.length * refine if edge else None
                plan[seg.name] = Layer(seg.name, n_elements, size * refine, rim, outlines)
        if not thick:
            return plan
        layered -= thick


def layer_element_estimate(seg: Segment, layer: Layer) -> float:
    """Tetrahedra of a layer and of the refinement its rim brings into the neighbours.

    Three per prism; prisms = triangles of the face (edge h: sqrt(3)/4 h^2, Gmsh's a little
    smaller) x element layers. A refined rim of perimeter P adds triangles in the strip where
    the size grows from ``rim`` to ``size`` and, in the two neighbours, tetrahedra in the
    half-tube around the edge (about 3 P / (growth^2 rim), calibrated on the 3 mm test stack).
    """
    area = seg.area_at(0.0)
    n = 3.0 * layer.n_elements * area / (0.4 * layer.size ** 2)
    if layer.rim is not None:
        perimeter = edge_fraction(seg) * area / seg.length
        strip = perimeter / (0.4 * RIM_GROWTH) * (1 / layer.rim - 1 / layer.size)
        n += 3.0 * layer.n_elements * strip + 3.0 * perimeter / (RIM_GROWTH ** 2 * layer.rim)
    return n


# ============================================================================ OCC


def _section(occ, seg: Segment, seg_z0: float, z_at: float, z_place: float) -> list[tuple[int, int]]:
    """OCC plane surface(s) at height ``z_place``: the cross-section of ``seg`` (which starts at
    ``seg_z0``) at height ``z_at`` (it differs along a cone only)."""
    if seg.kind == "box":
        return [(2, occ.addRectangle(-seg.thickness / 2, -seg.width / 2, z_place, seg.thickness, seg.width))]
    d = seg.outer_diameter
    if seg.kind == "cone":
        d += (seg.end_diameter - seg.outer_diameter) * min(max((z_at - seg_z0) / seg.length, 0.0), 1.0)
    disk = [(2, occ.addDisk(0, 0, z_place, d / 2, d / 2))]
    if seg.inner_diameter > 0:
        hole = occ.addDisk(0, 0, z_place, seg.inner_diameter / 2, seg.inner_diameter / 2)
        disk, _ = occ.cut(disk, [(2, hole)])
    return disk


def make_layer(occ, design: StackDesign, layer: Layer) -> list[tuple[int, int]]:
    """The OCC volumes of one layer: its bottom cross-section, imprinted with the run's
    outlines, extruded through the thickness with ``layer.n_elements`` mesh layers."""
    segs = {s.name: s for s in design.segments}
    ext = design.segment_extents()
    seg = segs[layer.name]
    z0, z1 = ext[layer.name]
    face = _section(occ, seg, z0, z0, z0)
    others = []
    for name, z_at in layer.outlines:
        if name != layer.name:
            others += _section(occ, segs[name], ext[name][0], z_at, z0)
    if others:
        out, out_map = occ.fragment(face, others)
        face = sorted({dt for pieces in out_map[:len(face)] for dt in pieces})
        stray = [dt for dt in out if dt not in face]
        if stray:
            occ.remove(stray, recursive=True)
    swept = occ.extrude(face, 0, 0, z1 - z0, numElements=[layer.n_elements], recombine=False)
    return [dt for dt in swept if dt[0] == 3]


def rim_fields(gmsh, layers: dict[str, Layer], region_vols: dict[str, list[int]]) -> list[int]:
    """Gmsh size fields refining the edges of the layers that have a ``rim`` size: that size
    at the edge curves, growing by ``RIM_GROWTH`` per unit distance up to the in-plane size."""
    fields = []
    for name, layer in layers.items():
        if layer.rim is None:
            continue
        h_min = layer.rim
        faces = gmsh.model.getBoundary([(3, v) for v in region_vols[name]], combined=False, oriented=False)
        curves = gmsh.model.getBoundary(faces, combined=False, oriented=False)
        tags = sorted({abs(c) for dim, c in curves if dim == 1})
        longest = max(gmsh.model.occ.getMass(1, c) for c in tags)
        dist = gmsh.model.mesh.field.add("Distance")
        gmsh.model.mesh.field.setNumbers(dist, "CurvesList", tags)
        gmsh.model.mesh.field.setNumber(dist, "Sampling", max(20, math.ceil(2 * longest / h_min)))
        thr = gmsh.model.mesh.field.add("Threshold")
        for opt, val in (("InField", dist), ("SizeMin", h_min), ("SizeMax", layer.size), ("DistMin", 0.0),
                         ("DistMax", (layer.size - h_min) / RIM_GROWTH), ("StopAtDistMax", 1)):
            gmsh.model.mesh.field.setNumber(thr, opt, val)
        fields.append(thr)
    return fields

