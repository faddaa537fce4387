"""Impact model: analytic references, a second method (solve_ivp), properties, bad input, CLI."""

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from rpud_common import ParameterError
from impact.model import simulate
from impact.params import ImpactParams
from impact.reference import simulate_ivp


def ball(e, v0=1.0, t_end=1.0):
    """Fixed table: A0 = 0 horn, gravity toward it (g < 0), tool out of reach."""
    return ImpactParams(A0=0.0, e2=e, g=-9.81, v0=v0, gap=1.0, t_end=t_end, k0=1e3, c=0.0,
                        sample_dt=1e-4)


ENGINES = pytest.mark.parametrize("engine", ["kernel", "python"])


@ENGINES
def test_bouncing_ball_flight_times_heights_energy(engine, vv):
    e = 0.8
    r = simulate(ball(e, t_end=1.0), series=False, engine=engine)
    assert r.horn_impacts >= 8 and r.tool_impacts == 0
    t = np.concatenate([[0.0], r.t])
    flights = np.diff(t)[:8]
    if engine == "kernel":
        vv.record("VV-IM-01", title="Bouncing ball: first flight time", quantity="first flight time",
                  description="A free mass leaves a fixed table (horn amplitude A0 = 0) upward at "
                  "v0 = 1 m/s under gravity g = 9.81 m/s^2, restitution e = 0.8; the tool is out of reach. "
                  "The compiled event kernel's time of the first impact is compared with the closed form.",
                  reference="Ballistic flight: t = 2 v0 / g.",
                  assumptions="Rigid table, instantaneous Newton impacts, no air drag; event times found by "
                  "the kernel's root finder (round-off level).",
                  target=2 * 1.0 / 9.81, computed=flights[0], tolerance=1e-12, unit="s")
    # flight time 2 v / g exactly, shrinking by e; tolerance: root finding to ~1e-15 s
    np.testing.assert_allclose(flights[0], 2 * 1.0 / 9.81, rtol=1e-12)
    np.testing.assert_allclose(flights[1:] / flights[:-1], e, rtol=1e-9)
    heights = (np.concatenate([[1.0], r.w_after[:7]]) ** 2) / (2 * 9.81)
    np.testing.assert_allclose(heights[1:] / heights[:-1], e ** 2, rtol=1e-9)
    # energy lost per impact: (1 - e^2) of the kinetic energy relative to the table
    ke_b, ke_a = 0.5 * 0.008 * r.w_before[:8] ** 2, 0.5 * 0.008 * r.w_after[:8] ** 2
    np.testing.assert_allclose((ke_b - ke_a) / ke_b, 1 - e ** 2, rtol=1e-9)


@ENGINES
def test_bouncing_ball_chattering_terminates_by_sticking(engine, vv):
    e = 0.5
    r = simulate(ball(e, t_end=2.0), series=False, engine=engine)
    if engine == "kernel" and r.stick:
        vv.record("VV-IM-02", title="Bouncing ball: chattering accumulation time", quantity="time of sticking",
                  description="The ball of VV-IM-01 with e = 0.5 bounces ever lower until it sticks to "
                  "the table; the time at which the compiled kernel declares sticking is compared with the "
                  "accumulation point of the geometric series of flight times.",
                  reference="Sum of flights 2 v0 / g * (1 + e + e^2 + ...) = 2 v0 / (g (1 - e)).",
                  assumptions="The run sticks once the relative speed falls below v_stick = 1e-6 m/s, so the "
                  "flights it leaves out sum to less than 2 v_stick / (g (1 - e)) = 4e-7 s: tolerance 1e-5.",
                  target=2 * 1.0 / (9.81 * (1 - e)), computed=r.stick[0][0], tolerance=1e-5, unit="s")
    # relative speed falls by e per impact until below v_stick = 1e-6 m/s: ~log(1e-6)/log(0.5)
    assert r.horn_impacts <= math.ceil(math.log(1e-6) / math.log(e)) + 2
    assert len(r.stick) == 1 and r.stick[0][2] == "horn" and r.stick[0][1] == 2.0
    # accumulation point of the flights: 2 v0 / (g (1 - e)); the run sticks once a speed falls
    # below v_stick, so the flights it leaves out sum to < 2 v_stick / (g (1 - e)) = 4e-7 s, 1e-6
    # of it: rel 1e-5
    assert r.stick[0][0] == pytest.approx(2 * 1.0 / (9.81 * (1 - e)), rel=1e-5)


