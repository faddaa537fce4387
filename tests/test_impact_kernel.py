"""Compiled kernel vs the Python reference, damping regimes, article horn law, bounded time."""

import math
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from impact import event_rules, kernel, kernel_blocks
from impact import model
from impact.model import SimulationError, simulate, window_stats
from impact.oscillator import Oscillator as _Osc
from impact.params import ImpactParams
from impact.reference import simulate_ivp

from test_impact import ivp_error_bounds

EV_KEYS = ("w_before", "w_after", "v_before", "v_after")


def random_params(rng, t_end):
    """Broad ranges: masses, amplitudes, restitution, gaps, gravity, spring, stiffness and
    damping from 0 to 5x critical, both horn laws."""
    k0 = 10 ** rng.uniform(3, 6)
    c_crit = 2 * math.sqrt(k0 * 0.05)
    zeta = rng.choice([rng.uniform(0, 1), 1.0, rng.uniform(1, 5)])
    return ImpactParams(
        m_free=10 ** rng.uniform(-3, math.log10(2e-2)), A0=rng.uniform(0, 30e-6),
        e1=rng.uniform(0, 1), e2=rng.uniform(0, 1),
        gap=10 ** rng.uniform(math.log10(0.3e-3), math.log10(4e-3)), v0=rng.uniform(0, 6),
        g=float(rng.choice([-9.8, 0.0, 9.8])), spring_force=rng.uniform(0, 8), k0=k0,
        c=float(zeta * c_crit), horn_law=str(rng.choice(["kinematic", "article"])),
        t_end=t_end, max_events=300)


def run(p, engine):
    try:
        return simulate(p, series=False, engine=engine), None
    except SimulationError as exc:
        return None, str(exc)


EPS = np.finfo(float).eps
T_CAP, V_CAP = 1e-9, 1e-6
"""Largest error bound (s, m/s) at which an event is still compared: 1000x below what a wrong
impact law, restitution or missed contact changes (> 1e-6 s, > 1e-3 m/s)."""


def python_error_bounds(p, rp, n):
    """(bounds, k): per-event error bounds of the Python engine's first ``n`` events ``rp`` (``"t"``
    in s and EV_KEYS in m/s) and the number k of leading events it resolves within T_CAP / V_CAP.

    The engine is exact to round-off between events (closed forms) and locates each event by
    Brent's method to ``_XTOL + _RTOL |t|`` (s). An error in one event's time grows at every later
    impact (the random cases include chaotic ones: a change of 1 ulp in v0 moves the 20th event
    by up to 1e-6 s). The growth is read off the engine itself, rerun with v0 larger by 1e-10:
    G_k = |change at event k| / min_{j <= k} |change of t_j|. An event's own time error also
    enters its velocities directly, at most at the largest acceleration of the problem, B = the
    horn's A0 w^2 + the flight's |a| + the tool's (k0 gap + c |v'|) / m_tool, times (1 + e) <= 2
    (where impacts contract, as in chattering, this term dominates). Each event adds its own
    error and the compiled kernel makes the same kind, so two correct engines differ at event k
    by at most 2 n (_XTOL + _RTOL t_k) G_k in time, and 2 n (_XTOL + _RTOL t_k) (G_k + 2 B) plus
    64 eps of itself (the round-off of its closed form) in a velocity. The engines are written
    to return the same bits, but only these bounds are promised: a compiler or libm that rounds
    one operation differently must not fail the test."""
    rq, err = run(p.with_(v0=p.v0 * (1 + 1e-10)), "python")
    if rq is None:                     # the perturbed run fails: no growth to read, nothing resolved
        return {key: np.zeros(0) for key in ("t", *EV_KEYS)}, 0
    m = min(n, rq.t.size)
    t = rp.t[:m]
    dt = np.abs(rq.t[:m] - t)
    first = np.minimum.accumulate(dt)
    # an event the perturbation does not move gives no growth to divide by: not resolved
    scale = 2 * n * (event_rules.XTOL + event_rules.RTOL * np.abs(t)) / np.where(first > 0, first, np.nan)
    bounds = {"t": np.where(first > 0, scale * dt, np.inf)}
    ok = (np.asarray(rq.contact[:m]) == np.asarray(rp.contact[:m])) & (bounds["t"] <= T_CAP)
    v_tool = max(np.abs(rp.v_before[:m]).max(initial=0), np.abs(rp.v_after[:m]).max(initial=0))
    B = (p.A0 * (2 * math.pi * p.freq) ** 2 + abs(p.g - p.spring_force / p.m_free)
         + (p.k0 * p.gap + p.c * v_tool) / p.m_tool)
    for key in EV_KEYS:
        x = getattr(rp, key)[:m]
        dx = np.abs(getattr(rq, key)[:m] - x)
        bounds[key] = np.where(first > 0, scale * (dx + 2 * B * first), np.inf) + 64 * EPS * np.abs(x)
        ok &= bounds[key] <= V_CAP
    return bounds, int(np.cumprod(ok).sum())


