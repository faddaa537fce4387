"""One of ``N`` identical sectors of a drill with cyclic symmetry (converged modes at the
default cost).

The default RPUD is unchanged by a turn of 60 degrees about its axis: its coupler has 6 slots
and 6 teeth, every other part is a body of revolution. Its modes then split into circumferential
harmonics ``k = 0 .. N/2`` (Thomas 1979, "Dynamics of rotationally periodic structures"):
``k = 0`` holds the working longitudinal mode and the torsion, ``k = 1`` the bending pairs. Each
harmonic is an eigenproblem on one sector with its two cut faces tied by the phase
``exp(i k 2 pi / N)`` (:mod:`fem.cyclic`), about ``N`` times smaller than the whole drill.

A sector mesh covers ``0 <= theta <= 2 pi / N``; its cut face at ``theta = 2 pi / N`` is the
image of the face at ``theta = 0`` under that rotation, node for node (Gmsh's periodic meshing,
:func:`set_periodic`). A free sector is Gmsh's; a swept one is built by
:mod:`geometry.sector_sweep` (Gmsh drops a swept volume's extrusion constraints when
OpenCASCADE glues it to the cut coupler, "Unknown source point -1 for extrusion", Gmsh 4.15).
:func:`sector_pairs` finds those node pairs; :func:`replicate` turns a sector into the whole
drill (for mode-shape output and for the tests that check the reduction against the full model).

Gmsh (``gmsh``) is handed in; this module does not import it.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from rpud_common import ParameterError

from .design_rpud import RPUDDesign
from .mesh import TaggedMesh

__all__ = ["symmetry_order", "check_sectors", "rotation", "set_periodic", "SectorPairs", "sector_pairs",
           "replicate", "keep_periodic", "MAX_SECTORS", "SectorMeshing", "AXIAL_RULE", "LATERAL_RULE"]

MAX_SECTORS = 72
"""Most sectors a mesh may be cut into (5 degrees: one element layer at refine 0.2)."""

@dataclass(frozen=True)
class SectorMeshing:
    """How a swept sector is meshed beyond ``refine`` (:mod:`geometry.sector_sweep`).

    Attributes
    ----------
    coupler_refine : float
        The coupler's sizes and curvature rule scaled by this on top of ``refine``.
    notch_fraction : float or None
        The coupler's notch edges graded to this fraction of the slot zone's size
        (:mod:`geometry.notches`); None: not graded.
    layer_deg : float or None
        Element layers across the sector no wider than this (degrees); None: the whole turn's
        rule (:func:`geometry.revolve.sectors_per_quarter`).
    junction_fraction : float or None
        The section's outer junctions (electrode edges, the stack's ends) graded to this fraction
        of the adjacent region size (:func:`geometry.sizing.junction_edges`); None: not graded.
    slot_refine : float
        The slot zone's size cap (``@slots``, :func:`geometry.sizing.feature_caps`), and with it
        the notch edges' size, scaled by this on top of ``coupler_refine``.
    floor_fraction, root_fraction : float or None
        The slots' floor lines (a V groove's apex) and the teeth's roots graded to these fractions
        of the slot zone's size instead of ``notch_fraction`` (:data:`geometry.notches.NOTCH_CLASSES`);
        None: ``notch_fraction``.
    """

    coupler_refine: float = 1.0
    notch_fraction: float | None = None
    layer_deg: float | None = None
    junction_fraction: float | None = None
    slot_refine: float = 1.0
    floor_fraction: float | None = None
    root_fraction: float | None = None

    def __post_init__(self):
        for name in ("notch_fraction", "floor_fraction", "root_fraction"):
            value = getattr(self, name)
            if value is not None and not 0.01 <= value <= 1.0:
                raise ParameterError(name, value, "must lie in [0.01, 1] (a fraction of the slot zone's size)")

    def scaled(self, refine: float) -> "SectorMeshing":
        """The same rule at a command line's ``--refine`` (layers narrowed alike)."""
        return dataclasses.replace(self, layer_deg=None if self.layer_deg is None else self.layer_deg * refine)

    @property
    def notch_classes(self) -> dict[str, float]:
        """Class of notch edge -> its own fraction of the slot zone's size (the classes that differ
        from ``notch_fraction``; :func:`geometry.notches.add_notch_field`)."""
        own = {"floors": self.floor_fraction, "roots": self.root_fraction}
        return {k: v for k, v in own.items() if v is not None}


