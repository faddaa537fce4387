"""The cheap discretisation-error estimator (fem.errors) against exact answers, and its output convention.

Validation case: the default design without slots and teeth (fully axisymmetric), on the default
ungraded mesh (refine 1) with the estimator's one coarser solve (refine 1.4), order 1 assumed
(ungraded, re-entrant edges). Exact answers from the independent axisymmetric (r, z) model
(tests/axisym_reference.py, graded, P2):
- f_r, f_a: 19 682.31 / 21 410.33 Hz (converged to 1e-7), and k_eff from them;
- the horn-tip axial amplitude per volt at the mode's own f_r with Q = 100 on every part and the
  datasheet tan delta (the pipeline's setting): 107.949 nm/V (Richardson of h = 1.41, 1.0, 0.707 mm:
  107.9406, 107.9468, 107.9485 nm/V, observed order 3.8, estimated error 1e-5 relative).
Assertion for each of f_r, f_a, k_eff and the tip amplitude per volt: the estimate is on the safe
side and at most ``FACTOR`` = 5 times the true error (measured 2.37x, 2.24x, 1.93x and 1.21x: true
errors +0.451 %, +0.563 %, +0.61 % and -0.77 %; estimates 210 Hz, 270 Hz, 0.0046, 1.0 nm/V; 35k
and 13k DOFs; the coarse mesh's 5 folded elements at the coupler's bore straightened stepwise, see
geometry.revolve.STRAIGHTEN_STEP; with Gmsh's high-order optimiser it was 2.06x / 1.45x).
The smooth case (a free-free steel cylinder, observed order 4.25, order 2 assumed: 2.5x the
study's Richardson error) is tests/test_mesh_grading.py's. The teeth ellipse ratio has no exact
reference (slots and teeth are not axisymmetric): benchmarks/study_discretisation_error.py
compares its estimate with a 3-D refinement study of the default design (README).
On the default design itself (slots and teeth, swept mesh) the estimate of ``fem.modal --error``
is checked against the error that benchmarks/study_coupler_convergence.py puts on that mesh.
"""

import math

import numpy as np
import pytest

import geometry
from fem.convergence import ConvergenceStudy, Level, working_mode_level
from fem.errors import ErrorEstimate, annotate, estimate, estimate_from_levels, has_reentrant_edges, plus_minus
from rpud_common import ParameterError
from reference_designs import reference_default
from geometry.examples import article_design

F_R, F_A = 19682.31, 21410.33
"""Converged working mode of the default design without slots and teeth (tests/axisym_reference.py), Hz."""
K_EFF = math.sqrt(1 - (F_R / F_A) ** 2)
TIP_PER_VOLT = 107.949e-9
"""Converged horn-tip amplitude per volt of that design at its f_r, Q = 100, datasheet tan delta, m/V."""
FACTOR = 5.0
"""Largest accepted ratio of the estimate to the true error."""


def no_slots():
    """The references' design: the default without slots, teeth, fillets and bolt part, at the
    lengths the constants above were computed for (tests/reference_designs.py)."""
    return geometry.filleted(reference_default(), 0.0).replace({"coupler.n_slots": 0, "coupler.n_teeth": 0,
                                                                "stack.bolt_diameter": 0.0})


@pytest.fixture(scope="module")
def axisym_estimate():
    d = no_slots()
    fine = working_mode_level(d, 1.0)
    return fine, estimate(d, fine.values, fine.ndof, refine=1.0)


def test_tip_reference_of_the_axisymmetric_model():
    """The constant is the converged answer of tests/axisym_reference.py: a coarse level (h = 2 mm,
    8.7k DOFs) is 0.036 % below it and the error falls as h^3-h^4."""
    import axisym_reference as ar

    model = ar.assemble(ar.section(no_slots()), 2e-3, 4e-3)
    res = ar.modes(model, 20e3, 3)
    tip = ar.tip_per_volt(model, res.f_r[res.working], q_mech=100.0)
    assert 0 < 1 - tip / TIP_PER_VOLT < 5e-4


