"""The compiled compliant engine (impact.kernel_compliant via impact.compliant_engine) against the
Python reference (impact.compliant_loop, engine="python"), its window energy balance, and its
ensemble statistics. The limits (stiff contacts -> Newton model, heavy tip -> kinematic horn) run
on the compiled engine in tests/test_contact_loop.py."""

import math

import numpy as np
import pytest

from impact.compliant_engine import compliant_batch
from impact.compliant_loop import simulate_compliant
from impact.hertz import HertzLaw
from impact.horn import ModalHorn
from impact.params import ImpactParams
from impact.stats import DRIVING, Scenario, StatsSettings
from rpud_common import ParameterError

W = 2 * np.pi * 20e3
V0 = 225.0


def _horn3():
    """Three modes (the working mode near the drive, two above it with larger tip participation),
    damped, steady start: the structure of the FE drill's wide-band horn on a small scale."""
    om = 2 * np.pi * np.array([20.3e3, 31.8e3, 55.0e3])
    s = np.array([1 / math.sqrt(0.1), 2.1 / math.sqrt(0.1), 1.5 / math.sqrt(0.1)])
    zeta = np.array([0.005, 0.004, 0.004])
    cre = 15e-6 / s[0] * abs(om[0] ** 2 - W ** 2 + 2j * zeta[0] * om[0] * W) / V0
    return ModalHorn(om, zeta, [1.0, 1.0, 1.0], s, [cre, 0.1 * cre, 0.05 * cre], [0.1 * cre, 0.0, 0.0], V0,
                     start="steady")


def _laws(p, k=1e10):
    return dict(horn_law=HertzLaw(k, p.e2), tool_law=HertzLaw(k, p.e1))


def test_kernel_reproduces_the_python_reference():
    """The same run by both engines: the same first contacts (body, start, separation speeds).

    Tolerance from the error control: each engine keeps the local error of a step below rtol of
    the state's scale (m/s speeds); a contact takes N ~ 100-300 steps, so a speed after it is
    within ~N rtol |v| of the exact one: the kernel at rtol 1e-11 to 3e-9 m/s at |v| ~ 1 m/s, the
    reference at 1e-12 to 3e-10 m/s. The chaotic motion amplifies a difference ~10x per contact,
    so the first three contacts are compared, at 1e-7 m/s (the amplified sum), and their start
    times at 1e-10 s (a speed error of 1e-7 m/s over the ~1 ms between contacts moves a touch by
    1e-10 m, ~1e-10 s at ~1 m/s)."""
    p = ImpactParams(m_free=0.008, t_end=0.0035)
    h = _horn3()
    a = simulate_compliant(p, h, **_laws(p), horn_residual=2e-9, rtol=1e-12, engine="python")
    b = simulate_compliant(p, h, **_laws(p), horn_residual=2e-9, rtol=1e-11)
    assert len(a.contacts) >= 3
    for ca, cb in zip(a.contacts[:3], b.contacts[:3]):
        assert ca.body == cb.body
        assert cb.t_start == pytest.approx(ca.t_start, abs=1e-10)
        assert cb.free_mass_after == pytest.approx(ca.free_mass_after, abs=1e-7)
        assert cb.tool_after == pytest.approx(ca.tool_after, abs=1e-7)
        assert cb.d_max == pytest.approx(ca.d_max, rel=1e-6)
        assert cb.loss == pytest.approx(ca.loss, rel=1e-5)


