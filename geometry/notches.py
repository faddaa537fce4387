"""Re-entrant edges of the coupler's slots and teeth, and the size field graded toward them.

The V-LT coupler is not a body of revolution: its slots (helical V grooves or rectangular
channels) and the gaps between its teeth are notches. Where a notch's faces meet inside the
material (a V groove's apex, the walls of a slot's ends, a rectangular slot's floor edges, a tooth's
root) the material angle is 270 degrees or more, the strain field is singular and the eigenvalue
error falls only as about h^1.1 under uniform refinement (the same corner rate as the
re-entrant edges of the swept section, :mod:`geometry.sizing`). Measured on the article's drill
(swept mesh, refine 1): scaling the coupler's caps by 0.75 / 0.5 / 0.4 moved the first torsion
mode by -0.04 / -0.10 / -0.13 % and the working f_r by -0.02 / -0.04 / -0.05 % for 1.3x / 2.4x /
3.9x the DOFs, still not converged. Grading toward these edges is what the swept section's
corners got: a size ``h_edge`` on the edge that grows by ``growth`` per unit distance.

API
---
``add_notch_field(gmsh, design, sizes, region_vols, refine, fraction=None, classes=None) -> int | None``:
the graded size field of a synchronised model (``None``: no notches), used by
:func:`geometry.sizing.apply_fields`; ``classes`` grades each class of edge (:data:`NOTCH_CLASSES`:
the slots' floor lines, their end walls, the teeth's roots) to its own size.
``notch_cells(design, sizes, refine) -> (float, float)``: the graded wedges' integral of h^-3
(elements up to the guard's tets-per-cube factor) and the edge size (m), for :mod:`geometry.guard`.
``notch_edges(gmsh, design, coupler_vols) -> list[int]``: the curve tags of those edges (after
fragmenting and synchronising); ``notch_edge_classes`` the same by class.
``notch_field(gmsh, curves, h_edge, growth, h_max, vols) -> int``: the Gmsh field of given curves. ``notch_length(design) -> float``: their total length (m).

Opt-in (``grade=True``, CLIs ``--grade``), like the graded edges of the free mesh: on the default
design's swept mesh it costs 1.22x the DOFs (111.6k -> 136.0k) and ~1.3x the modal time (one run: 9.7 -> 12.4 s).
"""

from __future__ import annotations

import math

import numpy as np

from .design_rpud import RPUDDesign

__all__ = ["add_notch_field", "notch_cells", "notch_edges", "notch_edge_classes", "notch_field", "notch_length",
           "NOTCH_CLASSES", "NOTCH_FRACTION",
           "NOTCH_GROWTH", "NOTCH_ANGLE"]

NOTCH_FRACTION = 0.4
"""Edge size at a notch's re-entrant edge as a fraction of the slot zone's size (``@slots``, or
``@teeth`` without slots; it carries ``refine``). Measured on the article drill's swept mesh (DOFs, first torsion, working
f_r): ungraded 111.6k, 15411.1, 19915.2 Hz; 0.4 / 0.8 (the rule) 136.0k, 15399.7, 19910.5 Hz;
0.2 / 0.5 255k, 15385.8, 19905.0 Hz; 0.1 / 0.3 827k, 15379.9, 19903.3 Hz."""

NOTCH_GROWTH = 0.8
"""Growth of the element size with the distance from a notch edge (dh/dd), times ``refine``."""

NOTCH_ANGLE = 1.75 * math.pi
"""Material angle (rad) around a notch edge, for the element estimate (a V groove of the default
design: 316 degrees; a floor edge or a tooth root: 270)."""

NOTCH_CLASSES = ("floors", "ends", "roots")
"""Classes of notch edges (:func:`notch_edge_classes`) a rule may grade each to its own size: the
slots' floor lines (a V groove's apex), the slots' end walls, the teeth's roots."""

_SAMPLES = 9
"""Points per curve where its radius and height are read to classify it."""


def _curve_points(gmsh, curve: int) -> np.ndarray:
    """``(_SAMPLES, 3)`` points along a curve (m)."""
    lo, hi = gmsh.model.getParametrizationBounds(1, curve)
    t = np.linspace(lo[0], hi[0], _SAMPLES)
    return np.asarray(gmsh.model.getValue(1, curve, t.tolist())).reshape(-1, 3)


