"""Resource guard: estimate the mesh and the FE problem of a design before building them.

Meshing and solving cost grows with the cube of the inverse element size, so a mistyped
``--mesh-size`` or a sub-millimetre feature can ask for billions of elements and hang Gmsh or
exhaust memory long after the run started. :func:`estimate` predicts the element count from
the same per-region sizes the builder uses (:func:`geometry.sizing.region_sizes`), capped as
Gmsh caps them (curvature: 12 elements per circle at ``refine`` 1; at least one layer across a
thin part; thin layers meshed as structured extrusions counted as such, see
:mod:`geometry.layers`), adds the graded zones around re-entrant edges when the mesh is graded
(:func:`geometry.sizing.graded_edges`), and derives nodes, degrees of freedom and the memory of a sparse direct factorisation from it.
:func:`check_budget` refuses a run above the budget with one line naming the option to change.

Calibration (default RPUD design and its textbook variants, order 2): the estimate lies within
a factor of about two of Gmsh's count; the budgets leave a margin of that size.
"""

from __future__ import annotations

import logging
import math
import dataclasses
from dataclasses import dataclass

from rpud_common import ParameterError

__all__ = ["Estimate", "estimate", "sector_estimate", "fillet_sector_dofs", "check_budget", "MAX_ELEMENTS", "MAX_DOFS", "TETS_PER_CUBE"]

log = logging.getLogger(__name__)

MAX_ELEMENTS = 300_000
"""Budget of estimated tetrahedra for meshing alone (``python -m geometry``): ~25x the default
design, about a minute of Gmsh and 2 GB."""

MAX_DOFS = 500_000
"""Budget of estimated degrees of freedom for an FE solve (``fem``, ``results``): ~7x the
the article's drill (68 561 DOFs, 1 GB peak); the factorisation memory model below puts 500 000 DOFs
near 10 GB."""

TETS_PER_CUBE = 7.0
"""Tetrahedra per cube of the target size ``h`` in a Delaunay mesh (a regular tetrahedron of
edge h fills h^3 / 8.5; Gmsh's are a little larger on average)."""

def _curvature_fraction(refine: float) -> float:
    """Gmsh's Mesh.MeshSizeFromCurvature = N / refine caps the size at radius x 2 pi refine / N."""
    from .sizing import CURVATURE_ELEMENTS

    return 2 * math.pi * refine / CURVATURE_ELEMENTS


REVOLVE_FACTOR = 1.7
"""DOFs of ``mesher="revolve"`` over those of the free mesh (the article's drill: 111 619 vs 68 561,
1.63x; the swept section's graded edges cost about the same at every ``refine``)."""


SECTOR_FACTOR = 1.207
"""DOFs of the ``k = 0`` swept sector (:data:`geometry.sector.AXIAL_RULE`) over the whole drill's
swept, graded estimate at the rule's refine divided by the sector count (the article's drill at horn
67.1 mm and coupler 49.9 mm with sharp horn corners at ``--refine 1``: 80 345 DOFs against 399 048 / 6)."""

SECTOR_EXPONENT = 2.36
"""Growth of the sector's DOFs as ``refine^-SECTOR_EXPONENT`` (the article's drill with sharp horn
corners: 80 345 DOFs at ``--refine 1``, 268 106 at 0.6; the notch grading and the layer rule grow slower than h^-3)."""


@dataclass(frozen=True)
class Estimate:
    """Predicted size of a mesh and of its FE problem.

    Attributes
    ----------
    elements : int
        Tetrahedra.
    nodes : int
        Mesh nodes at the requested order.
    dofs : int
        Degrees of freedom of the piezo-elastic model (3 displacements + potential per node).
    memory_bytes : float
        Peak memory of assembly and sparse direct factorisation, bytes (rough: fill-in of a 3-D
        nested-dissection factor grows as DOFs^(4/3); calibrated at 68 561 DOFs -> 1 GB).
    smallest_size : float
        Smallest effective element size, m.
    """

    elements: int
    nodes: int
    dofs: int
    memory_bytes: float
    smallest_size: float

    def describe(self) -> str:
        return (f"~{self.elements:,} tetrahedra, ~{self.dofs:,} DOFs, ~{self.memory_bytes / 1e9:.1f} GB "
                f"(smallest element ~{self.smallest_size * 1e3:.3g} mm)")