def assert_same_events(rk, rp, bounds, k):
    """The first k events of the kernel (rk) against the Python engine (rp), within ``bounds``;
    and the sticking phases that end before the last of them."""
    assert rk.t.size >= k
    assert list(rk.contact[:k]) == list(rp.contact[:k])
    assert np.all(np.abs(rk.t[:k] - rp.t[:k]) <= bounds["t"][:k]), (rk.t[:k] - rp.t[:k], bounds["t"][:k])
    for key in EV_KEYS:
        diff = np.abs(getattr(rk, key)[:k] - getattr(rp, key)[:k])
        assert np.all(diff <= bounds[key][:k]), (key, diff, bounds[key][:k])
    if k:
        sticks = [s for s in rp.stick if s[1] <= rp.t[k - 1]]
        assert [s[2] for s in rk.stick[:len(sticks)]] == [s[2] for s in sticks]
        if sticks:
            np.testing.assert_allclose(np.array([s[:2] for s in rk.stick[:len(sticks)]]),
                                       np.array([s[:2] for s in sticks]), rtol=0, atol=bounds["t"][:k].max())


def test_constants_agree():
    for name in ("CONTACT_TOL", "H_MIN"):
        assert getattr(kernel_blocks, name) == getattr(event_rules, name), name
    assert model.CONTACT_TOL == event_rules.CONTACT_TOL
    for name in ("FREE", "ON_HORN", "ON_TOOL",
                 "N_STATS", "S_N_TOOL", "S_N_HORN", "S_KE_AFTER", "S_KE_GAIN", "S_HORN_WORK",
                 "S_T_ON_HORN", "S_T_ON_TOOL", "S_STATUS", "S_N_EVENTS"):
        assert getattr(kernel, name) == getattr(model, name), name


def test_pack_layout():
    p = ImpactParams(horn_law="article", m_free=0.006, max_events=1234)
    v = kernel.pack(p)
    assert v.shape == (kernel.N_PARAMS,) and v.dtype == np.float64
    assert v[kernel.P_M_FREE] == 0.006 and v[kernel.P_HORN_LAW] == kernel.HORN_LAW_ARTICLE
    assert v[kernel.P_MAX_EVENTS] == 1234 and v[kernel.P_T_END] == p.t_end
    assert kernel.pack(ImpactParams())[kernel.P_HORN_LAW] == kernel.HORN_LAW_KINEMATIC


def test_kernel_equals_python_event_by_event():
    """First 20 events of 240 random cases: the same kinds, times and velocities within the
    Python engine's own error bound at each event (python_error_bounds), as far as that bound
    stays below T_CAP = 1e-9 s and V_CAP = 1e-6 m/s (the chaotic cases resolve fewer events to
    that: about two thirds of all events are compared)."""
    rng = np.random.default_rng(20240611)
    compared, events, total = 0, 0, 0
    for _ in range(240):
        p = None
        while p is None:
            try:
                p = random_params(rng, t_end=float(rng.uniform(2e-3, 6e-3)))
            except ValueError:     # a rare invalid draw (gap within the static deflection)
                p = None
        rk, ek = run(p, "kernel")
        rp, ep = run(p, "python")
        assert ek == ep, p
        if rp is None:
            continue
        n = min(20, rp.t.size)
        bounds, k = python_error_bounds(p, rp, n)
        assert_same_events(rk, rp, bounds, k)
        compared += 1
        events += k
        total += n
    assert compared >= 200 and events >= total / 2, (compared, events, total)