@pytest.mark.parametrize("rtol", [1e-10, 1e-9])
def test_window_energy_balance_closes(rtol, monkeypatch):
    """Per member, over the statistics window (from its start inside the run): drive work =
    modal damping + tool damping + contact losses + change of the stored energy, to 1e-9 of the
    drive work. The flights' terms are closed form; the contacts' are integrated with the motion
    at rtol, whose local errors (~rtol of each step's energy change) add up over ~1e4 steps
    without a sign, to ~rtol / 10 .. rtol of the drive work: within 1e-9 at the batch's rtol
    (1e-9) and below. The batch's own re-runs of a member that misses it are switched off here,
    so the balance is the integration's."""
    import impact.compliant_engine as CE

    monkeypatch.setattr(CE, "LEDGER_TOL", math.inf)
    sc = Scenario("short device", 5.0, 0.005, 0.03)
    st = StatsSettings(n_start=4, n_max=4)
    p = ImpactParams(m_free=0.004, freq=20e3)
    res = compliant_batch([p], _horn3(), **_laws(p), horn_residual=2e-9, scenario=sc, settings=st, rtol=rtol)[0]
    from impact import kernel_compliant as KC

    raw = res.raw
    assert raw.shape[0] == 4 and np.all(raw[:, KC.S_N_TOOL] >= 3) and np.all(raw[:, KC.K_LOSS] > 0)
    assert np.all(np.abs(raw[:, KC.K_LEDGER]) <= 1e-9 * raw[:, KC.C_DRIVE])


def test_members_missing_the_balance_run_again_at_a_tighter_rtol(monkeypatch):
    """A member whose window balance misses the batch's target runs again at a tenth of its rtol,
    down to the floor (1e-12). With a target no member meets (0), every member ends at the floor:
    its row is the single run's at 1e-12 bit for bit."""
    import impact.compliant_engine as CE
    from impact import kernel_compliant as KC
    from impact.kernel import pack
    from impact.stats import ensemble_members

    monkeypatch.setattr(CE, "LEDGER_TOL", 0.0)
    sc = Scenario("short device", 5.0, 0.005, 0.02)
    st = StatsSettings(n_start=2, n_max=2)
    p = ImpactParams(m_free=0.004, freq=20e3)
    laws = _laws(p)
    res = compliant_batch([p], _horn3(), **laws, scenario=sc, settings=st, rtol=1e-10)[0]
    tab, xs = _horn3().pack(20e3)
    base = sc.apply(p)
    for i, member in enumerate(ensemble_members(base, 2, st)):
        row = KC.run_contacts(pack(member), KC.pack_laws(*laws.values(), 0.0, CE.RTOL_FLOOR), tab, xs, sc.t_from,
                              sc.t_end, base.max_events)[-1]
        assert np.array_equal(row, res.raw[i])


def test_batch_is_reproducible_and_carries_intervals():
    """Same command, same numbers; every quantity with a 95 % interval; one law per case."""
    sc = Scenario("short device", 5.0, 0.005, 0.03)
    st = StatsSettings(n_start=4, n_max=4)
    cases = [ImpactParams(m_free=m, freq=20e3) for m in (0.002, 0.008)]
    laws = dict(horn_law=[HertzLaw(k, 0.8) for k in (1e10, 2e10)], tool_law=HertzLaw(1e10, 0.8))
    a = compliant_batch(cases, _horn3(), **laws, scenario=sc, settings=st)
    b = compliant_batch(cases, _horn3(), **laws, scenario=sc, settings=st)
    for ra, rb in zip(a, b):
        assert np.array_equal(ra.raw, rb.raw)
        ke = ra["mean_tool_ke_after_j"]
        assert ke.mean > 0 and 0 < ke.half_width < ke.mean
        assert math.isfinite(ra["tip_amplitude_m"].half_width)


def test_bad_inputs_are_refused():
    p = ImpactParams(t_end=1e-4)
    with pytest.raises(ParameterError, match="rtol"):
        simulate_compliant(p, _horn3(), **_laws(p), rtol=1e-3)
    with pytest.raises(ParameterError, match="horn_law"):
        compliant_batch([p, p], _horn3(), horn_law=[HertzLaw(1e10)], tool_law=HertzLaw(1e10))
    with pytest.raises(ParameterError, match="tool_law"):
        simulate_compliant(p, _horn3(), horn_law=HertzLaw(1e10), tool_law=1e10)


