"""Drilling under load: the rod's wave model against Saint-Venant's pulse, the bit-rock
law against closed forms with its energy balance, WOB settling to the static equilibrium,
momentum (mean rock force), the free-mass trend, and bad input."""

import math
import subprocess
import sys

import numpy as np
import pytest

from rpud_common import ParameterError
from impact import drill_kernel as K
from impact.drilling import DrillParams, DrillSettings, drilling_sweep, pack
from impact.params import ImpactParams
from impact.rock import R_N, RockLaw, rock_response
from impact.rod import ToolRod, saint_venant_exit_speed


def _striker_case(cells):
    """A rigid collar (the rest of the 50 g tool) moving at 1 m/s onto a free-free 3 mm rod:
    no horn, no free mass, no rock, no spring, fixed housing."""
    ip = ImpactParams(A0=0.0, k0=1e-9, c=0.0, g=0.0, spring_force=0.0)
    p = DrillParams(impact=ip, rod=ToolRod(cells=cells), wob=0.0)
    pv = pack(p, 0.0, collar_v0=1.0, unilateral=True, rock_on=False, housing_fixed=True)
    return p, pv


def test_rod_struck_by_rigid_mass_gives_saint_venant_pulse():
    """Force at the struck end Z V exp(-Z t / M) for t < 2L/c, then separation; the free far end
    moves at 2 F(t - L/c) / Z; the mass leaves at V exp(-2 m_rod / M). Tolerance 1 %."""
    p, pv = _striker_case(128)
    rod = p.rod
    M, V, Z, dt = pv[K.D_M_COLLAR], 1.0, rod.impedance, rod.dt
    _, rec = K.run_record(pv, 3.5 * rod.transit, 1)
    t1 = rec[:, K.C_T]
    t0 = t1 - dt

    def avg_force(a, b):       # step average of Z V exp(-Z t / M) over [a, b], 0 outside [0, 2L/c)
        a, b = np.clip(a, 0, 2 * rod.transit), np.clip(b, 0, 2 * rod.transit)
        return V * M * (np.exp(-Z * a / M) - np.exp(-Z * b / M)) / dt

    top = rec[:, K.C_N_TOP]
    ref = avg_force(t0, t1)
    assert np.max(np.abs(top - ref)) <= 0.01 * Z * V
    assert abs(top[0] - Z * V) <= 0.01 * Z * V                      # amplitude Z V (impedance x speed)
    pos = t1[top > 1e-9 * Z * V]
    duration = pos[-1]
    assert abs(duration - 2 * rod.transit) <= 0.01 * 2 * rod.transit  # duration 2L/c
    vbit = rec[:, K.C_V_BIT]
    ref_bit = 2.0 * avg_force(t0 - rod.transit, t1 - rod.transit) / Z
    assert np.max(np.abs(vbit[t1 < 3 * rod.transit] - ref_bit[t1 < 3 * rod.transit])) <= 0.01 * 2 * V
    vexit = rec[-1, K.C_V_COLLAR]
    assert abs(vexit - saint_venant_exit_speed(V, M, rod)) <= 0.01 * V


def test_rod_pulse_converges_with_the_cell_count():
    """The rod is exact; the separation is resolved to one step, so the exit speed's error is first
    order in dt: four times the cells, at least half the error."""
    errs = []
    for cells in (16, 64):
        p, pv = _striker_case(cells)
        _, rec = K.run_record(pv, 2.5 * p.rod.transit, 1)
        errs.append(abs(rec[-1, K.C_V_COLLAR] - saint_venant_exit_speed(1.0, pv[K.D_M_COLLAR], p.rod)))
    assert errs[1] < 0.5 * errs[0]
    assert errs[1] < 0.01


def _rect_pulse(a0, n_on, n_total):
    inc = np.zeros(n_total)
    inc[:n_on] = a0
    return inc


@pytest.mark.parametrize("fth", [0.0, 150.0])
def test_single_blow_on_rock_closed_form_and_energy(fth):
    """A rectangular incident wave (a0, duration tau) on the bilinear rock: F(t) = 2 Z a0 (1 - exp(
    -k t / Z)) while loading, peak at tau; permanent penetration (F_peak - F_th)(1/k_l - 1/k_u);
    largest penetration F_peak / k_l; incident energy = work on the rock + reflected energy."""
    Z, kl, ku, a0, dt = 287.0, 4.8e7, 2.4e8, 1.0, 1e-7
    n_on = 40
    inc = _rect_pulse(a0, n_on, 4000)
    f, d, p, work, refl = rock_response(inc, Z, kl, ku, fth, np.array([0.0, 0.0, fth]), dt)
    tau = n_on * dt
    fpeak = 2 * Z * a0 * (1 - math.exp(-kl * tau / Z))
    assert abs(f.max() - fpeak) <= 1e-9 * fpeak
    assert abs(d.max() - fpeak / kl) <= 1e-9 * fpeak / kl
    assert abs(p[-1] - (fpeak - fth) * (1 / kl - 1 / ku)) <= 1e-9 * fpeak / kl
    e_in = Z * a0 * a0 * tau
    assert abs(e_in - work - refl) <= 1e-6 * e_in
    # F(t) on the loading branch, exactly
    t = (np.arange(n_on) + 1) * dt
    assert np.allclose(f[:n_on], 2 * Z * a0 * (1 - np.exp(-kl * t / Z)), rtol=1e-9, atol=0)


