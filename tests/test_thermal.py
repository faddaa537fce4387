"""Heat of the driven transducer and the lumped thermal model (fem.thermal).

References:
- the lumped model's closed form: under a constant heat P, T(t) = T_amb + P/(hA) (1 - exp(-t/tau)),
  tau = C/(hA), and the crossing time of a rated temperature from it (exact: tolerance round-off);
- a duty-cycled drive against scipy's solve_ivp of the same ODE (a second method; rtol 1e-10,
  steps well inside each stretch: agreement to 1e-6 of the temperature rise);
- energy conservation: the heat (w/2) x^H L x of a direct solution equals the cycle-averaged
  electrical input minus the power a tip damper takes, to 1e-6 (round-off of the direct solve).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from fem.thermal import LumpedBody, ThermalSettings, heat_generation, lumped_temperature

BODY = LumpedBody(capacity_j_per_k=300.0, area_m2=0.02, mass_kg=0.6, rated_c={"PZT-8": 150.0})


def test_continuous_drive_is_the_exponential_approach():
    P, h = 40.0, 10.0
    res = lumped_temperature(P, BODY, ThermalSettings(h_w_per_m2k=h, duration_s=3000.0))
    tau = 300.0 / (h * 0.02)
    rise = P / (h * 0.02)
    assert res.tau_s == pytest.approx(tau, rel=1e-15) and res.steady_c == pytest.approx(25 + rise, rel=1e-15)
    exact = 25.0 + rise * (1 - np.exp(-res.t_s / tau))
    np.testing.assert_allclose(res.temperature_c, exact, rtol=1e-12)
    assert res.time_to_rated_s["PZT-8"] == pytest.approx(tau * math.log(rise / (rise - 125.0)), rel=1e-12)
    # below the rating at steady state: never reached, said so
    assert lumped_temperature(10.0, BODY, ThermalSettings(h_w_per_m2k=h)).time_to_rated_s["PZT-8"] is None


def test_duty_cycle_against_an_ode_integration():
    from scipy.integrate import solve_ivp

    P, s = 60.0, ThermalSettings(h_w_per_m2k=8.0, duty=0.3, period_s=20.0, duration_s=400.0)
    res = lumped_temperature(P, BODY, s)
    hA = s.h_w_per_m2k * BODY.area_m2

    def rhs(t, T):
        on = (t % s.period_s) < s.duty * s.period_s
        return [(P * on - hA * (T[0] - s.ambient_c)) / BODY.capacity_j_per_k]

    # integrate stretch by stretch so that no step straddles a switch
    edges = np.unique(np.r_[np.arange(0.0, s.duration_s + 1e-9, s.period_s),
                            np.arange(s.duty * s.period_s, s.duration_s, s.period_s), s.duration_s])
    T, ts, Ts = [s.ambient_c], [], []
    for a, b in zip(edges[:-1], edges[1:]):
        mid = 0.5 * (a + b)
        sol = solve_ivp(lambda t, y: rhs(mid, y), (a, b), T, rtol=1e-11, atol=1e-12, dense_output=True)
        sel = res.t_s[(res.t_s > a) & (res.t_s <= b)]
        ts.extend(sel)
        Ts.extend(sol.sol(sel)[0])
        T = [sol.y[0, -1]]
    assert np.array_equal(np.array(ts), res.t_s[1:])
    rise = P / hA
    assert np.max(np.abs(np.array(Ts) - res.temperature_c[1:])) < 1e-6 * rise
    # the mean temperature settles at the duty-weighted steady rise
    assert res.steady_c == pytest.approx(25.0 + 0.3 * rise, rel=1e-15)


@pytest.fixture(scope="module")
def stack():
    from test_fem_harmonic import _stack

    from fem.assembly import assemble
    from fem.modal import modal_analysis

    system = assemble(_stack())
    modes = modal_analysis(system, 70e3, 8)
    i = int(np.argmax(modes.shares[:, 0]))
    return system, float(modes.f_r_hz[i])


def _direct(system, f, V, loss, damper=0.0, surface="electrode_4"):
    """Direct solution with an optional viscous damper c on the surface's mean axial motion."""
    import scipy.sparse as sp

    from fem.harmonic import loss_matrix, surface_functional

    split = system.split(())
    L = loss_matrix(system, loss)
    Lf = L[split.free][:, split.free]
    w = 2 * np.pi * f
    a = surface_functional(system, surface).rows[0]                 # mean axial displacement row
    af = a[:, split.free]
    A = (split.K - w ** 2 * split.M + 1j * Lf + 1j * w * damper * (af.T @ af)).tocsc()
    lh = np.asarray(L[:, [system.hot_dof]].toarray()).ravel()[split.free]
    b = -(split.k_hot + 1j * lh) * (V / system.phi_scale)
    x = system.expand(sp.linalg.spsolve(A, b), split.free, V)
    hot = system.hot_dof
    Q = -(system.K[hot] @ x + 1j * (L[hot] @ x)) / system.phi_scale
    p_in = 0.5 * float(np.real(V * np.conj(1j * w * Q[0])))
    u = complex((a @ x)[0])
    return x, L, p_in, 0.5 * damper * w ** 2 * abs(u) ** 2


