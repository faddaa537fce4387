"""The coupler's re-entrant notch edges (geometry.notches) and the opt-in grading toward them.

* Classification on the default design (6 helical V slots, 6 teeth): per slot its apex line and
  the four inner edges of its two end walls, per tooth its two roots: 42 curves, in the classes
  floors / ends / roots of ``notch_edge_classes``; and on six
  variants (rectangular slots, no teeth, no slots, axial and left-handed slots). Their total
  length measured by OCC against the closed form of ``notch_length`` (helices of the apex or floor
  radius, end-wall edges, radial roots) within 1e-5 (measured 1e-8 on the default design).
* Grading is opt-in (``grade=True``): the default mesh is unchanged; the graded one puts the edge
  size along every apex line (node count within 15 % of length / (h_edge / 2)), the ungraded one
  less than 0.6 of that.
"""

import gmsh
import numpy as np
import pytest

import geometry
from geometry.examples import article_design
from geometry.guard import estimate
from geometry.notches import NOTCH_CLASSES, NOTCH_FRACTION, notch_edge_classes, notch_edges, notch_length
from geometry.sizing import region_sizes
from geometry.tagging import parametric_model


VARIANTS = {
    "default": ({}, 6 * (1 + 4) + 2 * 6),
    "rectangular slots": ({"coupler.slot_profile": "rectangular"}, 6 * (2 + 2 * 3) + 2 * 6),
    "v slots, no teeth": ({"coupler.n_teeth": 0}, 6 * (1 + 4)),
    "rectangular slots, no teeth": ({"coupler.slot_profile": "rectangular", "coupler.n_teeth": 0}, 6 * (2 + 2 * 3)),
    "teeth, no slots": ({"coupler.n_slots": 0}, 2 * 6),
    "axial slots": ({"coupler.slot_angle_deg": 0.0}, 6 * (1 + 4) + 2 * 6),
    "left-handed slots": ({"coupler.slot_angle_deg": -45.0}, 6 * (1 + 4) + 2 * 6),
}
"""Coupler variants: the replaced parameters and the expected count of notch curves (per V slot its
apex and the two flanks of each end wall; per rectangular slot two floor edges and, per end wall,
two radial edges and the floor arc; two roots per tooth)."""


@pytest.mark.parametrize("name", list(VARIANTS))
def test_notch_edges_counted_and_measured(name):
    changes, expected = VARIANTS[name]
    d = article_design().replace(changes) if changes else article_design()
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        region_vols, _meta, _facets = parametric_model(gmsh, d, {}, 3)
        curves = notch_edges(gmsh, d, region_vols["coupler"])
        classes = notch_edge_classes(gmsh, d, region_vols["coupler"])
        length = sum(gmsh.model.occ.getMass(1, c) for c in curves)
    finally:
        gmsh.finalize()
    assert len(curves) == expected
    # the classes partition the edges: per V slot one floor line (its apex), per rectangular slot
    # two floor edges, two roots per tooth, the end walls' edges the rest
    assert sorted(c for v in classes.values() for c in v) == sorted(curves) and tuple(classes) == NOTCH_CLASSES
    floors = (1 if d.coupler.slot_profile == "v" else 2) * d.coupler.n_slots
    assert (len(classes["floors"]), len(classes["roots"])) == (floors, 2 * d.coupler.n_teeth)
    # OCC's lengths against the closed form (the apex of a helical slot is a B-spline lofted
    # through five sections: measured 1e-8 from the helix's length)
    assert length == pytest.approx(notch_length(d), rel=1e-5)


def test_no_notches_without_slots_and_teeth():
    assert notch_length(article_design().replace({"coupler.n_slots": 0, "coupler.n_teeth": 0})) == 0.0


def _apex_distance(d, points):
    """Distance (m) of points to the nearest slot apex line (a helix at the apex radius)."""
    from geometry.solids import _slot_phase

    c = d.coupler
    ra = c.outer_diameter / 2 - c.slot_depth
    z0 = -c.length + c.tooth_height + c.slot_offset
    s = np.linspace(0, 1, 400)
    best = np.full(len(points), np.inf)
    for k in range(c.n_slots):
        phi = _slot_phase(c) + 2 * np.pi * k / c.n_slots + c.slot_twist * s
        helix = np.column_stack([ra * np.cos(phi), ra * np.sin(phi), z0 + c.slot_length * s])
        dist = np.linalg.norm(points[:, None, :] - helix[None, :, :], axis=2).min(axis=1)
        best = np.minimum(best, dist)
    return best


@pytest.mark.parametrize("grade", [False, True])
def test_grading_puts_the_edge_size_along_the_apex_lines(grade):
    """P2 nodes on the apex lines (within 30 um of the exact helix: the slot is a loft through five
    sections, its apex a B-spline) of a graded mesh: one per half edge size, measured 138 for 141
    expected at refine 2 (198 for 199 at refine 1.4); ungraded 66."""
    d = article_design()
    refine = 2.0       # cheap; the 20 mm slot zone is still ~4 elements (4.8 mm) long
    tm = geometry.build_mesh(d, mesher="revolve", refine=refine, grade=grade)
    c = d.coupler
    ra = c.outer_diameter / 2 - c.slot_depth
    apex_length = c.n_slots * np.hypot(c.slot_length, ra * c.slot_twist)
    h_edge = NOTCH_FRACTION * region_sizes(d, refine=refine)["@slots"]
    expected = apex_length / (h_edge / 2) + c.n_slots
    n_on = int((_apex_distance(d, tm.points) < 3e-5).sum())
    if grade:
        assert n_on == pytest.approx(expected, rel=0.15)
    else:
        assert n_on < 0.6 * expected
    # the guard's estimate follows the mesh it predicts (measured 1.29x ungraded, 1.19x graded)
    est = estimate(d, refine=refine, grade=grade, mesher="revolve").dofs
    assert 0.9 < est / (3 * tm.n_points) < 2.5

