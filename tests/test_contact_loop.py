"""The compliant impact model (impact.compliant_loop): its energy ledger closes, and its two limits
are the models it replaces: contact stiffness -> infinity gives the Newton coupled model
(impact.coupled), and a horn of infinite tip mass besides gives the kinematic horn (impact.model)."""

import math

import numpy as np
import pytest

from impact.compliant_loop import simulate_compliant
from impact.hertz import HertzLaw
from impact.horn import ModalHorn
from impact.params import ImpactParams
from rpud_common import ParameterError

W = 2 * np.pi * 20e3
V0 = 225.0


def _horn(tip_mass=0.1, A=15e-6, zeta=0.005, f1=20.3e3):
    """One mode near the drive, steady tip amplitude A (the coupled model's test horn)."""
    om = np.array([2 * np.pi * f1])
    s = np.array([1 / math.sqrt(tip_mass)])
    cre = A / s[0] * abs(om[0] ** 2 - W ** 2 + 2j * zeta * om[0] * W) / V0
    return ModalHorn(om, [zeta], [1.0], s, [cre], [0.1 * cre], V0, start="steady")


def _cosine_horn(tip_mass, A=15e-6):
    """An undamped mode at twice the drive whose steady tip motion is ``A cos(W t)`` (the kinematic
    horn's) and whose tip mass is ``tip_mass``: coupling in phase with V'/W only."""
    om = 2 * W
    s = 1 / math.sqrt(tip_mass)
    gamma = A * (om ** 2 - W ** 2) / (s * V0)
    return ModalHorn([om], [0.0], [1.0], [s], [0.0], [gamma], V0, start="steady")


def _laws(k, p):
    return dict(horn_law=HertzLaw(k, p.e2), tool_law=HertzLaw(k, p.e1))


@pytest.mark.parametrize("engine, flights", [("kernel", "closed-form"), ("python", "closed-form"),
                                             ("python", "integrated")])
def test_energy_ledger_closes(engine, flights):
    """Drive work + the constant force's work = change of the bodies' and contacts' energy + modal
    damping + tool damping + contact losses. Every term is integrated with the motion (rtol 1e-11)
    or closed form; the balance must close to 1e-9 of the drive work (the integration's
    accumulated error over ~60 drive periods is ~rtol x steps ~ 1e-11 x 1e3 ~ 1e-8 at worst, with
    cancellation between steps well below)."""
    p = ImpactParams(m_free=0.008, t_end=0.003)
    r = simulate_compliant(p, _horn(), **_laws(1e10, p), horn_residual=2e-9, flights=flights, engine=engine)
    led = r.ledger
    assert len(r.contacts) >= 4 and led["contact_loss_j"] > 0
    assert abs(led["residual_j"]) <= 1e-9 * abs(led["drive_j"])


def test_closed_form_flights_equal_the_integrated_reference():
    """The fast path (closed-form flights, touch found on a grid and refined by Brent) against the
    all-integrated reference: the same contacts, at the same times within 1e-9 s and with the same
    speeds after them within 1e-6 m/s (both integrate the contacts at rtol 1e-11; the reference's
    flight integration error over ~1 ms, ~1e-11 of mm positions, shifts a touch by ~1e-13 s)."""
    p = ImpactParams(m_free=0.008, t_end=0.003)
    a = simulate_compliant(p, _horn(), **_laws(1e10, p), horn_residual=2e-9, flights="integrated", engine="python")
    b = simulate_compliant(p, _horn(), **_laws(1e10, p), horn_residual=2e-9, engine="python")
    assert [c.body for c in a.contacts] == [c.body for c in b.contacts] and len(a.contacts) >= 4
    for ca, cb in zip(a.contacts, b.contacts):
        assert cb.t_start == pytest.approx(ca.t_start, abs=1e-9)
        assert cb.free_mass_after == pytest.approx(ca.free_mass_after, abs=1e-6)
        assert cb.tool_after == pytest.approx(ca.tool_after, abs=1e-6)