@pytest.mark.parametrize("damper", [0.0, 3.0])
@pytest.mark.parametrize("detune", [1.0, 1.01])
def test_heat_is_input_minus_delivered_power(stack, damper, detune):
    from fem.harmonic import LossModel

    system, f_r = stack
    f = f_r * detune
    x, L, p_in, p_out = _direct(system, f, 10.0, LossModel(100.0, 0.004), damper)
    heat = heat_generation(system, x, f, L)
    assert heat.mechanical_w > 0 and heat.dielectric_w > 0
    assert heat.total_w == pytest.approx(p_in - p_out, rel=1e-6)
    if damper:
        assert p_out > 0.05 * p_in                      # the load takes a real share


def test_lumped_body_of_the_stack_from_its_materials(stack):
    from fem.thermal import lumped_body

    system, _ = stack
    body = lumped_body(system)
    vol = 0.01 * 0.01 * 0.02                                     # 10 x 10 x 20 mm of PZT-8
    assert body.mass_kg == pytest.approx(7600 * vol, rel=1e-9)
    assert body.capacity_j_per_k == pytest.approx(7600 * vol * 420.0, rel=1e-9)
    assert body.area_m2 == pytest.approx(2 * 1e-4 + 4 * 0.01 * 0.02, rel=1e-9)
    assert body.rated_c == {"PZT-8": 150.0}


def test_a_failing_body_says_why_and_what_fixes_it():
    """The fixes are the heat balance at the rated temperature: each of them, applied alone, keeps
    the steady mean temperature at or below the rating (checked by running the model with it)."""
    import re

    from fem.thermal import thermal_verdict

    s = ThermalSettings(h_w_per_m2k=10.0, duration_s=3000.0)
    res = lumped_temperature(60.0, BODY, s)
    text = thermal_verdict(res)
    assert text.startswith("thermal: FAILS: PZT-8 reaches its rated 150 C")
    duty = float(re.search(r"duty cycle <= ([0-9.]+)", text).group(1))
    h = float(re.search(r"h >= ([0-9.]+) W", text).group(1))
    assert lumped_temperature(60.0, BODY, ThermalSettings(10.0, duty=duty)).steady_c <= 150.0 + 0.01 * 125
    assert lumped_temperature(60.0, BODY, ThermalSettings(h + 0.5)).steady_c <= 150.0
    assert "stays below" in thermal_verdict(lumped_temperature(10.0, BODY, s))


def test_lumped_body_of_a_sector_is_the_whole_drill():
    """The k = 0 sector (fem.harmonic's default path) stands for the whole drill: N x its mass, its
    cut faces not counted as surface. Mass against the design's own part volumes (exact for its
    idealised solids) within 1 % (the P2 mesh's facets on the slotted coupler and the teeth: the
    mesh volumes of geometry's tests differ from the design by ~0.3 %); the sector's outer area
    against the whole drill's from the design's free mesh (the same surface) within 1 %."""
    import geometry
    from geometry.design import default_design
    from fem.assembly import assemble
    from fem.sector_system import axial_sector
    from fem.thermal import lumped_body

    d = default_design()
    sector = lumped_body(axial_sector(d))
    assert sector.mass_kg == pytest.approx(d.total_mass(), rel=0.01)
    whole = lumped_body(assemble(geometry.build_mesh(d, mesh_size=0.006)))
    assert sector.area_m2 == pytest.approx(whole.area_m2, rel=0.01)
    assert sector.capacity_j_per_k == pytest.approx(whole.capacity_j_per_k, rel=0.01)
