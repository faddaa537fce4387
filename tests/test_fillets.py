"""Fillets at the horn's shoulders (geometry.fillets) and converged stresses at them.

- Design data: radii validated (>= 0, inside the faces they join), TOML round trip, the arcs
  tangent to both faces, the volumes they add against the closed-form spandrel (Pappus).
- Every mesher builds them (free, revolve, swept sector; the exponential horn's loft): region
  volumes within the project's 0.5 % of the closed form; the axial morph keeps the arcs exact.
- The independent (r, z) model (tests/axisym_reference.py, curved P2 triangles): the peak von
  Mises stress on each fillet of the working mode (per unit tip displacement) converges on nested
  meshes at an order of about 2 (P2 stresses at a smooth point; a sharp corner's peak diverges,
  order < 0), and the 3-D swept sector's k = 0 working mode agrees with its Richardson limit
  within 2 % (the brief's figure; the reference's own error is below a tenth of it, asserted).
- The utilisation table: the filleted junction of flange and horn is not a singular edge, the
  sharp one is; a row whose peak lies on a singular edge is marked and headlined off it; the
  two-mesh estimate of :func:`fem.stress_table.converged_table`.
"""

import math

import numpy as np
import pytest

import geometry
from geometry.fillets import Outline, revolved_volume
from rpud_common import ParameterError

import axisym_reference as ar
from geometry.examples import article_design


def plain():
    """The default drill without slots and teeth (axisymmetric), with 2 mm fillets and without the
    bolt part (the fillet references were computed without it)."""
    return geometry.filleted(article_design().replace({"coupler.n_slots": 0, "coupler.n_teeth": 0,
                                                                "stack.bolt_diameter": 0.0}))


# ---------------------------------------------------------------------------- design data


@pytest.mark.parametrize("changes, field", [
    ({"horn.flange_fillet": -1e-3}, "horn.flange_fillet"),
    ({"horn.step_fillet": float("nan")}, "horn.step_fillet"),
    ({"horn.step_fillet": 5e-5}, "horn.step_fillet"),                   # below the smallest feature
    ({"horn.step_fillet": 0.0065}, "horn.step_fillet"),                 # the whole step height (6.5 mm)
    ({"horn.flange_fillet": 0.0105}, "horn.flange_fillet"),             # beyond the flange's face
    ({"horn.flange_fillet": 0.034}, "horn.flange_fillet"),              # longer than the back section
    ({"horn.profile": "conical", "horn.flange_fillet": 0.04}, "horn.flange_fillet"),
])
def test_fillet_radii_are_checked(changes, field):
    with pytest.raises(ParameterError, match=field.replace(".", r"\.")):
        article_design().replace(changes)


def test_fillets_round_trip_through_toml(tmp_path):
    d = geometry.filleted(article_design(), 0.0015)
    d.save(tmp_path / "d.toml")
    back = geometry.load_design(tmp_path / "d.toml")
    assert back == d and back.horn.flange_fillet == back.horn.step_fillet == 0.0015
    d0 = article_design()                            # a horn maker's radii by default
    assert d0.horn.flange_fillet == d0.horn.step_fillet == geometry.HORN_MAKER_FILLET == 0.002
    assert set(d0.fillets()) == {"flange", "step"}
    assert geometry.filleted(d0, 0.0).fillets() == {}         # 0: sharp