AXIAL_RULE = (0.8, SectorMeshing(coupler_refine=1.0, notch_fraction=0.15, layer_deg=20.0, junction_fraction=0.2,
                                  slot_refine=1.22, floor_fraction=0.08, root_fraction=0.3))
"""``(refine, meshing)`` of the swept sector that solves harmonic 0 (the working mode, its
anti-resonance, the torsion) at the command line's ``--refine 1``. The coupler's notch edges
converge slowest (about h^0.7 to h^1 measured): they are graded to 0.15 of the slot zone's size
(``--grade`` uses 0.4), the slots' floor lines (a V groove's apex) to 0.08 and the teeth's roots
only to 0.3. The teeth's motion (ellipse ratio) is limited by the floor lines: one class of edge
or region at a time from the rule without the floor and root classes (all notch edges at 0.15),
at refine 1 on the article's drill with matched lengths (86 579 DOFs, ratio 0.17090): floors at
0.08 +0.00205 for +11.5k DOFs, end walls at 0.08 +0.00091 (+10.3k), roots at 0.08 +0.00045
(+15.3k), the slot zone 0.8x finer (notch edges kept) +0.00077 (+9.4k), 6 layers instead of 3
+0.00213 (+57.9k); the roots at 0.3 pay for the floors (89 498 DOFs, +3.4 %). Past that first
step every refinement measured gains about 0.5e-4 of the ratio per 1k DOFs (same design, refine
1, DOFs and ratio against the rule's 89 498 and 0.17266): floors at 0.05 105 885, 0.17351; floors
growing at 0.45 instead of 0.64 103 679, 0.17351; floors at 0.04 within 30 % of the slot's length
from either end 93.1k-93.7k, 0.17287; floors 0.06 with roots 0.5 95 795, 0.17289; floors 0.06 with
roots 1.0 94 016, 0.17278; the coupler outside the slot zone 0.8x finer 89 865, 0.17267
(docs/theory/piezo-elastic.md: none gains the ratio faster per DOF). The section's outer
junctions (the electrodes' outer edges, the stack's ends) are graded to 0.2 of the ring size:
they hold most of the horn-tip amplitude's error (:data:`geometry.sizing.JUNCTION_FRACTION`), and
the slot zone's cap is 1.22x coarser to pay for them. Default design at horn 67.1 mm and coupler
49.9 mm (tests/reference_designs.py) with sharp horn corners: f_r / f_a 19 898.93 / 21 653.67 Hz,
80 345 DOFs, against best estimates of the converged values
19 893.2 / 21 648.2 Hz (README): +0.029 / +0.025 %; first torsion 15 375.80 Hz (+0.073 %). Without
slots and teeth (sharp corners, against the (r, z) model of tests/axisym_reference.py): f_r / f_a
/ tip amplitude per volt +0.015 / +0.018 / -0.041 % at 39.7k DOFs (-0.080 % without the junction
grading)."""

LATERAL_RULE = (0.8, SectorMeshing(coupler_refine=2.0, notch_fraction=None, layer_deg=15.0))
"""The same for harmonics k >= 1 (the bending pairs): their error lies in the swept parts' layers
(the coupler holds ~0.01 %), so the coupler stays coarse. Default design: first bending pair
5 207.53 Hz, 40 651 DOFs (+0.083 % against 5 203.2 Hz)."""


def symmetry_order(design) -> int:
    """Order ``N`` of the design's cyclic symmetry: the greatest common divisor of its slot and
    tooth counts (those present); 0 for a design that is a body of revolution (any ``N``)."""
    c = design.coupler
    counts = [n for n in (c.n_slots, c.n_teeth) if n]
    return math.gcd(*counts) if counts else 0


