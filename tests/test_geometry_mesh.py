"""Gmsh builds: volumes vs closed form, named groups, electrodes, conformity, quality, determinism."""

import math

import numpy as np
import pytest

from geometry import examples
from geometry.builder import DEFAULT_ORDER, MIN_QUALITY, MIN_SICN_DEFAULT, build
from geometry.design import default_design
from geometry.report import mesh_part_volumes

VOLUME_TOL = 0.005  # the 0.5 %


@pytest.fixture(scope="module")
def default_build():
    """The default design at its default size and order: the mesh fem consumes."""
    return build(default_design())


def _variants():
    d = examples.article_design()
    return {
        "conical_bore": d.replace({"horn.profile": "conical", "stack.bolt_diameter": 0.0, "bore_diameter": 0.006}),
        "exponential_rect_slots": d.replace({"horn.profile": "exponential", "coupler.slot_profile": "rectangular",
                                             "coupler.slot_angle_deg": -20.0}),
        "axial_slots_shims": d.replace({"coupler.slot_angle_deg": 0.0, "stack.electrode_shims": True}),
    }


@pytest.fixture(scope="module", params=sorted(_variants()))
def variant_build(request):
    design = _variants()[request.param]
    return (design, *build(design, mesh_size=0.008, order=2))


@pytest.fixture(scope="module", params=["k33_rod", "k31_bar", "langevin", "slender_rod", "cone"])
def stack_build(request):
    if request.param == "cone":
        from geometry.design import Segment, StackDesign

        design = StackDesign(name="cone", segments=(
            Segment("tube", 0.03, outer_diameter=0.03, inner_diameter=0.01, material="al7075"),
            Segment("cone", 0.05, kind="cone", outer_diameter=0.03, end_diameter=0.012, inner_diameter=0.004,
                    material="al7075")))
    else:
        design = examples.EXAMPLES[request.param]()
    return (design, *build(design, order=2))


def _check_volumes(design, tm):
    volumes, masses = mesh_part_volumes(tm)
    closed = design.part_volumes()
    assert set(volumes) == set(closed)
    for part, v in volumes.items():
        assert v == pytest.approx(closed[part], rel=VOLUME_TOL), part
    for part, m in design.part_masses().items():
        assert masses[part] == pytest.approx(m, rel=VOLUME_TOL), part


def _check_conformal(tm):
    """No two nodes at the same place (a non-conformal interface would duplicate them) and every
    part touches its neighbour through shared nodes."""
    q = np.round(tm.points / 1e-9).astype(np.int64)
    assert len(np.unique(q, axis=0)) == tm.n_points
    parts = tm.parts
    nodes = {p: set(np.unique(tm.cells[tm.cells_in(part=p)][:, :4]).tolist()) for p in parts}
    return nodes


# ------------------------------------------------------------------ default design


def test_default_mesh_size_order_and_volumes(default_build):
    tm, rep = default_build
    assert tm.order == DEFAULT_ORDER == 2
    assert 10_000 <= tm.n_cells <= 25_000  # the fem engineer's budget (50k-120k P2 displacement DOFs)
    _check_volumes(default_design(), tm)
    assert (tm.cell_volumes() > 0).all()


def test_default_groups_regions_and_electrodes(default_build):
    tm, rep = default_build
    d = default_design()
    names = {r.name: r for r in tm.regions}
    assert set(names) == {"coupler", "ring_1", "ring_2", "ring_3", "ring_4", "flange_disc", "horn", "bolt"}
    assert (names["bolt"].part, names["bolt"].material) == ("bolt", d.stack.bolt_material)      # the M12 part
    for k in range(1, 5):
        r = names[f"ring_{k}"]
        assert (r.part, r.material) == ("stack", "PZT-8")
        assert r.poling == ((0.0, 0.0, -1.0) if k % 2 else (0.0, 0.0, 1.0))
    assert names["horn"].poling is None and names["flange_disc"].part == "flange"
    expected = {"horn_tip", "teeth_tops", "flange"} | {f"electrode_{k}" for k in range(5)}
    assert set(tm.facet_sets) == expected
    for name, group in rep.physical_groups.items():
        assert group["entities"] > 0 and group["elements"] > 0, name
    assert rep.physical_groups["teeth_tops"]["entities"] == d.coupler.n_teeth
    assert [(e.name, e.role) for e in tm.electrodes] == [
        ("electrode_0", "ground"), ("electrode_1", "hot"), ("electrode_2", "ground"), ("electrode_3", "hot"),
        ("electrode_4", "ground")]
    # electrodes: planar at the design's z, exactly the ring faces (annulus area, nodes of ring cells)
    ring_area = math.pi / 4 * (d.stack.outer_diameter ** 2 - d.stack.inner_diameter ** 2)
    for name, planes in d.electrode_planes().items():
        tri = tm.facet_sets[name]
        assert np.allclose(tm.points[tri, 2], planes[0][1], atol=1e-9), name
        r = np.hypot(tm.points[tri, 0], tm.points[tri, 1])
        assert r.min() >= d.stack.inner_diameter / 2 - 1e-9 and r.max() <= d.stack.outer_diameter / 2 + 1e-9
        p = tm.points[tri]
        area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum()
        assert area == pytest.approx(ring_area, rel=0.02), name  # flat triangles on a circle: a little low
    ext = d.part_extents()
    assert np.allclose(tm.points[tm.facet_sets["horn_tip"], 2], ext["horn"][1], atol=1e-9)
    assert np.allclose(tm.points[tm.facet_sets["teeth_tops"], 2], ext["coupler"][0], atol=1e-9)
    fl = tm.points[tm.facet_sets["flange"]]
    assert set(np.round(fl[..., 2].ravel(), 9)) == {round(z, 9) for z in ext["flange"]}
    assert np.hypot(fl[..., 0], fl[..., 1]).max() == pytest.approx(d.flange.outer_diameter / 2, rel=1e-6)


