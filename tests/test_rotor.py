"""The rotary unit's friction drive (impact.rotor) against independent references.

References and tolerances:
- no-load speed, rigid-contact limit: the tooth's mean tangential velocity over the contact
  window divided by the contact radius (analytic, ``U omega |sin phi| sin(tc)/tc``). The model's
  exact no-load condition weighs the velocity by the normal force; the two differ by the window's
  width, at most ``tc^2/6`` relative, and by the slider's elastic travel; the cases keep both
  below 1e-3 (asserted), so the analytic value is good to ~1e-3 and the test allows the 1 % the
  rigid-contact formula is quoted to;
- stall torque: at most ``mu F r`` (Coulomb bound, exact); equal to it to 1e-9 relative when the
  tooth slides one way over the whole window (the window solve and the quadrature are exact to
  round-off, so 1e-9 leaves five orders for the root finders);
- energy per cycle: teeth work = friction loss + rotor work + change of the stored tangential
  energy, each integral computed from its own integrand, 1e-9 relative (every term is a
  Gauss-Legendre quadrature of a smooth phase-wise solution, exact to ~1e-14);
- a second method: the same contact law marched by a return mapping across the window
  (impact.rotor.marched_mean_force) on N and 2N steps; the event-driven mean force lies within
  twice |T_N - T_2N| of T_2N (the march converges at second order, so the error of T_2N is about
  a third of that difference; doubled for the uncertainty of the estimate itself);
- the whole torque-speed curve in the rigid-contact limit against the closed form of the
  rigid-rotor model of Hagedorn and Wallaschek (1992) / Wallaschek (1998) (linear normal springs,
  Coulomb friction, an ellipse on its axes): T(v) = mu F r (2 A(theta_a) / A(theta_b) - 1), the
  tolerance from the slider's stick phases at the two reversals (derived in the test, 2e-4 of
  mu F r at k_t = 1e16 N/m);
- the flat-punch stiffnesses against Johnson's closed forms for one rigid body (E2 -> inf), 1e-12;
- bad input: one line, exit 2, nothing written.

A published ultrasonic-motor case (a motor's own dimensions, preload, friction and amplitudes with
a result of stated accuracy) is not reproduced here: none was reachable (the sources searched and
why each fails: docs/theory/rotor.md, "Verification").
"""

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rpud_common import ParameterError
from impact.rotor import (RotorParams, TeethMotion, bit_friction_torque, contact_stiffness, marched_mean_force,
                          rotor_performance, solve_cycle)


def _teeth(phase=171.2, axial=5e-6, ratio=0.2):
    return TeethMotion(freq=20e3, axial=axial, tangential=ratio * axial, phase_deg=phase)


@pytest.mark.parametrize("phase", [171.2, 100.0, 60.0, -120.0])
def test_no_load_speed_rigid_contact_limit(phase):
    tm = _teeth(phase)
    p = RotorParams(k_normal=1e11, k_tangential=1e15)
    res = rotor_performance(tm, p, 0.0, points=3, check_hover=False)
    tc = res.load_cycle.window[1]
    kn, kt = p.stiffness
    assert tc ** 2 / 6 < 1e-3                                       # window-width term of the reference
    slider = p.mu * kn * tm.axial * math.sin(tc) / kt               # elastic travel of the slider per rad
    assert slider < 1e-3 * tm.crest_speed / tm.omega                # against the tooth's drive travel per rad
    mean_v = tm.crest_speed * math.sin(tc) / tc
    assert res.no_load_speed == pytest.approx(mean_v / p.radius, rel=0.01)
    assert res.teeth.sense == (1 if -math.sin(math.radians(phase)) >= 0 else -1)


@pytest.mark.parametrize("case", [dict(), dict(mu=0.5), dict(k_normal=1e8, k_tangential=2e7), dict(preload=60.0)])
def test_stall_torque_below_coulomb_bound(case):
    p = RotorParams(**case)
    for phase in (171.2, 120.0, 178.0):
        res = rotor_performance(_teeth(phase, axial=2e-6), p, 0.0, points=3, check_hover=False)
        assert 0.0 < res.stall_torque <= p.mu * p.preload * p.radius * (1 + 1e-12)


