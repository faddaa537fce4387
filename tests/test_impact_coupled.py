"""The coupled model (modal horn in the impact loop) against independent references.

References and tolerances:
- compiled kernel = Python reference engine, seeded random cases: event kinds identical, times
  1e-12 s, velocities and modal states 1e-9 relative;
- superposition: a linear horn hit by impulses J_k at t_k moves as its impact-free response plus
  sum_k (-s J_k / m) e^{-zeta w tau} sin(w_d tau) / w_d (textbook form, written here): 1e-10 relative;
- energy balance over 0.1 s: drive work = damping loss + stored change + work on the free mass,
  to 1e-6 of the drive work (and the compiled window integrals = the numpy ones, 1e-9);
- compliant (Hunt-Crossley) contacts, compiled vs the DOP853 reference: each event's values to the
  contact integration's accuracy times that value's condition number (see ``_hc_tolerances``);
- very stiff, lossless, heavy horn: the kinematic model's first 5 impacts within 1e-9 s;
- no impacts: the FE-reduced horn's tip = the direct harmonic working point (amplitude and phase
  0.5 %), and = fem.transient.ring_up (modal Newmark, 8 modes) within 1 % of the peak over 20 cycles;
- bad input: ParameterError naming the field.
"""

import math

import numpy as np
import pytest

from rpud_common import ParameterError
from impact.coupled import simulate_coupled
from impact.horn import ModalHorn
from impact.model import simulate
from impact.params import ImpactParams
from geometry.examples import article_design

F = 20e3
W = 2 * math.pi * F


def _horn(n=1, start="rest", A=15e-6, tip_mass=0.1, zeta=0.005, f1=20.3e3, seed=None):
    """A horn whose first mode sits near the drive and gives a steady tip amplitude A."""
    rng = np.random.default_rng(seed) if seed is not None else None
    om = 2 * np.pi * np.array([f1, 35e3, 52e3, 61e3, 70e3, 81e3, 90e3, 99e3])[:n]
    s = np.array([1 / math.sqrt(tip_mass)] + [0.3] * (n - 1))[:n]
    z = np.full(n, zeta)
    cre = np.array([0.0] + [20.0] * (n - 1))[:n]
    if rng is not None:
        s[1:] *= rng.uniform(-2, 2, n - 1)
        z = z * rng.uniform(0.2, 5, n)
        cre[1:] *= rng.uniform(-1, 1, n - 1)
    cre[0] = A / s[0] * abs(om[0] ** 2 - W ** 2 + 2j * z[0] * om[0] * W) / 225.0
    return ModalHorn(om, z, np.ones(n), s, cre, 0.1 * cre, 225.0, residual_re=2e-10, residual_im=-1e-11,
                     start=start)


HC_EPS = 1e-8
"""Relative accuracy of one compliant contact as the compiled engine integrates it: Dormand-Prince
5(4) with a local error test at rtol 1e-10 takes steps h ~ tc rtol^(1/5) = tc / 100, so about 100
steps per contact whose local errors add up to at most 100 x 1e-10. The DOP853 reference (rtol
1e-11) contributes a tenth of that."""


def _hc_tolerances(p, horn, contact, k, delta=1e-7):
    """Allowed kernel-reference differences of the first k events' time, outgoing free-mass speed
    and cumulative horn work (s, m/s, J).

    A contact integrated to relative accuracy ``HC_EPS`` leaves the free mass's state wrong by that
    fraction; the events after it inherit the error amplified by the flight and the drive's phase
    (an event-time error dt moves the next contact's work by about its tip acceleration times dt).
    That amplification is the condition number of each event value with respect to a relative
    change of the launch state, obtained here from a run whose launch speed is changed by
    ``delta`` (1e-7: far above round-off, small enough for the response to stay linear). Each
    tolerance is ``HC_EPS`` times (the value's scale + its sensitivity).
    """
    from impact import kernel_modal as KM

    ev = KM.run_events(p, horn, contact)[0]
    evd = KM.run_events(p.with_(v0=p.v0 * (1.0 + delta)), horn, contact)[0]
    assert len(ev) >= k and len(evd) >= k
    cols = {"t": 0, "w_after": 3, "horn_work": 7}
    tol = {}
    for name, c in cols.items():
        scale = np.abs(ev[:k, c]).max() if name != "t" else 0.0
        sens = np.abs(evd[:k, c] - ev[:k, c]) / delta
        tol[name] = HC_EPS * (scale + sens)
    tol["t"] = np.maximum(tol["t"], 1e-15)   # Brent's event-time resolution
    return tol