def test_window_statistics_count_the_reference_contacts():
    """The kernel's window row over a short run (window = the whole run) against the statistics
    written out from the Python reference's contact list: tool and horn contact counts, the tool's
    kinetic energy after each contact and the time the contacts are closed. The runs agree on
    every contact to ~1e-6 m/s in speed and ~1e-11 s in time (the reproduction test's tolerances,
    amplified over five contacts), so the sums agree to 1e-5 relative."""
    from impact import kernel_compliant as KC
    from impact.kernel import pack

    p = ImpactParams(m_free=0.008, t_end=0.0035)
    h = _horn3()
    ref = simulate_compliant(p, h, **_laws(p), horn_residual=2e-9, rtol=1e-12, engine="python")
    tab, xs = h.pack(p.freq)
    laws = KC.pack_laws(_laws(p)["horn_law"], _laws(p)["tool_law"], 2e-9, 1e-11)
    row = KC.run_contacts(pack(p), laws, tab, xs, 0.0, p.t_end, 1000)[-1]
    tool = ref.tool_contacts()
    assert row[KC.S_N_TOOL] == len(tool) >= 2
    assert row[KC.S_N_HORN] == len(ref.contacts) - len(tool) >= 2
    ke = sum(0.5 * p.m_tool * c.tool_after ** 2 for c in tool)
    assert row[KC.S_KE_AFTER] == pytest.approx(ke, rel=1e-5)
    on = {b: sum(c.t_end - c.t_start for c in ref.contacts if c.body == b) for b in ("horn", "tool")}
    assert row[KC.S_T_ON_HORN] == pytest.approx(on["horn"], rel=1e-5)
    assert row[KC.S_T_ON_TOOL] == pytest.approx(on["tool"], rel=1e-5)
    assert row[KC.K_LOSS] == pytest.approx(ref.ledger["contact_loss_j"], rel=1e-5)


def test_event_interpolant_matches_the_steps_it_stands_for():
    """The contact phase finds its branch events on the DOP853 step's 7th-order interpolant; a
    second method is the step itself, taken to the same point. From a horn contact just after
    touch, a step that the error control accepts (its error estimate within atol + rtol |y| in
    every state component) is interpolated at 0.2 ... 0.9 of its length and compared with direct
    steps of those lengths. Both are of higher order (7 and 8) than the 5th-order estimate that
    bounds the accepted error, so they agree within that tolerance; the interpolant's ends are the
    step's ends (to rounding, 1e-12 relative)."""
    from impact import kernel_compliant as KC
    from impact.kernel import P_GAP, pack

    p = ImpactParams(m_free=0.004, freq=20e3)
    h3 = _horn3()
    tab, xs = h3.pack(p.freq)
    mt = KC.rhs_table(tab, xs)
    pv, n = pack(p), h3.n_modes
    lw = KC.pack_laws(*_laws(p).values(), 2e-9, 1e-10)
    m = 4 + 2 * n + KC.N_INT
    y, cs = np.zeros(m), np.zeros((2, KC.CS_N))
    KC._start(pv, lw, tab, xs, n, y, cs)
    ud = KC.approaches(0.0, y, n, tab, xs, pv[P_GAP])[1] + y[1]      # the tip's speed
    y[0], y[1] = y[0] - 1e-9, ud - 0.8                # 1 nm in, closing at 0.8 m/s
    KC.touch(cs, 0, lw, 0.0, 0.8, 0.0, 0.0)
    atol = KC._tolerances(tab, n, 1e-10)
    wk = np.empty((KC.R8_S + 13, m))
    st, y8, tmp, F = wk[:KC.R8_S + 4], wk[KC.R8_S + 4], wk[KC.R8_S + 5], wk[KC.R8_S + 6:, :4 + 2 * n]
    h = 2e-6
    while True:
        KC._step(0.0, y, h, n, mt, xs, pv, lw, cs, st, y8, tmp, True)
        if KC._error(y, y8, st, h, atol, 1e-10) <= 1.0:
            break
        h *= 0.5
    end = y8.copy()
    KC._dense(0.0, y, end, h, n, mt, xs, pv, lw, cs, st, tmp, F)
    k = 4 + 2 * n
    tol = atol + 1e-10 * np.maximum(np.abs(y[:k]), np.abs(end[:k]))
    got = np.empty(m)
    KC._interpolate(y, F, 1.0, got)
    assert np.all(np.abs(got[:k] - end[:k]) <= 1e-12 * np.abs(end[:k]) + 1e-12 * tol)
    for x in (0.2, 0.5, 0.9):
        KC._interpolate(y, F, x, got)
        KC._step(0.0, y, x * h, n, mt, xs, pv, lw, cs, st, y8, tmp, True)
        assert np.all(np.abs(got[:k] - y8[:k]) <= tol)