def test_stall_torque_equals_bound_when_sliding_one_way():
    tm = _teeth(90.0)                       # tangential velocity U omega cos(theta) > 0 over the window
    p = RotorParams(k_tangential=1e15)      # no elastic stick at the window's start
    cyc = solve_cycle(tm, p, 0.0)
    assert [k for _, _, k in cyc.phases] == ["slip+"]
    res = rotor_performance(tm, p, 0.0, points=3, check_hover=False)
    assert res.stall_torque == pytest.approx(p.mu * p.preload * p.radius, rel=1e-9)


@pytest.mark.parametrize("case", [
    (dict(), 171.2, 5e-6, [0.0, 0.3, 0.6, 0.9, 1.2]),                          # stiff metal contact
    (dict(k_normal=2e7, k_tangential=1e7), 120.0, 3e-6, [0.0, 0.005, 0.02, 0.05]),  # compliant layer
    (dict(k_normal=1e6, k_tangential=5e5, preload=40.0), 100.0, 1e-6, [0.0, 0.004, 0.01]),  # never lifts off
])
def test_energy_balance_per_cycle(case):
    params, phase, axial, fractions = case
    tm = _teeth(phase, axial)
    p = RotorParams(**params)
    top = tm.tangential * tm.omega
    for f in fractions:
        cyc = solve_cycle(tm, p, f * top)
        parts = cyc.friction_loss + cyc.rotor_work + cyc.elastic_change
        # the largest tangential force over the tooth's stroke: the work scale even when the net is ~0
        scale = max(abs(cyc.teeth_work), np.abs(cyc.force_samples[2]).max() * 4 * tm.tangential)
        assert abs(cyc.teeth_work - parts) <= 1e-9 * scale
        assert abs(cyc.normal_work) <= 1e-9 * scale           # elastic normal contact, rotor held: no net work
        assert cyc.friction_loss >= 0.0
    full = solve_cycle(tm, p, 0.0)
    if params.get("preload") == 40.0:
        assert full.fraction("contact") == pytest.approx(1.0)


def test_second_method_return_mapping():
    # marched_mean_force: a return mapping across the window (its own window solve), second order
    tm = _teeth(120.0, 3e-6)
    p = RotorParams(k_normal=2e7, k_tangential=1e7)
    for speed in (0.0, 0.3 * tm.crest_speed, 1.5 * tm.crest_speed):
        exact = solve_cycle(tm, p, speed).mean_force
        t1, t2 = marched_mean_force(tm, p, speed, 2000), marched_mean_force(tm, p, speed, 4000)
        assert abs(exact - t2) <= 2 * abs(t1 - t2) + 1e-12 * abs(exact)


def test_flat_punch_stiffness_closed_forms():
    p = RotorParams(e_rotor=2e12 * 0.999999999999, nu_rotor=0.3)     # near-rigid rotor
    kn, kt = contact_stiffness(p)
    a = math.sqrt(p.tooth_area / math.pi)
    e, nu = p.e_tooth, p.nu_tooth
    g = e / (2 * (1 + nu))
    # rigid flat punch on one elastic half-space: P = 2 a E delta / (1 - nu^2), Q = 8 a G delta / (2 - nu)
    assert kn == pytest.approx(2 * a * e / (1 - nu ** 2), rel=0.1)
    assert kt == pytest.approx(8 * a * g / (2 - nu), rel=0.1)
    same = RotorParams(e_rotor=p.e_tooth, nu_rotor=p.nu_tooth)
    kn2, kt2 = contact_stiffness(same)
    assert kn2 == pytest.approx(a * e / (1 - nu ** 2), rel=1e-12)             # two equal bodies halve it
    assert kt2 == pytest.approx(4 * a * g / (2 - nu), rel=1e-12)