def notch_edges(gmsh, design: RPUDDesign, coupler_vols: list[int]) -> list[int]:
    """Curve tags of the coupler's re-entrant notch edges (every class of :func:`notch_edge_classes`).

    Parameters
    ----------
    gmsh : module
        The initialised gmsh module, model fragmented and synchronised.
    design : RPUDDesign
    coupler_vols : list of int
        The coupler's volume tags.

    Returns
    -------
    list of int
        Curve tags.
    """
    return sorted(c for curves in notch_edge_classes(gmsh, design, coupler_vols).values() for c in curves)


def notch_edge_classes(gmsh, design: RPUDDesign, coupler_vols: list[int]) -> dict[str, list[int]]:
    """The coupler's re-entrant notch edges by class (:data:`NOTCH_CLASSES`), curve tags.

    Classified by where the curve lies (within ``tol`` = 1e-6 m + 1e-6 x the coupler's length):
    in the slotted zone, every curve that is not on the outer surface or the bore (the lips on
    the outer surface are convex): ``"floors"`` if it runs along more than half the slot's length
    (a V groove's apex, a rectangular slot's floor edges), else ``"ends"`` (the end walls' inner
    edges); on the teeth's root plane, every curve that is not an arc of the outer surface or the
    bore: ``"roots"`` (the roots of the tooth sides). With ``slot_offset = 0`` the slots' lower end
    walls lie in the root plane and are counted as roots, with some convex edges there (a finer
    mesh than needed, nothing worse).
    """
    c = design.coupler
    R, Ri = c.outer_diameter / 2, design.coupler_bore / 2
    tol = 1e-6 + 1e-6 * c.length
    z_root = -c.length + (c.tooth_height if c.n_teeth else 0.0)
    z_slot = z_root + c.slot_offset
    surfaces = gmsh.model.getBoundary([(3, v) for v in coupler_vols], combined=False, oriented=False)
    curves = sorted({abs(t) for _d, t in gmsh.model.getBoundary(surfaces, combined=False, oriented=False)})
    out: dict[str, list[int]] = {k: [] for k in NOTCH_CLASSES}
    for curve in curves:
        p = _curve_points(gmsh, curve)
        r, z = np.hypot(p[:, 0], p[:, 1]), p[:, 2]
        if np.all(np.abs(r - R) < tol) or np.all(np.abs(r - Ri) < tol):
            continue
        if c.n_teeth and np.all(np.abs(z - z_root) < tol):
            out["roots"].append(int(curve))
        elif c.n_slots and np.all((z > z_slot - tol) & (z < z_slot + c.slot_length + tol)) and r.max() < R + tol:
            out["floors" if np.ptp(z) > 0.5 * c.slot_length else "ends"].append(int(curve))
    return out


def notch_length(design: RPUDDesign) -> float:
    """Total length of the coupler's re-entrant notch edges, m.

    Per V slot: its apex (a helix at the apex radius) and the two flanks of each end wall (apex to
    lip, in a plane normal to the axis). Per rectangular slot: its two floor edges (helices at the
    floor radius) and, per end wall, two radial edges and the floor arc. Per tooth: two radial roots.
    """
    c = design.coupler
    R, Ri = c.outer_diameter / 2, design.coupler_bore / 2
    total = 0.0
    if c.n_slots:
        r_in = R - c.slot_depth
        alpha = c.slot_width / (2 * R)
        floor = math.hypot(c.slot_length, r_in * c.slot_twist)
        if c.slot_profile == "v":
            flank = math.hypot(R * math.cos(alpha) - r_in, R * math.sin(alpha))
            total += c.n_slots * (floor + 4 * flank)
        else:
            total += c.n_slots * (2 * floor + 2 * (2 * c.slot_depth + 2 * r_in * alpha))
    if c.n_teeth:
        total += 2 * c.n_teeth * (R - Ri)
    return total


def notch_field(gmsh, curves: list[int], h_edge: float, growth: float, h_max: float, vols: list[int]) -> int:
    """A Gmsh size field ``min(h_max, h_edge + growth * d)``, ``d`` the distance to the curves.

    The distance is sampled every ``h_edge / 2`` along each curve (within ``h_edge / 4``) and the
    field acts only in the volumes ``vols`` and on their boundaries (elsewhere it sets no limit).

    Parameters
    ----------
    gmsh : module
    curves : list of int
        Curve tags (:func:`notch_edges`).
    h_edge, h_max : float
        Element size on the curves and the largest size, m.
    growth : float
        Size increase per unit distance (dimensionless).
    vols : list of int
        Volume tags where the field acts.

    Returns
    -------
    int
        The field's tag (to go into the builder's ``Min`` field).
    """
    field = gmsh.model.mesh.field
    length = max(gmsh.model.occ.getMass(1, c) for c in curves)
    dist = field.add("Distance")
    field.setNumbers(dist, "CurvesList", curves)
    field.setNumber(dist, "Sampling", max(20, math.ceil(2 * length / h_edge)))
    fid = field.add("MathEval")
    field.setString(fid, "F", f"Min({h_max!r}, {h_edge!r} + {growth!r} * F{dist})")
    out = field.add("Restrict")
    field.setNumber(out, "InField", fid)
    field.setNumbers(out, "VolumesList", vols)
    field.setNumber(out, "IncludeBoundary", 1)
    return out


