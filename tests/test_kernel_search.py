"""The guaranteed root search on the modal horn: the tip turned along the grid by per-mode factors
(impact.kernel_blocks.rot_*) against the library's exp, cos and sin at every point, and the search's
first touch against a dense scan with Brent's method (scipy).

References and tolerances:
- at an anchor the rotated tip is the direct one's sums in the same order: equal bit for bit;
- between anchors the difference must stay within rot_setup's bounds e0, e1 (derived in its
  docstring from the rounding of each turn and of the grid's times), which the search takes off
  the rotated values before it clears an interval;
- the first touch: scipy.optimize.brentq on the first sign change of a scan 40x finer than the
  search's grid, to xtol 1e-18 s; the search's Brent stops within XTOL + RTOL |t|
  (impact.event_rules), so the two agree within twice that (f's own rounding, ~1e-20 m over a
  slope of ~0.1 m/s, moves a root by ~1e-19 s).
"""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from impact import kernel_blocks as KB
from impact.event_rules import RTOL, XTOL
from impact.horn import H_A, H_B, H_MASS, H_OMEGA, H_TIP, H_ZETA

N_MODES = 16
#: the tool's oscillator (unused by the horn's functions)
TOOL = np.zeros(KB.O_N)
W_DRIVE = 2 * math.pi * 20e3


def _horn(rng, t0):
    """A 16-mode horn table (20-70 kHz, Q 100), its mode records at t0 from a random modal state,
    and the contact record of a segment starting at t0."""
    tab = np.zeros((N_MODES, 12))
    tab[:, H_OMEGA] = 2 * math.pi * np.linspace(20e3, 70e3, N_MODES)
    tab[:, H_ZETA] = 0.005
    tab[:, H_MASS] = rng.uniform(0.02, 0.2, N_MODES)
    tab[:, H_TIP] = rng.uniform(-1.5, 1.5, N_MODES)
    tab[:, H_A] = rng.normal(0, 1e-6, N_MODES)
    tab[:, H_B] = rng.normal(0, 1e-6, N_MODES)
    q = tab[:, H_A] + rng.normal(0, 2e-7, N_MODES)
    qd = W_DRIVE * tab[:, H_B] + rng.normal(0, 2e-7, N_MODES) * tab[:, H_OMEGA]
    ho = np.empty((N_MODES, KB.O_N))
    KB.horn_records(ho, tab, N_MODES, W_DRIVE, t0, q, qd)
    cp = np.zeros(KB.C_N)
    cp[KB.C_T0], cp[KB.C_W], cp[KB.C_UC], cp[KB.C_US] = t0, W_DRIVE, 15e-6, -6e-6
    return tab, ho, cp


@pytest.mark.parametrize("kind", [KB.FN_HORN, KB.FN_HREL])
def test_rotated_tip_within_its_bound_of_the_direct_one(kind):
    rng = np.random.default_rng(34)
    order = 2 if kind == KB.FN_HREL else 0
    worst = [0.0, 0.0]
    for _ in range(20):
        t0 = rng.uniform(0.0, 0.22)
        tab, ho, cp = _horn(rng, t0)
        hh = rng.uniform(0.2e-6, 2e-6)
        start = t0 + rng.uniform(0.0, 1e-3)
        t_max = start + 3 * KB.ROT_K * hh
        rot, e0, e1 = KB.rot_setup(kind, cp, tab, ho, N_MODES, t_max)
        assert rot.shape == (N_MODES + 1, 6) and 0.0 < e0 and 0.0 < e1
        for j in range(3 * KB.ROT_K):
            tt = start + j * hh
            f, fp, anchor = KB.grid_value(kind, tt, j, hh, cp, TOOL, tab, ho, N_MODES, rot)
            u, ud = KB.tip(tt, cp, tab, ho, N_MODES, order)
            g, gp = KB.tip_gap(kind, tt, cp, TOOL, u, ud)
            assert anchor == (j % KB.ROT_K == 0)
            if anchor:
                assert (f, fp) == (g, gp)
            else:
                assert abs(f - g) <= e0 and abs(fp - gp) <= e1, (j, f - g, e0, fp - gp, e1)
                worst = [max(worst[0], abs(f - g) / e0), max(worst[1], abs(fp - gp) / e1)]
    # the rotation moves the values (the comparison is not empty) and the bounds are not loose by orders
    assert 0.0 < worst[0] < 1.0 and 1e-4 < max(worst) < 1.0, worst


def test_tool_and_kinematic_searches_are_not_rotated():
    rng = np.random.default_rng(1)
    tab, ho, cp = _horn(rng, 0.01)
    assert KB.rot_setup(KB.FN_TOOL, cp, tab, ho, N_MODES, 0.02)[0].shape[0] == 0
    assert KB.rot_setup(KB.FN_HORN, cp, None, None, 0, 0.02)[0].shape[0] == 0
    ho[3, KB.O_KIND] = 1.0                        # an overdamped mode: no rotation
    assert KB.rot_setup(KB.FN_HORN, cp, tab, ho, N_MODES, 0.02)[0].shape[0] == 0


def test_search_finds_the_first_touch_of_a_dense_scan():
    """A free mass falling onto the oscillating 16-mode tip from above its reach: the touch comes
    after hundreds of grid points (several anchors, chunks of 32 to 256 points)."""
    rng = np.random.default_rng(7)
    stack = np.empty((128, 6))
    checked = 0
    for _ in range(12):
        t0 = rng.uniform(0.0, 0.2)
        tab, ho, cp = _horn(rng, t0)
        hb0, hb2, _ = KB.horn_records(ho, tab, N_MODES, W_DRIVE, t0, *_state(tab, ho, t0))
        reach = math.hypot(cp[KB.C_UC], cp[KB.C_US]) + hb0
        a = -rng.uniform(50.0, 400.0)
        cp[KB.C_W0], cp[KB.C_WD0], cp[KB.C_A] = reach + rng.uniform(0.0, 5e-6), rng.uniform(-0.02, 0.02), a
        B = abs(a) + math.hypot(cp[KB.C_UC], cp[KB.C_US]) * W_DRIVE ** 2 + hb2
        h = KB.grid_step(B, 1.0, 1e-7)
        hi = t0 + 2e-3
        found, t_hit = KB.search(KB.FN_HORN, cp, TOOL, tab, ho, N_MODES, B, t0, hi, h, stack)
        ts = np.arange(t0, hi, h / 40)
        fs = np.array([KB.contact_fn(KB.FN_HORN, t, cp, TOOL, tab, ho, N_MODES)[0] for t in ts])
        below = np.nonzero(fs < 0.0)[0]
        assert found == (below.size > 0)
        if not found:
            continue
        i = below[0]
        ref = brentq(lambda t: KB.contact_fn(KB.FN_HORN, t, cp, TOOL, tab, ho, N_MODES)[0], ts[i - 1], ts[i],
                     xtol=1e-18, rtol=4 * np.finfo(float).eps)
        assert (t_hit - t0) / h > 2 * KB.ROT_K
        assert abs(t_hit - ref) <= 2 * (XTOL + RTOL * abs(ref)), (t_hit, ref)
        checked += 1
    assert checked >= 8


def _state(tab, ho, t0):
    """The modal state the records of ``_horn`` hold at t0."""
    q, qd = np.empty(N_MODES), np.empty(N_MODES)
    KB.modal_at(ho, tab, N_MODES, W_DRIVE, t0, t0, q, qd)
    return q, qd