@pytest.mark.parametrize("q, exact", [("f_r_hz", F_R), ("f_a_hz", F_A), ("k_eff", K_EFF),
                                      ("tip_per_volt_m", TIP_PER_VOLT)])
def test_two_level_estimate_bounds_the_true_error(axisym_estimate, q, exact):
    fine, est = axisym_estimate
    true = abs(fine.values[q] - exact)
    assert true <= est.error(q) <= FACTOR * true, (q, fine.values[q], exact, est.error(q))


def test_estimate_record(axisym_estimate):
    fine, est = axisym_estimate
    assert est.order == 1.0 and est.corners and not est.grade           # ungraded, re-entrant edges
    assert est.coarse_refine == pytest.approx(1.4) and est.coarse_ndof < fine.ndof / 2
    assert est.ratio == pytest.approx((fine.ndof / est.coarse_ndof) ** (1 / 3))
    d = est.to_dict()
    assert d["errors"]["f_r_hz"] == est.error("f_r_hz") and "order 1 assumed" in d["method"]
    assert d["coarse"]["f_r_hz"] == est.coarse["f_r_hz"]


def test_annotate_and_plus_minus():
    est = estimate_from_levels(Level(1.0, 8000, {"f_r_hz": 100.0, "tip_per_volt_m": 2.0}),
                               Level(1.4, 1000, {"f_r_hz": 101.0, "tip_per_volt_m": 2.2}), grade=True, corners=True)
    assert isinstance(est, ErrorEstimate) and est.ratio == pytest.approx(2.0) and est.order == 2.0
    # |q(h) - q(2h)| / (2^2 - 1), to 2 significant digits
    assert est.error("f_r_hz") == 0.33 and est.error("tip_per_volt_m") == 0.067
    rec = annotate({"f_r_hz": 100.0, "used_m": 4.0, "k_eff": 0.3}, est,
                   {"f_r_hz": "f_r_hz", "used_m": "tip_per_volt_m", "k_eff": "k_eff"})
    assert rec["f_r_hz_error"] == 0.33 and rec["used_m_error"] == pytest.approx(4.0 * 0.067 / 2)
    # the coarse value is kept to 2 significant digits of its difference: a jitter of the coarse mesh is gone
    a, b = (estimate_from_levels(Level(1.0, 8000, {"f_r_hz": 20000.0}), Level(1.4, 1000, {"f_r_hz": 20061.23 + j}),
                                 grade=False, corners=True) for j in (0.0, 0.04))
    assert a.coarse == b.coarse == {"f_r_hz": 20061.0} and a.errors == b.errors == {"f_r_hz": 61.0}
    # an angle's levels differ modulo 360: 179 and -179 degrees are 2 degrees apart, not 358
    ph = estimate_from_levels(Level(1.0, 8000, {"teeth_phase_deg": 179.0}), Level(1.4, 1000, {"teeth_phase_deg": -179.0}),
                              grade=True, corners=True)
    assert ph.error("teeth_phase_deg") == 0.67 and ph.coarse["teeth_phase_deg"] == 181.0
    assert rec["k_eff_error"] is None                                    # not estimated: stated as such
    assert annotate({"f_r_hz": 1.0}, None, {"f_r_hz": "f_r_hz"}) == {"f_r_hz": 1.0, "f_r_hz_error": None}
    assert plus_minus(19996.8, 90.4, "Hz") == "19 997 ± 90 Hz"
    assert plus_minus(1.0394e-7, 2.13e-9, "nm/V", 1e9) == "103.9 ± 2.1 nm/V"
    assert plus_minus(0.1578, None) == "0.1578"
    with pytest.raises(ParameterError):
        estimate_from_levels(Level(1.0, 1000, {}), Level(1.4, 1000, {}), grade=False, corners=True)