def _rule(design, sizes: dict[str, float], refine: float, fraction: float | None = None) -> tuple[float, float] | None:
    """``(h_edge, growth)`` (m, -) of a design's notches, ``None`` without them (``fraction``:
    the edge size over the slot zone's size, default :data:`NOTCH_FRACTION`)."""
    h_zone = _zone_size(design, sizes)
    if not h_zone:
        return None
    return (NOTCH_FRACTION if fraction is None else fraction) * h_zone, NOTCH_GROWTH * refine


def _zone_size(design, sizes: dict[str, float]) -> float | None:
    """The size the notch edges' sizes are fractions of (m): the slot zone's (``@slots``), or the
    teeth zone's without slots; ``None`` for a design without notches."""
    return sizes.get("@slots", sizes.get("@teeth")) if isinstance(design, RPUDDesign) else None


def add_notch_field(gmsh, design, sizes: dict[str, float], region_vols: dict[str, list[int]],
                    refine: float, fraction: float | None = None,
                    classes: dict[str, float] | None = None) -> int | None:
    """The graded size field toward the coupler's notch edges (``None`` if it has none).

    Also lowers Gmsh's ``Mesh.LcIntegrationPrecision`` (every curve of the model) from 1e-9 to 1e-5:
    at 1e-9 the 1-D meshing integrates the kinked distance field for seconds (measured 3.3 s
    instead of 0.2 s on the article's drill).

    Parameters
    ----------
    gmsh : module
        The initialised gmsh module, model fragmented and synchronised.
    design : DesignBase
        Only an :class:`RPUDDesign` with slots or teeth has notches.
    sizes : dict
        Region sizes at ``refine`` (m; :func:`geometry.sizing.region_sizes`).
    region_vols : dict
        Region name -> volume tags.
    refine : float
        The refinement factor (scales the growth; the sizes carry it already).
    fraction : float, optional
        Edge size over the slot zone's size (default :data:`NOTCH_FRACTION`).
    classes : dict, optional
        Class of :data:`NOTCH_CLASSES` -> its own edge size over the slot zone's size (the
        classes not named take ``fraction``).

    Returns
    -------
    int or None
        The field's tag.
    """
    rule = _rule(design, sizes, refine, fraction)
    if not rule or "coupler" not in region_vols:
        return None
    by_class = notch_edge_classes(gmsh, design, region_vols["coupler"])
    h_zone = _zone_size(design, sizes)
    by_size: dict[float, list[int]] = {}
    for name, curves in by_class.items():
        h_edge = h_zone * classes[name] if classes and name in classes else rule[0]
        by_size.setdefault(h_edge, []).extend(curves)
    by_size = {h: sorted(c) for h, c in by_size.items() if c}
    if not by_size:
        return None
    gmsh.option.setNumber("Mesh.LcIntegrationPrecision", 1e-5)
    fields = [notch_field(gmsh, curves, h, rule[1], sizes["coupler"], region_vols["coupler"])
              for h, curves in sorted(by_size.items())]
    if len(fields) == 1:
        return fields[0]
    out = gmsh.model.mesh.field.add("Min")
    gmsh.model.mesh.field.setNumbers(out, "FieldsList", fields)
    return out


def notch_cells(design, sizes: dict[str, float], refine: float) -> tuple[float, float]:
    """The graded wedges' extra integral of h^-3 over their volume (a dimensionless count of
    element-size cubes) and the edge size (m; ``inf`` without notches).

    A wedge of :data:`NOTCH_ANGLE` along the edges with h = a + g d up to the coupler's size H (the
    field's cap): integral of angle d (h^-3 - H^-3) dd = angle / g^2 (1/(2a) - 1/H + a/(2H^2) -
    (H-a)^2/(2H^3)) per metre of edge."""
    rule = _rule(design, sizes, refine)
    if rule is None:
        return 0.0, math.inf
    (a, g), H = rule, sizes["coupler"]
    per_m = NOTCH_ANGLE / g ** 2 * (1 / (2 * a) - 1 / H + a / (2 * H ** 2) - (H - a) ** 2 / (2 * H ** 3))
    return per_m * notch_length(design), a