@pytest.mark.parametrize("case", range(12))
def test_kernel_equals_python_engine(case):
    rng = np.random.default_rng(1000 + case)
    n = int(rng.integers(1, 9))
    horn = _horn(n, ("rest", "steady")[case % 2], A=rng.uniform(5e-6, 25e-6), tip_mass=rng.uniform(0.03, 1.0),
                 seed=case)
    p = ImpactParams(m_free=rng.uniform(0.001, 0.01), e1=rng.uniform(0.3, 1), e2=rng.uniform(0.3, 1),
                     c=rng.uniform(0, 100), spring_force=rng.choice([0.0, 5.0]), v0=rng.uniform(1, 5), t_end=0.02,
                     g=rng.uniform(-10, 10))
    rp = simulate_coupled(p, horn, engine="python", series=False)
    rk = simulate_coupled(p, horn, engine="kernel", series=False)
    k = min(20, rp.impact.t.size)
    assert rk.impact.t.size >= k and k >= 3
    assert list(rk.impact.contact[:k]) == list(rp.impact.contact[:k])
    np.testing.assert_allclose(rk.impact.t[:k], rp.impact.t[:k], rtol=0, atol=1e-12)
    for name in ("w_after", "v_after"):
        a, b = getattr(rk.impact, name)[:k], getattr(rp.impact, name)[:k]
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9 * np.max(np.abs(b)))
    np.testing.assert_allclose(rk.seg_qd[:k], rp.seg_qd[:k], rtol=1e-9, atol=1e-9 * np.max(np.abs(rp.seg_qd[:k])))


@pytest.mark.parametrize("n", [1, 3])
def test_modal_motion_is_free_response_plus_impulse_responses(n):
    """Linear horn: the response to the drive (from rest) plus one damped impulse response per
    horn impact, at the impact's time and with its impulse (textbook SDOF form)."""
    horn = _horn(n, "rest", seed=7)
    p = ImpactParams(m_free=0.008, spring_force=5.0, t_end=0.03)
    res = simulate_coupled(p, horn, engine="kernel", series=False)
    hi = ~res.impact.is_tool
    tk, Jk = res.impact.t[hi], res.impulse[hi]
    assert tk.size >= 5
    # drive response from rest, textbook: steady part + homogeneous part fixed by q(0) = q'(0) = 0
    om, ze, m, s = horn.omega, horn.zeta, horn.modal_mass, horn.tip
    wd = om * np.sqrt(1 - ze ** 2)
    fc, fs = horn.voltage * horn.coupling_im, horn.voltage * horn.coupling_re
    den = (om ** 2 - W ** 2) ** 2 + (2 * ze * om * W) ** 2
    # q_p = A cos + B sin solving q'' + 2 ze om q' + om^2 q = (fc cos + fs sin) / m
    A = ((om ** 2 - W ** 2) * fc - 2 * ze * om * W * fs) / den / m
    B = ((om ** 2 - W ** 2) * fs + 2 * ze * om * W * fc) / den / m
    c1 = -A
    c2 = (-W * B + ze * om * c1) / wd          # q'(0) = 0

    def q_ref(t):
        q = A * np.cos(W * t) + B * np.sin(W * t) + np.exp(-ze * om * t) * (c1 * np.cos(wd * t) + c2 * np.sin(wd * t))
        for tj, Jj in zip(tk, Jk):
            if t > tj:
                tau = t - tj
                q = q + (-s * Jj / m) * np.exp(-ze * om * tau) * np.sin(wd * tau) / wd
        return q

    ref = np.array([q_ref(t) for t in res.seg_t0])
    scale = np.max(np.abs(ref), axis=0)
    assert np.max(np.abs(res.seg_q - ref) / scale) <= 1e-10