def test_fillet_arcs_are_tangent_and_their_volumes_exact():
    d = plain()
    fil = d.fillets()
    h, z0 = d.horn, d.stack.length + d.flange.thickness
    for name, a in fil.items():
        c = np.asarray(a.centre)
        for p in (a.start, a.end, a.mid):
            assert np.hypot(*(np.asarray(p) - c)) == pytest.approx(a.radius, rel=1e-12)
        assert a.start[1] == pytest.approx(a.corner[1], abs=1e-15)       # on the face plane
        assert a.end[0] == pytest.approx(a.corner[0], abs=1e-15)         # on the cylinder
        assert a.angle == pytest.approx(math.pi / 2, rel=1e-9)
    assert fil["flange"].corner == (h.back_diameter / 2, z0)
    assert fil["step"].corner == (h.tip_diameter / 2, z0 + h.step_fraction * h.length)
    # a quarter-circle spandrel: area r^2 (1 - pi / 4), centroid (10 - 3 pi) / (12 - 3 pi) r from
    # each straight side; Pappus V = 2 pi A r_centroid
    rho, rt = h.step_fillet, h.tip_diameter / 2
    k = (10 - 3 * math.pi) / (12 - 3 * math.pi)
    assert h.step_fillet_volume() == pytest.approx(2 * math.pi * rho ** 2 * (1 - math.pi / 4) * (rt + k * rho), rel=1e-12)
    split = d.fillet_volumes()
    r0 = h.back_diameter / 2
    whole = 2 * math.pi * rho ** 2 * (1 - math.pi / 4) * (r0 + k * rho)
    assert split["flange_disc"] + split["horn"] - h.step_fillet_volume() == pytest.approx(whole, rel=1e-9)
    # the outline's exact integral agrees with the closed form of a plain annulus
    ring = Outline(((0.01, 0.0), (0.02, 0.0), (0.02, 0.003), (0.01, 0.003)))
    assert revolved_volume(ring) == pytest.approx(math.pi * (0.02 ** 2 - 0.01 ** 2) * 0.003, rel=1e-14)


def test_reference_section_has_no_singular_point_at_a_fillet():
    sharp = ar.singular_points(ar.section(geometry.filleted(article_design(), 0.0).replace(
        {"coupler.n_slots": 0, "coupler.n_teeth": 0, "stack.bolt_diameter": 0.0})))
    round_ = ar.singular_points(ar.section(plain()))
    h = plain().horn
    corners = np.array([a.corner for a in plain().fillets().values()])
    near = lambda pts: np.min(np.hypot(*(pts[:, None, :] - corners[None]).transpose(2, 0, 1)), axis=0)   # noqa: E731
    assert np.all(near(sharp) < 1e-12)                  # both sharp corners are singular points
    assert np.all(near(round_) > 0.5 * h.step_fillet)   # no singular point near a fillet
    assert len(round_) == len(sharp) - 2                # only the rings' bimaterial edges are left


# ---------------------------------------------------------------------------- meshes


@pytest.mark.slow
@pytest.mark.parametrize("variant, mesher, sectors", [
    ("stepped", "free", None), ("stepped", "revolve", None), ("stepped", "revolve", 6),
    ("conical_bore", "revolve", None), ("exponential", "free", None)])
def test_every_mesher_builds_the_fillets(variant, mesher, sectors):
    """Region volumes within the project's 0.5 % (tests/test_geometry_mesh.py) of the closed
    form with the fillets (measured: 1.5e-4 at most); a swept sector is one sixth of them."""
    d = {"stepped": plain(), "conical_bore": plain().replace({"horn.profile": "conical", "bore_diameter": 0.006}),
         "exponential": plain().replace({"horn.profile": "exponential"})}[variant]
    tm, rep = geometry.build(d, mesher=mesher, sectors=sectors)
    assert rep.quality["n_inverted"] == 0
    closed = {r: v for r, _p, _m, v in d.region_table()}
    vols = tm.cell_volumes()
    for i, r in enumerate(tm.regions):
        if r.name in ("flange_disc", "horn"):
            assert (sectors or 1) * vols[tm.cell_region == i].sum() == pytest.approx(closed[r.name], rel=0.005), r.name
    # the step fillet is resolved: nodes on its arc, a few elements per quarter turn
    a = d.fillets().get("step")
    if a is not None:
        r, z = np.hypot(tm.points[:, 0], tm.points[:, 1]), tm.points[:, 2]
        on = np.abs(np.hypot(r - a.centre[0], z - a.centre[1]) - a.radius) < 1e-6 * a.radius
        theta = np.arctan2(tm.points[on, 1], tm.points[on, 0])
        first = np.abs(theta - theta[0]) < 1e-9               # one meridian
        assert first.sum() >= 3


@pytest.mark.slow
def test_morph_keeps_the_fillets_exact():
    """Matching changes the horn's length: the fillets have zones of their own, so the morphed
    mesh's arc nodes lie on the new design's arcs (to round-off)."""
    d = plain()
    tm, _ = geometry.build(d, mesher="revolve", refine=2.0)
    new = d.replace({"horn.length": d.horn.length * 1.05})
    moved = d.morph_points(tm.points, new)
    r = np.hypot(tm.points[:, 0], tm.points[:, 1])
    for name, a in d.fillets().items():
        on = np.abs(np.hypot(r - a.centre[0], tm.points[:, 2] - a.centre[1]) - a.radius) < 1e-9
        assert on.sum() > 10
        b = new.fillets()[name]
        rm = np.hypot(moved[on, 0], moved[on, 1])
        assert np.allclose(np.hypot(rm - b.centre[0], moved[on, 2] - b.centre[1]), b.radius, atol=1e-9)