@ENGINES
def test_bouncing_ball_elastic_conserves_energy_1000_impacts(engine, vv):
    r = simulate(ball(1.0, v0=0.4, t_end=1000 * 2 * 0.4 / 9.81 + 0.01), series=False, engine=engine)
    assert r.horn_impacts >= 1000
    if engine == "kernel":
        worst = r.energy[:1000][np.argmax(np.abs(r.energy[:1000] - r.energy0))]
        vv.record("VV-IM-03", title="Elastic bouncing ball: energy over 1000 impacts",
                  quantity="mechanical energy after the worst of 1000 impacts",
                  description="The ball of VV-IM-01 with e = 1 and v0 = 0.4 m/s bounces 1000 times; the "
                  "mechanical energy after each impact must equal the initial one.",
                  reference="Conservation of energy for perfectly elastic impacts (e = 1).",
                  assumptions="Rigid table, no drag; the recorded value is the impact whose energy departs "
                  "most from the initial energy.",
                  target=r.energy0, computed=worst, tolerance=1e-12, unit="J")
    # mechanical energy after every impact equals the initial one to 1e-12 relative
    np.testing.assert_allclose(r.energy[:1000], r.energy0, rtol=1e-12, atol=0)


@ENGINES
def test_two_body_tool_impact_momentum_and_restitution(engine):
    p = ImpactParams()
    r = simulate(p, series=False, engine=engine)
    it = r.is_tool
    assert it.sum() > 10
    mom_b = p.m_free * r.w_before[it] + p.m_tool * r.v_before[it]
    mom_a = p.m_free * r.w_after[it] + p.m_tool * r.v_after[it]
    np.testing.assert_allclose(mom_a, mom_b, rtol=0, atol=1e-15)   # round-off of ~0.01 kg m/s
    np.testing.assert_allclose(r.w_after[it] - r.v_after[it], -p.e1 * (r.w_before[it] - r.v_before[it]),
                               rtol=1e-12, atol=1e-14)
    # kinetic energy lost = (1 - e^2) m1 m2 / (2 (m1 + m2)) (v1 - v2)^2
    ke = lambda w, v: 0.5 * p.m_free * w ** 2 + 0.5 * p.m_tool * v ** 2
    lost = ke(r.w_before[it], r.v_before[it]) - ke(r.w_after[it], r.v_after[it])
    ref = (1 - p.e1 ** 2) * p.m_free * p.m_tool / (2 * (p.m_free + p.m_tool)) * (r.w_before[it] - r.v_before[it]) ** 2
    np.testing.assert_allclose(lost, ref, rtol=1e-10)


IVP_KEYS = ("w_before", "w_after", "v_before", "v_after")
EPS = np.finfo(float).eps