def test_members_do_not_depend_on_rounds_or_threads():
    """Member i of a case is one deterministic run: the same row bit for bit whether it runs in one
    parallel call with another case's members, with its own case alone, on one thread, grown over
    several rounds, or as a single recorded run (kernel_compliant.run_contacts)."""
    import numba

    from impact import kernel_compliant as KC
    from impact.kernel import pack
    from impact.stats import ensemble_members

    sc = Scenario("short device", 5.0, 0.005, 0.03)
    cases = [ImpactParams(m_free=m, freq=20e3) for m in (0.002, 0.008)]
    h_laws, t_law = [HertzLaw(k, 0.8) for k in (1e10, 2e10)], HertzLaw(1e10, 0.8)
    st = StatsSettings(n_start=6, n_max=6)
    both = compliant_batch(cases, _horn3(), horn_law=h_laws, tool_law=t_law, scenario=sc, settings=st)
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        alone = [compliant_batch([c], _horn3(), horn_law=h, tool_law=t_law, scenario=sc, settings=st)[0]
                 for c, h in zip(cases, h_laws)]
    finally:
        numba.set_num_threads(threads)
    # a target no ensemble meets: 2 members, then the cap (6) in a second round
    rounds = compliant_batch(cases[:1], _horn3(), horn_law=h_laws[0], tool_law=t_law, scenario=sc,
                             settings=StatsSettings(rel_tol=1e-6, n_start=2, n_max=6))[0]
    for a, b in zip(both, alone):
        assert a.raw.shape == (6, KC.N_KSTATS) and np.array_equal(a.raw, b.raw)
    assert np.array_equal(rounds.raw, both[0].raw) and not rounds.converged
    tab, xs = _horn3().pack(20e3)
    p = sc.apply(cases[1])
    member = ensemble_members(p, 1, st, start=4)[0]
    rtol = 1e-9                               # the batch's, a tenth of it while the balance misses 1e-9
    while True:
        row = KC.run_contacts(pack(member), KC.pack_laws(h_laws[1], t_law, 0.0, rtol), tab, xs, sc.t_from, sc.t_end,
                              p.max_events)[-1]
        if abs(row[KC.K_LEDGER]) <= 1e-9 * abs(row[KC.C_DRIVE]) or rtol <= 1.001e-12:
            break
        rtol /= 10
    assert np.array_equal(row, both[1].raw[4])


def test_members_grow_to_what_the_widest_interval_asks():
    """A half-width falls as 1/sqrt(n): at n members with the widest driving CI h (relative), the
    target r needs n (h / r)^2 members; the batch asks 20 % more, at least 1.25 n, in steps of 8, up
    to n_max; per-case settings hold each case to its own target."""
    from impact.compliant_engine import _members_wanted

    st = StatsSettings(rel_tol=0.03, n_start=16, n_max=1000)
    assert _members_wanted(16, 0.06, st) == 80           # 16 x 4 x 1.2 = 76.8 -> 80
    assert _members_wanted(64, 0.031, st) == 88          # 1.2 x 64 x 1.068 = 82.0 -> 88
    assert _members_wanted(64, 0.0301, st) == 80         # 77.3, at least 1.25 x 64 = 80
    assert _members_wanted(600, 0.06, st) == 1000        # capped
    assert _members_wanted(16, math.inf, st) == 32       # no estimate yet: double
    sc = Scenario("short device", 5.0, 0.005, 0.03)
    p = ImpactParams(m_free=0.004, freq=20e3)
    # the loose target just above what 4 members give (the chaotic members' spread is not known
    # beforehand), so that case is done at once while the tight one grows to its cap
    first = compliant_batch([p], _horn3(), **_laws(p), scenario=sc, settings=StatsSettings(n_start=4, n_max=4))[0]
    widest = max(first.estimates[q].rel_half_width for q in DRIVING)
    assert widest < 0.99
    loose, tight = (StatsSettings(rel_tol=r, n_start=4, n_max=12) for r in (min(1.0, 1.01 * widest), 1e-6))
    a, b = compliant_batch([p, p], _horn3(), **_laws(p), scenario=sc, settings=[loose, tight])
    assert (a.members, a.converged) == (4, True) and (b.members, b.converged) == (12, False)
    assert np.array_equal(a.raw, b.raw[:4])