def test_torque_speed_curve_and_load_point():
    tm = _teeth(171.2, 3e-6)
    res = rotor_performance(tm, RotorParams(), 2.8e-3, points=21)
    c = res.curve
    assert np.all(np.diff(c["torque_n_m"]) <= 1e-12)                  # torque falls with speed
    assert c["torque_n_m"][-1] == pytest.approx(0.0, abs=1e-9 * res.stall_torque)
    assert 0 < res.load_speed < res.no_load_speed
    assert res.load_power == pytest.approx(2.8e-3 * res.load_speed)
    assert 0 < res.load_efficiency < 1
    stalled = rotor_performance(tm, RotorParams(), 1.0, points=3, check_hover=False)
    assert stalled.stalled and stalled.load_speed == 0.0
    d = res.to_dict()
    json.dumps(d)
    assert d["load"]["speed_rpm"] == pytest.approx(res.load_speed * 30 / math.pi)


def test_straight_stroke_rigid_tangential_gives_no_drive():
    # stroke odd about the crest, force even: the Coulomb sign integral vanishes. A stiff slider
    # still sticks where the stroke turns, over theta_s ~ sqrt(4 mu p_max / (k_t U)), while its
    # force swings from +mu p to -mu p: the torque departs from 0 by at most N r 2 mu p_max theta_s / 2 pi
    tm = _teeth(180.0)
    p = RotorParams(k_tangential=1e16)
    kn, kt = p.stiffness
    res = rotor_performance(tm, p, 0.0, points=3, check_hover=False)
    p_max = res.peak_penetration * kn
    theta_s = math.sqrt(4 * p.mu * p_max / (kt * tm.tangential))
    assert abs(res.curve["torque_n_m"][0]) <= p.n_teeth * p.radius * 2 * p.mu * p_max * theta_s / (2 * math.pi)
    assert res.no_load_speed * p.radius <= tm.tangential * tm.omega * theta_s


def test_straight_stroke_full_stick_pushes_elastically():
    # an oblique straight stroke (tangential = -rho * axial) in full stick at rest: q = k_t rho d and
    # p = k_n d at every instant, so the mean torque is r F k_t rho / k_n (exact while k_t rho <= mu k_n)
    rho = 0.158
    tm = _teeth(180.0, ratio=rho)
    p = RotorParams()
    kn, kt = p.stiffness
    assert kt * rho <= p.mu * kn
    res = rotor_performance(tm, p, 0.0, points=3, check_hover=False)
    cyc = solve_cycle(tm, p, 0.0)
    assert cyc.fraction("stick") >= (1 - 1e-9) * cyc.fraction("contact")   # round-off slip as p -> 0
    assert res.stall_torque == pytest.approx(p.radius * p.preload * kt * rho / kn, rel=1e-9)


def test_params_toml_round_trip(tmp_path):
    p = RotorParams(preload=20.0, mu=0.3, n_teeth=4)
    path = tmp_path / "rotor.toml"
    path.write_text(p.to_toml())
    assert RotorParams.from_toml(path) == p


def test_bad_input_is_refused():
    with pytest.raises(ParameterError, match="mu"):
        RotorParams(mu=0.0)
    with pytest.raises(ParameterError, match="preload"):
        RotorParams(preload=-1.0)
    with pytest.raises(ParameterError, match="axial"):
        TeethMotion(freq=20e3, axial=0.0, tangential=1e-7, phase_deg=90.0)
    with pytest.raises(ParameterError, match="load_torque"):
        rotor_performance(_teeth(), RotorParams(), -1.0)
    assert bit_friction_torque(7.0, 3e-3, 0.4) == pytest.approx(2 / 3 * 0.4 * 7.0 * 1.5e-3)


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "impact", "rotor", *args], capture_output=True, text=True,
                          timeout=120)


def test_cli_runs_and_writes(tmp_path):
    out, plots = tmp_path / "r.json", tmp_path / "plots"
    r = _cli("--axial", "3e-6", "--json", str(out), "--plots", str(plots))
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("inputs:") and "preload 18 N" in r.stdout
    d = json.loads(out.read_text())
    assert d["stall_torque_n_m"] <= d["torque_bound_mu_f_r_n_m"] * (1 + 1e-12)
    assert (plots / "torque_speed.png").is_file() and (plots / "contact_phases.png").is_file()


