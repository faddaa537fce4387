"""Thin layers (geometry.layers): bonds and shims meshed as structured extrusions.

References: closed-form volumes; the same small stack meshed with free tetrahedra (two through
the bond, the pre-layer builder: the reference a layered mesh must reproduce); a one-refinement
step of the 55 mm bonded sandwich; and the textbook free-free rod with a spring at its middle
(the bond as a laterally constrained spring k = M A / t, M = E (1 - nu) / ((1 + nu)(1 - 2 nu)))
for a 50 um layer.
"""

import math

import numpy as np
import pytest
import scipy.optimize

import fem
import geometry.layers as layers
from geometry import examples
from geometry.builder import MIN_QUALITY, build, mesh_layers
from geometry.design import ElectrodeSpec, Segment, StackDesign
from geometry.guard import estimate
from geometry.materials import get_material
from geometry.report import mesh_part_volumes

SANDWICH_CELLS = 15_276
"""Tetrahedra of the default bonded sandwich (Gmsh is seeded and single-threaded: deterministic)."""


@pytest.fixture(scope="module")
def sandwich():
    design = examples.bonded_sandwich()
    return (design, *build(design))


def _coupled_mode(tm, near_hz, n_modes=4):
    """(f_r, f_a) of the most strongly coupled mode near ``near_hz``."""
    modes = fem.modal_analysis(fem.assemble(tm), near_hz=near_hz, n_modes=n_modes)
    i = int(np.argmax(modes.k_eff))
    assert modes.k_eff[i] > 0.2
    return modes.f_r_hz[i], modes.f_a_hz[i]


# ------------------------------------------------------------------ the 55 mm bonded sandwich



def _assert_conformal_and_whole(tm, design, rel):
    """No node twice (a non-conformal interface would duplicate them); part volumes within rel."""
    q = np.round(tm.points / 1e-9).astype(np.int64)
    assert len(np.unique(q, axis=0)) == tm.n_points
    volumes, _ = mesh_part_volumes(tm)
    for part, v in design.part_volumes().items():
        assert volumes[part] == pytest.approx(v, rel=rel), part


def test_sandwich_layers_are_structured_conformal_and_cheap(sandwich):
    design, tm, rep = sandwich
    plan = mesh_layers(design)
    assert set(plan) == {"bond_1", "bond_2"} and {lay.n_elements for lay in plan.values()} == {1}
    assert {lay.rim for lay in plan.values()} == {None}  # edge zone 2 % of the area: not refined
    assert tm.n_cells == SANDWICH_CELLS  # free tetrahedra at the bond thickness: millions
    # a bond is its face's triangles swept through one element layer, three tetrahedra per prism
    ext = design.segment_extents()
    for bond, face in (("bond_1", "electrode_bottom"), ("bond_2", "electrode_top")):
        cells = tm.cells[tm.cells_in(region=bond)]
        assert len(cells) == 3 * len(tm.facet_sets[face])
        z = np.unique(np.round(tm.points[np.unique(cells[:, :4]), 2], 9))
        z0, z1 = ext[bond]
        np.testing.assert_allclose(z, [z0, z1], atol=1e-9)
    assert rep.quality["layer_elements"] == sum(len(tm.cells_in(region=b)) for b in plan)
    _assert_conformal_and_whole(tm, design, rel=1e-4)
    # quality: the free elements keep the usual bound, the flat layer elements are valid
    assert rep.quality["n_inverted"] == 0 and rep.quality["min_gamma"] > MIN_QUALITY
    assert rep.quality["layer_min_sicn"] > 0.05
    # the resource guard counts layers as layers (it predicted millions before)
    assert 0.7 < estimate(design).elements / tm.n_cells < 1.3