def test_reentrant_edges_detected():
    from geometry.design import Segment, StackDesign

    assert has_reentrant_edges(geometry.filleted(article_design(), 0.0))
    # filleted shoulders are not re-entrant, the stack's bore edge on the flange face still is
    assert has_reentrant_edges(article_design())
    rod = StackDesign(name="rod", target_frequency=40e3, segments=(Segment("rod", 0.04, material="steel_45",
                                                                           outer_diameter=0.02),))
    assert not has_reentrant_edges(rod)


DEFAULT_CONVERGED = {"f_r_hz": (19892.7, 19896.8), "f_a_hz": (21647.1, 21651.8)}
"""Converged working mode of the default design with sharp horn corners (Hz, a range): the coupler refined alone with its
notches graded (benchmarks/study_coupler_convergence.py, p = 2 in the coupler's size from levels
0.7 / 0.5 and 0.5 / 0.4) plus the swept parts' true error at refine 1 (the design without slots
and teeth against its converged (r, z) answer, +0.041 % / +0.044 %)."""


def test_error_estimate_of_the_default_swept_mesh_covers_the_coupler_study():
    """``fem.modal --error`` on the sharp-cornered default design (swept, refine 1) against the error the coupler
    study puts on it: at least the smallest of the range, at most 4x its largest (measured 30 / 27 Hz
    against 18.4-22.5 / 14.6-19.3 Hz)."""
    import fem

    d = geometry.filleted(reference_default(), 0.0).replace({"stack.bolt_diameter": 0.0})   # the study's design
    tm, _rep = geometry.build(d, mesher="revolve")
    system = fem.assemble(tm)
    res = fem.modal_analysis(system, 20e3, 4)          # the working mode and its neighbours
    w = fem.working_mode(system, res.f_r_hz, res.vectors, 20e3)
    values = {"f_r_hz": float(res.f_r_hz[w]), "f_a_hz": float(res.f_a_hz[w])}
    est = estimate(d, values, system.ndof, harmonic=False, n_modes=4, mesher="revolve")
    for key, (lo, hi) in DEFAULT_CONVERGED.items():
        smallest, largest = values[key] - hi, values[key] - lo
        assert smallest > 0                                  # converging from above
        assert smallest <= est.error(key) <= 4 * largest, (key, est.error(key), smallest, largest)
    assert values["f_r_hz"] == pytest.approx(19915.19, abs=0.01)   # the mesh the study measured


STUDY_DESIGN = {"horn.length": 0.0680402, "coupler.length": 0.04970987}
"""The teeth study's design: the default with the lengths the pipeline matches (no bolt part)."""

TEETH_STUDY = {1.96: (24_923, 0.1553732463, 171.7095478), 1.4: (50_734, 0.1680414504, 171.3147275),
               1.0: (89_498, 0.1726646332, 171.2418897), 0.8: (154_759, 0.1755938508, 171.1492743),
               0.64: (267_234, 0.1771842678, 171.1109388)}
"""Refine -> (DOFs, teeth ellipse ratio, phase in degrees) of :data:`STUDY_DESIGN` on the k = 0 sector path (Q 100,
harmonic response on the modes + residual, geometry.sector.AXIAL_RULE), measured once (refine 0.64: 61 s CPU)."""

SECOND_FAMILY = {1.96: (25_736, 0.1567676550, 171.6872870), 1.4: (53_047, 0.1689996400, 171.2968589),
                 1.0: (94_016, 0.1727746585, 171.2346405), 0.8: (164_329, 0.1754852793, 171.1387197),
                 0.64: (282_396, 0.1769891398, 171.1035624)}
"""The same for a second mesh family of the same design: the rule with the floor lines at 0.06 of the slot zone's
size and the roots at 1.0 (measured once, refine 0.64: 65 s CPU). Independent meshes of the same answer."""

STUDIES = (TEETH_STUDY, SECOND_FAMILY)
"""The two families of :func:`_study_bound`."""