def test_linear_rock_returns_the_energy():
    """k_unload = k_load (linear, elastic rock): no crater, and after the blow the whole incident
    energy has been reflected (work on the rock back to ~0)."""
    Z, k = 287.0, 4.8e7
    inc = _rect_pulse(0.5, 100, 20000)
    f, d, p, work, refl = rock_response(inc, Z, k, k, 0.0, np.zeros(R_N), 1e-7)
    e_in = Z * 0.25 * 100 * 1e-7
    assert p[-1] == 0.0
    assert abs(work) <= 1e-6 * e_in
    assert abs(refl - e_in) <= 1e-6 * e_in


def test_rock_lifts_off_and_recontacts():
    """A tensile (negative) incident wave lifts the bit off: F = 0 and the free end moves at 2a;
    a later compressive wave brings it back into contact."""
    Z, kl = 287.0, 4.8e7
    inc = np.concatenate([np.full(200, -0.2), np.full(400, 0.3)])
    f, d, p, work, refl = rock_response(inc, Z, kl, 5 * kl, 1e9, np.zeros(R_N), 1e-7)
    assert np.all(f[:200] == 0.0)
    assert abs(d[199] - 2 * -0.2 * 200 * 1e-7) <= 1e-15
    assert f[-1] > 0.0
    e_in = Z * (0.04 * 200 + 0.09 * 400) * 1e-7
    assert abs(e_in - work - refl) <= 1e-6 * e_in


def test_energy_is_conserved_without_drive_or_losses_and_converges():
    """Still horn (A0 = 0), elastic impacts (e1 = e2 = 1), no damper, elastic rock (k_unload =
    k_load, no crushing), WOB and restoring spring on: the mechanical energy (kinetic, k0, rod
    waves, rock, WOB / gravity / spring potentials) stays constant over 50 ms (8-9 blows) but for
    the first-order error of sampling an impact inside a step: < 5 % of the free mass's launch
    energy at 32 cells (measured 3.1 %), at least 3x less at 128 cells (0.8 %)."""
    errs = []
    for cells in (32, 128):
        ip = ImpactParams(A0=0.0, e1=1.0, e2=1.0, c=0.0, freq=19.95e3, spring_force=5.0)
        p = DrillParams(impact=ip, rock=RockLaw(4.8e7, 4.8e7, 1e6), rod=ToolRod(cells=cells))
        st, rec = K.run_record(pack(p, 0.008), 0.05, 50)
        assert st[K.S_BLOWS] >= 5
        e = rec[:, K.C_ENERGY]
        errs.append(np.max(np.abs(e - e[0])) / (0.5 * 0.008 * 4.0 ** 2))
    assert errs[0] < 0.05
    assert errs[1] < errs[0] / 3.0


def test_wob_alone_settles_to_the_static_equilibrium():
    """No drive, no free mass, cold start (nothing stressed): the WOB pushes the housing until the
    spring carries wob (q = -wob / k0) and the rock bears wob (e = wob / k_load)."""
    p = DrillParams(impact=ImpactParams(A0=0.0, spring_force=0.0))
    pv = pack(p, 0.0, cold=True)
    _, rec = K.run_record(pv, 0.6, 1000)
    f_end = rec[-1, K.C_F_ROCK]
    assert abs(f_end - p.wob) <= 1e-4 * p.wob
    assert abs(rec[-1, K.C_D] - p.wob / p.rock.k_load) <= 1e-4 * p.wob / p.rock.k_load
    assert rec[-1, K.C_P] == 0.0
    # and it did move: the first record is far from it
    assert abs(rec[0, K.C_F_ROCK] - p.wob) > 0.1 * p.wob


def test_static_start_stays_static():
    """Started in the static state (no drive, no free mass) nothing moves: rock force = wob."""
    p = DrillParams(impact=ImpactParams(A0=0.0, spring_force=0.0))
    _, rec = K.run_record(pack(p, 0.0), 0.01, 100)
    assert np.max(np.abs(rec[:, K.C_F_ROCK] - p.wob)) <= 1e-9 * p.wob
    assert np.max(np.abs(rec[:, K.C_X_HOUSING])) <= 1e-15