def ivp_error_bounds(p, ref, n):
    """Error bounds of the first ``n`` events of ``simulate_ivp`` (``ref``), per event: ``"t"`` (s)
    and each of IVP_KEYS (m/s), as arrays, derived from the reference's own accuracy.

    * Its flights are exact to round-off: the free flight is a quadratic in t, which DOP853
      integrates exactly, and the tool's fastest rate times max_step (h = 2.5 us; |lambda| h is
      4.7e-3 at the default tool, 0.04 at 4x critical damping) leaves a truncation of order
      (|lambda| h)^9, far below rtol = 1e-12, so its step-size control never acts. Its event times
      are exact to scipy's root finder on the dense output: brentq with xtol = rtol = 4 eps, i.e.
      |dt| <= 4 eps (1 s + t).
    * The dynamics amplifies an event-time error at every later impact (chaotic: 10-300x per
      impact at these parameters). The growth from event j to event k is read off the reference
      itself, rerun with v0 larger by 1e-10 (its linear range: ~1e-14 s at the first event, <1e-8 s
      at the sixth): G_k = |change of the quantity at event k| / min_{j <= k} |change of t_j|.
    * Each of the n events adds its own error, and the engine under test makes one too (its Brent
      stops at 2e-16 + 8.9e-16 t s, within scipy's), so the two differ at event k by at most
      2 n 4 eps (1 s + t_k) G_k; a velocity the perturbation leaves unchanged (the tool at rest
      before its first impact) still carries the round-off of its closed form, 64 eps of itself.
    """
    q = simulate_ivp(p.with_(v0=p.v0 * (1 + 1e-10)), max_events=n)
    assert q["contact"] == ref["contact"]
    t = np.asarray(ref["t"])
    dt = np.abs(np.asarray(q["t"]) - t)
    first = np.minimum.accumulate(dt)
    assert first[-1] > 0
    scale = 2 * n * 4 * EPS * (1.0 + t) / first
    bounds = {"t": scale * dt}
    for key in IVP_KEYS:
        x = np.asarray(ref[key])
        bounds[key] = scale * np.abs(np.asarray(q[key]) - x) + 64 * EPS * np.abs(x)
    # the test keeps its teeth: every bound stays far below what a wrong impact law or a missed
    # contact changes (> 1e-2 m/s in a velocity, > 1e-6 s in a time)
    assert bounds["t"].max() < 1e-7 and max(bounds[k].max() for k in IVP_KEYS) < 1e-3, bounds
    return bounds


@pytest.mark.parametrize("changes", [{}, {"g": 0.0, "v0": 2.0}, {"horn_law": "article", "m_free": 0.004}])
@ENGINES
def test_cross_check_against_solve_ivp(changes, engine, vv):
    """The first 5 events against solve_ivp (DOP853), each within the reference's own error bound
    at that event (ivp_error_bounds: scipy's event-time tolerance grown by the chaotic impacts;
    from ~1e-14 s / 1e-10 m/s at the first event to ~1e-8 s / 3e-5 m/s at the fifth)."""
    p = ImpactParams(**changes)
    r = simulate(p, series=False, engine=engine)
    n = 5
    ref = simulate_ivp(p, max_events=n)
    assert list(r.contact[:n]) == ref["contact"]
    bounds = ivp_error_bounds(p, ref, n)
    if not changes and engine == "kernel":
        vv.record("VV-IM-04", title="Impact model against solve_ivp: time of the fifth event",
                  quantity="time of the fifth impact",
                  description="The article's impact case (default ImpactParams: sinusoidal horn, free "
                  "mass, spring-loaded tool) run by the compiled event kernel and by an independent "
                  "second method, scipy's solve_ivp (DOP853) with event location, over the first five "
                  "impacts; the same sequence of contacts is required and the time of the fifth is compared.",
                  reference="The same equations integrated by scipy.integrate.solve_ivp (DOP853, rtol 1e-12, "
                  "event root finding) in impact/reference.py.",
                  assumptions="The tolerance is the reference's own error bound at that event: scipy's "
                  "event-time tolerance grown by the chaotic amplification between impacts, measured by "
                  "rerunning the reference with v0 perturbed by 1e-10 (ivp_error_bounds).",
                  target=ref["t"][n - 1], computed=r.t[n - 1], tolerance=bounds["t"][n - 1],
                  tolerance_kind="absolute", unit="s")
    assert np.all(np.abs(r.t[:n] - ref["t"]) <= bounds["t"]), (r.t[:n] - ref["t"], bounds["t"])
    for key in IVP_KEYS:
        diff = np.abs(getattr(r, key)[:n] - ref[key])
        assert np.all(diff <= bounds[key]), (key, diff, bounds[key])


@settings(max_examples=25, deadline=None)
@given(m_free=st.floats(0.002, 0.01), A0=st.floats(5e-6, 25e-6), e1=st.floats(0.3, 1.0),
       e2=st.floats(0.3, 1.0), gap=st.floats(1.5e-3, 3e-3), v0=st.floats(0.5, 5.0),
       g=st.sampled_from([9.8, 0.0, -9.8]))
