"""A rigid ball striking the end of a free-free uniform elastic rod: the reduced modal model with a
compliant (Hertz) contact converges to the 1-D wave solution as its cut-off grows; with an
instantaneous (Newton) impact the modal answer does not converge.

The reference (written here, independent of impact.compliant): d'Alembert for the rod,
``u = f(t - x/c) + g(t + x/c)``. The contact force F pushes the end x = 0 into the rod,
``F = Z (f' - g')`` at x = 0 (``Z = rho c A``); the far end x = L is free, ``g'(t) = f'(t - T)``
(``T = 2 L / c``). So ``f'(t) = F(t)/Z + f'(t - T)`` and the struck end moves at

    u0'(t) = f' + g' = (F(t) + 2 sum_{n >= 1} F(t - n T)) / Z,

and the ball obeys ``M w'' = -F``, ``F = k (w - u0)^{3/2}`` (Hertz, elastic). The delayed terms are
known from the earlier windows of length T (method of steps, each window DOP853 at rtol 1e-11 with
dense output). This is the exact 1-D rod (no truncation); its only error is the integrator's
(~1e-9 relative), so any difference above that is the modal model's.

The modal model: rod modes ``cos(n pi x / L)``, ``omega_n = n pi c / L``, modal mass ``rho A L`` (n = 0,
rigid) and ``rho A L / 2``, unit participation at x = 0, kept for n <= N, plus the static residual
of the rest, ``sum_{n > N} 1/(m_n omega_n^2) = 2 L / (pi^2 E A) psi_1(N + 1)`` (trigamma).
"""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.special import polygamma

from impact.compliant import ModalBody, strike
from impact.hertz import ContactGeometry, HertzLaw, effective_modulus, hertz_stiffness

E, NU, RHO = 209e9, 0.269, 7850.0      # steel rod and ball
ROD_RADIUS = 3e-3
BALL_RADIUS = 6e-3
SPEED = 1.0


def _setup(length):
    area = math.pi * ROD_RADIUS ** 2
    c = math.sqrt(E / RHO)
    k = hertz_stiffness(effective_modulus(E, NU, E, NU), ContactGeometry.crowned(BALL_RADIUS))
    mass = 4.0 / 3.0 * math.pi * BALL_RADIUS ** 3 * RHO
    return dict(L=length, A=area, c=c, Z=RHO * c * area, T=2 * length / c, k=k, M=mass)