def test_run_events_status_and_growth():
    p = ImpactParams(A0=0.0, e2=1.0, g=-9.81, v0=0.01, gap=1.0, k0=1e3, c=0.0, t_end=3.0)
    out = kernel.run_events(kernel.pack(p), p.t_end, 3000)
    # ~1,470 flights of 2 ms with room for 3,000 events: storage grew past 1024
    assert out[19] == kernel.STATUS_OK and out[0].size == out[21] > 1024
    assert out[1].dtype == np.int8 and np.all(out[1] == kernel.KIND_HORN)
    out = kernel.run_events(kernel.pack(p), p.t_end, 50)
    assert out[19] == kernel.STATUS_MAX_EVENTS and out[0].size == 50
    assert out[20] == pytest.approx(51 * 2 * 0.01 / 9.81, rel=1e-9)


def pinching():
    # a short gap (found by fuzzing): the tool swings back into the horn's stroke at 5.7 ms
    return ImpactParams(m_free=0.012341698363316349, A0=1.2276625558599345e-05,
                        gap=0.00036900692503698864, v0=2.352220363695055, g=0.0,
                        spring_force=1.1504131848910493, k0=596833.1537469635, c=19.108821204057907,
                        e1=0.8743490740124116, e2=0.98205877036022, t_end=0.02)


@pytest.mark.parametrize("engine", ["kernel", "python"])
def test_pinch_and_max_events_messages(engine):
    with pytest.raises(SimulationError, match="increase gap or k0"):
        simulate(pinching(), engine=engine)
    with pytest.raises(SimulationError, match=r"more than max_events = 5 events by t = "):
        simulate(ImpactParams(max_events=5), engine=engine)


def test_ensemble_stats_equal_window_stats():
    """The parallel ensemble's statistics equal window_stats of the same runs. The reference runs
    the same compiled event code (kernel._core, engine="kernel"), so its events are the same
    bits on this machine; a Python-engine run would not do here: over a 16 ms window a change of
    1 ulp in v0 moves these statistics by up to 84 % (chaos), far beyond its round-off. The
    columns then differ only in summation order: at most ~N eps of the sum of |terms| for N <= 100
    terms, i.e. < 1e-13 of it; rtol 1e-9 leaves room for a sum 1e4 times smaller than its terms
    (KE gain: gains and losses cancel), atol 1e-15 J / s for a column that sums to zero."""
    base = ImpactParams(t_end=0.02, gap=2.0e-3)   # the gap at which these members exercise every column
    members = [base, base.with_(v0=2.0, m_free=0.004), base.with_(A0=8e-6, horn_law="article", e2=0.05),
               # chattering into a stick on the horn; a plastic tool impact that sticks
               base.with_(spring_force=5.0, v0=2.0, e2=0.3),
               base.with_(A0=0.0, g=9.8, e1=0.0, v0=0.3, c=200.0),
               base.with_(c=3 * 2 * math.sqrt(base.k0 * base.m_tool))]
    pmat = np.array([kernel.pack(p) for p in members] + [kernel.pack(pinching().with_(t_end=0.02))])
    t_from, t_end = 4e-3, 0.02
    out = kernel.ensemble_stats(pmat, t_from, t_end, 100_000)
    assert out.shape == (len(members) + 1, kernel.N_STATS)
    assert out[-1, kernel.S_STATUS] == kernel.STATUS_PINCHED       # and the others ran on
    seen = np.zeros(kernel.N_STATS, bool)
    for i, p in enumerate(members):
        ref = window_stats(simulate(p, series=False, engine="kernel"), t_from, t_end)
        np.testing.assert_allclose(out[i], ref, rtol=1e-9, atol=1e-15)
        seen |= ref != 0
    # the cases exercise every column but the status
    assert seen[[kernel.S_N_TOOL, kernel.S_N_HORN, kernel.S_KE_AFTER, kernel.S_KE_GAIN, kernel.S_HORN_WORK,
                 kernel.S_T_ON_HORN, kernel.S_T_ON_TOOL, kernel.S_N_EVENTS]].all()


def test_window_stats_whole_run_matches_result():
    r = simulate(ImpactParams(t_end=0.02), series=False)
    s = window_stats(r, 0.0, 0.02)
    assert s[model.S_N_TOOL] == r.tool_impacts and s[model.S_N_HORN] == r.horn_impacts
    assert s[model.S_KE_AFTER] == pytest.approx(r.tool_ke_after.sum(), rel=1e-12)
    assert s[model.S_HORN_WORK] == pytest.approx(r.horn_work[-1], rel=1e-12)


# ----------------------------------------------------------------------------- damping regimes

ZETAS = [0.3, 0.999999, 1.0, 1.000001, 1.5, 4.0]