def _layers(refine: float) -> int:
    """Element layers across the k = 0 sector at ``refine`` (geometry.sector_sweep, both families' layer angle)."""
    from geometry.sector import AXIAL_RULE

    return math.ceil(360.0 / 6 / (AXIAL_RULE[1].layer_deg * refine) - 1e-9)


def _consistent_triples(study: dict) -> list[tuple[float, float, float]]:
    """The triples of successive levels that form one refinement family: every size, the sector's layer angle
    included, refined at each step. The other triples mix two error laws: between refine 1.4 and 1 the layers stay
    at 3, so the triple 1.4 / 1 / 0.8 has the 3 -> 4 layers' gain (+0.00107 at refine 0.8: 0.17452 at 135 316 DOFs
    with 3 layers) on one step only, and its observed order (2.3; 1.6 in the second family) and its extrapolation
    (0.18133; 0.18315) are artefacts of that step: with the layers held at 3 the same triple converges at order 3.6.
    Likewise 1.96 / 1.4 / 1 (2, 3, 3 layers: order 3.6 and 4.3)."""
    refines = sorted(study, reverse=True)
    return [t for t in zip(refines, refines[1:], refines[2:])
            if _layers(t[0]) < _layers(t[1]) < _layers(t[2])]


def _study_bound(q: str, index: int, fine_value: float) -> float:
    """The largest error of the refine-1 value ``fine_value`` the studies admit: for each family and each of its
    consistent triples (:func:`_consistent_triples`: 1 / 0.8 / 0.64), the distance to its Richardson limit plus that
    limit's own error (its last extrapolation step, |limit - finest level|), the largest over both families (the
    limits of the two families agree within 4e-5 for the ellipse ratio, 0.17909 and 0.17905, orders 3.3 and 3.0)."""
    bound = 0.0
    for study in STUDIES:
        for triple in _consistent_triples(study):
            levels = tuple(Level(r, study[r][0], {q: study[r][index]}) for r in triple)
            s = ConvergenceStudy(levels)
            limit = s.richardson(q)
            bound = max(bound, abs(limit - fine_value) + abs(limit - levels[-1].values[q]))
    return bound


def _limits_agree(q: str, index: int) -> None:
    """The two families' consistent triples extrapolate to one value within the larger of their last extrapolation
    steps (a Richardson limit is good to about its last step), the condition for :func:`_study_bound` to stand for
    the converged answer (measured: ellipse ratio 0.17909 / 0.17905 against steps 0.0019 / 0.0021; phase
    171.084 / 171.082 degrees against 0.027 / 0.022)."""
    limits, steps = [], []
    for study in STUDIES:
        (triple,) = _consistent_triples(study)
        s = ConvergenceStudy(tuple(Level(r, study[r][0], {q: study[r][index]}) for r in triple))
        assert np.isfinite(s.order(q)), (q, triple)
        limits.append(s.richardson(q))
        steps.append(abs(s.richardson(q) - study[triple[-1]][index]))
    assert abs(limits[0] - limits[1]) <= max(steps), (q, limits, steps)