def wave_solution(p):
    """First contact of the ball on the rod by the wave solution: ``(force(t), separation time,
    ball velocity at separation)``."""
    k, M, Z, T = p["k"], p["M"], p["Z"], p["T"]
    windows = []

    def past_force(t):
        s = windows[int(t // T)].sol(t)
        return k * max(s[0] - s[2], 0.0) ** 1.5

    def rhs(t, y):
        F = k * max(y[0] - y[2], 0.0) ** 1.5
        echoes = sum(past_force(t - n * T) for n in range(1, int(t // T) + 1) if t - n * T > 0.0)
        return [y[1], -F / M, (F + 2.0 * echoes) / Z]

    def separation(t, y):
        return y[0] - y[2]

    separation.terminal, separation.direction = True, -1
    y, t0 = [0.0, SPEED, 0.0], 0.0
    while True:
        s = solve_ivp(rhs, (t0, t0 + T), y, method="DOP853", rtol=1e-11, atol=[1e-18, 1e-12, 1e-18],
                      events=separation, dense_output=True, first_step=1e-10)
        windows.append(s)
        if s.t_events[0].size:
            t_sep = float(s.t_events[0][0])
            force = np.vectorize(lambda t: past_force(min(t, t_sep)))
            return force, t_sep, float(s.y_events[0][0][1])
        y, t0 = s.y[:, -1], t0 + T


def rod_modes(p, n_max, residual=True):
    n = np.arange(n_max + 1)
    mass = np.where(n == 0, RHO * p["A"] * p["L"], 0.5 * RHO * p["A"] * p["L"])
    g = 2.0 * p["L"] / (math.pi ** 2 * E * p["A"]) * float(polygamma(1, n_max + 1)) if residual else 0.0
    return ModalBody(n * math.pi * p["c"] / p["L"], np.zeros(n_max + 1), mass, np.ones(n_max + 1), g)


def test_residual_is_the_compliance_of_the_modes_left_out():
    """The trigamma closed form of the residual equals the direct sum of the omitted modes'
    compliances (summed to 10^6 modes plus the integral tail 1/n: 1e-12)."""
    p = _setup(0.1)
    n = np.arange(9, 1_000_001, dtype=float)
    direct = np.sum(1.0 / (0.5 * RHO * p["A"] * p["L"] * (n * math.pi * p["c"] / p["L"]) ** 2))
    direct += 1.0 / (0.5 * RHO * p["A"] * p["L"] * (math.pi * p["c"] / p["L"]) ** 2) / 1_000_000.5
    assert rod_modes(p, 8).residual == pytest.approx(direct, rel=1e-12)


@pytest.mark.parametrize("length", [0.1, 0.4])
def test_compliant_modal_impact_converges_to_the_wave_solution(length, vv):
    """Rod 0.1 m (wave round trip T = 39 us, about the contact's 42 us) and 0.4 m (T = 155 us, the
    contact ends before the first echo). As the cut-off grows the modal model's force history
    (largest difference over the contact / peak force) and rebound speed approach the wave solution;
    at cut-off frequency x contact time >= 4 both are within 1 % (the issue's acceptance; the
    reference's own error is ~1e-9), and the error falls with every doubling of the cut-off until the
    force sampling's floor (4e-5)."""
    p = _setup(length)
    law = HertzLaw(p["k"], 1.0)
    force, t_sep, v_reb = wave_solution(p)
    tau = law.contact_time(p["M"], SPEED)
    grid = np.linspace(0.0, t_sep, 1500)
    ref = force(grid)
    errors = []
    for n in (2, 4, 8, 16, 32, 64):
        s = strike(rod_modes(p, n), law, p["M"], SPEED)
        f_err = np.max(np.abs(np.interp(grid, s.t, s.force) - ref)) / ref.max()
        v_err = abs(s.rebound_velocity / v_reb - 1.0)
        errors.append((n, f_err, v_err))
        f_cut = n * p["c"] / (2 * p["L"])
        if f_cut * tau >= 4.0:
            assert f_err < 1e-2 and v_err < 1e-2
        if n == 64 and length == 0.4:
            vv.record("VV-CT-04", title="Ball on a free-free rod: modal model with Hertz contact vs wave solution",
                      quantity="rebound speed of the ball",
                      description="A 7.1 g steel ball strikes the end of a 0.4 m steel rod (3 mm radius) at 1 m/s "
                      "through a Hertz contact. The rod is reduced to its modes up to 64 x 6.5 kHz plus the static "
                      "residual of the rest (impact.compliant.strike); the ball's rebound speed is compared "
                      "with the 1-D wave solution.",
                      reference="d'Alembert solution of the rod with a free far end (method of steps, written in "
                      "tests/test_rod_impact.py) and the Hertz ODE of the ball.",
                      assumptions="1-D rod (no lateral inertia), rigid ball, quasi-static Hertz contact; the "
                      "issue's acceptance for the converged modal model: 1 %.",
                      target=v_reb, computed=s.rebound_velocity, tolerance=1e-2, unit="m/s")
    f_errs = [e[1] for e in errors]
    v_errs = [e[2] for e in errors]
    for a, b in zip(f_errs, f_errs[1:]):
        assert b < a or b < 1e-4          # falls with every doubling down to the sampling floor
    assert v_errs[-1] < 1e-4 and f_errs[-1] < 1e-4


def test_without_the_residual_it_still_converges_but_slowly():
    """Leaving the static residual out, the error falls only like 1/N (the residual compliance
    itself, ``~ 1/N``): halving per doubling, 1e-3 needs hundreds of modes; with the residual,
    16 modes suffice (0.4 m rod)."""
    p = _setup(0.4)
    law = HertzLaw(p["k"], 1.0)
    _, _, v_reb = wave_solution(p)
    bare = [abs(strike(rod_modes(p, n, residual=False), law, p["M"], SPEED).rebound_velocity / v_reb - 1)
            for n in (16, 32, 64)]
    assert bare[1] / bare[0] == pytest.approx(0.5, abs=0.1) and bare[2] / bare[1] == pytest.approx(0.5, abs=0.1)
    assert abs(strike(rod_modes(p, 16), law, p["M"], SPEED).rebound_velocity / v_reb - 1) < bare[2] / 10


def test_newton_impact_does_not_converge_in_the_modes():
    """Without the contact spring the ball meets the rod's end mass ``1 / sum 1/m_n = rho A L / (1 + 2N)``
    (Newton, restitution e): the impulse of the impact, ``(1 + e) M m_N / (M + m_N) V``, halves with each
    doubling of N and tends to 0, while the wave solution of the same rigid contact (ball pressed on
    the end, ``F = Z V exp(-Z t / M)``) transfers ``M V (1 - exp(-Z T / M))`` within the first round
    trip: the modal sum has no limit to converge to; the compliant one above has."""
    p = _setup(0.1)
    M, e = p["M"], 0.8
    impulses = []
    for n in (8, 16, 32, 64, 128):
        m_end = rod_modes(p, n, residual=False).end_mass
        assert m_end == pytest.approx(RHO * p["A"] * p["L"] / (1 + 2 * n), rel=1e-12)
        impulses.append((1 + e) * M * m_end / (M + m_end) * SPEED)
    ratios = np.array(impulses[1:]) / np.array(impulses[:-1])
    assert np.all(ratios < 0.6)                                   # no Cauchy sequence: x ~0.5 per doubling
    wave_impulse = M * SPEED * (1 - math.exp(-p["Z"] * p["T"] / M))
    assert impulses[-1] < 0.1 * wave_impulse
    # the compliant contact's impulse at the same cut-offs is the wave solution's (1e-3)
    law = HertzLaw(p["k"], 1.0)
    _, _, v_reb = wave_solution(p)
    for n in (32, 64):
        s = strike(rod_modes(p, n), law, M, SPEED)
        assert M * (SPEED - s.rebound_velocity) == pytest.approx(M * (SPEED - v_reb), rel=1e-3)
