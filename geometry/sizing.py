"""Mesh-size rules of the builder: per-region sizes, feature caps, layers and graded edges.

The rules below are all scaled together by one refinement factor ``refine`` (``F < 1``
refines; the element count grows about as ``F**-3``):

* **Region sizes** (:func:`region_sizes`): an elements-per-wavelength rule on each material's
  shear wavelength at the design's target frequency (or a user's base size), capped near thin
  parts (rings, shims, the flange) and small features (slots, teeth).
* **Thin layers** (:func:`mesh_layers`, :mod:`geometry.layers`): in-plane size times ``F``,
  element layers through the thickness divided by ``F``.
* **Curvature**: Gmsh's ``Mesh.MeshSizeFromCurvature`` (:data:`CURVATURE_ELEMENTS` elements
  per 2 pi of a curved edge, divided by ``F``).
* **Graded edges** (:func:`graded_edges`, opt-in: ``grade=True``, ``--grade``): where two coaxial parts of different diameter meet
  (the flange and the horn, the horn's step, the rings' faces on the flange...), the section
  has a 270-degree re-entrant corner. The stress there is singular (~ d^-0.46) and on a
  quasi-uniform mesh the eigenvalue error falls only as h^1.1 whatever the element order. A
  size field ``h(d) = min(region size, F (h_edge + GROWTH d))`` (``d`` the distance to the
  circular edge) grades the mesh geometrically toward each such edge and recovers the smooth
  rate (h^4 with P2). It is off by default: on the article's drill it roughly doubles the DOFs
  (12 925 -> ~29 000 tetrahedra) for +0.12 % instead of +0.45 % on the working mode, and the
  pipeline's and the test suite's time budgets are set on the ungraded mesh.
  Study knobs (module constants, defaults = the ``--grade`` rule): :data:`EDGE_FRACTION`,
  :data:`GROWTH`, :data:`GRADE_MINOR`, :data:`GRADE_BORES`, :data:`MINOR_FRACTION`,
  :data:`RING_ELEMENTS`, :data:`FLANGE_FACTOR`. An error within 0.05 % on the working mode of the
  axisymmetric variant (no slots, no teeth) is reached only at ~260k DOFs (EDGE_FRACTION 0.04,
  GRADE_BORES, GROWTH 0.4: +0.044 % / +0.055 %): isotropic tetrahedra pay the edge size along
  the whole circumference of each edge (elements ~ r / (GROWTH^2 h_edge)), and single meshes
  scatter by ~0.02 % (the smallest elements at the edges are placed differently), see
  ``benchmarks/bench_mesh_grading.py --study``.
  The swept mesher (``mesher="revolve"``, :mod:`geometry.revolve`) stretches the elements along
  the edges instead and meets 0.05 % at 80k DOFs (:data:`REVOLVE_EDGE_FRACTION`, :data:`REVOLVE_GROWTH`).

Gmsh is handed to :func:`apply_fields` by the builder; this module does not import it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rpud_common import ParameterError, check_positive, check_range
from .design_base import DesignBase
from .design_cad import CadDesign
from .design_rpud import RPUDDesign
from .design_stack import StackDesign
from .layers import Layer, layer_plan, rim_fields
from .materials import Material, get_material
from .notches import add_notch_field

__all__ = ["region_sizes", "mesh_layers", "feature_caps", "shear_wavelength", "graded_edges", "GradedEdge", "apply_fields",
           "REFINE_RANGE", "CURVATURE_ELEMENTS", "EDGE_FRACTION", "GROWTH", "MAJOR_STEP",
           "check_refine", "revolve_sizes", "REVOLVE_EDGE_FRACTION", "REVOLVE_GROWTH", "fillet_sizes",
           "FILLET_ELEMENTS", "REVOLVE_FILLET_ELEMENTS", "junction_edges", "JUNCTION_FRACTION", "JUNCTION_GROWTH", "BOLT_END_FRACTION"]

REFINE_RANGE = (0.2, 5.0)
"""Accepted refinement factors: 0.2 is ~125x the default element count (far above any
budget), 5 ~ 1/125 of it (a handful of elements per part)."""

CURVATURE_ELEMENTS = 12.0
"""Elements per full circle of a curved edge at ``refine = 1`` (Gmsh Mesh.MeshSizeFromCurvature)."""

EDGE_FRACTION = 0.08
"""Element size at a re-entrant edge as a fraction of the smaller of the two adjacent region
sizes (at ``refine = 1``)."""

GROWTH = 0.5
"""Growth of the element size with the distance from a re-entrant edge (dh/dd): each element
about 1.5x the one before it, toward the edge."""

MAJOR_STEP = 0.3
"""A drop of the outer radius by at least this fraction of the larger radius is a major edge."""

GRADE_MINOR = False
"""Grade the minor outer steps too (at :data:`MINOR_FRACTION`)."""

GRADE_BORES = False
"""Grade the edges where a bore narrows (at :data:`MINOR_FRACTION`)."""

MINOR_FRACTION = 0.08
"""Edge size of minor steps and bore edges as a fraction of the smaller adjacent region size."""

REVOLVE_EDGE_FRACTION = 0.02
"""Edge size of the major re-entrant edges of a swept (r, z) section (:mod:`geometry.revolve`),
as a fraction of the smaller adjacent region size: the section is 2-D, so fine edges cost
little (the bore edge on the flange is graded too, at the same fraction)."""

REVOLVE_GROWTH = 0.8
"""Growth of the element size with the distance from an edge in a swept section. Measured on
the article's drill without slots and teeth (working mode against the converged (r, z) answer,
f_r / f_a, DOFs of that design; the article drill's DOFs in brackets):
edge 0.02 / growth 0.8 (the rule) +0.041 % / +0.044 % at 80k (112k); 0.01 / 0.7 +0.030 % /
+0.030 % at 98k (129k, 1.2x the modal time); 0.01 / 0.8 +0.034 % at 92k; 0.005 / 0.8 +0.032 % at
104k; 0.02 / 0.6 +0.032 % at 94k; 0.03 / 1.0 +0.068 % at 64k; 0.08 / 0.5 without the bore edge
+0.088 % at 56k. Without the sector cap of :func:`revolve_sizes`: 0.02 / 0.8 +0.047 % / +0.052 %
(107k), 0.01 / 0.8 +0.038 % / +0.040 % (119k). The rest of the error: the sweep's 12 sectors
(16, with the 0.01 / 0.7 rule: -0.008 %) and the coupler's free mesh (half its size: -0.008 %).
The rule is the cheapest measured that keeps both within 0.045 %: ``python -m fem.modal`` on the
article's drill took 0.88x the CPU of the free 68.6k-DOF whole-drill run when the rule was
chosen (benchmarks/bench_modal_cli.py has the current comparison)."""

JUNCTION_FRACTION = 0.2
"""Default edge size (:func:`junction_edges`; the ``k = 0`` sector's rule,
:data:`geometry.sector.AXIAL_RULE`, sets its own), in a swept (r, z) section, at a junction on the outer surface: a circle where
two parts of different material or poling meet without a major step (the electrodes' outer
edges between oppositely poled rings, the stack's ends on the coupler and on the flange), as a
fraction of the smaller adjacent region size. The fields jump there (the piezoelectric constants
change sign across an electrode), and the tip amplitude per volt converges slowly toward them
while the frequencies hardly move. Measured on the article's drill without slots and teeth,
sharp corners, sector path at refine 1 (working f_r / f_a / tip amplitude per volt against the
converged (r, z) model, DOFs): not graded +0.019 / +0.022 / -0.080 %, 29.3k; 0.2 / growth 0.4
(the rule) +0.015 / +0.019 / -0.041 %, 39.3k; 0.1 / 0.5 -0.041 %, 44.2k; 0.1 / 0.8 -0.049 %,
40.8k; 0.05 / 0.8 -0.044 %, 47.9k; the inner edges too (0.05 / 0.8) -0.038 % at 60.6k: the
outer ones carry most of it."""

JUNCTION_GROWTH = 0.4
"""Growth of the element size with the distance from a junction (:data:`JUNCTION_FRACTION`)."""

BOLT_END_FRACTION = 0.05
"""Edge size at the stack bolt's bonded ends (re-entrant corners on the coupler's and the
flange's faces, :func:`junction_edges`; with a threaded bolt the same circles, where its shank
leaves the coupler's and the flange's thread: the thread's far ends and the hole's bottom lie
away from the rings and are not graded) as a fraction of the smallest of the bolt's, the
coupler's and the flange's sizes; growth :data:`REVOLVE_GROWTH`. Measured on a bolted variant of
the design without slots and teeth (tests/test_sector_paths.py, sector path at refine 1; f_r /
f_a / tip amplitude per volt against the (r, z) model, DOFs): not graded +0.089 / +0.065 /
-0.243 % at 49.9k (the two-level estimate states 0.029 % for the tip: the ungraded corners
converge non-monotonically); 0.05 (the rule) +0.023 / +0.022 / -0.019 % at 55.9k; 0.02 +0.021 /
+0.021 / -0.009 % at 61.0k. The article's drill with a bonded-face M12 bolt, sector at refine 1: 89.6k -> 94.9k DOFs."""