@pytest.mark.parametrize("args,word", [(["--axial", "3e-6", "--mu", "-1"], "mu"),
                                       (["--axial", "3e-6", "--load-torque", "0.01", "--wob", "5"], "--wob"),
                                       (["--axial", "abc"], "--axial"),
                                       (["--axial", "3e-6", "--phase-error-deg", "-1"], "--phase-error-deg"),
                                       (["--axial", "3e-6", "--axial-error", "3e-6"], "--axial-error")])
def test_cli_bad_input_is_one_line_exit_2(tmp_path, args, word):
    out = tmp_path / "r.json"
    r = _cli(*args, "--json", str(out))
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and word in r.stderr
    assert not out.exists()


def test_cli_carries_the_teeth_errors(tmp_path):
    import re

    # the command's error box is the pipeline stage's (the same function on the same inputs: equal
    # to round-off) and prints each error to two significant digits
    from results.rotor_stage import OUTPUTS, TeethReport, rotor_stage

    out = tmp_path / "r.json"
    r = _cli("--axial", "5e-6", "--ratio", "0.2", "--phase-deg", "150", "--freq", "20000", "--axial-error", "5e-8",
             "--ratio-error", "0.01", "--phase-error-deg", "1", "--load-torque", "0.002", "--points", "5",
             "--json", str(out))
    assert r.returncode == 0, r.stderr
    errors = json.loads(out.read_text())["errors"]
    ref = rotor_stage(TeethReport(20000.0, 5e-6, 5e-8, 0.2, 0.01, 150.0, 1.0), RotorParams(), 0.002, 0.0,
                      points=5)["json"]
    for key, _, _ in OUTPUTS:
        assert errors[f"{key}_error"] == pytest.approx(ref[f"{key}_error"], rel=1e-9, abs=1e-15)
    assert errors["no_load_speed_rpm_error"] > 0
    assert "errors axial 50 nm, ratio 0.01, phase 1 deg" in r.stdout
    line = next(x for x in r.stdout.splitlines() if x.startswith("with the teeth motion's errors"))
    err = ref["no_load_speed_rpm_error"]
    shown = re.search(r"no-load \S+ ± (\S+) rpm", line).group(1)
    assert float(shown) == pytest.approx(float(f"{err:.2g}"))          # two significant digits


# --------------------------------------------------------------------------- the pipeline stage


def test_stage_params_follow_the_design():
    from geometry import default_design
    from results.rotor_stage import rotor_params_from_design

    d = default_design()
    p = rotor_params_from_design(d)
    c = d.coupler
    ro, ri = c.outer_diameter / 2, d.coupler_bore / 2
    assert p.n_teeth == c.n_teeth
    assert p.tooth_area == pytest.approx(c.tooth_width / ro * (ro ** 2 - ri ** 2) / 2, rel=1e-12)
    assert p.radius == pytest.approx((ro + ri) / 2)
    assert (p.e_tooth, p.nu_tooth) == (113.8e9, 0.342)           # Ti-6Al-4V, the default coupler's


def test_stage_carries_the_teeth_error_into_speed_and_torque():
    from results.rotor_stage import OUTPUTS, TeethReport, rotor_stage

    exact = TeethReport(20e3, 5e-6, 0.0, 0.2, 0.0, 150.0, 0.0)
    out = rotor_stage(exact, RotorParams(), 2e-3, 100.0, points=5)["json"]
    assert all(out[f"{k}_error"] == 0.0 for k, _, _ in OUTPUTS)    # no input error, no output error
    # a small axial error alone: the corner spread is the linear sensitivity times the error (central
    # difference over +-h, h = 1e-3 W, equals the one-sided departures to O(h^2): 2 % allowed)
    h = 5e-9
    small = rotor_stage(TeethReport(20e3, 5e-6, h, 0.2, 0.0, 150.0, 0.0), RotorParams(), 2e-3, 100.0, points=5)["json"]
    up = rotor_performance(TeethMotion.from_ellipse(20e3, 5e-6 + h, 0.2, 150.0), RotorParams(), 2e-3, points=3, check_hover=False)
    dn = rotor_performance(TeethMotion.from_ellipse(20e3, 5e-6 - h, 0.2, 150.0), RotorParams(), 2e-3, points=3, check_hover=False)
    slope = abs(up.no_load_speed - dn.no_load_speed) / 2 * 30 / math.pi
    assert small["no_load_speed_rpm_error"] == pytest.approx(slope, rel=0.02)
    lo, hi = small["electric_efficiency_bounds"]
    assert 0 < lo < hi == pytest.approx(small["contact_efficiency"])
    with pytest.raises(ParameterError, match="axial_error_m"):
        TeethReport(20e3, 5e-6, 6e-6, 0.2, 0.0, 150.0, 0.0)


