"""The teeth motion's finer mesh (results.stage_teeth): when it runs, its estimate's orders, and
that the rotary unit is driven by it (the converged numbers: tests/test_discretisation_error.py)."""

import pytest

import geometry
from fem.convergence import Level
from fem.errors import sector_layers, teeth_estimate
from results.stage_fe import MeshOptions
from results.stage_teeth import TEETH_REFINE, teeth_mesh_text, teeth_refine

TEETH = ("horn_tip", "teeth_tops")


def test_the_finer_mesh_runs_on_sector_runs_with_teeth_only():
    d = geometry.default_design()
    sector = MeshOptions().resolved(d)
    assert teeth_refine(d, sector, TEETH) == (pytest.approx(TEETH_REFINE), "")
    assert teeth_mesh_text(d, sector).startswith("swept sector 1/6 (k = 0), refine 0.8")
    refine, why = teeth_refine(d, MeshOptions(path="whole").resolved(d), TEETH)
    assert refine is None and "not a k = 0 sector run" in why
    assert teeth_refine(d, sector, ("horn_tip",))[0] is None
    # the mesh of a design without teeth still names the coupler's end face teeth_tops
    plain = d.replace({"coupler.n_slots": 0, "coupler.n_teeth": 0})
    plain_sector = MeshOptions().resolved(plain)
    assert plain_sector.path == "sector"
    refine, why = teeth_refine(plain, plain_sector, TEETH)
    assert refine is None and "with teeth" in why
    assert teeth_mesh_text(plain, plain_sector).startswith("the run's mesh's")
    assert teeth_refine(d, MeshOptions(refine=0.24).resolved(d), TEETH)[0] is None    # 0.19: below the range


def test_estimate_orders_follow_the_sector_layers():
    """Refine 1 -> 0.8 adds an element layer (3 -> 4): order 2 for every quantity; 1.4 -> 1 keeps 3 layers: the
    phase at order 1. The errors are |difference (2 digits)| / (r^p - 1), r from the DOFs, to 2 digits: by hand,
    (154 759 / 89 498)^(1/3) = 1.2004, 0.0029 / 0.44096 = 0.00658 and 0.093 / 0.44096 = 0.211; (89 498 / 50 734)^(1/3)
    = 1.2083, 0.0046 / 0.45998 = 0.0100 and 0.073 / 0.2083 = 0.350 (the study's levels,
    tests/test_discretisation_error.py TEETH_STUDY)."""
    d = geometry.default_design()
    assert [sector_layers(d, r) for r in (1.4, 1.0, 0.8, 0.64)] == [3, 3, 4, 5]
    lev = {1.4: Level(1.4, 50_734, {"teeth_ellipse_ratio": 0.1680414504, "teeth_phase_deg": 171.3147275}),
           1.0: Level(1.0, 89_498, {"teeth_ellipse_ratio": 0.1726646332, "teeth_phase_deg": 171.2418897}),
           0.8: Level(0.8, 154_759, {"teeth_ellipse_ratio": 0.1755938508, "teeth_phase_deg": 171.1492743})}
    est = teeth_estimate(d, lev[0.8], lev[1.0])
    assert est.orders == {} and est.order == 2
    assert est.error("teeth_ellipse_ratio") == pytest.approx(0.0066, abs=1e-12)
    assert est.error("teeth_phase_deg") == pytest.approx(0.21, abs=1e-12)
    est = teeth_estimate(d, lev[1.0], lev[1.4])
    assert est.orders == {"teeth_phase_deg": 1.0}
    assert est.error("teeth_ellipse_ratio") == pytest.approx(0.010, abs=1e-12)
    assert est.error("teeth_phase_deg") == pytest.approx(0.35, abs=1e-12)