RING_ELEMENTS = 1.0
"""Element size cap in a ring: its thickness divided by this."""

FLANGE_FACTOR = 1.5
"""Element size cap in the flange: this times its thickness."""

_TOL = 1e-7
"""Two radii closer than this (m) are the same: no corner."""


def revolve_sizes(design: DesignBase, sizes: dict[str, float], per_quarter: int) -> dict[str, float]:
    """Region sizes (m) with the swept regions of an RPUD capped at the arc of one sector at
    their outer radius: the section's triangles then match the elements along the circle."""
    out = dict(sizes)
    if isinstance(design, RPUDDesign):
        arc = 2 * math.pi / (4 * per_quarter)
        radius = {"flange_disc": design.flange.outer_diameter / 2, "horn": design.horn.back_diameter / 2}
        for region, _kind, _z0, _z1 in design.stack_layers():
            radius[region] = design.stack.outer_diameter / 2
        for region, r in radius.items():
            if region in out:
                out[region] = min(out[region], arc * r)
        if "bolt" in out:
            # the bolt runs along the rings: no coarser than they are
            out["bolt"] = min([out["bolt"]] + [out[region] for region, *_ in design.stack_layers()])
    return out


def check_refine(refine: float, name: str = "refine") -> float:
    """Validate a refinement factor (dimensionless; < 1 refines); returns it as float."""
    check_range(name, refine, *REFINE_RANGE)
    return float(refine)