def test_a_pressed_free_mass_chatters_on_the_horn():
    """A spring of 50 N presses the free mass onto a horn of 5 um amplitude: it leaves and touches
    again many times, some right after a separation. Both flight modes run it, close the ledger
    (1e-9 of the drive work) and agree on the first five contacts (speeds after them 1e-6 m/s;
    later ones may differ: a grazing touch shorter than an integration step escapes the reference's
    event detection). The compiled engine runs it too, at rtol 1e-11: its ledger error grows with
    rtol (~5e-9 of this run's small drive work at 1e-10, ~8e-10 at 1e-11: long contacts, little
    drive)."""
    p = ImpactParams(m_free=0.008, t_end=0.002, spring_force=50.0, v0=0.05)
    runs = [simulate_compliant(p, _horn(A=5e-6), **_laws(1e10, p), horn_residual=2e-9, flights=fl, engine="python")
            for fl in ("closed-form", "integrated")]
    runs.append(simulate_compliant(p, _horn(A=5e-6), **_laws(1e10, p), horn_residual=2e-9, rtol=1e-11))
    for r in runs:
        assert len(r.contacts) >= 10
        assert abs(r.ledger["residual_j"]) <= 1e-9 * abs(r.ledger["drive_j"])
    for run in runs[1:]:
        for a, b in zip(runs[0].contacts[:5], run.contacts[:5]):
            assert a.body == b.body and a.free_mass_after == pytest.approx(b.free_mass_after, abs=1e-6)


def _converges_to(runs, target_v, target_t):
    """Speeds after the first two contacts (a tool impact, then a horn impact) at contact stiffnesses
    1e14, 1e16, 1e18 N/m^1.5 against the Newton model's: the difference is of the order of the
    contact time, ~k^{-2/5}, so it shrinks by 100^{-2/5} = 0.158 per step (asserted within [0.1, 0.25]),
    and the first-order Richardson extrapolation ``v18 + (v18 - v16) r / (1 - r)`` removes it up to
    the next order (the 1e18 difference times 0.158: tested at 3e-3 m/s). Times within 1 us from 1e16 on."""
    r = 100 ** -0.4
    v = np.array([[c.free_mass_after for c in run.contacts[:2]] for run in runs])
    err = np.abs(v - np.asarray(target_v)[None, :2])
    for j in range(2):
        if err[1, j] > 1e-9:
            assert 0.1 < err[2, j] / err[1, j] < 0.25
        assert v[2, j] + (v[2, j] - v[1, j]) * r / (1 - r) == pytest.approx(target_v[j], abs=3e-3)
    for run in runs:
        assert [c.body for c in run.contacts[:2]] == ["tool", "horn"]
    for run in runs[1:]:                  # contact times 0.1-0.02 us (1e14: 0.8 us, left out)
        for c, t in zip(run.contacts[:2], target_t[:2]):
            assert c.t_start == pytest.approx(t, abs=1e-6)


def test_stiff_contacts_reproduce_the_newton_coupled_model():
    """Contact stiffness -> infinity with one mode: the Newton coupled model (impact.coupled, python
    engine) with the same horn and restitutions (see _converges_to for the rate and tolerance)."""
    from impact.coupled import simulate_coupled

    p = ImpactParams(m_free=0.008, t_end=0.0011)
    h = _horn()
    newt = simulate_coupled(p, h, engine="python", series=False).impact
    assert list(newt.contact[:2]) == ["tool", "horn"]
    _converges_to([simulate_compliant(p, h, **_laws(k, p)) for k in (1e14, 1e16, 1e18)], newt.w_after, newt.t)


def test_heavy_tip_and_stiff_contacts_reproduce_the_kinematic_horn():
    """A horn whose tip moves as ``A0 cos(W t)`` with a tip mass of 1e6 kg (an impact changes its
    speed by ~m_w v / m_tip ~ 1e-8 m/s) and ever stiffer contacts: the kinematic horn of
    impact.model (Newton, infinite mass; see _converges_to)."""
    from impact.model import simulate

    p = ImpactParams(m_free=0.008, t_end=0.0016)
    kin = simulate(p, engine="python")
    assert list(kin.contact[:2]) == ["tool", "horn"]
    _converges_to([simulate_compliant(p, _cosine_horn(1e6), **_laws(k, p)) for k in (1e14, 1e16, 1e18)],
                  kin.w_after, kin.t)


def test_bad_inputs_are_refused():
    p = ImpactParams(t_end=1e-4)
    with pytest.raises(ParameterError, match="horn_residual"):
        simulate_compliant(p, _horn(), **_laws(1e10, p), horn_residual=-1.0)
    with pytest.raises(ParameterError, match="horn"):
        simulate_compliant(p, "horn", **_laws(1e10, p))
    with pytest.raises(ParameterError, match="flights"):
        simulate_compliant(p, _horn(), **_laws(1e10, p), flights="euler", engine="python")
    with pytest.raises(ParameterError, match="engine"):
        simulate_compliant(p, _horn(), **_laws(1e10, p), engine="fortran")
