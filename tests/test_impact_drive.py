"""The series-resistance drive (impact.drive) against independent references.

References and tolerances:
- steady state: the pseudo-modal form equals the frequency-domain solution of the physical
  equations (modes + electrode circuit, solved directly here): 1e-9 relative;
- ring-up from rest without impacts: the closed form (eigen-decomposition) equals the exact
  propagation by scipy's matrix exponential (Pade) of the physical ODE over 20 drive periods: 1e-9
  of the peak;
- with impacts: the compiled kernel's first 6 events equal a reference written here (matrix
  exponentials on a grid of 64 points per period, gap sign changes located by Brent's method,
  Newton impacts on the physical state): 1e-10 s, velocities 1e-7 relative;
- energy balance over 0.1 s: the port (source = resistor and dielectric loss + electrode energy +
  conversion) and the modes (conversion = damping + stored + to the free mass) each close to 1e-9
  of the source's work; the compiled window statistics equal the balance's integrals (1e-9);
- R -> 0: the voltage drive of the same horn, the difference falling as R (x 0.1 per decade
  within 1 %);
- bad input: ParameterError naming the field.
"""

import math

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.optimize import brentq

from rpud_common import ParameterError
from impact import kernel_modal as KM
from impact.coupled import simulate_coupled
from impact.drive import physical_states, series_model
from impact.horn import ModalHorn
from impact.params import ImpactParams

F = 20e3
W = 2 * math.pi * F
C0 = 4e-9


def _horn(n=2, R=50.0, start="rest", zeta=0.005):
    """Modes near and above the drive, a 4 nF clamped capacitance with tan delta = 0.01."""
    om = 2 * np.pi * np.array([20.3e3, 35e3, 52e3, 61e3])[:n]
    s = np.array([1 / math.sqrt(0.1), 0.3, -0.5, 0.2])[:n]
    z = np.full(n, zeta)
    cre = np.array([0.0, 0.02, -0.01, 0.015])[:n]
    cre[0] = 15e-6 / s[0] * abs(om[0] ** 2 - W ** 2 + 2j * z[0] * om[0] * W) / 225.0
    return ModalHorn(om, z, np.ones(n), s, cre, 0 * cre, 225.0, blocked_charge_re=C0, blocked_charge_im=-0.01 * C0,
                     start=start, series_resistance=R)


def _physical_system(h):
    """``x' = A x + b V_s`` of x = (q, q', V_p), written from the equations (not from impact.drive)."""
    n = h.n_modes
    R, G = h.series_resistance, -W * h.blocked_charge_im
    th, m = h.coupling_re, h.modal_mass
    A = np.zeros((2 * n + 1, 2 * n + 1))
    A[:n, n:2 * n] = np.eye(n)
    A[n:2 * n, :n] = -np.diag(h.omega ** 2)
    A[n:2 * n, n:2 * n] = -np.diag(2 * h.zeta * h.omega)
    A[n:2 * n, 2 * n] = th / m
    A[2 * n, n:2 * n] = -th / C0
    A[2 * n, 2 * n] = -(1 / R + G) / C0
    b = np.zeros(2 * n + 1)
    b[2 * n] = 1 / (R * C0)
    X = np.linalg.solve(1j * W * np.eye(2 * n + 1) - A, -1j * h.voltage * b)
    return A, b, X


class _Exact:
    """Exact propagation of the physical ODE by the matrix exponential (scipy's Pade expm):
    x(t0 + s) = e^{A s} (x(t0) - x_p(t0)) + x_p(t0 + s), x_p = Re(X e^{jWt})."""

    def __init__(self, h):
        self.A, self.b, self.X = _physical_system(h)

    def xp(self, t):
        return (self.X * np.exp(1j * W * t)).real

    def xpd(self, t):
        return (1j * W * self.X * np.exp(1j * W * t)).real

    def at(self, t0, x0, s):
        return expm(self.A * s) @ (x0 - self.xp(t0)) + self.xp(t0 + s)

    def velocity(self, t, x):
        return self.A @ (x - self.xp(t)) + self.xpd(t)