# ---------------------------------------------------------------------------- converged stresses


@pytest.fixture(scope="module")
def reference_peaks():
    """The (r, z) model's fillet peaks on three nested levels (bulk 2 mm, 0.8 mm on the arcs,
    split twice: up to ~100k unknowns)."""
    sec = ar.section(plain())
    return [ar.fillet_peaks(sec, 2e-3, 5e-3, 20000.0, splits=k)[1] for k in range(3)]


def _working(m) -> int:
    """The strongly coupled mode of a k = 0 solve: the largest f_a^2 - f_r^2 (a mode without an
    anti-resonance of its own, NaN, is not it)."""
    return int(np.argmax(np.nan_to_num(m.f_open_hz ** 2 - m.f_hz ** 2, nan=-np.inf)))


def _sector_peaks(design, refine=1.0, sectors=6):
    """Peak von Mises on each fillet arc of the swept sector's k = 0 working mode per unit axial
    tip displacement (Pa/m), the system and its stress field. The k = 0 sector system of the
    commands: its recovery averages a cut face's nodes with the next sector's cells (the values
    on the cut plane taken here are the whole drill's)."""
    from fem.assembly import assemble
    from fem.modal import modal_analysis
    from fem.sector_system import sector_system
    from fem.stress import StressRecovery, von_mises

    tm, _ = geometry.build(design, mesher="revolve", sectors=sectors, refine=refine)
    system = sector_system(assemble(tm), sectors)
    m = modal_analysis(system, 20000.0, 3)
    w = int(np.argmax(np.nan_to_num(m.f_a_hz ** 2 - m.f_r_hz ** 2, nan=-np.inf)))
    x = np.real(m.vectors[:, w])
    p = system.nodes
    top = np.flatnonzero((np.hypot(p[:, 0], p[:, 1]) < 1e-12) & (np.abs(p[:, 2] - p[:, 2].max()) < 1e-12))
    x = x / system.displacement(x)[top[0], 2]
    fld = StressRecovery(system).field(x)
    vm = von_mises(fld.nodal_average("stress").real)
    horn = [r.name for r in system.regions].index("horn")
    sel = fld.region == horn
    pts, v = fld.points[sel].reshape(-1, 3), vm[sel].reshape(-1)
    r, z = np.hypot(pts[:, 0], pts[:, 1]), pts[:, 2]
    out = {}
    for name, a in design.fillets().items():
        on = ((np.abs(np.hypot(r - a.centre[0], z - a.centre[1]) - a.radius) < 1e-7) & (np.abs(pts[:, 1]) < 1e-12)
              & (r <= a.centre[0] + 1e-9) & (z <= a.centre[1] + 1e-9))
        ang = np.arctan2(z[on] - a.centre[1], r[on] - a.centre[0])
        _u, first = np.unique(np.round(ang, 9), return_index=True)
        out[name] = ar.arc_peak(ang[first], v[on][first])
    return out, system, fld