@pytest.mark.heavy
def test_sandwich_thickness_mode_converges(sandwich):
    """First thickness mode (metal discs moving apart, k_eff ~0.38, ~47.5 kHz): a mesh 1.5x
    coarser everywhere (caps and layers included) agrees with the default within 0.3 %."""
    design, tm, _ = sandwich
    coarse, _ = build(design, refine=1.5)
    assert coarse.n_cells < tm.n_cells / 2.5
    f_r, f_a = _coupled_mode(tm, 47.5e3, 3)
    c_r, c_a = _coupled_mode(coarse, 47.5e3, 3)
    assert 46e3 < f_r < 49e3
    assert abs(c_r / f_r - 1) < 0.003 and abs(c_a / f_a - 1) < 0.003
    # an independent check: the axisymmetric (r, z) model of tests/axisym_reference.py, its own
    # graded triangles (1 mm, grading toward the layer corners), the same most-coupled mode
    import axisym_reference as ar

    model = ar.assemble(ar.section(design), 2e-3, 4e-3)
    ref = ar.modes(model, 47.5e3, 6)
    i = int(np.argmax(ref.k_eff))
    # measured: +0.020 % (f_r), +0.009 % (f_a); the issue asks 0.5 %. The 2 mm reference is
    # within 1e-5 of a 1 mm one (47 496.98 / 51 255.99 Hz)
    assert abs(f_r / ref.f_r[i] - 1) < 0.001 and abs(f_a / ref.f_a[i] - 1) < 0.001


# ------------------------------------------------------------------ layered vs free tetrahedra


def _small_stack(bond=0.00025, diameter=0.003):
    return StackDesign(
        name="small_bonded", target_frequency=60e3,
        segments=(Segment("back", 0.008, material="al7075", outer_diameter=diameter),
                  Segment("bond", bond, material="epoxy", outer_diameter=diameter),
                  Segment("disc", 0.004, material="PZT-4", outer_diameter=diameter, poling="+z")),
        electrodes=(ElectrodeSpec("electrode_bottom", "disc", "bottom", "ground"),
                    ElectrodeSpec("electrode_top", "disc", "top", "hot")))


def test_layered_mesh_matches_free_tetrahedra(monkeypatch):
    """3 mm aluminium / 0.25 mm epoxy / PZT-4 rod: the coupled longitudinal mode (~139 kHz) of the
    layered mesh (bond edge refined) within 0.2 % of a free mesh with two elements through the
    bond and 0.125 mm elements all over it (8x the elements)."""
    design = _small_stack()
    layered, _ = build(design, mesh_size=0.001)
    assert mesh_layers(design, mesh_size=0.001)["bond"].rim is not None
    monkeypatch.setattr(layers, "LAYER_RATIO", 0.0)
    assert not mesh_layers(design, mesh_size=0.001)
    free, _ = build(design, mesh_size=0.001)
    assert free.n_cells > 4 * layered.n_cells
    l_r, l_a = _coupled_mode(layered, 139e3, 3)
    f_r, f_a = _coupled_mode(free, 139e3, 3)
    assert abs(l_r / f_r - 1) < 0.002 and abs(l_a / f_a - 1) < 0.002
    # the bonded stack's admittance (lossy, datasheet losses) below and above the coupled mode:
    # direct 3-D solves of the layered mesh against the independent axisymmetric model
    import axisym_reference as ar

    model = ar.assemble(ar.section(design), 2.5e-4, 1e-3)
    freqs = [0.5 * l_r, 1.2 * l_a]
    y3 = fem.harmonic_sweep(fem.assemble(layered), freqs, 1.0, surfaces=("top",), method="direct").admittance
    np.testing.assert_allclose(y3, ar.admittance(model, freqs), rtol=0.005)


# ------------------------------------------------------------------ a 50 um layer