def _regions(design) -> list[tuple[str, float, float, float]]:
    """``(region, volume m^3, axial length m, radius m)`` of every region."""
    from .design_cad import CadDesign
    from .design_rpud import RPUDDesign

    out = []
    if isinstance(design, RPUDDesign):
        lengths = {"coupler": design.coupler.length, "flange_disc": design.flange.thickness,
                   "horn": design.horn.length}
        radii = {"coupler": design.coupler.outer_diameter / 2, "flange_disc": design.flange.outer_diameter / 2,
                 "horn": min(design.horn.back_diameter, design.horn.tip_diameter) / 2}
        s = design.stack
        for region, kind, z0, z1 in design.stack_layers():
            lengths[region] = z1 - z0
            radii[region] = s.outer_diameter / 2
        if s.bolt_diameter:
            z0, z1 = design.part_extents()["bolt"]
            lengths["bolt"], radii["bolt"] = z1 - z0, s.bolt_diameter / 2
        for region, _part, _mat, vol in design.region_table():
            out.append((region, vol, lengths[region], radii[region]))
    elif isinstance(design, CadDesign):
        boxes = design.resolve().region_box
        for region, _part, _mat, vol in design.region_table():
            b = boxes[region]
            # the bounding box's smaller half-width stands for the radius of a round piece
            out.append((region, vol, b[5] - b[2], 0.5 * min(b[3] - b[0], b[4] - b[1])))
    else:
        for seg in design.segments:
            if seg.kind == "box":
                radius = math.inf  # flat sides: no curvature cap, thin sides are handled by the size rule
            else:
                radius = min(seg.outer_diameter, seg.end_diameter if seg.kind == "cone" else math.inf) / 2
            out.append((seg.name, seg.volume(), seg.length, radius))
    return out


def _nodes(elements: int, order: int) -> int:
    """Nodes of a tetrahedral mesh of ``elements`` cells (vertices, and edge midpoints at order 2)."""
    return int(elements * (1.45 if order == 2 else 0.2))


def _memory(dofs: int) -> float:
    """Peak memory of assembly and factorisation, bytes (fill-in grows as DOFs^(4/3))."""
    return 3e8 + 1e4 * dofs * (dofs / 7e4) ** (1 / 3)


