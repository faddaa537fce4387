"""The coupler's re-entrant notch edges (geometry.notches) and the opt-in grading toward them.

* Classification on the default design (6 helical V slots, 6 teeth): per slot its apex line and
  the four inner edges of its two end walls, per tooth its two roots: 42 curves; their total
  length measured by OCC against the closed form of ``notch_length`` (helix of the apex radius,
  end-wall edges, radial roots) within 1 % (measured 0.68 %: the end walls lie in the slot's
  oblique cross-section, the closed form takes them normal to the axis).
* Grading is opt-in (``grade=True``): the default mesh is unchanged; the graded one puts the edge
  size along every apex line (node count within 15 % of length / (h_edge / 2)), the ungraded one
  less than 0.6 of that.
* The two-level error estimate of ``fem.modal --error`` on the default swept mesh covers the error
  that the coupler-alone refinement study puts on it (the p = 2 bound of the uniform study did not).
"""

import gmsh
import numpy as np
import pytest

import geometry
from geometry.design import default_design
from geometry.guard import estimate
from geometry.notches import NOTCH_FRACTION, notch_edges, notch_length
from geometry.sizing import region_sizes
from geometry.tagging import parametric_model


def test_notch_edges_of_the_default_design():
    d = default_design()
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        region_vols, _meta, _facets = parametric_model(gmsh, d, {}, 3)
        curves = notch_edges(gmsh, d, region_vols["coupler"])
        length = sum(gmsh.model.occ.getMass(1, c) for c in curves)
    finally:
        gmsh.finalize()
    c = d.coupler
    assert len(curves) == c.n_slots * (1 + 4) + 2 * c.n_teeth
    assert length == pytest.approx(notch_length(d), rel=0.01)
    # no notches, no edges: the design without slots and teeth has none
    assert notch_length(d.replace({"coupler.n_slots": 0, "coupler.n_teeth": 0})) == 0.0


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
    sections, its apex a B-spline) of a graded mesh: one per half edge size, measured 198 for 199
    expected at refine 1.4; ungraded 90."""
    d = default_design()
    refine = 1.4
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
    # the guard counts the graded wedges only when asked
    assert (estimate(d, refine=refine, grade=grade, mesher="revolve").elements
            > estimate(d, refine=refine, mesher="revolve").elements) == grade


DEFAULT_CONVERGED = {"f_r_hz": (19892.7, 19896.8), "f_a_hz": (21647.1, 21651.8)}
"""Converged working mode of default_design() (Hz, a range): the coupler refined alone with its
notches graded (benchmarks/study_coupler_convergence.py, p = 2 in the coupler's size from levels
0.7 / 0.5 and 0.5 / 0.4) plus the swept parts' true error at refine 1 (the design without slots
and teeth against its converged (r, z) answer, +0.041 % / +0.044 %)."""


def test_error_estimate_of_the_default_swept_mesh_covers_the_coupler_study():
    """``fem.modal --error`` on the default design (swept, refine 1) against the error the coupler
    study puts on it: at least the smallest of the range, at most 4x its largest (measured 30 / 27 Hz
    against 18.4-22.5 / 14.6-19.3 Hz)."""
    import fem
    from fem.errors import estimate as error_estimate

    d = default_design()
    tm, _rep = geometry.build(d, mesher="revolve")
    system = fem.assemble(tm)
    res = fem.modal_analysis(system, 20e3, 12)
    w = fem.working_mode(system, res.f_r_hz, res.vectors, 20e3)
    values = {"f_r_hz": float(res.f_r_hz[w]), "f_a_hz": float(res.f_a_hz[w])}
    est = error_estimate(d, values, system.ndof, harmonic=False, n_modes=12, mesher="revolve")
    for key, (lo, hi) in DEFAULT_CONVERGED.items():
        smallest, largest = values[key] - hi, values[key] - lo
        assert smallest > 0                                  # converging from above
        assert smallest <= est.error(key) <= 4 * largest, (key, est.error(key), smallest, largest)