@pytest.mark.slow
def test_fillet_stress_converges_and_the_sector_agrees(reference_peaks, vv):
    """Reference: observed order of the three nested levels (size ratio 2) in [1.5, 4.5] (P2 gives
    stresses at order 2 at a smooth point, the node average can add up to one; a singular corner
    would give a peak growing with refinement, order < 0), the Richardson error of the finest
    level below 0.2 % (a tenth of the comparison's 2 %). The sector (refine 1, 16 elements per
    quarter arc) within 2 % of the limit on both fillets (the horn's side of the flange fillet:
    horn.2; the step: horn.5; on the k = 0 system, its cut-face nodes averaged with the next
    sector's cells). Measured: orders 2.85 / 2.61, sector -1.1 % / +0.1 %."""
    limits = {}
    for key, name in (("horn.2", "flange"), ("horn.5", "step")):
        seq = [lv[key] for lv in reference_peaks]
        p, limit = ar.richardson(seq, 2.0)
        assert 1.5 < p < 4.5, (key, seq, p)
        assert abs(limit - seq[-1]) < 0.002 * limit, (key, seq)
        limits[name] = limit
    sector, _system, _fld = _sector_peaks(plain())
    for vid, name in (("VV-SC-03", "flange"), ("VV-SC-04", "step")):
        vv.record(vid, title=f"Stress at the {name} fillet of the drill: 3-D sector against the (r, z) model",
                  quantity="peak von Mises on the fillet per unit axial tip displacement of the working mode",
                  description="The default drill without slots and teeth with 2 mm fillets: the swept 1/6 sector "
                  "(refine 1, harmonic k = 0, P2 tetrahedra, recovered field) against the independent (r, z) "
                  "model's Richardson limit of three nested levels.",
                  reference="tests/axisym_reference.py: curved P2 triangles, nested refinement, Richardson limit "
                  "(its own error below 0.2 %).", assumptions="Linear piezo-elasticity, no losses; the field is "
                  "axisymmetric (k = 0).", target=limits[name], computed=sector[name], tolerance=0.02, unit="Pa/m")
        assert sector[name] == pytest.approx(limits[name], rel=0.02), (name, sector[name], limits[name])


def _pipeline_path_horn_table(design, refine):
    """The horn's row of the utilisation table of the working mode (per unit axial displacement of
    the tip's centre) on the pipeline's path (the k = 0 sector of :func:`fem.sector_system.axial_sector`),
    and the sector's DOFs."""
    from fem.modal import modal_analysis, working_mode
    from fem.sector_system import axial_sector
    from fem.stress import StressRecovery
    from fem.stress_table import stress_table

    system = axial_sector(design, refine=refine)
    res = modal_analysis(system, 20000.0, 4)
    w = working_mode(system, res.f_r_hz, res.vectors, 20000.0)
    x = np.real(res.vectors[:, w])
    p = system.nodes
    top = np.flatnonzero((np.hypot(p[:, 0], p[:, 1]) < 1e-9) & (np.abs(p[:, 2] - p[:, 2].max()) < 1e-12))
    assert len(top)
    x = x / system.displacement(x)[top[0], 2]
    return stress_table(StressRecovery(system).field(x), regions=["horn"]), system.ndof


@pytest.mark.slow
def test_pipeline_stress_error_covers_the_fillet_peak(reference_peaks, vv):
    """The utilisation table's two-mesh estimate on the pipeline's path (the discretisation-error
    stage's coarse mesh at refine 1.4 against refine 1, :func:`fem.stress_converged.with_error`,
    order 2 in the h ratio of the DOFs) covers the true error of the horn's peak, which lies on the
    flange fillet, against the (r, z) model's Richardson limit (its own error below 0.2 %,
    asserted in the test above), and is not more than 5x it (as the other two-level estimates of
    tests/test_discretisation_error.py); the peak itself within the brief's 2 %. Measured: peak
    -0.32 %, estimate 0.97 % (3.0x), h ratio 1.160."""
    from types import SimpleNamespace

    from fem.stress_converged import with_error

    d = plain()
    (fine, n1), (coarse, n2) = (_pipeline_path_horn_table(d, r) for r in (1.0, 1.4))
    est = SimpleNamespace(extra={"stress": coarse}, ratio=(n1 / n2) ** (1 / 3), ndof=n1, coarse_ndof=n2, refine=1.0,
                          coarse_refine=1.4)
    row = with_error(fine, est).rows[0]
    a = d.fillets()["flange"]
    loc = np.array(row.location)
    assert np.hypot(np.hypot(loc[0], loc[1]) - a.centre[0], loc[2] - a.centre[1]) == pytest.approx(a.radius, rel=1e-3)
    limit = ar.richardson([lv["horn.2"] for lv in reference_peaks], 2.0)[1]
    true = abs(row.headline - limit)
    vv.record("VV-SC-05", title="Stated stress error on the pipeline's path covers the true error",
              quantity="peak von Mises of the horn (on the flange fillet) per unit axial tip displacement",
              description="The default drill without slots and teeth with 2 mm fillets on the pipeline's k = 0 "
              "sector at refine 1, its two-mesh estimate from refine 1.4, against the (r, z) model's Richardson "
              "limit.", reference="tests/axisym_reference.py: curved P2 triangles, nested refinement, Richardson "
              "limit (its own error below 0.2 %).", assumptions="Linear piezo-elasticity, no losses; k = 0.",
              target=limit, computed=row.headline, tolerance=0.02, unit="Pa/m")
    assert row.headline == pytest.approx(limit, rel=0.02)
    assert true <= row.error_estimate <= 5 * max(true, 0.002 * limit), (row.headline, limit, row.error_estimate)