def check_sectors(design, sectors) -> int:
    """``sectors`` as an int, or a ParameterError saying what is allowed for ``design``."""
    if not isinstance(design, RPUDDesign):
        raise ParameterError("--sectors", sectors, "needs an RPUD design (cyclic symmetry of the coupler)")
    if isinstance(sectors, bool) or not isinstance(sectors, (int, np.integer)):
        raise ParameterError("--sectors", sectors, "must be an integer")
    order = symmetry_order(design)
    if order:
        allowed = [n for n in range(3, order + 1) if order % n == 0]
        if sectors not in allowed:
            what = ", ".join(map(str, allowed)) if allowed else "none (fewer than 3-fold symmetry)"
            raise ParameterError("--sectors", sectors, f"must divide the coupler's {order}-fold symmetry "
                                 f"(gcd of n_slots and n_teeth) and be >= 3: {what}")
    elif not 3 <= sectors <= MAX_SECTORS:
        raise ParameterError("--sectors", sectors, f"must lie in [3, {MAX_SECTORS}]")
    return int(sectors)


def rotation(angle: float) -> np.ndarray:
    """3 x 3 rotation by ``angle`` (rad) about the z axis."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _on_plane(points: np.ndarray, angle: float, tol: float) -> np.ndarray:
    """Points on the half-plane ``theta = angle`` (the axis included)."""
    c, s = math.cos(angle), math.sin(angle)
    normal = -s * points[:, 0] + c * points[:, 1]
    along = c * points[:, 0] + s * points[:, 1]
    return (np.abs(normal) <= tol) & (along >= -tol)


def set_periodic(gmsh, vols, sectors: int, tol: float = 1e-7) -> int:
    """Make Gmsh mesh the faces of ``vols`` on the cut ``theta = 2 pi / sectors`` as the rotated
    copies of their partners on ``theta = 0``. Returns the number of face pairs.

    Faces are found by their boundary points; each face at the far cut is paired with the face
    at ``theta = 0`` whose rotated bounding box matches.
    """
    angle = 2 * math.pi / sectors
    R = rotation(angle)
    faces = sorted({t for v in vols for _d, t in gmsh.model.getBoundary([(3, v)], oriented=False)})

    def corners(f):
        pts = gmsh.model.getBoundary([(2, f)], recursive=True, oriented=False)
        return np.array([gmsh.model.getValue(0, t, []) for _d, t in pts]).reshape(-1, 3)

    near, far = {}, {}
    for f in faces:
        p = corners(f)
        if len(p) and _on_plane(p, 0.0, tol).all():
            near[f] = p
        elif len(p) and _on_plane(p, angle, tol).all():
            far[f] = p
    pairs = []
    for f, p in far.items():
        back = p @ R          # rotated by -angle
        match = [g for g, q in near.items() if len(q) == len(p)
                 and np.allclose(np.sort(back, axis=0), np.sort(q, axis=0), atol=tol)]
        if len(match) != 1:
            raise ParameterError("--sectors", sectors, f"the cut faces of the sector do not pair up "
                                 f"(face {f}: {len(match)} partners); the design is not {sectors}-fold symmetric")
        pairs.append((f, match[0]))
    if len(pairs) != len(near):
        raise ParameterError("--sectors", sectors, f"{len(near)} faces on the cut theta = 0 but {len(pairs)} "
                             f"on theta = 360/{sectors} degrees")
    affine = np.eye(4)
    affine[:3, :3] = R
    for f, g in pairs:
        gmsh.model.mesh.setPeriodic(2, [f], [g], affine.ravel().tolist())
    return len(pairs)


@dataclass(frozen=True)
class SectorPairs:
    """Node pairs of a sector mesh (indices into its points).

    ``near`` (on ``theta = 0``) and ``far`` (on ``theta = 2 pi / N``): ``points[far[j]] =
    R points[near[j]]``; ``axis``: the nodes on the axis (on both cuts).
    """

    sectors: int
    near: np.ndarray
    far: np.ndarray
    axis: np.ndarray


def sector_pairs(points: np.ndarray, sectors: int, tol: float | None = None) -> SectorPairs:
    """Pair the nodes of the two cut faces of a sector mesh (see :class:`SectorPairs`).

    ``tol`` (m; default 1e-9 of the mesh size) bounds the distance between a rotated near node
    and its far partner. Raises a ParameterError if the faces are not node-for-node copies.
    """
    from scipy.spatial import cKDTree

    points = np.asarray(points, dtype=float)
    if tol is None:
        tol = 1e-9 * max(float(np.ptp(points, axis=0).max()), 1e-3)
    angle = 2 * math.pi / sectors
    r = np.hypot(points[:, 0], points[:, 1])
    axis = np.flatnonzero(r <= tol)
    off = r > tol
    near = np.flatnonzero(_on_plane(points, 0.0, tol) & off)
    far = np.flatnonzero(_on_plane(points, angle, tol) & off)
    if len(near) != len(far):
        raise ParameterError("sector mesh", f"{len(near)} / {len(far)} nodes",
                             "the two cut faces must carry the same number of nodes")
    dist, j = cKDTree(points[far]).query(points[near] @ rotation(angle).T)
    if len(near) and (dist.max() > tol or len(np.unique(j)) != len(j)):
        raise ParameterError("sector mesh", f"cut faces {dist.max():.3g} m apart",
                             f"the far cut face must be the near one rotated by 360/{sectors} degrees")
    return SectorPairs(sectors, near, far[j], axis)


def keep_periodic(before: np.ndarray, after: np.ndarray, sectors: int) -> np.ndarray:
    """``after`` (points moved by :func:`geometry.revolve.straighten`) with the two cut faces node
    for node copies again, the pairs taken from ``before`` (Gmsh's periodic mesh): a node that
    straightening moved on one cut carries its partner on the other along (the free elements
    behind the two cuts differ, so only one side may have been straightened)."""
    pairs = sector_pairs(before, sectors)
    R = rotation(2 * math.pi / sectors)
    out = after.copy()
    near_moved = np.any(after[pairs.near] != before[pairs.near], axis=1)
    far_moved = np.any(after[pairs.far] != before[pairs.far], axis=1) & ~near_moved
    out[pairs.near[far_moved]] = after[pairs.far[far_moved]] @ R         # rotated back by -alpha
    moved = near_moved | far_moved                  # the others keep Gmsh's (snapped) coordinates
    out[pairs.far[moved]] = out[pairs.near[moved]] @ R.T
    return out


def replicate(tm: TaggedMesh, sectors: int, pairs: SectorPairs | None = None) -> tuple[TaggedMesh, np.ndarray]:
    """The whole drill from one sector: ``sectors`` rotated copies, their shared cut-face and
    axis nodes merged.

    Returns ``(full, index)``: ``index[s, i]`` is the full mesh's node of sector node ``i`` in
    copy ``s`` (rotated by ``s 2 pi / N``).
    """
    if pairs is None:
        pairs = sector_pairs(tm.points, sectors)
    n = tm.n_points
    angle = 2 * math.pi / sectors
    index = np.empty((sectors, n), dtype=np.int64)
    points = []
    count = 0
    for s in range(sectors):
        own = np.ones(n, dtype=bool)
        if s > 0:
            own[pairs.near] = False       # copy s's near cut is copy s-1's far cut
            own[pairs.axis] = False
        if s == sectors - 1 and sectors > 1:
            own[pairs.far] = False        # the last far cut closes onto copy 0's near cut
        idx = np.full(n, -1, dtype=np.int64)
        idx[own] = count + np.arange(own.sum())
        count += int(own.sum())
        if s > 0:
            idx[pairs.near] = index[s - 1, pairs.far]
            idx[pairs.axis] = index[0, pairs.axis]
        if s == sectors - 1 and sectors > 1:
            idx[pairs.far] = index[0, pairs.near]
        index[s] = idx
        points.append(tm.points[own] @ rotation(s * angle).T)
    cells = np.concatenate([index[s][tm.cells] for s in range(sectors)])
    facet_sets = {k: np.concatenate([index[s][v] for s in range(sectors)]) for k, v in tm.facet_sets.items()}
    full = TaggedMesh(np.concatenate(points), cells, np.tile(tm.cell_region, sectors), tm.regions,
                      facet_sets, tm.electrodes, tm.materials)
    return full, index