def shear_wavelength(material: str | Material, frequency: float, library=None) -> float:
    """Shear wavelength (m) of ``material`` (a record, or a name in ``library``, default the
    built-in one) at ``frequency`` (Hz).

    Isotropic: sqrt(G / rho) / f; piezoceramic: sqrt(min(c44, c55, c66) / rho) / f (the slowest
    shear wave along the material axes).
    """
    m = material if isinstance(material, Material) else get_material(material, library)
    if m.is_piezo:
        G = float(np.diag(m.voigt_matrices()[0])[3:].min())
    else:
        G = m.youngs_modulus / (2 * (1 + m.poisson_ratio))
    return math.sqrt(G / m.density) / frequency


def region_sizes(design: DesignBase, mesh_size: float | None = None,
                 elements_per_wavelength: float | None = None, refine: float = 1.0) -> dict[str, float]:
    """Target element size (m) per region, and the feature sizes (keys starting with ``@``).

    ``mesh_size`` replaces the wavelength rule as the base size of every region; the feature
    caps (ring and shim thickness, flange thickness, slot width and depth, tooth height) still
    apply, so halving it alone does not refine uniformly. ``refine`` scales every size, base,
    caps and layers alike (a uniform refinement: 1 / 1.5 is one step of a convergence study).
    A thin layer (:mod:`geometry.layers`) gets its in-plane size, not a thickness cap.
    The graded edges (opt-in) add size fields, not region sizes: see :func:`graded_edges`.
    """
    refine = check_refine(refine)
    own, capped = _free_sizes(design, mesh_size, elements_per_wavelength)
    sizes = {k: v * refine for k, v in capped.items()}
    for name, layer in layer_plan(design, own, capped, refine).items():
        sizes[name] = layer.size
    return sizes


def mesh_layers(design: DesignBase, mesh_size: float | None = None,
                elements_per_wavelength: float | None = None, refine: float = 1.0) -> dict[str, Layer]:
    """The segments meshed as structured layers, by name (see :mod:`geometry.layers`)."""
    refine = check_refine(refine)
    return layer_plan(design, *_free_sizes(design, mesh_size, elements_per_wavelength), refine)