@pytest.mark.slow
def test_utilisation_table_marks_singular_edges_only():
    """On the filleted sector the horn's peak is at the flange fillet, not singular, headlined as
    is; on the sharp design the same row's peak sits on the sharp flange/horn edge: marked
    singular and headlined by the off-edge value. The rings' rims and bores on the electrode
    planes (PZT/PZT of opposite poling, PZT/titanium) are singular edges on both; the sharp
    horn step (a re-entrant crease inside one region) is one, its fillet's arc is not."""
    from fem.stress_table import bonded_edge_nodes, stress_table

    d = plain()
    _peaks, system, fld = _sector_peaks(d, refine=2.0)
    table = {(r.region, r.quantity): r for r in stress_table(fld, freq_hz=20e3, voltage=1.0).rows}
    horn = table[("horn", "von_mises")]
    a = d.fillets()["flange"]
    loc = np.array(horn.location)
    assert not horn.singular and horn.headline == horn.value
    assert np.hypot(np.hypot(loc[0], loc[1]) - a.centre[0], loc[2] - a.centre[1]) == pytest.approx(a.radius, rel=1e-3)
    edge = system.nodes[bonded_edge_nodes(system)]
    r = np.hypot(edge[:, 0], edge[:, 1])
    assert np.all(np.abs(edge[:, 2] - a.mid[1]) > 1e-4)             # the filleted junction is clear
    st = d.fillets()["step"]
    assert np.all(np.hypot(r - st.corner[0], edge[:, 2] - st.corner[1]) > 0.5 * st.radius)   # and the step's arc
    assert np.isclose(r, d.stack.outer_diameter / 2).any() and np.isclose(r, d.stack.inner_diameter / 2).any()

    sharp = d.replace({"horn.flange_fillet": 0.0, "horn.step_fillet": 0.0})
    from fem.assembly import assemble
    from fem.stress import StressRecovery

    from fem.cyclic import cyclic_modes

    tm, _ = geometry.build(sharp, mesher="revolve", sectors=6, refine=2.0)
    sys2 = assemble(tm)
    m = cyclic_modes(sys2, 6, 0, 20000.0, 3)
    x = np.real(m.vectors[:, _working(m)])
    rows = {(r.region, r.quantity): r for r in stress_table(StressRecovery(sys2).field(x)).rows}
    h2 = rows[("horn", "von_mises")]
    z0 = sharp.stack.length + sharp.flange.thickness
    e2 = sys2.nodes[bonded_edge_nodes(sys2)]
    step = np.hypot(np.hypot(e2[:, 0], e2[:, 1]) - st.corner[0], e2[:, 2] - st.corner[1]) < 1e-9
    assert step.sum() >= 2                                            # the sharp step's crease
    assert h2.singular and h2.headline == h2.value_off_edges < h2.value
    assert h2.location[2] == pytest.approx(z0, abs=1e-9)
    assert np.hypot(*h2.location[:2]) == pytest.approx(sharp.horn.back_diameter / 2, abs=1e-9)


def test_converged_table_is_the_richardson_estimate():
    from fem.stress_table import StressRow, StressTable, converged_table

    def row(v):
        return StressRow("horn", "horn", "ti6al4v", "von_mises", v, (0.0, 0.0, 0.0), 500e6, 1.0)

    coarse = StressTable((row(100e6), StressRow("ring_1", "stack", "PZT-8", "principal_max", 300e6, (0, 0, 0),
                                                None, 1.0, 90e6, (0, 0, 0), True)), 20e3, 1.0, 0.0)
    fine = StressTable((row(103e6), StressRow("ring_1", "stack", "PZT-8", "principal_max", 420e6, (0, 0, 0),
                                              None, 1.0, 92e6, (0, 0, 0), True)), 20e3, 1.0, 0.0)
    out = converged_table(coarse, fine, 2.0)
    a, b = out.rows
    assert a.error_estimate == pytest.approx(3e6 / 3)              # |103 - 100| / (2^2 - 1)
    assert b.headline == 92e6 and b.error_estimate == pytest.approx(2e6 / 3)   # off the singular edge
    assert a.utilisation == pytest.approx(103e6 / 500e6)
    assert "Richardson" in out.note
    with pytest.raises(ParameterError, match="ratio"):
        converged_table(coarse, fine, 1.0)