def estimate(design, mesh_size: float | None = None, order: int = 2,
             elements_per_wavelength: float | None = None, refine: float = 1.0,
             grade: bool = False, mesher: str = "free") -> Estimate:
    """Predict the mesh and FE size of ``design`` meshed as :func:`geometry.builder.build` would.

    Parameters
    ----------
    design : RPUDDesign, StackDesign or CadDesign
    mesh_size : float, optional
        Base element size, m (as ``build``).
    order : {1, 2}
    elements_per_wavelength : float, optional
    refine : float
        The builder's refinement factor (every size rule scaled by it).
    grade : bool
        The mesh is graded toward the re-entrant edges (as ``build``).
    mesher : {"free", "revolve", "auto"}
        As ``build``; the swept mesh is the free estimate times :data:`REVOLVE_FACTOR`.

    Returns
    -------
    Estimate
    """
    from .layers import layer_element_estimate
    from .sizing import feature_caps, graded_edges, mesh_layers, region_sizes

    sizes = region_sizes(design, mesh_size, elements_per_wavelength, refine)
    layers = mesh_layers(design, mesh_size, elements_per_wavelength, refine)
    segments = {s.name: s for s in getattr(design, "segments", ())}
    n = 0.0
    smallest = math.inf
    for region, vol, length, radius in _regions(design):
        if region in layers:
            # structured: the face's triangles times the element layers, plus the refined rim
            n += layer_element_estimate(segments[region], layers[region])
            smallest = min(smallest, length / layers[region].n_elements)
            continue
        h = min(sizes[region], _curvature_fraction(refine) * radius, max(length, 1e-12))
        smallest = min(smallest, h)
        n += TETS_PER_CUBE * vol / h ** 3
    for key, h in sizes.items():
        # refinement boxes around slots and teeth: their zone of the coupler at the feature size
        if key in ("@slots", "@teeth"):
            c = design.coupler
            zone = c.slot_length if key == "@slots" else c.tooth_height
            shell = math.pi / 4 * (c.outer_diameter ** 2 - design.coupler_bore ** 2) * zone
            smallest = min(smallest, h)
            n += TETS_PER_CUBE * shell / h ** 3
        elif key.startswith("@"):
            # a size box of a CAD design: the box, at most the whole solid (an upper bound)
            box = feature_caps(design)[1][key][1]
            inside = min(math.prod(box[i + 3] - box[i] for i in range(3)), sum(r[1] for r in _regions(design)))
            smallest = min(smallest, h)
            n += TETS_PER_CUBE * inside / h ** 3
    from .revolve import resolve_mesher

    swept = resolve_mesher(design, mesher) == "revolve"
    # a swept section's graded edges are in REVOLVE_FACTOR: --grade adds only the notches there
    for e in (graded_edges(design, sizes, refine) if grade and not swept else []):
        # a torus of 270 degrees around the edge with h(d) = h_edge + g d:
        # integral of 2 pi r (3 pi / 2) d dd / h^3 over d > 0 = 3 pi^2 r / (2 g^2 h_edge)
        smallest = min(smallest, e.h_edge)
        n += TETS_PER_CUBE * 1.5 * math.pi ** 2 * e.r / (e.growth ** 2 * e.h_edge)
    elements = int(min(n, 1e18))
    nodes = _nodes(elements, order) + 1
    dofs = 4 * nodes
    est = Estimate(elements=elements, nodes=nodes, dofs=dofs, memory_bytes=_memory(dofs), smallest_size=smallest)
    if swept:
        f = REVOLVE_FACTOR
        est = dataclasses.replace(est, elements=int(est.elements * f), nodes=int(est.nodes * f),
                                  dofs=int(est.dofs * f), memory_bytes=est.memory_bytes * f ** (4 / 3))
    if grade:
        # the coupler is free-meshed by both meshers: its notch wedges are added after the swept factor
        from .notches import notch_cells

        cells, h_edge = notch_cells(design, sizes, refine)
        extra = int(TETS_PER_CUBE * cells)
        nodes = est.nodes + _nodes(extra, order)
        dofs = 4 * nodes
        est = dataclasses.replace(est, elements=est.elements + extra, nodes=nodes, dofs=dofs,
                                  memory_bytes=_memory(dofs),
                                  smallest_size=min(est.smallest_size, h_edge))
    return est


def sector_estimate(design, sectors: int, mesh_size: float | None = None, refine: float = 1.0) -> Estimate:
    """Predict the ``k = 0`` swept sector's FE size (:func:`fem.sector_system.axial_sector`: the
    largest system a sector run factorises) at the command line's ``refine``: the whole drill's
    swept, graded estimate at the rule's refine over ``sectors``, scaled by
    :data:`SECTOR_FACTOR` and grown as ``refine^-``:data:`SECTOR_EXPONENT`."""
    from .sector import AXIAL_RULE

    whole = estimate(design, mesh_size, 2, None, AXIAL_RULE[0], True, "revolve")
    dofs = int(whole.dofs * SECTOR_FACTOR / sectors * refine ** -SECTOR_EXPONENT)
    dofs += fillet_sector_dofs(design, sectors, mesh_size, refine)
    return Estimate(elements=int(whole.elements * dofs / max(whole.dofs, 1)), nodes=dofs // 4, dofs=dofs,
                    memory_bytes=_memory(dofs), smallest_size=whole.smallest_size * refine)