def test_teeth_motion_estimate_on_the_sector_covers_the_finer_study():
    """The stated errors of the teeth ellipse ratio (two-level on the k = 0 sector, order 2) and
    phase (order 1, fem.convergence.SECTOR_PHASE_ORDER) at refine 1 against the refinement studies
    of :data:`STUDIES` (two mesh families, finest levels 267k and 282k DOFs): at least the largest
    error they admit (:func:`_study_bound`: ellipse 0.0084, phase 0.19 degrees), at most 4x it (the
    reference's own accuracy is in the bound; the factor 4 only keeps the estimate from being
    useless). Measured: ellipse 0.010 (5.8 % of the value, 1.19x the bound; the 5 % asked of it is
    not reached at these DOFs, docs/theory/piezo-elastic.md: at ``--refine 0.8`` the levels 1 and
    0.8 give 0.0067, 3.8 %), phase 0.35 degrees (order 2 would state 0.16 and miss the bound)."""
    d = article_design().replace({"stack.bolt_diameter": 0.0, **STUDY_DESIGN})
    fine = working_mode_level(d, 1.0, path="sector", q_mech=100.0, harmonic_method="modal")
    ndof, ratio, phase = TEETH_STUDY[1.0]
    assert fine.ndof == ndof                                          # the mesh the study measured
    assert fine.values["teeth_ellipse_ratio"] == pytest.approx(ratio, abs=2e-6)
    assert fine.values["teeth_phase_deg"] == pytest.approx(phase, abs=2e-4)
    est = estimate(d, fine.values, fine.ndof, refine=1.0, q_mech=100.0, path="sector")
    for q, index in (("teeth_ellipse_ratio", 1), ("teeth_phase_deg", 2)):
        _limits_agree(q, index)
        bound = _study_bound(q, index, fine.values[q])
        assert bound <= est.error(q) <= 4 * bound, (q, est.error(q), bound)
    assert est.relative("teeth_ellipse_ratio") <= 0.06
    assert "teeth_phase_deg: order 1" in est.method


def test_pipeline_teeth_motion_on_the_finer_mesh_states_at_most_5_percent_and_covers_the_studies():
    """The teeth motion as the pipeline reports it on the default design (results.stage_teeth: the k = 0 sector at
    refine 0.8, its own resonance, the run's losses; the run's refine-1 values the coarse level of an order-2
    two-level estimate) against the two mesh families' refinement studies.

    Reference and tolerance: the converged answer is the families' consistent-triple limit, good to its last
    extrapolation step (:func:`_limits_agree`); :func:`_study_bound` of the refine-0.8 value adds that step to the
    distance from the limit (ellipse 0.0055, phase 0.093 degrees). The stated error
    must be at least that bound (it covers the true error whatever the limit's own error) and at most 4x it (an
    estimate larger than that would be useless). Measured: ellipse 0.1756 +- 0.0066 (3.8 %, 1.2x the bound; 1.9x
    the distance to the limit), phase 171.15 +- 0.21 degrees (2.3x the bound). The coarse values are the study's
    refine-1 level, which :func:`test_teeth_motion_estimate_on_the_sector_covers_the_finer_study` reproduces to
    2e-6; the fine level must be the study's refine-0.8 one (same mesh, same method: 154 759 DOFs, 2e-6)."""
    from fem.harmonic import LossModel
    from results.stage_fe import MeshOptions
    from results.stage_teeth import teeth_motion

    d = article_design().replace({"stack.bolt_diameter": 0.0, **STUDY_DESIGN})
    ndof1, ratio1, phase1 = TEETH_STUDY[1.0]
    coarse = Level(1.0, ndof1, {"teeth_ellipse_ratio": ratio1, "teeth_phase_deg": phase1})
    t = teeth_motion(d, MeshOptions().resolved(d), loss=LossModel(q_mech=100.0), near_hz=20e3, voltage=1.0,
                     surfaces=("horn_tip", "teeth_tops"), coarse=coarse)
    ndof, ratio, phase = TEETH_STUDY[0.8]
    assert t.ndof == ndof
    values = {"teeth_ellipse_ratio": t.wp.teeth_ellipse_ratio, "teeth_phase_deg": t.wp.teeth_phase_deg}
    assert values["teeth_ellipse_ratio"] == pytest.approx(ratio, abs=2e-6)
    assert values["teeth_phase_deg"] == pytest.approx(phase, abs=2e-4)
    for q, index in (("teeth_ellipse_ratio", 1), ("teeth_phase_deg", 2)):
        _limits_agree(q, index)
        bound = _study_bound(q, index, values[q])
        assert bound <= t.est.error(q) <= 4 * bound, (q, t.est.error(q), bound)
    assert t.est.relative("teeth_ellipse_ratio") <= 0.05