@pytest.mark.slow
def test_reference_stress_on_a_curved_surface_against_goodier(vv):
    """The (r, z) model's recovered stress on an arc (curved P2 triangles, node averages, the
    parabolic peak along the arc): a spherical cavity of radius a in a cylinder 20 a wide and
    40 a long under uniform tension has at its equator K_t = (27 - 15 nu) / (2 (7 - 5 nu))
    (Goodier 1933, infinite body; the finite body changes it by O((a / R)^3) ~ 1e-4). Tolerance
    0.5 %: that plus the finest level's discretisation error, bounded by the change from the
    level before (measured 0.27 %; result +0.13 %)."""
    import scipy.sparse.linalg as sla
    from skfem import Basis, ElementTriP2, ElementVector, FacetBasis, LinearForm, asm

    from geometry.materials import get_material

    nu = get_material("ti6al4v").poisson_ratio
    a, R, L = 1e-3, 20e-3, 20e-3
    # the upper half (u_z = 0 on the plane z = 0), the cavity's quarter arc from (a, 0) to (0, a)
    sec = ar.Section((ar.Block("body", "ti6al4v", 0, ((a, 0.0), (R, 0.0), (R, L), (0.0, L), (0.0, a)),
                               ((4, 0.0, 0.0),)),), ())
    model = ar.assemble(sec, a, 2 * a, fixed=(("z", "z", 0.0),), splits=2)
    ub = Basis(model.mesh, ElementVector(ElementTriP2()), intorder=6)
    top = FacetBasis(model.mesh, ub.elem, facets=model.mesh.facets_satisfying(lambda x: np.abs(x[1] - L) < 1e-12),
                     intorder=6)

    @LinearForm
    def traction(v, w):              # 1 Pa along +z on the top face
        return v.value[1] * 2 * math.pi * w.x[0]

    K, _L, _M, nu_ = model.matrices("short")
    u = np.zeros(ub.N)
    u[model.u_free] = sla.spsolve(K[:nu_, :nu_].tocsc(), asm(traction, top)[model.u_free])
    xy, stress, _nodes = ar.nodal_stress(model, u)
    on = np.abs(np.hypot(xy[0], xy[1]) - a) < 1e-9
    rr, _tt, zz, rz = stress[0][on].T
    s1 = 0.5 * (rr + zz) + np.sqrt(0.25 * (rr - zz) ** 2 + rz ** 2)
    kt = ar.arc_peak(np.arctan2(xy[1][on], xy[0][on]), s1)
    exact = (27 - 15 * nu) / (2 * (7 - 5 * nu))
    vv.record("VV-SC-02", title="Spherical cavity in tension: the (r, z) reference's stress on a curved surface",
              quantity="stress concentration factor K_t", description="A spherical cavity of radius a in a "
              "titanium cylinder 40 a wide and 40 a long under uniform tension; the (r, z) model's largest "
              "principal stress on the cavity over the applied stress.",
              reference="Goodier (1933): K_t = (27 - 15 nu) / (2 (7 - 5 nu)) in an infinite body.",
              assumptions="Linear elasticity; the finite body changes K_t by O((a / R)^3) ~ 1e-4.",
              target=exact, computed=kt, tolerance=0.005)
    assert kt == pytest.approx(exact, rel=0.005)


# ---------------------------------------------------------------------------- Peterson


def _peterson_flat(H, d, r):
    """K_t of a stepped flat bar in tension with shoulder fillets (Pilkey & Pilkey, Peterson's
    Stress Concentration Factors, 3rd ed., Chart 3.1's curve fit; nominal stress P / (h d)):
    K_t = C1 + C2 (2t/H) + C3 (2t/H)^2 + C4 (2t/H)^3, t = (H - d) / 2, for 0.1 <= t/r <= 20."""
    t = (H - d) / 2
    tr = t / r
    sq = math.sqrt(tr)
    if tr <= 2.0:
        c = (1.006 + 1.008 * sq - 0.044 * tr, -0.115 - 0.584 * sq + 0.315 * tr,
             0.245 - 1.006 * sq - 0.257 * tr, -0.135 + 0.582 * sq - 0.017 * tr)
    else:
        c = (1.020 + 1.009 * sq - 0.048 * tr, -0.065 - 0.165 * sq - 0.007 * tr,
             -3.459 + 1.266 * sq - 0.016 * tr, 3.505 - 2.109 * sq + 0.069 * tr)
    q = 2 * t / H
    return sum(ci * q ** i for i, ci in enumerate(c))