def _free_sizes(design, mesh_size, elements_per_wavelength):
    """(size of each region's own material, size after the thin-feature caps), m, at refine 1."""
    epw = design.elements_per_wavelength if elements_per_wavelength is None else elements_per_wavelength
    check_range("elements_per_wavelength", epw, 1.0, 200.0)
    if mesh_size is not None:
        check_positive("mesh_size", mesh_size, "m")

    def base(material: str) -> float:
        return mesh_size if mesh_size is not None else shear_wavelength(lib[material], design.target_frequency) / epw

    lib = design.library
    sizes: dict[str, float] = {}
    for region, part, material, _vol in design.region_table():
        sizes[region] = base(material)
    own = dict(sizes)
    caps, boxes = feature_caps(design)
    for region, cap in caps.items():
        sizes[region] = min(sizes[region], cap)
    for key, (cap, _box, region) in boxes.items():
        sizes[key] = min(sizes[region], cap) if region else cap
    return own, sizes


def feature_caps(design: DesignBase) -> tuple[dict[str, float], dict[str, tuple[float, tuple, str]]]:
    """The thin-feature caps of a design at ``refine`` 1, m.

    Returns
    -------
    region caps : dict region -> largest element size
    box caps : dict key (``@...``) -> (largest size, box (xmin, ymin, zmin, xmax, ymax, zmax) m,
        region whose size also bounds it or "")
    """
    caps: dict[str, float] = {}
    boxes: dict[str, tuple[float, tuple, str]] = {}
    if isinstance(design, RPUDDesign):
        s, c = design.stack, design.coupler
        for region, kind, z0, z1 in design.stack_layers():
            caps[region] = s.ring_thickness / RING_ELEMENTS if kind == "ring" else 4 * s.shim_thickness
        caps["flange_disc"] = FLANGE_FACTOR * design.flange.thickness
        R = c.outer_diameter / 2 + 1e-3
        zones = {z[0]: z for z in design._zones()}
        if c.n_slots:
            _l, _p, z0, z1 = zones["coupler.slots"]
            boxes["@slots"] = (min(0.6 * c.slot_width, 1.2 * c.slot_depth), (-R, -R, z0 - 1e-4, R, R, z1 + 1e-4),
                               "coupler")
        if c.n_teeth:
            _l, _p, z0, z1 = zones["coupler.teeth"]
            boxes["@teeth"] = (max(0.8 * c.tooth_height, 0.5 * c.tooth_width), (-R, -R, z0 - 1e-4, R, R, z1 + 1e-4),
                               "coupler")
    elif isinstance(design, CadDesign):
        for rule in design.sizes:
            if rule.region:
                caps[rule.region] = min(caps.get(rule.region, math.inf), rule.size)
        for k, rule in enumerate(r for r in design.sizes if r.box is not None):
            boxes[f"@box_{k}"] = (rule.size, rule.box, "")
    else:
        for seg in design.segments:
            dims = [seg.length]
            if seg.kind == "box":
                dims += [seg.thickness, seg.width]
            # at least ~2 elements across the smallest dimension of a thin piece
            caps[seg.name] = max(min(dims) / 2, 0.25 * max(dims) / 20)
    return caps, boxes


# ============================================================================ graded edges


@dataclass(frozen=True)
class GradedEdge:
    """A circular re-entrant edge on the axis: radius ``r`` at height ``z`` (m), element size
    ``h_edge`` there (m), growing by ``growth`` (m per m of distance), between ``regions``."""

    z: float
    r: float
    h_edge: float
    growth: float
    regions: tuple[str, str]


@dataclass(frozen=True)
class _Section:
    """An axisymmetric slice of the profile: z0..z1, outer radius at each end, bore radius."""

    region: str
    z0: float
    z1: float
    r0: float
    r1: float
    bore: float