def test_energy_balance_closes_over_0p1_s():
    horn = _horn(3, "rest", seed=3)
    p = ImpactParams(m_free=0.008, spring_force=5.0, t_end=0.1)
    res = simulate_coupled(p, horn, engine="kernel", series=False)
    rows = res.energy_balance([0.0, 0.02, 0.05, 0.1])
    drive = sum(r["drive_j"] for r in rows)
    resid = sum(r["residual_j"] for r in rows)
    assert drive > 0 and res.impact.horn_impacts > 20
    assert abs(resid) <= 1e-6 * drive
    for r in rows:
        assert abs(r["residual_j"]) <= 1e-6 * r["drive_j"]
        assert r["damping_j"] > 0 and r["to_free_mass_j"] > 0 and r["restitution_horn_j"] >= 0
    # the compiled window integrals (whole run) agree with the numpy closed forms
    win = res.extra["window"]
    from impact.kernel_modal import C_DAMP, C_DRIVE
    whole = res.energy_balance([0.0, 0.1])[0]
    assert win[C_DRIVE] == pytest.approx(whole["drive_j"], rel=1e-9)
    assert win[C_DAMP] == pytest.approx(whole["damping_j"], rel=1e-9)
    # and the numpy closed forms agree with a plain quadrature of the sampled integrand (1e-5)
    t = np.linspace(0.0, 0.01, 400_001)
    from impact.coupled_result import states_on as _states_on
    q, qd, _ = _states_on(res, t)
    fc, fs = horn.forcing()
    f = np.outer(np.cos(W * t), fc) + np.outer(np.sin(W * t), fs)
    quad = np.trapezoid(np.sum(f * qd, axis=1), t)
    assert res.energy_balance([0.0, 0.01])[0]["drive_j"] == pytest.approx(quad, rel=1e-5)


def test_stiff_lossless_heavy_horn_reproduces_the_kinematic_events():
    A0 = 15e-6
    m, om = 1e12, 2 * np.pi * 1e6
    fc = A0 * m * (om ** 2 - W ** 2)         # steady q = A0 cos(W t), tip participation 1
    horn = ModalHorn([om], [0.0], [m], [1.0], [0.0], [fc / 100.0], 100.0, start="steady")
    for sf in (0.0, 5.0):
        p = ImpactParams(A0=A0, freq=F, t_end=0.01, spring_force=sf)
        kin = simulate(p, series=False)
        cop = simulate_coupled(p, horn, series=False).impact
        assert kin.t.size >= 5
        assert list(cop.contact[:5]) == list(kin.contact[:5])
        np.testing.assert_allclose(cop.t[:5], kin.t[:5], rtol=0, atol=1e-9)
        np.testing.assert_allclose(cop.w_after[:5], kin.w_after[:5], rtol=1e-6)


def test_bad_horn_and_params_are_clear_errors():
    ok = dict(omega=[1e5], zeta=[0.01], modal_mass=[1.0], tip=[1.0], coupling_re=[1.0], coupling_im=[0.0],
              voltage=10.0)
    with pytest.raises(ParameterError, match="zeta"):
        ModalHorn(**{**ok, "zeta": [1.5]})
    with pytest.raises(ParameterError, match="omega"):
        ModalHorn(**{**ok, "omega": [-1.0]})
    with pytest.raises(ParameterError, match="tip"):
        ModalHorn(**{**ok, "tip": [0.0]})
    with pytest.raises(ParameterError, match="coupling_re"):
        ModalHorn(**{**ok, "coupling_re": [1.0, 2.0]})
    with pytest.raises(ParameterError, match="start"):
        ModalHorn(**{**ok, "start": "hot"})
    with pytest.raises(ParameterError, match="voltage"):
        ModalHorn(**{**ok, "voltage": -1.0})
    with pytest.raises(ParameterError, match="horn_law"):
        simulate_coupled(ImpactParams(horn_law="article"), ModalHorn(**ok))
    h = ModalHorn(**ok)
    assert ModalHorn.from_dict(h.to_dict()).tip_mass == h.tip_mass


# ----------------------------------------------------------------------------- with the FE model


@pytest.fixture(scope="module")
def fe():
    from fem.assembly import assemble
    from fem.harmonic import LossModel, modal_basis
    from fem.modal import modal_analysis
    from test_fem_harmonic import _stack

    system = assemble(_stack())
    modes = modal_analysis(system, 70e3, 8, open_circuit=False)
    f_r = float(modes.f_r_hz[int(np.argmax(modes.shares[:, 0]))])
    loss = LossModel(100.0, 0.004)
    basis = modal_basis(system, f_r, 8, loss=loss, modes=modes)
    return system, f_r, loss, basis


def _quiet_params(freq, t_end):
    # the free mass flies away from the tip and never reaches the tool: no impacts
    return ImpactParams(freq=freq, v0=2.0, g=0.0, gap=0.5, t_end=t_end, sample_dt=1.0 / (400 * freq), A0=0.0)