def _stepped_plate(H, d, r, t, h_far, h_arc):
    """A stepped flat bar (widths H, d, lengths 2 H and 3 d, fillets r on both sides, thickness t,
    all m) as a TaggedMesh of 10-node tetrahedra with facet sets ``bottom`` and ``top`` (its end
    faces); element size h_arc on the arcs growing by 0.3 per m to h_far."""
    import gmsh

    from geometry.materials import get_material
    from geometry.mesh import Region, TaggedMesh

    zs, a, b = 2 * H, H / 2, d / 2
    outline = [(-a, 0), (a, 0), (a, zs), (b + r, zs), (b, zs + r), (b, zs + 3 * d), (-b, zs + 3 * d), (-b, zs + r),
               (-b - r, zs), (-a, zs)]
    arcs = {3: (b + r, zs + r), 7: (-b - r, zs + r)}
    gmsh.initialize(interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        occ = gmsh.model.occ
        pts = [occ.addPoint(x, -t / 2, z) for x, z in outline]
        curves = [occ.addCircleArc(pts[i], occ.addPoint(arcs[i][0], -t / 2, arcs[i][1]), pts[(i + 1) % len(pts)])
                  if i in arcs else occ.addLine(pts[i], pts[(i + 1) % len(pts)]) for i in range(len(pts))]
        face = occ.addPlaneSurface([occ.addCurveLoop(curves)])
        vol = [dt for dt in occ.extrude([(2, face)], 0, t, 0) if dt[0] == 3][0][1]
        occ.synchronize()
        dist = [f"Sqrt((x - ({cx!r}))^2 + (z - ({cz!r}))^2)" for cx, cz in arcs.values()]
        fid = gmsh.model.mesh.field.add("MathEval")
        gmsh.model.mesh.field.setString(fid, "F", f"Min({h_far!r}, {h_arc!r} + 0.3 * (Min({dist[0]}, {dist[1]}) - {r!r}))")
        gmsh.model.mesh.field.setAsBackgroundMesh(fid)
        for key, value in (("MeshSizeFromPoints", 0), ("MeshSizeFromCurvature", 0), ("MeshSizeExtendFromBoundary", 0),
                           ("MeshSizeMax", h_far)):
            gmsh.option.setNumber(f"Mesh.{key}", value)
        gmsh.model.mesh.generate(3)
        gmsh.model.mesh.setOrder(2)
        tags, xyz, _ = gmsh.model.mesh.getNodes()
        index = np.zeros(int(tags.max()) + 1, dtype=np.int64)
        index[np.asarray(tags, dtype=np.int64)] = np.arange(len(tags))
        nodes = gmsh.model.mesh.getElements(3, vol)[2][0]
        # Gmsh's 10-node order lists the edges (2, 3) and (1, 3) the other way round from VTK's
        cells = index[np.asarray(nodes, dtype=np.int64)].reshape(-1, 10)[:, [0, 1, 2, 3, 4, 5, 6, 7, 9, 8]]
        sets = {}
        for name, z in (("bottom", 0.0), ("top", zs + 3 * d)):
            for _dim, s in gmsh.model.getEntities(2):
                bb = gmsh.model.getBoundingBox(2, s)
                if abs(bb[2] - z) < 1e-6 and abs(bb[5] - z) < 1e-6:
                    sets[name] = index[np.asarray(gmsh.model.mesh.getElements(2, s)[2][0], dtype=np.int64)].reshape(-1, 6)[:, :3]
    finally:
        gmsh.finalize()
    points = np.asarray(xyz).reshape(-1, 3)
    used = np.unique(cells)
    renum = np.full(len(points), -1)
    renum[used] = np.arange(len(used))
    return TaggedMesh(points[used], renum[cells], np.zeros(len(cells), dtype=np.int64),
                      (Region("plate", "plate", "ti6al4v", None),), {k: renum[v] for k, v in sets.items()}, (),
                      {"ti6al4v": get_material("ti6al4v")})


@pytest.mark.slow
def test_filleted_flat_bar_in_tension_against_peterson(vv):
    """The 3-D FE's stress concentration factor (fem.assembly, fem.preload.static_solve free-free
    with equal and opposite end tractions, fem.stress recovered field, largest principal stress on
    the fillet arcs of the plate's faces, parabola along the arc) against Peterson's stepped flat
    bar in tension (:func:`_peterson_flat`; H / d = 2, r / d = 0.2: K_t = 1.992). The chart is a
    fit of photoelastic data (Wilson and White 1973) whose stated accuracy we could not find:
    the tolerance is the brief's 3 %; a plane-stress P2 solve of the same outline (independent
    2-D code) gives 1.988, 0.2 % from the fit, so the fit carries this geometry well. A plate
    t = r / 4.4 thin is in plane stress to well within that. Measured: 1.973-1.981 on the four arc
    edges (-0.6 % to -1.0 %).

    The stepped round bar in tension (Chart 3.4, its fit K_t = C1 + C2 (2t/D) + C3 (2t/D)^2 +
    C4 (2t/D)^3, nominal stress 4 P / (pi d^2) on the smaller section, 0.1 <= t/r <= 20) is not
    a reference to 3 %: its curves are not measurements but Peterson's estimate from other
    geometries (the flat bar's fillet scaled by the ratio of round-bar to flat-bar groove factors),
    which finite-element studies (Tipton, Sorem and Rolovic, J. Mech. Des. 118 (1996) 321; the
    source the 3rd edition cites) found to underpredict by up to about 24 %. The (r, z) model
    (tests/axisym_reference.py: long sections on both sides, nested levels, converged to 0.2 %)
    gives 2.227 at D/d = 2, r/d = 0.1 (fit 1.964), 2.111 at 1.5 / 0.1 (fit 1.860), 2.310 at
    1.2 / 0.05 (fit 2.018), 2.693 at 1.5 / 0.05 (fit 2.261), 1.819 at 2.18 / 0.18 (the horn's
    step; fit 1.689): 8-19 % above the fit, inside that range, with the ratios, t/r and the nominal stress within the fit's definition; the
    same model meets Goodier's cavity to 0.13 %."""
    from fem.assembly import assemble
    from fem.preload import face_area, static_solve, traction_load
    from fem.stress import StressRecovery, principal_values

    H, d, r, t = 22e-3, 11e-3, 2.2e-3, 0.5e-3
    system = assemble(_stepped_plate(H, d, r, t, 2e-3, 0.28e-3))
    force = 1.0
    load = (traction_load(system, "top", (0, 0, force / face_area(system, "top")))
            + traction_load(system, "bottom", (0, 0, -force / face_area(system, "bottom"))))
    fld = StressRecovery(system).field(static_solve(system, load))
    s1 = principal_values(fld.nodal_average("stress").real)[..., 2].reshape(-1)
    p = fld.points.reshape(-1, 3)
    zs, b = 2 * H, d / 2
    kts = []
    for sign in (1, -1):
        for face in (1, -1):
            cx, cz = sign * (b + r), zs + r
            on = (np.abs(np.hypot(p[:, 0] - cx, p[:, 2] - cz) - r) < 1e-7) & (np.abs(p[:, 1] - face * t / 2) < 1e-9)
            ang = np.arctan2(p[on, 2] - cz, sign * (p[on, 0] - cx))
            _u, first = np.unique(np.round(ang, 9), return_index=True)
            kts.append(ar.arc_peak(ang[first], s1[on][first]) / (force / (d * t)))
    target = _peterson_flat(H, d, r)
    vv.record("VV-SC-01", title="Stepped flat bar with shoulder fillets in tension", quantity="stress concentration "
              "factor K_t (the lowest of the four fillet edges)", description="A titanium plate 22 mm wide stepped "
              "to 11 mm with 2.2 mm fillets, 0.5 mm thick, pulled by equal and opposite end tractions (free-free "
              "static solve); largest principal stress of the recovered field on the fillet arcs over P / (h d).",
              reference="Pilkey & Pilkey, Peterson's Stress Concentration Factors, 3rd ed., Chart 3.1 curve fit.",
              assumptions="Linear elasticity; a thin plate (plane stress).", target=target, computed=min(kts),
              tolerance=0.03)
    for kt in kts:
        assert kt == pytest.approx(target, rel=0.03), kts
