"""The k = 0 sector system (fem/sector_system.py): every driven analysis on one sector equals the
same analysis on the whole drill replicated from it.

Reference: the whole drill (geometry.sector.replicate of the same sector, assembled as it is)
solved by the same functions. The restriction to k = 0 is exact (fem.cyclic), so the two differ
by round-off and the solvers' tolerances only:
* eigenvalues: both solve omega^2 to 1e-10 relative (fem.eigen's bound), f to 5e-11, so they
  differ by at most 1e-10; TOL_EIG = 1e-9 leaves 10x for the Rayleigh quotients' round-off;
* direct solves (working point, capacitance, Newmark): one factorisation each of matrices whose
  condition number near the band is below 1e6 (the nearest resonance 1e-3 away, relative, at
  most 1e3 amplification, times the potential scaling's 1e3 spread), in double precision
  (1e-16): 1e-10; TOL_SOLVE = 1e-8 leaves 100x for the summation order of the sparse products.
The stack ceramic is PZT-4 (its c66 equals (c11 - c12) / 2: the drill is exactly symmetric; see
tests/test_cyclic.py).
"""

import dataclasses

import numpy as np
import pytest

from fem.assembly import assemble
from fem.harmonic import LossModel, harmonic_sweep, modal_basis, working_point
from fem.modal import modal_analysis
from fem.reduced import reduce_transducer
from fem.sector_system import SectorSystem, sector_system
from fem.transient import ring_up
from geometry.builder import build
from geometry.examples import article_design
from geometry.sector import replicate
from rpud_common import ParameterError

N = 6
TOL_EIG = 1e-9
TOL_SOLVE = 1e-8
SURFACES = ("horn_tip", "teeth_tops")
SHARE_TOL = 0.01


@pytest.fixture(scope="module")
def pair():
    d = article_design()
    d = dataclasses.replace(d, stack=dataclasses.replace(d.stack, material="PZT-4"))
    tm, _ = build(d, mesher="revolve", sectors=N, refine=2.0)
    whole, _ = replicate(tm, N)
    return sector_system(assemble(tm), N), assemble(whole)


@pytest.fixture(scope="module")
def modes(pair):
    return [modal_analysis(s, 20e3, 8) for s in pair]


def _close(a, b, tol):
    a, b = np.asarray(a), np.asarray(b)
    assert np.all(np.abs(a - b) <= tol * np.max(np.abs(b))), (a, b)


def test_sector_modes_are_the_whole_drills_axisymmetric_modes(pair, modes):
    sector, whole = modes
    assert sector.f_r_hz.size == 8
    # every sector mode is a whole-drill mode, with its anti-resonance
    for fr, fa in zip(sector.f_r_hz, sector.f_a_hz):
        j = np.argmin(np.abs(whole.f_r_hz - fr))
        if abs(whole.f_r_hz[j] - fr) <= TOL_EIG * fr:
            assert whole.f_a_hz[j] == pytest.approx(fa, rel=TOL_EIG, nan_ok=True)
    work_s, work_w = sector.working, whole.working
    assert abs(sector.f_r_hz[work_s] - whole.f_r_hz[work_w]) <= TOL_EIG * whole.f_r_hz[work_w]
    assert abs(sector.f_a_hz[work_s] - whole.f_a_hz[work_w]) <= TOL_EIG * whole.f_a_hz[work_w]
    # the same motion: no bending (k = 1), and the energy shares of each k = 0 mode the whole drill's.
    # The decomposition fits per axial slab, bins half a mean edge wide where the mesh has no layers,
    # and the sector's mean edge is not the whole drill's: the shares agree to the fits' resolution,
    # not to round-off. SHARE_TOL = 0.01 (one point) is a tenth of the labels' thresholds' distance
    # (fem.modeshape.THRESHOLDS: 0.15), so a label cannot flip on it.
    assert "bending" not in sector.labels
    # a mode's own anti-resonance never lies below it (the open circuit adds a positive rank-one stiffness)
    for m in modes:
        ok = np.isfinite(m.f_a_hz)
        assert np.all(m.f_a_hz[ok] >= m.f_r_hz[ok]) and ok[m.working]
    for i, fr in enumerate(sector.f_r_hz):
        j = np.argmin(np.abs(whole.f_r_hz - fr))
        if abs(whole.f_r_hz[j] - fr) <= TOL_EIG * fr:
            assert sector.labels[i] == whole.labels[j]
            assert np.abs(sector.shares[i] - whole.shares[j]).max() <= SHARE_TOL