def _sections(design: DesignBase) -> list[_Section | None]:
    """Profile slices in z order; ``None`` for a piece that is not a body of revolution."""
    out: list[_Section | None] = []
    if isinstance(design, RPUDDesign):
        c, s, f, h = design.coupler, design.stack, design.flange, design.horn
        R = c.outer_diameter / 2
        out.append(_Section("coupler", -c.length, 0.0, R, R, design.coupler_bore / 2))
        for region, _kind, z0, z1 in design.stack_layers():
            out.append(_Section(region, z0, z1, s.outer_diameter / 2, s.outer_diameter / 2, s.inner_diameter / 2))
        zf = s.length
        out.append(_Section("flange_disc", zf, zf + f.thickness, f.outer_diameter / 2, f.outer_diameter / 2,
                            design.bore_diameter / 2))
        z0 = zf + f.thickness
        b = design.bore_diameter / 2
        if h.profile == "stepped":
            l1 = h.step_fraction * h.length
            out.append(_Section("horn", z0, z0 + l1, h.back_diameter / 2, h.back_diameter / 2, b))
            out.append(_Section("horn", z0 + l1, z0 + h.length, h.tip_diameter / 2, h.tip_diameter / 2, b))
        else:
            out.append(_Section("horn", z0, z0 + h.length, h.back_diameter / 2,
                                float(h.diameter_at(h.length)) / 2, b))
    elif isinstance(design, StackDesign):
        ext = design.segment_extents()
        for seg in sorted(design.segments, key=lambda g: ext[g.name][0]):
            z0, z1 = ext[seg.name]
            if seg.kind == "box":
                out.append(None)
                continue
            r1 = (seg.end_diameter if seg.kind == "cone" else seg.outer_diameter) / 2
            out.append(_Section(seg.name, z0, z1, seg.outer_diameter / 2, r1, seg.inner_diameter / 2))
    return out


def graded_edges(design: DesignBase, sizes: dict[str, float], refine: float = 1.0,
                 revolve: bool = False) -> list[GradedEdge]:
    """The re-entrant circular edges of a coaxial design and their edge sizes (m).

    Between consecutive axisymmetric slices that touch, a drop of the outer radius by at least
    :data:`MAJOR_STEP` of the larger radius leaves a re-entrant edge at the smaller radius (the
    flange/horn edge and the horn's step of the article's drill; with :data:`GRADE_MINOR` also
    smaller steps, e.g. the rings' outer edge on the flange), and a bore that narrows leaves one
    at the larger bore radius (the stack's bore on the flange face, :data:`GRADE_BORES`). Edge size:
    :data:`EDGE_FRACTION` of the smaller adjacent region size (:data:`MINOR_FRACTION` for minor
    steps and bores). ``sizes`` are :func:`region_sizes` at ``refine`` (the edge sizes inherit it
    from them); the growth is :data:`GROWTH` x ``refine``, so that the whole size function h(d)
    scales by ``refine`` and the graded zone's element count grows as ``refine**-3`` like the rest.
    ``revolve``: the rule of a swept section (:data:`REVOLVE_EDGE_FRACTION`,
    :data:`REVOLVE_GROWTH`, bores graded alike).
    """
    major_frac, growth = (REVOLVE_EDGE_FRACTION, REVOLVE_GROWTH) if revolve else (EDGE_FRACTION, GROWTH)
    bores, bore_frac = (True, REVOLVE_EDGE_FRACTION) if revolve else (GRADE_BORES, MINOR_FRACTION)
    secs = _sections(design)
    edges: list[GradedEdge] = []
    for a, b in zip(secs, secs[1:]):
        if a is None or b is None or abs(a.z1 - b.z0) > _TOL:
            continue
        h_min = min(sizes[a.region], sizes[b.region])
        if abs(a.r1 - b.r0) > _TOL:
            r, big = min(a.r1, b.r0), max(a.r1, b.r0)
            major = 1 - r / big >= MAJOR_STEP
            if major or GRADE_MINOR:
                frac = major_frac if major else MINOR_FRACTION
                edges.append(GradedEdge(a.z1, r, frac * h_min, growth * refine, (a.region, b.region)))
        if bores and abs(a.bore - b.bore) > _TOL:
            r = max(a.bore, b.bore)
            # the wider bore's edge is re-entrant unless the other part ends outside it
            if r < min(a.r1, b.r0) - _TOL:
                edges.append(GradedEdge(a.z1, r, bore_frac * h_min, growth * refine, (a.region, b.region)))
    # a filleted corner is not re-entrant: its arc gets its own size (fillet_sizes)
    corners = {(round(a.corner[0], 9), round(a.corner[1], 9)) for a in _fillets(design)}
    return [e for e in edges if (round(e.r, 9), round(e.z, 9)) not in corners]