def test_steady_state_equals_frequency_domain_solution():
    h = _horn(n=3, R=80.0)
    m = series_model(h, F)
    n = h.n_modes
    R, G = h.series_resistance, -W * h.blocked_charge_im
    # unknowns (q^, V_p^): modal rows and the electrode node, V_s = Re(-j V0 e^{jWt})
    A = np.zeros((n + 1, n + 1), complex)
    A[:n, :n] = np.diag(h.modal_mass * (h.omega ** 2 - W ** 2 + 2j * h.zeta * h.omega * W))
    A[:n, n] = -h.coupling_re
    A[n, :n] = 1j * W * h.coupling_re
    A[n, n] = 1j * W * C0 + G + 1 / R
    rhs = np.zeros(n + 1, complex)
    rhs[n] = -1j * h.voltage / R
    sol = np.linalg.solve(A, rhs)
    np.testing.assert_allclose(m.X[:n], sol[:n], rtol=1e-9, atol=1e-9 * np.max(np.abs(sol[:n])))
    assert m.X[2 * n] == pytest.approx(sol[n], rel=1e-9)
    tip_ref = h.tip @ sol[:n]
    assert complex(m.tip @ m.steady) == pytest.approx(tip_ref, rel=1e-9)
    i = (rhs[n] * R - sol[n]) / R
    u = m.unloaded(h)
    assert u["tip_amplitude_m"] == pytest.approx(abs(tip_ref), rel=1e-9)
    assert u["source_power_w"] == pytest.approx(0.5 * (rhs[n] * R * np.conj(i)).real, rel=1e-9)
    assert u["source_current_rms_a"] == pytest.approx(abs(i) / math.sqrt(2), rel=1e-9)


@pytest.mark.parametrize("R", [5.0, 500.0])
def test_ring_up_equals_matrix_exponential(R):
    h = _horn(n=3, R=R)
    m = series_model(h, F)
    t = np.linspace(0, 20 / F, 401)
    x = physical_states(m, np.array([0.0]), np.zeros((1, m.n_pseudo)), np.zeros((1, m.n_pseudo)), t, order=0)[0]
    ex = _Exact(h)
    ref = np.array([ex.at(0.0, np.zeros(7), tt) for tt in t])
    u, u_ref = x[:, :3] @ h.tip, ref[:, :3] @ h.tip
    assert np.max(np.abs(u - u_ref)) < 1e-9 * np.max(np.abs(u_ref))
    assert np.max(np.abs(x[:, -1] - ref[:, -1])) < 1e-9 * np.max(np.abs(ref[:, -1]))


def _reference_events(p, h, n_events, per_period=64):
    """Events of the physical ODE with the free mass, the tool and Newton impacts: exact
    propagation (matrix exponentials) on a grid of ``per_period`` points per drive period, each
    sign change of a gap located by Brent's method on the exact state (written here)."""
    n = h.n_modes
    ex = _Exact(h)
    c = np.zeros(2 * n + 1)
    c[:n] = h.tip
    a = p.a_free
    At = np.array([[0.0, 1.0], [-p.k0 / p.m_tool, -p.c / p.m_tool]])
    x = ex.X.real.copy() if h.start == "steady" else np.zeros(2 * n + 1)
    t0, w0, wd0, y0 = 0.0, c @ x, c @ ex.velocity(0.0, x) + p.v0, np.zeros(2)
    x0 = x
    Sg = float(np.sum(h.tip ** 2 / h.modal_mass))
    dt = 1 / (per_period * F)
    Ex, Et = expm(ex.A * dt), expm(At * dt)
    out = []

    def gaps(s, xs=None, ys=None):
        xs = ex.at(t0, x0, s) if xs is None else xs
        ys = expm(At * s) @ y0 if ys is None else ys
        w = w0 + wd0 * s + 0.5 * a * s * s
        return w - c @ xs, p.gap + ys[0] - w

    while len(out) < n_events:
        k, xk, yk = 0, x0.copy(), y0.copy()
        g_prev = gaps(0.0, xk, yk)
        while True:
            s1 = (k + 1) * dt
            xk = Ex @ (xk - ex.xp(t0 + k * dt)) + ex.xp(t0 + s1)
            yk = Et @ yk
            g = gaps(s1, xk, yk)
            hits = [j for j in (0, 1) if g[j] <= 0.0 and (g_prev[j] > 0.0 or k == 0)]
            if hits:
                roots = [(brentq(lambda s, j=j: gaps(s)[j], k * dt if g_prev[j] > 0 else 1e-12, s1, xtol=1e-16,
                                 rtol=1e-15), j) for j in hits]
                s_e, kind = min(roots)
                break
            g_prev, k = g, k + 1
        te = t0 + s_e
        x = ex.at(t0, x0, s_e)
        y = expm(At * s_e) @ y0
        w, wd = w0 + wd0 * s_e + 0.5 * a * s_e ** 2, wd0 + a * s_e
        if kind == 0:
            J = -(1 + p.e2) * (wd - c @ ex.velocity(te, x)) / (1 / p.m_free + Sg)
            wd += J / p.m_free
            x[n:2 * n] -= h.tip * J / h.modal_mass
        else:
            M = p.m_free + p.m_tool
            rel = wd - y[1]
            y[1] += p.m_free / M * (1 + p.e1) * rel
            wd -= p.m_tool / M * (1 + p.e1) * rel
        out.append((te, kind, wd, y[1]))
        t0, x0, y0, w0, wd0 = te, x, y, w, wd
    return out