def test_hover_check_by_direct_integration():
    # the constant axial position against the rotor's axial motion integrated directly (RK4, 400
    # steps per cycle, 60 cycles): a heavy rotor (0.6 kg, ripple 0.047 of the peak penetration)
    # hovers with every cycle's peak penetration within 2 ripple + sampling of the model's
    tm = TeethMotion.from_ellipse(19900.0, 9.71e-6, 0.177, 170.8)
    heavy = rotor_performance(tm, RotorParams(rotor_mass=0.6), 0.0, points=3)
    assert heavy.axial_ripple / heavy.peak_penetration < 0.05
    assert heavy.hover["holds"] and heavy.hover["first_cycle_without_contact"] is None
    lo, hi = heavy.hover["peak_penetration_range_m"]
    assert max(abs(lo - heavy.peak_penetration), abs(hi - heavy.peak_penetration)) <= heavy.hover["allowed_departure_m"]
    # the default 61 g rotor on metal teeth at 9.7 um is thrown off: flagged, not hidden
    light = rotor_performance(tm, RotorParams(), 0.0, points=3)
    assert not light.hover["holds"] and light.hover["first_cycle_without_contact"] is not None
    assert any("does not hover" in n for n in light.notes)


def test_pipeline_adapter_reads_the_working_point():
    from types import SimpleNamespace

    from geometry import default_design
    from results.rotor_stage import pipeline_rotor_stage

    wp = SimpleNamespace(surfaces={"teeth_tops": {"axial": 5e-6 + 0j, "tangential": 1e-6 + 0j}},
                         teeth_ellipse_ratio=0.2, teeth_phase_deg=150.0, power_w=200.0)
    errors = {"teeth_ellipse_ratio": 0.01, "teeth_phase_deg": 2.0, "teeth_axial_per_volt_m": 1e-9}
    est = SimpleNamespace(errors=errors, relative=lambda q: {"teeth_axial_per_volt_m": 0.02}[q],
                          error=lambda q: errors[q])
    out = pipeline_rotor_stage(default_design(), wp, 20e3, est, 7.0)["json"]
    assert out["teeth"]["axial_m_error"] == pytest.approx(1e-7) and out["teeth"]["ellipse_ratio_error"] == 0.01
    assert out["teeth"]["phase_deg_error"] == 2.0 and not any(k.endswith("_error_note") for k in out)
    assert out["load_torque_n_m"] == pytest.approx(bit_friction_torque(7.0, 3e-3, 0.4))
    assert out["no_load_speed_rpm_error"] > 0
    # an estimate without the teeth's phase: the phase's error is left out and said so
    errors.pop("teeth_phase_deg")
    out = pipeline_rotor_stage(default_design(), wp, 20e3, est, 7.0)["json"]
    assert out["teeth"]["phase_deg_error"] == 0.0 and "phase_error_note" in out
    assert pipeline_rotor_stage(default_design().replace({"coupler.n_teeth": 0}), wp, 20e3, est, 7.0) is None