def junction_edges(design: DesignBase, sizes: dict[str, float], refine: float = 1.0,
                   fraction: float = None) -> list[GradedEdge]:
    """The junctions of a swept section's outer surface (:data:`JUNCTION_FRACTION`): between
    consecutive slices that touch, belong to different regions and do not leave a major
    re-entrant edge (those are :func:`graded_edges`'), the circle at the smaller outer radius,
    sized ``fraction`` (default :data:`JUNCTION_FRACTION`) of the smaller adjacent region size;
    and the stack bolt's bonded ends (:data:`BOLT_END_FRACTION`).
    ``sizes`` are :func:`region_sizes` at ``refine``; the growth is :data:`JUNCTION_GROWTH` x
    ``refine`` (the size function scales with ``refine`` as a whole)."""
    secs = _sections(design)
    edges: list[GradedEdge] = []
    for a, b in zip(secs, secs[1:]):
        if a is None or b is None or abs(a.z1 - b.z0) > _TOL or a.region == b.region:
            continue
        r, big = min(a.r1, b.r0), max(a.r1, b.r0)
        if 1 - r / big < MAJOR_STEP:
            h_min = min(sizes[a.region], sizes[b.region])
            frac = JUNCTION_FRACTION if fraction is None else fraction
            edges.append(GradedEdge(a.z1, r, frac * h_min, JUNCTION_GROWTH * refine, (a.region, b.region)))
    if isinstance(design, RPUDDesign) and design.stack.bolt_diameter and "bolt" in sizes:
        # the bolt's bonded ends on the coupler and the flange (a threaded bolt's shank leaving
        # its threads): 270-degree re-entrant corners (the gap to the rings' bore beside them)
        h = BOLT_END_FRACTION * min(sizes["bolt"], sizes["coupler"], sizes["flange_disc"])
        for z, other in ((0.0, "coupler"), (design.stack.length, "flange_disc")):
            edges.append(GradedEdge(z, design.stack.bolt_diameter / 2, h, REVOLVE_GROWTH * refine, ("bolt", other)))
    return edges


FILLET_ELEMENTS = 2.0
"""Elements along a quarter turn of a fillet arc at ``refine = 1`` in the free mesh (size
``refine pi r / (2 FILLET_ELEMENTS)`` on the arc); a swept section, where the size costs only
2-D elements, takes :data:`REVOLVE_FILLET_ELEMENTS`."""

REVOLVE_FILLET_ELEMENTS = 16.0
"""Elements along a quarter turn of a fillet arc in a swept (r, z) section at ``refine = 1``."""


def _fillets(design) -> list:
    return list(design.fillets().values()) if isinstance(design, RPUDDesign) else []


def fillet_sizes(design: DesignBase, sizes: dict[str, float], refine: float = 1.0,
                 revolve: bool = False) -> list[tuple[float, float, float, float]]:
    """``(h_arc, growth, r_centre, z_centre, radius)`` (m) of each fillet arc of the design: the
    element size is ``h_arc`` on the arc and grows by ``growth`` per m away from it."""
    n = REVOLVE_FILLET_ELEMENTS if revolve else FILLET_ELEMENTS
    out = []
    for a in _fillets(design):
        h = min(refine * a.radius * (math.pi / 2) / n, sizes.get("horn", math.inf))
        out.append((h, (REVOLVE_GROWTH if revolve else GROWTH) * refine, a.centre[0], a.centre[1], a.radius))
    return out


# ============================================================================ Gmsh fields