def test_no_impacts_tip_equals_the_harmonic_working_point(fe):
    from fem.harmonic import working_point
    from fem.reduced import reduce_transducer
    from results.coupled import horn_from_reduced

    system, f_r, loss, basis = fe
    for ratio in (0.998, 1.0):
        f = ratio * f_r
        red = reduce_transducer(system, basis, f, tip_surface="electrode_4")
        horn = horn_from_reduced(red, 2.0, start="steady")
        res = simulate_coupled(_quiet_params(f, 20 / f), horn, series=True)
        assert res.impact.t.size == 0
        direct = working_point(system, f, 2.0, loss=loss, surfaces=("electrode_4",)).surfaces["electrode_4"]["axial"]
        Z = res._fundamental(0.0, 20 / f) * 2 / (20 / f)       # u = Re(Z e^{jWt})
        expect = -1j * direct                                   # drive V sin = Re(-j V e^{jWt})
        assert abs(Z) == pytest.approx(abs(expect), rel=5e-3)
        assert abs(np.angle(Z / expect)) <= 5e-3
        # the sampled series carries the same sine
        A = np.column_stack([np.cos(2 * np.pi * f * res.t_grid), np.sin(2 * np.pi * f * res.t_grid)])
        coef = np.linalg.lstsq(A, res.u, rcond=None)[0]
        assert complex(coef[0], -coef[1]) == pytest.approx(expect, rel=5e-3)
        # the power drawn (mean V I over 20 cycles, sampled current) equals the direct harmonic input power
        P, _ = res.drive_power(0.0, 20 / f)
        direct_p = working_point(system, f, 2.0, loss=loss, surfaces=("electrode_4",)).power_w
        assert P == pytest.approx(direct_p, rel=1e-3)


def test_no_impacts_ring_up_equals_fem_ring_up(fe):
    from fem.reduced import reduce_transducer
    from fem.transient import ring_up
    from results.coupled import horn_from_reduced

    system, f_r, loss, basis = fe
    red = reduce_transducer(system, basis, f_r, tip_surface="electrode_4")
    horn = horn_from_reduced(red, 1.0, start="rest")
    t_end = 20 / f_r
    res = simulate_coupled(_quiet_params(f_r, t_end), horn, series=True)
    ref = ring_up(system, f_r, 1.0, t_end, loss=loss, basis=basis, surfaces=("electrode_4",), steps_per_cycle=400)
    y_ref = ref.surfaces["electrode_4"]["axial"]
    y = np.interp(ref.t, res.t_grid, res.u)
    assert np.max(np.abs(y - y_ref)) <= 1e-2 * np.max(np.abs(y_ref))


def test_riding_the_horn_matches_between_engines_and_keeps_the_modal_balance():
    """A spring-loaded free mass on a horn ringing up from rest chatters into a ride on the tip
    (the approximation of impact.coupled): both engines agree, the modal balance still closes."""
    horn = _horn(2, "rest", seed=1)
    p = ImpactParams(m_free=0.008, spring_force=5.0, v0=0.0, t_end=0.004)
    rk = simulate_coupled(p, horn, engine="kernel", series=True)
    rp = simulate_coupled(p, horn, engine="python", series=False)
    rides = [s for s in rk.impact.stick if s[2] == "horn"]
    assert rides and rk.impact.stick == rp.impact.stick
    np.testing.assert_allclose(rk.impact.t, rp.impact.t, rtol=0, atol=1e-12)
    row = rk.energy_balance([0.0, p.t_end])[0]
    assert abs(row["residual_j"]) <= 1e-6 * row["drive_j"]
    # riding: the free mass is on the tip, and leaves it where u'' = a
    s0, s1, _ = rides[0]
    k = (rk.t_grid > s0) & (rk.t_grid < s1)
    np.testing.assert_array_equal(rk.impact.w[k], rk.u[k])


@pytest.mark.parametrize("args, name", [(["--voltage", "-1"], "--voltage"), (["--modes", "0"], "--modes"),
                                        (["--history", "0"], "--history"), (["--horn-law", "article"], "--horn-law"),
                                        (["--freq", "nan"], "--freq"),
                                        (["--contact", "hunt-crossley", "--plots", "figs"], "--plots")])