def test_tool_only_contacts_reproduce_the_reference():
    """While only the tool's contact is closed the kernel integrates the free mass and the tool
    alone and moves the modes in closed form (``kernel_compliant.tool_only``); the Python
    reference integrates every state through every contact. Each tool contact of a run whose tool
    contacts never overlap a horn contact (so every one of them is such a stretch, entered from a
    flight and left into one): start and end times, speeds after and loss at the reproduction
    test's tolerances (derived there from the two engines' error control: 1e-10 s, 1e-7 m/s, the
    loss through d_max^2.5 at 1e-5), over the run's first four contacts (the chaotic motion
    amplifies a difference ~10x per contact, so later ones are not held to them)."""
    p = ImpactParams(m_free=0.008, t_end=0.0025)
    h = _horn3()
    a = simulate_compliant(p, h, **_laws(p), horn_residual=2e-9, rtol=1e-12, engine="python")
    b = simulate_compliant(p, h, **_laws(p), horn_residual=2e-9, rtol=1e-11)
    tool = [c for c in a.contacts if c.body == "tool"]
    horn = [c for c in a.contacts if c.body == "horn"]
    assert len(tool) >= 2
    assert not any(t.t_start < c.t_end and c.t_start < t.t_end for t in tool for c in horn)
    assert [c.body for c in b.contacts[:len(a.contacts)]] == [c.body for c in a.contacts]
    for ca, cb in zip(a.contacts, b.contacts):
        if ca.body != "tool":
            continue
        assert cb.t_start == pytest.approx(ca.t_start, abs=1e-10)
        assert cb.t_end == pytest.approx(ca.t_end, abs=1e-10)
        assert cb.tool_after == pytest.approx(ca.tool_after, abs=1e-7)
        assert cb.free_mass_after == pytest.approx(ca.free_mass_after, abs=1e-7)
        assert cb.loss == pytest.approx(ca.loss, rel=1e-5)


def test_drive_phase_turned_to_the_stages_is_the_library_cosine_and_sine():
    """A step's stages take the drive's phase turned from the step's start by the node's angle x
    (:func:`impact.kernel_compliant.turn`: x's cosine and sine by their Taylor series through
    x^13 for |x| <= 0.3, the library's beyond). Reference: the library's cos / sin (correct to
    within an ulp) of the turned angle, with phases and angles chosen as binary fractions so that
    their sum is exact. Tolerance: each library value is within an ulp (1.1e-16 on [-1, 1]), the
    series' truncation is below its first dropped term (x^14 / 14! < 6e-19 at 0.3), and the
    rotation adds four products and two sums, each rounded: a few units of 1.1e-16, asserted
    within 1e-15 (the series alone, at phase 0, within 2.3e-16)."""
    from impact import kernel_compliant as KC

    angles = (-0.3, -0.25, -2.0 ** -10, 0.0, 2.0 ** -30, 0.046875, 0.2998046875, 0.3, 0.3125, 2.0)
    for x in angles:
        c, s = KC.turn(1.0, 0.0, x)
        assert abs(c - math.cos(x)) <= 2.3e-16 and abs(s - math.sin(x)) <= 2.3e-16, x
    for phi in (1.0, 25000.3125, 27600.0):
        co, si = math.cos(phi), math.sin(phi)
        for x in angles[1:-3] + angles[-2:]:          # binary fractions: phi + x exact
            c, s = KC.turn(co, si, x)
            assert abs(c - math.cos(phi + x)) <= 1e-15 and abs(s - math.sin(phi + x)) <= 1e-15, (phi, x)