def test_stage_errors_print_to_their_significant_digits():
    # the article drill's teeth motion and error box (its pipeline run: 9.88 um +- 0.11 %, ratio
    # 0.173 +- 0.012, phase 171.2 +- 0.18 deg): the tooth slides one way over the whole window at rest,
    # so the stall torque is mu F r at every corner of the box (exact, to the model's round-off): its
    # error is 0, and the printed line gives each error to two significant digits
    import re

    from results.rotor_stage import ROUNDOFF, TeethReport, rotor_stage, rotor_text

    p = RotorParams()
    box = TeethReport(20e3, 9.8787e-6, 1.125e-8, 0.17257, 0.012, 171.238, 0.18)
    lines = []
    out = rotor_stage(box, p, 2.8e-3, 270.0, points=5, say=lines.append)["json"]
    assert out["stall_torque_n_m"] == pytest.approx(p.mu * p.preload * p.radius, rel=ROUNDOFF)
    assert out["stall_torque_n_m_error"] == 0.0
    assert out["no_load_speed_rpm_error"] > 1e-3 * out["no_load_speed_rpm"]
    text = lines[0]
    assert "stall 45 mN m (the friction bound mu F r" in text, text      # not a "± 0"
    no_load = re.search(r"no-load (\S+) ± (\S+) rpm", text).groups()
    err = out["no_load_speed_rpm_error"]
    assert float(no_load[1]) == pytest.approx(float(f"{err:.2g}"))       # two significant digits
    assert len(no_load[0].split(".")[-1]) == len(no_load[1].split(".")[-1])   # the value to the error's last digit
    zero = {k: 0.0 for k in ("no_load_speed_rpm", "stall_torque_n_m", "load_speed_rpm")}
    assert rotor_text(out, zero, 2.8e-3, False).endswith("not a prediction")
    # below the friction bound the stall torque is a computed value and keeps its +- form
    assert "stall 45 ± 0 mN m" in rotor_text(out, zero, 2.8e-3, True, 2 * out["stall_torque_n_m"])


def test_report_section_states_what_the_terminal_printed():
    # the report's rotary-unit section carries the stage's own line (each number +- its error), the
    # teeth motion with its errors and the model's notes; a run without the stage has no section
    from results.report import report_lines as full_report
    from results.rotor_stage import TeethReport, report_lines, rotor_stage

    lines = []
    out = rotor_stage(TeethReport(20e3, 9.8787e-6, 1.125e-8, 0.17257, 0.012, 171.238, 0.18), RotorParams(), 2.8e-3,
                      270.0, points=5, say=lines.append)["json"]
    out["load_note"] = "the bit's friction in rock (assumed)"
    section = report_lines(out)
    assert section[1] == "## Rotary unit" and section[3] == lines[0].strip() + "."
    assert "axial 9.879 ± 0.011 um, ellipse ratio 0.173 ± 0.012, phase 171.24 ± 0.18 deg" in section[5], section[5]
    assert "the bit's friction in rock (assumed)" in section[5]
    assert all(f"- {note}" in section for note in out["notes"])
    assert report_lines(None) == []
    summary = json.loads((Path(__file__).resolve().parent.parent / "results" / "default" / "summary.json").read_text())
    summary["rotor"] = out
    assert "## Rotary unit" in full_report(summary)
    summary["rotor"] = None
    assert "## Rotary unit" not in full_report(summary)