def apply_fields(gmsh, design: DesignBase, sizes: dict[str, float], region_vols: dict[str, list[int]],
                 refine: float = 1.0, *, layers: dict[str, Layer] | None = None, grade: bool = False,
                 revolve: bool = False, region_faces: dict[str, list[int]] | None = None,
                 notch_fraction: float | None = None, junction_fraction: float | None = None,
                 notch_classes: dict[str, float] | None = None) -> None:
    """Install the size fields and the size options of a synchronised Gmsh model.

    Parameters
    ----------
    gmsh : module
        The initialised gmsh module (current model built and fragmented).
    sizes : dict
        :func:`region_sizes` at this ``refine``.
    region_vols : dict
        Region name -> Gmsh volume tags.
    refine : float
        The refinement factor the sizes were made with (scales the curvature rule here).
    layers : dict, optional
        :func:`mesh_layers` at this ``refine`` (their refined rims get size fields).
    grade : bool
        Grade the mesh toward the major re-entrant edges (:func:`graded_edges`) and the coupler's
        notch edges (:mod:`geometry.notches`); off by default.
    revolve : bool
        The bodies of revolution are a swept section: their edges graded by the section's rule
        (whatever ``grade``).
    region_faces : dict, optional
        Region name -> Gmsh face tags of regions meshed as faces only (a swept sector's section,
        :mod:`geometry.sector_sweep`).
    notch_fraction : float, optional
        With ``grade``: the notch edges' size over the slot zone's (default
        :data:`geometry.notches.NOTCH_FRACTION`).
    junction_fraction : float, optional
        With ``revolve``: grade the section's outer junctions (:func:`junction_edges`) to this
        fraction of the adjacent region size; None: not graded.
    notch_classes : dict, optional
        With ``grade``: classes of notch edges graded to their own fractions of the slot zone's
        size (:func:`geometry.notches.add_notch_field`).
    """
    field = gmsh.model.mesh.field
    fields = []
    for region, vols in region_vols.items():
        fid = field.add("Constant")
        field.setNumber(fid, "VIn", sizes[region])
        field.setNumbers(fid, "VolumesList", vols)
        field.setNumber(fid, "IncludeBoundary", 1)
        fields.append(fid)
    for region, faces in (region_faces or {}).items():
        fid = field.add("Constant")
        field.setNumber(fid, "VIn", sizes[region])
        field.setNumbers(fid, "SurfacesList", faces)
        field.setNumber(fid, "IncludeBoundary", 1)
        fields.append(fid)
    for key, (_cap, box, _region) in feature_caps(design)[1].items():
        fid = field.add("Box")
        for opt, val in (("VIn", sizes[key]), ("VOut", 1e22), ("XMin", box[0]), ("XMax", box[3]),
                         ("YMin", box[1]), ("YMax", box[4]), ("ZMin", box[2]), ("ZMax", box[5]),
                         ("Thickness", 2.0 * sizes[key])):
            field.setNumber(fid, opt, val)
        fields.append(fid)
    if layers:
        fields += rim_fields(gmsh, layers, region_vols)
    edges = graded_edges(design, sizes, refine, revolve) if grade or revolve else []
    if revolve and junction_fraction is not None:
        edges += junction_edges(design, sizes, refine, junction_fraction)
    for e in edges:
        # exact distance to the circle (r, z): no sampling of the curve, no curve tags needed
        fid = field.add("MathEval")
        field.setString(fid, "F", f"{e.h_edge!r} + {e.growth!r} * Sqrt((Sqrt(x*x + y*y) - {e.r!r})^2 "
                                  f"+ (z - {e.z!r})^2)")
        fields.append(fid)
    for h, g, rc, zc, rad in fillet_sizes(design, sizes, refine, revolve):
        # the distance to the arc's centre circle is at least the radius in the metal
        fid = field.add("MathEval")
        field.setString(fid, "F", f"{h!r} + {g!r} * Max(0, Sqrt((Sqrt(x*x + y*y) - {rc!r})^2 + (z - {zc!r})^2) - {rad!r})")
        fields.append(fid)
    notch = add_notch_field(gmsh, design, sizes, region_vols, refine, notch_fraction, notch_classes) if grade else None
    if notch is not None:
        fields.append(notch)
    fmin = field.add("Min")
    field.setNumbers(fmin, "FieldsList", fields)
    field.setAsBackgroundMesh(fmin)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", CURVATURE_ELEMENTS / refine)
    gmsh.option.setNumber("Mesh.MeshSizeMax", max(v for v in sizes.values()))
    if not (math.isfinite(refine) and refine > 0):  # pragma: no cover - check_refine guards it
        raise ParameterError("refine", refine, "must be a positive number")