_FAST = DrillSettings(rel_tol=0.1, n_start=8, n_max=32)


def _fast_params():
    return DrillParams(t_from=0.01, t_end=0.07)


def test_momentum_balance_gives_the_mean_rock_force():
    """Momentum: every impulse the horn gives the free mass is taken from the housing, so over the
    window the rock's impulse is (WOB + m_free g) T minus the change of the total momentum
    (housing, collar, free mass, rod waves). Per member, to 1e-3 of (WOB T)."""
    p = DrillParams(t_from=0.02, t_end=0.12)
    m = 0.008
    pm = np.array([pack(p, m, v0) for v0 in (3.8, 4.0, 4.2)])
    raw = K.ensemble(pm, p.t_from, p.t_end)
    T = raw[:, K.S_T]
    expect = (p.wob + m * p.impact.g) * T - (raw[:, K.S_P_END] - raw[:, K.S_P_FROM])
    assert np.all(np.abs(raw[:, K.S_FDT] - expect) <= 1e-3 * p.wob * T)
    assert np.all(raw[:, K.S_BLOWS] > 10)


def test_depth_grows_with_free_mass_and_reruns_identically():
    """The article's case: more free mass drills deeper (2 g vs 8 g, disjoint 95 % CIs); no free
    mass drills nothing (WOB 7 N is below the crushing threshold); a rerun is bit-identical."""
    p = _fast_params()
    rows = drilling_sweep(p, [0.0, 0.002, 0.008], _FAST)
    r0, r2, r8 = rows
    assert r0.depth_m.mean == 0.0 and r0.converged
    assert r8.depth_m.lo > r2.depth_m.hi
    again = drilling_sweep(p, [0.008], _FAST)[0]
    assert again.depth_m.mean == r8.depth_m.mean and again.members == r8.members


def test_pipeline_stage_uses_the_amplitude_per_mass():
    """results.drilling.drilling_stage (the opt-in pipeline stage): one row per mass, each run
    with its own A0 (0 g with the base amplitude), JSON without NaN; a larger A0 drills deeper."""
    import json

    from results.drilling import drilling_stage

    base = ImpactParams(A0=20e-6, freq=19.95e3)
    out = drilling_stage(base, [0.0, 0.006, 0.008], {0.006: 14e-6, 0.008: 22e-6}, 7.0, 20260,
                         settings=_FAST, window=(0.01, 0.07))
    rows = out["json"]["rows"]
    assert [r["A0_m"] for r in rows] == [20e-6, 14e-6, 22e-6]
    assert rows[0]["drilling_rate_m_s"]["mean"] == 0.0
    assert rows[2]["depth_after_drill_time_m"]["ci95"][0] > rows[1]["depth_after_drill_time_m"]["ci95"][1]
    json.dumps(out["json"], allow_nan=False)
    from results.drilling import report_lines

    table = [ln for ln in report_lines(out["json"]) if ln.startswith("| ") and ln[2].isdigit()]
    assert len(table) == 3 and table[2].startswith("| 8 | 22.00 |")
    # the numbers travel with the model's assumptions and calibration status (JSON, report, figure)
    from impact.drilling import MODEL_STATUS, STATUS_LINE
    from impact.drilling_plots import plot_depth_vs_mass

    assert out["json"]["model_status"] == MODEL_STATUS and "uncalibrated" in MODEL_STATUS["calibration"]
    assert any(ln.startswith("**Model (kinematic):**") and "**Status:** uncalibrated" in ln
               for ln in report_lines(out["json"]))
    assert "NOT credible" in STATUS_LINE and "NOT credible" in repr(out["result"])
    ax = plot_depth_vs_mass(out["result"])
    assert any("NOT credible" in t.get_text().replace("\n", " ") for t in ax.texts)


def test_bad_input_is_refused():
    with pytest.raises(ParameterError, match="k_unload"):
        RockLaw(k_load=1e8, k_unload=1e7)
    with pytest.raises(ParameterError, match="length"):
        DrillParams(rod=ToolRod(length=3.0))          # the rod alone would outweigh the tool
    with pytest.raises(ParameterError, match="wob"):
        DrillParams(wob=500.0)                         # closes the gap through k0
    with pytest.raises(ParameterError, match="cells"):
        ToolRod(cells=1)


def test_cli_bad_input_is_one_line_exit_2(tmp_path):
    out = tmp_path / "d.json"
    r = subprocess.run([sys.executable, "-m", "impact", "--load", "rock", "--wob", "-3", "--json", str(out)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and "wob" in r.stderr
    assert not out.exists()