@pytest.mark.parametrize("zeta", ZETAS)
def test_oscillator_closed_form_and_bounds(zeta):
    m, k = 0.05, 1.8e5
    wn = math.sqrt(k / m)
    c = zeta * 2 * math.sqrt(k * m)
    rng = np.random.default_rng(3)
    s = np.linspace(0, 30 / wn, 20001)
    for _ in range(20):
        x0, xd0 = rng.normal(0, 1e-4), rng.normal(0, 1.0)
        o = _Osc(m, k, c, 1e-5, x0 + 1e-5, xd0)
        y, yd = o.pv_vec(s)
        y = y - 1e-5
        # exact free decay in the textbook form of each regime
        al = c / (2 * m)
        if zeta < 1:
            be = math.sqrt(wn ** 2 - al ** 2)
            ref = np.exp(-al * s) * (x0 * np.cos(be * s) + (xd0 + al * x0) / be * np.sin(be * s))
        elif zeta == 1:
            ref = np.exp(-wn * s) * (x0 + (xd0 + wn * x0) * s)
        else:
            gm = math.sqrt(al ** 2 - wn ** 2)
            l1, l2 = -al + gm, -al - gm
            ref = ((xd0 - l2 * x0) * np.exp(l1 * s) - (xd0 - l1 * x0) * np.exp(l2 * s)) / (l1 - l2)
        scale = abs(x0) + abs(xd0) / wn
        # near-critical textbook forms cancel: compare to their own round-off
        tol = 1e-12 if abs(zeta - 1) > 1e-3 else 1e-6
        np.testing.assert_allclose(y, ref, rtol=0, atol=tol * scale)
        # derivatives satisfy the equation of motion; bounds hold for s >= 0
        acc, jerk = o.acc_jerk_vec(s)
        np.testing.assert_allclose(m * acc + c * yd + k * y, 0, atol=1e-9 * k * scale)
        y4 = -(c * jerk + k * acc) / m
        assert np.abs(y).max() <= o.b0 * (1 + 1e-12)
        assert np.abs(acc).max() <= o.b2 * (1 + 1e-12)
        assert np.abs(y4).max() <= o.b4 * (1 + 1e-12)
        # the kernel's closed form is the same: equal to the round-off of evaluating it,
        # exp/cos/sin within 1 ulp (numba's and CPython's libm calls need not agree to the bit)
        # and four more roundings, 8 eps of |delta| + |P| + |Q|; the bounds are a dozen more
        # roundings (recursion, sqrt, products, min) of the same coefficients: 1e-12 relative
        # still covers a cancellation by 1e3 among them
        ok = np.empty(kernel_blocks.O_N)
        kernel_blocks.osc_make(ok, m, k, c, 1e-5, x0 + 1e-5, xd0)
        tol_pos = 8 * np.finfo(float).eps * (1e-5 + abs(o.P[0]) + abs(o.Q[0]))
        tol_vel = 8 * np.finfo(float).eps * (abs(o.P[1]) + abs(o.Q[1]))
        for si in s[::997]:
            (yk, vk), (yp, vp) = kernel_blocks.osc_pv(ok, si), o.pv(si)
            assert abs(yk - yp) <= tol_pos and abs(vk - vp) <= tol_vel, (si, yk - yp, vk - vp)
        np.testing.assert_allclose([ok[kernel_blocks.O_B0], ok[kernel_blocks.O_B2], ok[kernel_blocks.O_B4]], [o.b0, o.b2, o.b4],
                                   rtol=1e-12, atol=0)


@pytest.mark.parametrize("engine", ["kernel", "python"])
@pytest.mark.parametrize("zeta", [1.0, 1.5, 4.0])
def test_overdamped_tool_against_solve_ivp(engine, zeta):
    """The first 6 events against solve_ivp, each within the reference's own error bound at that
    event (tests/test_impact.py, ivp_error_bounds: scipy's event-time tolerance grown by the
    impacts; at most ~1e-9 s and 2e-4 m/s by the sixth event here)."""
    p0 = ImpactParams(gap=2.0e-3)
    p = p0.with_(c=zeta * 2 * math.sqrt(p0.k0 * p0.m_tool), t_end=0.02)
    r = simulate(p, series=False, engine=engine)
    n = 6
    assert r.tool_impacts >= 2 and r.t.size >= n
    ref = simulate_ivp(p, max_events=n)
    assert list(r.contact[:n]) == ref["contact"]
    bounds = ivp_error_bounds(p, ref, n)
    assert np.all(np.abs(r.t[:n] - ref["t"]) <= bounds["t"]), (r.t[:n] - ref["t"], bounds["t"])
    for key in EV_KEYS:
        diff = np.abs(getattr(r, key)[:n] - ref[key])
        assert np.all(diff <= bounds[key]), (key, diff, bounds[key])