def test_working_point_equals_the_whole_drill(pair, modes):
    f = modes[1].f_r_hz[modes[1].working] * 1.002
    a, b = (working_point(s, f, 10.0, surfaces=SURFACES) for s in pair)
    _close(a.admittance, b.admittance, TOL_SOLVE)
    _close(a.tip_per_volt_m, b.tip_per_volt_m, TOL_SOLVE)
    assert a.teeth_ellipse_ratio == pytest.approx(b.teeth_ellipse_ratio, rel=TOL_SOLVE)
    assert a.teeth_phase_deg == pytest.approx(b.teeth_phase_deg, abs=TOL_SOLVE * 360)
    assert a.power_w == pytest.approx(b.power_w, rel=TOL_SOLVE)
    # the field on the whole drill, expanded from the sector: the whole drill's own
    s, w = pair
    shape = s.whole_shapes(a.x)[0]
    ref = np.real(w.displacement(b.x))
    assert np.max(np.abs(shape - ref)) <= TOL_SOLVE * np.max(np.abs(ref))


def test_capacitances_equal_the_whole_drill(pair):
    s, w = pair
    for mech in ("blocked", "free"):
        assert s.capacitance_static(mech) == pytest.approx(w.capacitance_static(mech), rel=TOL_SOLVE)


def test_direct_sweep_and_ring_up_equal_the_whole_drill(pair, modes):
    """The direct sweep and the direct Newmark ring-up: the identity holds at every frequency and
    every step, so one frequency (the whole drill's complex factorisation is the costly part) and two
    cycles of 20 steps check it."""
    f0 = modes[1].f_r_hz[modes[1].working]
    freqs = f0 * np.array([1.005])
    a, b = (harmonic_sweep(s, freqs, method="direct", surfaces=SURFACES) for s in pair)
    _close(a.admittance, b.admittance, TOL_SOLVE)
    _close(a.surfaces["teeth_tops"]["tangential"], b.surfaces["teeth_tops"]["tangential"], TOL_SOLVE)
    ra, rb = (ring_up(s, f0, 10.0, 2 / f0, method="direct", steps_per_cycle=20) for s in pair)
    _close(ra.surfaces["horn_tip"]["axial"], rb.surfaces["horn_tip"]["axial"], TOL_SOLVE)


def test_reduced_transducer_equals_the_whole_drills_working_mode(pair, modes):
    f0 = modes[1].f_r_hz[modes[1].working] * 1.002
    loss = LossModel()
    red = []
    for s in pair:
        basis = modal_basis(s, f0, 8, loss=loss)
        red.append(reduce_transducer(s, basis, f0))
    a, b = red
    w_a, w_b = a.mode_index[a.working], b.mode_index[b.working]
    assert a.stiffness[a.working] == pytest.approx(b.stiffness[b.working], rel=TOL_EIG)
    # the coupling of a mass-normalised mode: the whole drill's (its mass carries N sectors)
    assert abs(a.coupling_re[a.working]) == pytest.approx(abs(b.coupling_re[b.working]), rel=1e-6)
    assert abs(a.tip[a.working]) == pytest.approx(abs(b.tip[b.working]), rel=1e-6)
    assert w_a >= 0 and w_b >= 0


def test_clamped_modes_equal_the_whole_drill(pair):
    a, b = (modal_analysis(s, 20e3, 4, clamp=("flange",)) for s in pair)
    for fr in a.f_r_hz:
        assert np.min(np.abs(b.f_r_hz - fr)) <= TOL_EIG * fr or fr > b.f_r_hz.max()


def test_sector_system_refuses_what_it_cannot_restrict(pair):
    s, _ = pair
    assert isinstance(s, SectorSystem) and s.sectors == N
    with pytest.raises(ParameterError, match="sector's own"):
        sector_system(s, N)
    with pytest.raises(ParameterError, match="sectors"):
        sector_system(s.sector, 1)


def test_default_path_is_the_sector_where_the_design_can_be_swept():
    from fem.sector_system import check_path, default_path, path_label

    d = article_design()
    assert default_path(d) == "sector" and default_path(d, order=1) == "whole"
    horn = dataclasses.replace(d, horn=dataclasses.replace(d.horn, profile="exponential"))
    assert default_path(horn) == "whole"
    with pytest.raises(ParameterError, match="swept as a sector"):
        check_path(horn, "sector")
    assert path_label(d, "sector").startswith("swept sector 1/6 (k = 0)")
    assert path_label(horn, "whole", grade=True).startswith("whole drill, free")