@pytest.mark.parametrize("phase", [-90.0, 90.0])
def test_torque_speed_curve_rigid_contact_closed_form(phase):
    # The rigid-rotor model of Hagedorn and Wallaschek (1992) and Wallaschek (1998): linear normal
    # springs, Coulomb friction with no tangential compliance, an ellipse on its axes. The tooth's
    # tangential speed U omega cos(theta) equals the rotor's surface speed v at theta_a (cos theta_a =
    # v / (U omega)); inside |theta| < theta_a the tooth drives (+mu p), outside it brakes (-mu p). With
    # p = k (W cos theta - z0), z0 = W cos theta_b and A(x) = sin x - x cos theta_b, the mean force
    # balance is F = n k W A(theta_b) / pi and the torque T(v) = mu F r (2 A(theta_a) / A(theta_b) - 1),
    # mu F r while the tooth is faster over the whole window (v <= U omega cos theta_b).
    # Tolerance: the reference is exact for a rigid tangential contact; the model's slider of
    # stiffness k_t sticks across each reversal at +-theta_a while its force swings by 2 mu p, over
    # d_theta = sqrt(4 mu p_max / (k_t U sin theta_a)), which moves the mean force by at most
    # (4/3) mu p_max d_theta / (2 pi) per reversal: at k_t = 1e16 N/m, 2e-4 of mu F r.
    from scipy.optimize import brentq

    W, U, f, kn, kt = 2e-6, 1e-6, 30e3, 1e7, 1e16
    p = RotorParams(preload=3.0, n_teeth=1, k_normal=kn, k_tangential=kt, mu=0.25, radius=0.02)
    tm = TeethMotion(freq=f, axial=W, tangential=U, phase_deg=phase)
    tb = brentq(lambda x: kn * W * (math.sin(x) - x * math.cos(x)) / math.pi - p.preload, 1e-9, math.pi)

    def area(x):
        return math.sin(x) - x * math.cos(tb)

    crest, full = U * tm.omega, p.mu * p.preload * p.radius
    ta0 = brentq(lambda x: 2 * area(x) - area(tb), 0.0, tb)            # no load: 2 A(theta_a) = A(theta_b)
    ta_min = math.acos(0.995)
    p_max = kn * W * (1 - math.cos(tb))
    tol = 2 * (4 / 3) * p.mu * p_max * math.sqrt(4 * p.mu * p_max / (kt * U * math.sin(ta_min))) / (2 * math.pi) \
        * p.radius / full
    assert tol < 3e-4
    for v in (0.0, 0.2 * crest, crest * math.cos(tb), 0.6 * crest, crest * math.cos(ta0), 0.9 * crest, 0.995 * crest):
        ref = full if v <= crest * math.cos(tb) else full * (2 * area(math.acos(v / crest)) / area(tb) - 1)
        torque = p.n_teeth * p.radius * solve_cycle(tm, p, v).mean_force
        assert abs(torque - ref) <= tol * full, (v / crest, torque, ref)
    res = rotor_performance(tm, p, 0.0, points=3, check_hover=False)
    assert res.stall_torque == pytest.approx(full, rel=tol)
    assert res.no_load_speed * p.radius == pytest.approx(crest * math.cos(ta0), rel=tol)


def test_study_point_without_an_estimate_says_what_its_errors_leave_out():
    # a study whose refine leaves no coarser mesh: the rotor's errors are the box of the other
    # inputs (none here: all 0) and rotor_note names what is missing; with the estimate, the box
    from types import SimpleNamespace

    from geometry import default_design
    from results.rotor_stage import study_rotor

    wp = SimpleNamespace(surfaces={"teeth_tops": {"axial": 4.4e-8 + 0j}}, teeth_ellipse_ratio=0.2,
                         teeth_phase_deg=150.0)
    bare = study_rotor(default_design(), wp, 20e3, 225.0, {"preload": 25.0}, 7.0)
    assert all(bare[f"{c}_error"] == 0.0 for c in ("rotor_no_load_rpm", "rotor_stall_torque_n_m", "rotor_load_rpm"))
    assert "axial, ratio, phase" in bare["rotor_note"]
    errors = {"teeth_ellipse_ratio": 0.01, "teeth_phase_deg": 2.0, "teeth_axial_per_volt_m": 1e-10}
    est = SimpleNamespace(errors=errors, relative=lambda q: 0.02, error=lambda q: errors[q])
    boxed = study_rotor(default_design(), wp, 20e3, 225.0, {"preload": 25.0}, 7.0, est=est)
    assert boxed["rotor_note"] == "" and boxed["rotor_no_load_rpm"] == bare["rotor_no_load_rpm"]
    assert boxed["rotor_no_load_rpm_error"] > 0


def test_cli_defaults_are_the_default_designs_teeth_motion():
    # the command's default frequency, ellipse ratio and phase are the committed default run's
    # (results/default/summary.json), each within that run's own stated error
    from pathlib import Path

    from impact.rotor_cli import FREQ, PHASE, RATIO

    s = json.loads((Path(__file__).resolve().parents[1] / "results" / "default" / "summary.json").read_text())
    h, wm = s["harmonic"], s["working_mode"]
    assert abs(FREQ - wm["f_r_hz"]) <= wm["f_r_hz_error"]
    assert abs(RATIO - h["teeth_ellipse_ratio"]) <= h["teeth_ellipse_ratio_error"]
    assert abs(PHASE - h["teeth_phase_deg"]) <= h["teeth_phase_deg_error"]