def test_50um_layer_acts_as_a_constrained_spring():
    """Steel rod 2 x 50 mm, 10 mm diameter, free-free, with a 50 um epoxy insulator at its middle:
    the first longitudinal mode drops by the spring k = M A / t between the halves,
    kappa tan(kappa l) = 2 k / (E A) (u = cos(kappa x) from a free end), relative to the same rod
    without the layer; the FE ratio within 0.1 % of the model's (the drop is ~1.4 %)."""
    t, d, half = 50e-6, 0.01, 0.05
    rod = dict(material="steel_45", outer_diameter=d)
    shim = StackDesign(name="insulated_rod", target_frequency=26e3, segments=(
        Segment("left", half, **rod), Segment("insulator", t, material="epoxy", outer_diameter=d),
        Segment("right", half, **rod)))
    plain = StackDesign(name="plain_rod", target_frequency=26e3, segments=(Segment("rod", 2 * half, **rod),))
    plan = mesh_layers(shim)
    assert set(plan) == {"insulator"} and plan["insulator"].rim is None
    tm_shim, rep = build(shim)
    tm_plain, _ = build(plain)
    assert rep.quality["n_inverted"] == 0
    assert len(tm_shim.cells_in(region="insulator")) == rep.quality["layer_elements"] > 0
    assert tm_shim.n_cells < 3 * tm_plain.n_cells

    def longitudinal(tm):
        modes = fem.modal_analysis(fem.assemble(tm), near_hz=25e3, n_modes=6)
        return modes.f_r_hz[int(np.argmax(modes.shares[:, 0]))]

    steel, epoxy = get_material("steel_45"), get_material("epoxy")
    nu = epoxy.poisson_ratio
    m_constrained = epoxy.youngs_modulus * (1 - nu) / ((1 + nu) * (1 - 2 * nu))
    area = math.pi / 4 * d ** 2
    ratio_k = 2 * (m_constrained * area / t) / (steel.youngs_modulus * area) * half  # 2 k l / (E A)
    x = scipy.optimize.brentq(lambda x: x * math.tan(x) - ratio_k, 1.0, math.pi / 2 - 1e-12)
    model = x / (math.pi / 2)
    assert model < 0.99
    assert longitudinal(tm_shim) / longitudinal(tm_plain) == pytest.approx(model, rel=1e-3)


# ------------------------------------------------------------------ layouts


def test_layers_between_unlike_neighbours_stay_conformal():
    """A run of two layers (copper shim on an annulus, epoxy bond) between segments of other
    diameters, a box insulator on a disc, a cone above: every outline imprinted, the mesh
    conformal, the volumes exact, nothing inverted."""
    design = StackDesign(name="unlike", target_frequency=30e3, segments=(
        Segment("back", 0.01, material="steel_45", outer_diameter=0.03, inner_diameter=0.006),
        Segment("shim", 0.0001, material="copper", outer_diameter=0.034, inner_diameter=0.004),
        Segment("bond", 0.0002, material="epoxy", outer_diameter=0.025),
        Segment("disc", 0.004, material="PZT-4", outer_diameter=0.02, poling="+z"),
        Segment("insulator", 0.0003, kind="box", material="epoxy", thickness=0.01, width=0.012),
        Segment("cone", 0.02, kind="cone", material="al7075", outer_diameter=0.018, end_diameter=0.01)),
        electrodes=(ElectrodeSpec("electrode_bottom", "disc", "bottom", "ground"),
                    ElectrodeSpec("electrode_top", "disc", "top", "hot")))
    plan = mesh_layers(design)
    assert set(plan) == {"shim", "bond", "insulator"}
    assert {n for n, _z in plan["shim"].outlines} == {"shim", "bond", "back", "disc"}
    tm, rep = build(design)
    _assert_conformal_and_whole(tm, design, rel=1e-3)
    assert rep.quality["n_inverted"] == 0 and rep.quality["min_gamma"] > MIN_QUALITY
    assert rep.quality["layer_elements"] == sum(len(tm.cells_in(region=n)) for n in plan)
    for name in ("electrode_bottom", "electrode_top"):
        assert len(tm.facet_sets[name]) > 0
    assert 0.4 < estimate(design).elements / tm.n_cells < 2.5