def test_default_mesh_is_conformal_and_converts_to_skfem(default_build):
    tm, _ = default_build
    nodes = _check_conformal(tm)
    # neighbours share nodes on their interfaces
    for a, b in (("coupler", "stack"), ("stack", "flange"), ("flange", "horn")):
        assert len(nodes[a] & nodes[b]) > 20, (a, b)
    # each electrode's nodes belong to the ceramic and, at the stack ends, to the metal too
    e0 = set(tm.facet_sets["electrode_0"].ravel().tolist())
    assert e0 <= nodes["stack"] and e0 <= nodes["coupler"]
    sk = tm.to_skfem()
    assert set(sk.subdomains) == {r.name for r in tm.regions}
    assert {k: len(v) for k, v in sk.boundaries.items()} == {k: len(v) for k, v in tm.facet_sets.items()}


def test_default_mesh_quality_and_node_order(default_build):
    tm, rep = default_build
    assert rep.quality["n_inverted"] == 0
    assert rep.quality["min_sicn"] > MIN_SICN_DEFAULT and rep.quality["min_gamma"] > MIN_QUALITY
    assert rep.quality["median_sicn"] > 0.6
    # VTK order: node 8 is the midpoint of edge (1, 3), node 9 of edge (2, 3)
    p = tm.points[tm.cells]
    edge = np.linalg.norm(p[:, 1] - p[:, 3], axis=1)
    assert np.median(np.linalg.norm(p[:, 8] - 0.5 * (p[:, 1] + p[:, 3]), axis=1) / edge) < 1e-3
    assert np.median(np.linalg.norm(p[:, 9] - 0.5 * (p[:, 2] + p[:, 3]), axis=1) / edge) < 1e-3


def test_same_design_same_mesh(default_build):
    tm, _ = default_build
    again, _ = build(default_design())
    assert (again.n_points, again.n_cells) == (tm.n_points, tm.n_cells)
    assert np.array_equal(again.cells, tm.cells) and np.allclose(again.points, tm.points)


def test_morphed_mesh_matches_the_new_design(default_build):
    tm, _ = default_build
    d = default_design()
    new = d.replace({"horn.length": d.horn.length * 1.08, "coupler.length": d.coupler.length * 0.95})
    morphed = tm.replace(points=d.morph_points(tm.points, new))
    _check_volumes(new, morphed)
    assert morphed.points[:, 2].max() == pytest.approx(new.part_extents()["horn"][1])
    assert morphed.points[:, 2].min() == pytest.approx(-new.coupler.length)


# ------------------------------------------------------------------ variants and textbook stacks


def test_rpud_variants(variant_build):
    design, tm, rep = variant_build
    _check_volumes(design, tm)
    _check_conformal(tm)
    assert rep.quality["n_inverted"] == 0 and rep.quality["min_gamma"] > MIN_QUALITY
    assert all(len(v) for v in tm.facet_sets.values())
    if design.stack.electrode_shims:
        shims = [r for r in tm.regions if r.part == "electrodes"]
        assert len(shims) == 5 and all(r.material == "copper" for r in shims)
        # an inner electrode is both ceramic faces touching its shim
        z = np.unique(np.round(tm.points[tm.facet_sets["electrode_2"], 2], 12))
        assert z == pytest.approx([p[1] for p in design.electrode_planes()["electrode_2"]])


def test_textbook_stacks(stack_build):
    design, tm, rep = stack_build
    _check_volumes(design, tm)
    _check_conformal(tm)
    assert rep.quality["n_inverted"] == 0 and rep.quality["min_gamma"] > MIN_QUALITY
    assert {"bottom", "top"} <= set(tm.facet_sets)
    for e in design.electrodes:
        (axis, value), = design.electrode_planes()[e.name]
        i = "xyz".index(axis)
        assert np.allclose(tm.points[tm.facet_sets[e.name], i], value, atol=1e-9)
        assert dict((x.name, x.role) for x in tm.electrodes)[e.name] == e.role
    for seg in design.segments:
        r = tm.region(seg.name)
        assert r.poling == seg.poling_vector and r.material == seg.material
    if design.name == "k31_bar":
        area = sum(len(tm.facet_sets[n]) for n in ("electrode_plus_x", "electrode_minus_x"))
        assert area > 0 and tm.region("bar").poling == (1.0, 0.0, 0.0)


def test_first_order_mesh_is_coarser_in_volume_but_valid():
    d = examples.k33_rod()
    tm, rep = build(d, order=1)
    assert tm.order == 1 and rep.quality["n_inverted"] == 0
    v = tm.cell_volumes().sum()
    assert v == pytest.approx(d.part_volumes()["rod"], rel=0.05)  # faceted circle: a few % low
    assert v < d.part_volumes()["rod"]