def fillet_sector_dofs(design, sectors: int, mesh_size: float | None = None, refine: float = 1.0) -> int:
    """DOFs the fillet arcs' graded zones add to the ``k = 0`` swept sector at ``refine`` (the
    calibration of :data:`SECTOR_FACTOR` is on sharp corners, whose grading it holds).

    Each arc's (r, z) section zone, where the size grows from the arc's ``h`` at ``g`` per m up to
    the horn's size ``H`` (:func:`geometry.sizing.fillet_sizes`), holds
    ``T = (pi / 2) / c * int_0^(d*) (rho + x) (1 / (h + g x)^2 - 1 / H^2) dx`` triangles beyond
    the background (a quarter turn around the arc of radius ``rho``, equilateral triangles of
    area ``c h^2``, ``c = sqrt(3) / 4``, ``d* = (H - h) / g``); a P2 section has ~2 nodes per
    triangle, swept into ``2 L + 1`` node planes over the sector's ``L`` element layers, 4 DOFs
    each."""
    from .revolve import sectors_per_quarter
    from .sector import AXIAL_RULE
    from .sizing import fillet_sizes, region_sizes

    rule_refine, rule = AXIAL_RULE[0] * refine, AXIAL_RULE[1]
    sizes = region_sizes(design, mesh_size, refine=rule_refine)
    per_quarter = max(sectors_per_quarter(rule_refine), math.ceil(90.0 / (rule.layer_deg * rule_refine) - 1e-9))
    layers = max(1, math.ceil(per_quarter * 4 / sectors - 1e-9))
    c, T = math.sqrt(3) / 4, 0.0
    for h, g, _rc, _zc, rho in fillet_sizes(design, sizes, rule_refine, True):
        H = sizes.get("horn", h)
        if H <= h:
            continue
        ds = (H - h) / g
        inner = ((rho - h / g) * (1 / h - 1 / H) + math.log(H / h) / g) / g - (rho * ds + ds * ds / 2) / H ** 2
        T += math.pi / 2 / c * inner
    return int(4 * 2 * T * (2 * layers + 1))


def check_budget(design, mesh_size: float | None = None, order: int = 2,
                 elements_per_wavelength: float | None = None, *, solve: bool = True,
                 allow_large: bool = False, option: str = "--allow-large", refine: float = 1.0,
                 grade: bool = False, mesher: str = "free", sectors: int | None = None) -> Estimate:
    """Refuse a build/solve whose estimate exceeds the budget, before anything runs.

    Parameters
    ----------
    solve : bool
        The mesh is solved (budget :data:`MAX_DOFS`) or only written (:data:`MAX_ELEMENTS`).
    allow_large : bool
        The user's explicit override: log the estimate and go on.
    option : str
        Name of the override option, quoted in the message.
    refine, grade, mesher
        The builder's refinement factor, edge grading and mesher (as :func:`estimate`).
    sectors : int, optional
        The run solves swept sectors of this count (:func:`sector_estimate`), not the whole drill.

    Raises
    ------
    ParameterError
        Naming ``--mesh-size`` (with the smallest size that fits) or the design.
    """
    if sectors:
        est, growth = sector_estimate(design, sectors, mesh_size, refine), SECTOR_EXPONENT
    else:
        est, growth = estimate(design, mesh_size, order, elements_per_wavelength, refine, grade, mesher), 3.0
    value, budget, what = ((est.dofs, MAX_DOFS, "DOFs") if solve else (est.elements, MAX_ELEMENTS, "tetrahedra"))
    if value <= budget:
        log.debug("resource estimate: %s", est.describe())
        return est
    if allow_large:
        log.warning("above the budget of %s %s: %s (%s given)", f"{budget:,}", what, est.describe(), option)
        return est
    # the count grows as size^-3: the size that would fit, for the message
    if refine < 1:
        fit = refine * (value / budget) ** (1 / growth)
        raise ParameterError("--refine", refine, f"gives {est.describe()}, above the budget of {budget:,} "
                                                 f"{what}: use --refine >= {fit:.3g} or {option}")
    if mesh_size is not None:
        fit = mesh_size * (value / budget) ** (1 / 3)
        raise ParameterError("--mesh-size", mesh_size, f"gives {est.describe()}, above the budget of "
                                                       f"{budget:,} {what}: use --mesh-size >= {fit:.3g} m "
                                                       f"or {option}")
    raise ParameterError("design", getattr(design, "name", "?"),
                         f"gives {est.describe()}, above the budget of {budget:,} {what}: enlarge its "
                         f"smallest features, lower elements_per_wavelength, or give {option}")