@pytest.mark.parametrize("R,start,n", [(5.0, "steady", 3), (50.0, "rest", 2), (2000.0, "steady", 4)])
def test_impacts_equal_exact_propagation_reference(R, start, n):
    h = _horn(n=n, R=R, start=start)
    p = ImpactParams(m_free=0.004, v0=3.0, t_end=0.03, freq=F)
    res = simulate_coupled(p, h, series=False)
    ref = _reference_events(p, h, 6)
    imp = res.impact
    assert imp.t.size >= 6
    for k, (te, kind, w, v) in enumerate(ref):
        assert imp.t[k] == pytest.approx(te, abs=1e-10)
        assert (imp.contact[k] == "tool") == (kind == 1)
        assert imp.w_after[k] == pytest.approx(w, rel=1e-7)
        assert imp.v_after[k] == pytest.approx(v, rel=1e-7, abs=1e-9)


@pytest.mark.parametrize("R,start", [(1.0, "steady"), (50.0, "rest")])
def test_energy_balance_closes(R, start):
    h = _horn(n=3, R=R, start=start)
    p = ImpactParams(m_free=0.004, v0=3.0, t_end=0.1, freq=F, spring_force=5.0)
    res = simulate_coupled(p, h, series=False)
    assert res.impact.horn_impacts > 20
    whole = res.energy_balance([0.0, p.t_end])[0]
    assert abs(whole["residual_j"]) < 1e-9 * whole["electric_j"]
    assert abs(whole["electric_residual_j"]) < 1e-9 * whole["electric_j"]
    assert whole["to_free_mass_j"] > 0 and whole["source_loss_j"] > 0
    parts = res.energy_balance([0.0, 0.03, 0.07, p.t_end])
    for key in ("electric_j", "source_loss_j", "drive_j", "damping_j", "to_free_mass_j"):
        assert sum(r[key] for r in parts) == pytest.approx(whole[key], rel=1e-9)
    win = res.extra["window"]
    assert win[KM.C_ELEC] == pytest.approx(whole["electric_j"], rel=1e-9)
    assert win[KM.C_SOURCE_LOSS] == pytest.approx(whole["source_loss_j"], rel=1e-9)
    assert win[KM.C_DRIVE] == pytest.approx(whole["drive_j"], rel=1e-9)
    assert win[KM.C_DAMP] == pytest.approx(whole["damping_j"], rel=1e-9)
    # the mean source power from the sampled current agrees with the closed-form work
    P, i_rms = res.drive_power(0.0, p.t_end, dt=1 / (256 * F))
    assert P == pytest.approx(whole["electric_j"] / p.t_end, rel=2e-3)
    assert i_rms > 0


def test_small_resistance_tends_to_the_voltage_drive():
    """The difference to the voltage drive (steady tip, first impact times) falls as R (the drop
    R i at the electrodes): x 0.1 per decade within 1 %, and 3e-7 / 1e-10 s at 10 micro-ohm."""
    p = ImpactParams(m_free=0.004, v0=3.0, t_end=0.003, freq=F)
    du, dt = [], []
    for R in (1e-3, 1e-4, 1e-5):
        h = _horn(n=3, R=R, start="steady")
        hv = h.with_(series_resistance=0.0)
        m = series_model(h, F)
        U_volt = hv.steady_tip(F)
        du.append(abs(complex(m.tip @ m.steady) - U_volt) / abs(U_volt))
        a, b = simulate_coupled(p, h, series=False), simulate_coupled(p, hv, series=False)
        dt.append(abs(a.impact.t[1] - b.impact.t[1]))
    assert du[2] < 1e-6 and dt[2] < 1e-9
    for d in (du, dt):
        assert d[1] / d[0] == pytest.approx(0.1, rel=0.01)
        assert d[2] / d[1] == pytest.approx(0.1, rel=0.01)


def test_bad_input():
    with pytest.raises(ParameterError, match="series_resistance"):
        _horn(R=-1.0)
    with pytest.raises(ParameterError, match="series_resistance"):
        _horn(R=float("nan"))
    with pytest.raises(ParameterError, match="blocked_charge_re"):
        series_model(_horn().with_(blocked_charge_re=0.0), F)
    with pytest.raises(ParameterError, match="blocked_charge_im"):
        series_model(_horn().with_(blocked_charge_im=1e-10), F)
    p = ImpactParams(t_end=1e-3)
    with pytest.raises(ParameterError, match="engine"):
        simulate_coupled(p, _horn(), engine="python")
    from impact.contact import HuntCrossley
    with pytest.raises(ParameterError, match="contact"):
        simulate_coupled(p, _horn(), series=False, contact=HuntCrossley(1e10, 0.8))