def test_fem_horn_cli_bad_input_is_one_line_exit_2(args, name, tmp_path):
    import subprocess
    import sys

    out = tmp_path / "c.json"
    r = subprocess.run([sys.executable, "-m", "impact", "--horn", "fem", *args, "--json", str(out)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and name in lines[0]
    assert not out.exists()


def test_fem_horn_cli_end_to_end_on_a_coarse_drill(tmp_path):
    """``python -m impact --horn fem`` on a coarse drill: JSON, CSV history and figures written; the
    history's energy balance closes; the statistics carry their CIs; the CSV's tip matches the JSON."""
    import json
    import subprocess
    import sys

    import geometry

    design = geometry.filleted(article_design(), 0.0).replace({"coupler.n_slots": 0, "coupler.n_teeth": 0,
                                                "stack.ring_thickness": 0.006})
    d = tmp_path / "d.toml"
    d.write_text(design.to_toml())
    out, csv, figs = tmp_path / "c.json", tmp_path / "h.csv", tmp_path / "figs"
    r = subprocess.run([sys.executable, "-m", "impact", "--horn", "fem", "--design", str(d), "--mesh-size", "0.008",
                        "--m-free", "0.004", "--scenario", "device", "--members", "16", "--history", "0.01",
                        "--json", str(out), "--history-csv", str(csv), "--plots", str(figs), "--no-progress"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    doc = json.loads(out.read_text())
    for row in doc["history"]["energy_balance"]:
        assert abs(row["residual_j"]) <= 1e-6 * row["drive_j"]
    st = doc["statistics"]
    assert st["members"] == 16 and st["tip_amplitude_m"]["ci95_half_width"] > 0
    assert 0 < st["tip_amplitude_m"]["mean"] < doc["drive"]["unloaded_tip_amplitude_m"]
    data = np.loadtxt(csv, delimiter=",", skiprows=1)
    assert data.shape[1] == 7 and data[-1, 0] == pytest.approx(0.01, abs=3e-6)
    assert np.max(np.abs(data[:, 1])) <= 1.5 * doc["drive"]["unloaded_tip_amplitude_m"]
    assert (figs / "tip_envelope.png").stat().st_size > 10_000


# ----------------------------------------------------------------------------- compliant contact


def test_hunt_crossley_restitution_mapping():
    """e(chi) of the scaled Hunt-Crossley impact: Hunt & Crossley's small-damping limit
    1 - e = (2/3) chi (0.1 % at chi = 1e-3), and chi_for_restitution inverts e(chi) (1e-10)."""
    from impact.contact import chi_for_restitution, restitution_of

    assert (1 - restitution_of(1e-3)) / (2e-3 / 3) == pytest.approx(1.0, abs=1e-3)
    for e in (0.3, 0.6, 0.9):
        assert restitution_of(chi_for_restitution(e)) == pytest.approx(e, abs=1e-10)
    assert chi_for_restitution(1.0) == 0.0


def test_hunt_crossley_contact_duration_is_hertz_and_restitution_is_e2(vv):
    """A free mass falling back onto a heavy, still horn (voltage 0): the elastic contact lasts the
    Hertz time (closed form, 2 %); with e2 = 0.9 it leaves at 0.9 of its approach speed (1e-3,
    gravity acting during the 50 us contact)."""
    from impact.contact import HuntCrossley, hertz_contact_time, hertz_stiffness

    k = hertz_stiffness(113.8e9, 0.342, 209e9, 0.269, 6.2e-3)        # Ti-6Al-4V flat, 6.2 mm steel ball
    heavy = ModalHorn([2 * math.pi * 1e6], [0.0], [1e12], [1.0], [1.0], [0.0], 0.0)
    for e in (1.0, 0.9):
        p = ImpactParams(m_free=0.008, g=-10.0, v0=1.0, t_end=0.25, gap=0.5, A0=0.0, e2=e)
        r = simulate_coupled(p, heavy, engine="python", series=False, contact=HuntCrossley(k, e))
        t0, t1, J, _ = r.extra["contacts"][0]
        v_in = -r.impact.w_before[0]
        assert v_in == pytest.approx(1.0, rel=1e-9)
        assert r.impact.w_after[0] / v_in == pytest.approx(e, abs=1e-3)
        assert J == pytest.approx(0.008 * (r.impact.w_after[0] + v_in), rel=1e-3)
        if e == 0.9:
            vv.record("VV-IM-06", title="Hunt-Crossley contact: restitution of a free-mass impact",
                      quantity="outgoing / incoming speed",
                      description="The 8 g free mass falls at 1 m/s onto a heavy, still horn through the "
                      "compliant Hunt-Crossley contact scaled for e2 = 0.9; the ratio of its outgoing to its "
                      "incoming speed is compared with e2.",
                      reference="The damping of the scaled Hunt-Crossley law is chosen so the coefficient of "
                      "restitution equals e2 (impact.contact.chi_for_restitution).",
                      assumptions="Gravity (10 m/s^2) keeps acting during the ~50 us contact: tolerance 1e-3 absolute.",
                      target=e, computed=r.impact.w_after[0] / v_in, tolerance=1e-3, tolerance_kind="absolute")
        if e == 1.0:
            vv.record("VV-IM-05", title="Hertz contact time of a steel ball on a titanium flat",
                      quantity="contact duration",
                      description="An 8 g free mass (6.2 mm steel ball) meets a heavy, still Ti-6Al-4V horn "
                      "at 1 m/s through the elastic (e = 1) Hunt-Crossley contact; the contact duration the "
                      "coupled model integrates is compared with Hertz's closed form.",
                      reference="Hertz impact of a sphere on a flat (force k d^(3/2)): t_c = 2 (5/4)^(2/5) (2 sqrt(pi) / 5) "
                      "Gamma(2/5) / Gamma(9/10) (m^2 / (k^2 v))^(1/5) (impact.contact.hertz_contact_time), "
                      "k from the two materials' E and nu (impact.contact.hertz_stiffness).",
                      assumptions="Quasi-static Hertz contact, no wave propagation in the bodies; the horn is a "
                      "single 1 MHz mode of modal mass 1e12 kg (still); gravity acts during the contact: "
                      "tolerance 2 %.",
                      target=hertz_contact_time(0.008, k, v_in), computed=t1 - t0, tolerance=2e-2, unit="s")
            assert t1 - t0 == pytest.approx(hertz_contact_time(0.008, k, v_in), rel=2e-2)


def test_hunt_crossley_converges_to_newton_as_stiffness_grows():
    """Stiffer contacts approach the Newton law with the same e2: the outgoing speed of the first
    horn impact differs by O(contact time) ~ k^{-2/5} (x0.16 per two decades), below 1e-3 at 1e18."""
    from impact.contact import HuntCrossley

    h = _horn(2, "steady", seed=1)
    p = ImpactParams(m_free=0.008, t_end=0.004, spring_force=5.0)
    newt = simulate_coupled(p, h, engine="python", series=False).impact
    ih = int(np.flatnonzero(newt.contact == "horn")[0])
    err = {}
    for k in (1e14, 1e16, 1e18):
        r = simulate_coupled(p, h, engine="python", series=False, contact=HuntCrossley(k, p.e2)).impact
        j = int(np.flatnonzero(r.contact == "horn")[0])
        assert r.t[j] == newt.t[ih]                       # first touch: same flight
        err[k] = abs(r.w_after[j] / newt.w_after[ih] - 1)
    assert 0.1 < err[1e16] / err[1e14] < 0.25 and 0.1 < err[1e18] / err[1e16] < 0.25
    assert err[1e18] < 1e-3


def test_hunt_crossley_bad_input():
    from impact.contact import HuntCrossley

    with pytest.raises(ParameterError, match="stiffness"):
        HuntCrossley(-1.0, 0.9)
    with pytest.raises(ParameterError, match="restitution"):
        HuntCrossley(1e10, 0.0)
    with pytest.raises(ParameterError, match="contact"):
        simulate_coupled(ImpactParams(), _horn(1), contact=HuntCrossley(1e10, 0.9))    # no series with it


def test_contact_from_design_uses_the_horn_material_and_the_free_mass_sphere():
    import geometry
    from impact.contact import hertz_contact_time, hertz_stiffness
    from results.coupled import contact_from_design

    hc = contact_from_design(article_design(), 0.008, 0.9)
    r = (3 * 0.008 / (4 * np.pi * 7890.0)) ** (1 / 3)                 # 8 g steel sphere: 6.23 mm
    assert hc.stiffness == pytest.approx(hertz_stiffness(113.8e9, 0.342, 209e9, 0.269, r), rel=1e-12)
    # the contact lasts a sizeable part of the 50 us drive period at impact speeds of ~1 m/s
    assert 30e-6 < hertz_contact_time(0.008, hc.stiffness, 1.0) < 60e-6


def test_random_coupled_cases_finish_and_never_interpenetrate():
    """Seeded random horns (1-8 modes, damping ratios 1e-4-0.5, tip masses 20 g-2 kg, rest or steady)
    and impact parameters (springs up to 10 N, g of either sign, e down to 0.2): each 20 ms run
    finishes within 2 s, and on a 0.1 us grid the free mass never enters the horn or the tool by more
    than 1e-12 m (the event search's guarantee: no contact missed)."""
    import time

    simulate_coupled(ImpactParams(t_end=1e-3), _horn(1), series=False)     # compiled code loaded before timing
    rng = np.random.default_rng(20261)
    for case in range(30):
        n = int(rng.integers(1, 9))
        om = 2 * np.pi * np.sort(rng.uniform(15e3, 120e3, n))
        tip_mass = rng.uniform(0.02, 2.0)
        s = rng.uniform(-1, 1, n) * rng.uniform(0.05, 1.0)
        s[0] = 1 / math.sqrt(tip_mass)
        z = 10 ** rng.uniform(-4, math.log10(0.5), n)
        cre = rng.uniform(-50, 50, n)
        A = rng.uniform(3e-6, 30e-6)
        cre[0] = A / s[0] * abs(om[0] ** 2 - W ** 2 + 2j * z[0] * om[0] * W) / 100.0
        horn = ModalHorn(om, z, np.ones(n), s, cre, rng.uniform(-1, 1, n), 100.0,
                         start=("rest", "steady")[case % 2])
        p = ImpactParams(m_free=rng.uniform(0.001, 0.02), e1=rng.uniform(0.2, 1), e2=rng.uniform(0.2, 1),
                         spring_force=rng.uniform(0, 10), g=rng.uniform(-20, 20), v0=rng.uniform(0, 5),
                         t_end=0.02, sample_dt=1e-7)
        t0 = time.perf_counter()
        res = simulate_coupled(p, horn, series=True)
        assert time.perf_counter() - t0 < 2.0, case
        assert np.min(res.impact.w - res.u) >= -1e-12, case
        assert np.min(res.impact.tool_face - res.impact.w) >= -1e-12, case


def test_hunt_crossley_kernel_equals_python_engine_and_balances_energy():
    """Compiled compliant contact (adaptive Dormand-Prince 5(4), rtol 1e-10) vs the reference
    (DOP853, rtol 1e-11): the first 5 events' times, outgoing speeds and horn work to the contact
    integration's accuracy propagated through each value's condition number (``_hc_tolerances``);
    the kernel's window integrals (contact phases included) close the energy balance over 0.1 s to
    ``HC_EPS`` of the contacts' work and the drive work."""
    from impact import kernel_modal as KM
    from impact.contact import HuntCrossley
    from impact.coupled_result import propagate as _propagate

    h = _horn(2, "steady", seed=1)
    p = ImpactParams(m_free=0.008, t_end=0.01, spring_force=5.0)
    hc = HuntCrossley(1e10, p.e2)
    rk = simulate_coupled(p, h, series=False, contact=hc).impact
    rp = simulate_coupled(p, h, engine="python", series=False, contact=hc).impact
    assert rk.horn_impacts >= 3
    assert list(rk.contact[:5]) == list(rp.contact[:5])
    tol = _hc_tolerances(p, h, hc, 5)
    for name in ("t", "w_after", "horn_work"):
        assert np.all(np.abs(getattr(rk, name)[:5] - getattr(rp, name)[:5]) <= tol[name]), name
    p = p.with_(t_end=0.1)
    ev, kinds, segs, stk, E0, status, t_status, n_ev, win = KM.run_events(p, h, hc)
    assert status == 0 and np.count_nonzero(kinds == 0) > 20
    n = h.n_modes
    q1, qd1 = _propagate(h, p.freq, segs[-1, 0], segs[-1, 6:6 + n], segs[-1, 6 + n:6 + 2 * n], p.t_end - segs[-1, 0])
    q0, qd0 = h.initial_state(p.freq)

    def stored(q, qd):
        return 0.5 * np.sum(h.modal_mass * (qd ** 2 + h.omega ** 2 * q ** 2))

    to_free = ev[-1, 7]                 # cumulative work of the horn on the free mass (incl. contact losses)
    resid = win[KM.C_DRIVE] - win[KM.C_DAMP] - (stored(q1, qd1) - stored(q0, qd0)) - to_free
    assert abs(resid) <= _balance_tolerance(ev, win[KM.C_DRIVE])
    with pytest.raises(ParameterError, match="series"):
        simulate_coupled(p, h, contact=hc)


@pytest.mark.parametrize("e2,seed", [(0.3, 1), (0.3, 2), (0.5, 3)])
def test_hunt_crossley_energy_closes_where_the_damping_would_pull(e2, seed):
    """At low restitution (large chi) the damping term would pull the surfaces together while they
    unload (F clipped to 0): the unloading spring's energy -k d^1.5 d' is what the contact loses
    there (counting k chi d^1.5 d'^2 / v_in in the clipped phase too leaves 1e-3 of the drive
    unbalanced). Horn energy balance over 20 ms to the contact integration's accuracy
    (``_balance_tolerance``), and the kernel's horn work equals the Python reference's (DOP853) over
    the first events within ``_hc_tolerances``."""
    from impact import kernel_modal as KM
    from impact.contact import HuntCrossley
    from impact.coupled_result import propagate as _propagate

    h = _horn(2, "steady", seed=seed)
    p = ImpactParams(m_free=0.008, t_end=0.02, spring_force=5.0, e2=e2)
    hc = HuntCrossley(1e10, p.e2)
    ev, kinds, segs, _stk, _E0, status, _ts, _n, win = KM.run_events(p, h, hc)
    assert status == 0 and np.count_nonzero(kinds == 0) >= 8
    n = h.n_modes
    q1, qd1 = _propagate(h, p.freq, segs[-1, 0], segs[-1, 6:6 + n], segs[-1, 6 + n:6 + 2 * n], p.t_end - segs[-1, 0])
    q0, qd0 = h.initial_state(p.freq)

    def stored(q, qd):
        return 0.5 * np.sum(h.modal_mass * (qd ** 2 + h.omega ** 2 * q ** 2))

    resid = win[KM.C_DRIVE] - win[KM.C_DAMP] - (stored(q1, qd1) - stored(q0, qd0)) - ev[-1, 7]
    assert abs(resid) <= _balance_tolerance(ev, win[KM.C_DRIVE])
    p = p.with_(t_end=0.005)
    rp = simulate_coupled(p, h, engine="python", series=False, contact=hc).impact
    k = min(4, len(rp.t))
    assert k >= 2
    tol = _hc_tolerances(p, h, hc, k)
    assert np.all(np.abs(ev[:k, 7] - rp.horn_work[:k]) <= tol["horn_work"])


def _balance_tolerance(ev, drive):
    """What the contacts' integration error can leave in a horn energy balance, J: ``HC_EPS`` of
    the work exchanged in each contact (its magnitude) and of the drive work (integrated through
    the contacts at the same accuracy)."""
    return HC_EPS * (np.abs(np.diff(ev[:, 7])).sum() + abs(drive))


def test_random_compliant_cases_finish_in_bounded_time():
    """Seeded random horns and parameters with Hunt-Crossley contacts (k 1e8-1e14 N/m^1.5, e2 0.2-1):
    every 20 ms compiled run finishes within 2 s with finite, time-ordered events."""
    import time

    from impact.contact import HuntCrossley

    simulate_coupled(ImpactParams(t_end=1e-3), _horn(1), series=False, contact=HuntCrossley(1e10, 0.9))
    rng = np.random.default_rng(5)
    for case in range(12):
        n = int(rng.integers(1, 9))
        om = 2 * np.pi * np.sort(rng.uniform(15e3, 120e3, n))
        s = rng.uniform(-1, 1, n) * rng.uniform(0.05, 1.0)
        s[0] = 1 / math.sqrt(rng.uniform(0.02, 2.0))
        z = 10 ** rng.uniform(-4, math.log10(0.5), n)
        cre = rng.uniform(-50, 50, n)
        cre[0] = rng.uniform(3e-6, 30e-6) / s[0] * abs(om[0] ** 2 - W ** 2 + 2j * z[0] * om[0] * W) / 100.0
        horn = ModalHorn(om, z, np.ones(n), s, cre, rng.uniform(-1, 1, n), 100.0, start=("rest", "steady")[case % 2])
        p = ImpactParams(m_free=rng.uniform(0.001, 0.02), e1=rng.uniform(0.2, 1), e2=rng.uniform(0.2, 1),
                         spring_force=rng.uniform(0, 10), g=rng.uniform(-20, 20), v0=rng.uniform(0, 5), t_end=0.02)
        hc = HuntCrossley(10 ** rng.uniform(8, 14), p.e2)
        t0 = time.perf_counter()
        r = simulate_coupled(p, horn, series=False, contact=hc).impact
        assert time.perf_counter() - t0 < 2.0, case
        assert r.horn_impacts > 0 and np.all(np.isfinite(r.w_after)) and np.all(np.diff(r.t) > 0), case