def test_properties(m_free, A0, e1, e2, gap, v0, g):
    p = ImpactParams(m_free=m_free, A0=A0, e1=e1, e2=e2, gap=gap, v0=v0, g=g, t_end=0.02)
    r = simulate(p)
    assert np.all(np.diff(r.t) > 0)
    # no interpenetration beyond 1e-12 m, on the output grid and at the events
    assert (r.w - r.u).min() >= -1e-12
    assert (r.tool_face - r.w).min() >= -1e-12
    # energy is never created except by the horn's work (tool damping only removes it)
    scale = max(r.energy0, 1e-6) + np.abs(r.horn_work).max(initial=0)
    assert np.all(r.energy - r.energy0 - r.horn_work <= 1e-9 * scale)


@pytest.mark.parametrize("field,value", [("m_free", -0.001), ("m_tool", 0.0), ("e1", 1.2), ("e2", -0.1),
                                         ("A0", -1e-6), ("freq", 0.0), ("t_end", 0.0), ("gap", 0.0),
                                         ("k0", -1.0), ("c", 2e6), ("v0", -1.0)])
def test_bad_input_names_the_field(field, value):
    with pytest.raises(ParameterError, match=rf"^{field} = "):
        ImpactParams(**{field: value})


@pytest.mark.parametrize("field,value,allowed", [
    ("m_free", 11.0, r"\[1e-06, 10\] kg"), ("m_free", 1e-320, r"\[1e-06, 10\] kg"), ("A0", 2e-3, r"\[0, 0.001\] m"), ("freq", 2e6, r"\[1, 1e\+06\] Hz"),
    ("m_horn", 101.0, r"\[1e-06, 100\] kg"), ("m_tool", math.inf, r"\[1e-06, 100\] kg"),
    ("k0", 1e11, r"\(0, 1e\+10\] N/m"), ("c", 2e6, r"\[0, 1e\+06\] N s/m"), ("c", -1.0, "N s/m"),
    ("gap", 2.0, r"\(0, 1\] m"), ("gap", 20e-6, r"2 A0"), ("g", -2e4, "m/s\\^2"), ("g", math.nan, "m/s"),
    ("v0", 101.0, r"\[0, 100\] m/s"), ("t_end", 101.0, r"\(0, 100\] s"),
    ("spring_force", 2e4, r"\[0, 10000\] N"), ("v_stick", 2.0, r"\(0, 1\] m/s"),
    ("sample_dt", 1e-10, r"\[1e-09, 0.01\] s"), ("max_events", 0, r"\[1, 1e8\]"),
    ("max_events", 2.5, "integer"), ("max_events", 10 ** 9, r"\[1, 1e8\]"), ("e1", math.nan, r"\[0, 1\]")])
def test_bad_input_out_of_physical_range(field, value, allowed):
    with pytest.raises(ParameterError, match=rf"^{field} = .*{allowed}"):
        ImpactParams(**{field: value})


def test_bad_input_combinations():
    # more than 2e7 output samples
    with pytest.raises(ParameterError, match=r"^sample_dt = .*2e7"):
        ImpactParams(t_end=100.0, sample_dt=1e-6)
    # the resting free mass would push a soft tool into the horn's stroke
    with pytest.raises(ParameterError, match=r"^gap = .*increase gap or k0"):
        ImpactParams(k0=10.0, m_free=1.0, gap=0.5)
    # critically and over-damped tools are accepted
    p = ImpactParams()
    assert ImpactParams(c=4 * 2 * math.sqrt(p.k0 * p.m_tool)).tool_zeta == pytest.approx(4.0)


def test_toml_round_trip_and_config(tmp_path):
    p = ImpactParams(m_free=0.005, horn_law="article")
    path = tmp_path / "p.toml"
    path.write_text(p.to_toml())
    assert ImpactParams.from_toml(path) == p
    path.write_text("m_fre = 1.0\n")
    with pytest.raises(ParameterError, match="m_fre"):
        ImpactParams.from_toml(path)