# ----------------------------------------------------------------------------- article horn law


@pytest.mark.parametrize("engine", ["kernel", "python"])
@pytest.mark.parametrize("e2", [0.01, 0.05, 0.13])
def test_article_horn_law_small_e2_never_interpenetrates(engine, e2):
    # e2 < m_free / m_horn: eq. 21 alone would leave the mass approaching the horn
    p = ImpactParams(horn_law="article", e2=e2, t_end=0.02, v0=2.0, m_free=0.02, spring_force=5.0)
    r = simulate(p, engine=engine)
    assert (r.w - r.u).min() >= -1e-12
    assert (r.tool_face - r.w).min() >= -1e-12
    horn = ~r.is_tool
    assert horn.sum() > 3
    ud = -p.A0 * p.omega * np.sin(p.omega * r.t[horn])
    # the law never leaves the mass approaching the horn; the plastic closure is exercised
    assert np.all(r.w_after[horn] - ud >= -1e-12)
    raw = r.w_before[horn] - p.m_horn / (p.m_horn + p.m_free) * (1 + e2) * (r.w_before[horn] - ud)
    assert np.any(raw < ud)
    # energy gained only through the horn's work
    scale = max(r.energy0, 1e-6) + np.abs(r.horn_work).max()
    assert np.all(r.energy - r.energy0 - r.horn_work <= 1e-9 * scale)


# ----------------------------------------------------------------------------- bounded time


@pytest.fixture(scope="module")
def compiled():
    simulate(ImpactParams(t_end=1e-3), series=False)


@settings(max_examples=30, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.filter_too_much])
@given(m_free=st.floats(1e-3, 2e-2), A0=st.floats(0.0, 30e-6), e1=st.floats(0.0, 1.0),
       e2=st.floats(0.0, 1.0), gap=st.floats(0.3e-3, 1.5e-3), v0=st.floats(0.0, 6.0),
       g=st.sampled_from([-9.8, 0.0, 9.8]), spring=st.floats(0.0, 10.0), k0=st.floats(1e3, 1e6),
       zeta=st.sampled_from([0.05, 0.5, 0.95, 1.0, 2.0, 5.0]),
       law=st.sampled_from(["kinematic", "article"]))
def test_hard_regimes_finish_in_bounded_time(compiled, m_free, A0, e1, e2, gap, v0, g, spring, k0,
                                             zeta, law):
    """Small gaps, heavy and over-critical damping, restoring spring, negative g: chattering
    and sticking regimes. Each 20 ms case finishes within 2 s, with no interpenetration."""
    try:
        p = ImpactParams(m_free=m_free, A0=A0, e1=e1, e2=e2, gap=gap, v0=v0, g=g, spring_force=spring,
                         k0=k0, c=zeta * 2 * math.sqrt(k0 * 0.05), horn_law=law, t_end=0.02)
    except ValueError:
        return
    t0 = time.perf_counter()
    try:
        r = simulate(p, engine="kernel")
    except SimulationError as exc:
        assert "increase gap or k0" in str(exc)
        return
    assert time.perf_counter() - t0 < 2.0
    assert (r.w - r.u).min() >= -1e-12
    assert (r.tool_face - r.w).min() >= -1e-12


def test_numba_caches_are_dropped_when_a_compiled_source_changes(tmp_path):
    """numba checks only a cached function's own file; kernel_cache drops every cache of the
    package when any compiled source (a building block the loops inline) changed."""
    from impact import kernel_cache

    (tmp_path / "a.nbi").write_text("")
    assert kernel_cache.drop_stale(tmp_path) is True          # no stamp yet: dropped
    assert not (tmp_path / "a.nbi").exists()
    (tmp_path / "b.nbc").write_text("")
    assert kernel_cache.drop_stale(tmp_path) is False         # the same sources: kept
    assert (tmp_path / "b.nbc").exists()
    (tmp_path / "compiled-sources.sha256").write_text("the hash of other sources")
    assert kernel_cache.drop_stale(tmp_path) is True
    assert not (tmp_path / "b.nbc").exists()
