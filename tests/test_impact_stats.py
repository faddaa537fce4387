"""Impact statistics: confidence-interval coverage, the convergence rule, reproducibility, the
bouncing ball on a vibrating table (period-1 orbit and its period-doubling threshold), sweeps of
any size, and the impact CLIs."""

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from rpud_common import ParameterError
from impact.model import simulate
from impact.params import ImpactParams
from impact.stats import (
    Scenario, StatsSettings, ensemble_members, ensemble_statistics, mean_ci, ratio_ci,
)
from impact.sweeps import linear_fit, sweep

# --------------------------------------------------------------------------- estimators


def test_mean_ci_covers_the_true_mean_95_percent():
    """1,000 repetitions of a 20-member ensemble with known mean: coverage 95 +- 3 %."""
    rng = np.random.default_rng(1)
    hits = 0
    for _ in range(1000):
        e = mean_ci(rng.normal(3.0, 2.0, 20))
        hits += e.lo <= 3.0 <= e.hi
    assert 920 <= hits <= 980


def test_ratio_ci_covers_the_true_ratio_95_percent():
    """Per member a Poisson number of events with exponential values (mean 2 mJ): the pooled mean
    per event and its delta-method interval cover 2 mJ in 95 +- 3 % of 1,000 ensembles."""
    rng = np.random.default_rng(2)
    hits = 0
    for _ in range(1000):
        n_ev = rng.poisson(25.0, 40)
        sums = np.array([rng.exponential(2e-3, k).sum() for k in n_ev])
        e = ratio_ci(sums, n_ev)
        hits += e.lo <= 2e-3 <= e.hi
    assert 920 <= hits <= 980


def test_estimates_of_degenerate_ensembles_are_absent_not_nan_in_json():
    one = mean_ci([1.5])
    assert one.mean == 1.5 and math.isnan(one.half_width) and "one member" in one.reason
    none = ratio_ci([0.0, 0.0], [0, 0])
    d = none.to_dict()
    assert d["mean"] is None and d["ci95"] is None and "no event" in d["reason"]
    json.dumps(one.to_dict(), allow_nan=False)
    json.dumps(d, allow_nan=False)


def test_linear_fit_recovers_a_noisy_line_within_its_interval():
    rng = np.random.default_rng(3)
    x = np.linspace(0.001, 0.008, 8)
    y = 4.0 * x + 0.002 + rng.normal(0, 1e-4, x.size)
    f = linear_fit(x, y)
    assert abs(f.slope - 4.0) < f.slope_ci95 < 0.2
    assert 0.99 < f.r2 <= 1.0
    # the intercept's interval against the textbook closed form: s sqrt(1/n + xbar^2 / Sxx) t_{0.975, n-2}
    from scipy.stats import t
    resid = y - (f.slope * x + f.intercept)
    s_e = math.sqrt(float(resid @ resid) / (x.size - 2))
    sxx = float(((x - x.mean()) ** 2).sum())
    half = s_e * math.sqrt(1 / x.size + x.mean() ** 2 / sxx) * t.ppf(0.975, x.size - 2)
    assert f.intercept_ci95 == pytest.approx(half, rel=1e-9)
    assert abs(f.intercept - 0.002) < f.intercept_ci95
    assert f.to_dict()["intercept_ci95_half_width"] == f.intercept_ci95
    absent = linear_fit([0.004], [0.01])
    assert math.isnan(absent.slope) and "at least two" in absent.reason


# --------------------------------------------------------------------------- ensembles


def test_members_are_seeded_and_prefix_stable():
    p = ImpactParams()
    s = StatsSettings(seed=7)
    a = ensemble_members(p, 10, s)
    b = ensemble_members(p, 4, s, start=6)
    assert [q.v0 for q in a[6:]] == [q.v0 for q in b]
    v = np.array([q.v0 for q in a])
    assert np.all(np.abs(v / p.v0 - 1) <= 0.05) and np.unique(v).size == 10


def test_adaptive_rule_reaches_its_target_and_reruns_identically():
    s = StatsSettings(rel_tol=0.08, n_start=16, n_max=1024)
    r1 = ensemble_statistics(ImpactParams(), "article", s)
    r2 = ensemble_statistics(ImpactParams(), "article", s)
    assert r1.converged and r1.members in (16, 32, 64, 128, 256, 512, 1024)
    for q in ("tool_impact_rate_hz", "mean_tool_ke_after_j", "mean_ke_gain_j", "tool_power_w"):
        assert r1[q].rel_half_width <= 0.08
    assert np.array_equal(r1.raw, r2.raw)                       # bit-identical rerun
    assert r1.to_dict() == r2.to_dict()


def test_calibrated_defaults_give_the_article_rate():
    """Article section 4: "the average collision frequency of the free mass is about 520 Hz" (8 g,
    first 50 ms). Two uncertainties, each from its source: the article states the rate to the
    ten ("about 520": +- 10 Hz, one unit of its last digit), and the ensemble mean is an estimate
    with the 95 % half-width its convergence rule promises (the default 3 %: 15.6 Hz at 520 Hz).
    The calibrated defaults' mean must lie within their sum, 25.6 Hz, of 520
    (benchmarks/calibrate_impact.py documents the sweep)."""
    r = ensemble_statistics(ImpactParams(), "article")
    e = r["tool_impact_rate_hz"]
    assert r.converged and e.rel_half_width <= 0.03
    assert abs(e.mean - 520.0) <= 10.0 + 0.03 * 520.0, (e.mean, e.half_width)


def test_member_cap_is_reported():
    r = ensemble_statistics(ImpactParams(), "article", StatsSettings(rel_tol=0.001, n_start=8, n_max=16))
    assert not r.converged and r.members == 16 and "cap" in r.note


def test_device_scenario_never_rests_on_the_tool():
    """The 5 N restoring spring keeps the free mass bouncing (the article scenario's free mass ends
    up resting on the tool in long runs)."""
    r = ensemble_statistics(ImpactParams(), "device", StatsSettings(n_start=16, n_max=16))
    assert r["frac_on_tool"].mean == 0.0 and r["tool_impact_rate_hz"].mean > 200
    long_art = Scenario("long article", 0.0, 0.5, 1.0)
    q = ensemble_statistics(ImpactParams(), long_art, StatsSettings(n_start=16, n_max=16))
    assert q["frac_on_tool"].mean > 0.3


def test_sweep_of_one_mass_and_one_member_writes_clean_json():
    sw = sweep(None, [0.004], settings=StatsSettings(n_start=1, n_max=1))
    doc = json.dumps(sw.to_dict(), allow_nan=False)
    assert '"reason"' in doc and sw.fit.n == 1
    assert sw.csv().count("\n") == 2


def test_statistics_reject_bad_settings():
    with pytest.raises(ParameterError, match="rel_tol"):
        StatsSettings(rel_tol=0.0)
    with pytest.raises(ParameterError, match="n_start"):
        StatsSettings(n_start=100, n_max=10)
    with pytest.raises(ParameterError, match="scenario"):
        ensemble_statistics(ImpactParams(), "lab")
    with pytest.raises(ParameterError, match="t_end"):
        Scenario("x", 0.0, 0.1, 0.05)


# --------------------------------------------------------------------------- bouncing ball on a vibrating table


def _table(gamma_ratio, e=0.5, f=50.0, impacts=3000):
    """Ball on a table u = A cos(w t) with gravity toward it (g < 0), tool out of reach; A chosen
    so that Gamma = A w^2 / g is ``gamma_ratio`` times the period-doubling threshold."""
    g = 9.81
    w = 2 * math.pi * f
    s1 = math.pi * (1 - e) / (1 + e)
    s2 = 2 * (1 + e * e) / (1 + e) ** 2
    gamma = gamma_ratio * math.hypot(s1, s2)
    A = gamma * g / w ** 2
    T = 1 / f
    p = ImpactParams(A0=A, freq=f, e2=e, g=-g, v0=g * T / 2, gap=1.0, k0=1e3, c=0.0, m_tool=0.05, sample_dt=1e-4,
                     t_end=impacts * T)
    return p, gamma, s1


def test_bouncing_ball_period_one_orbit_and_period_doubling_threshold():
    """Period-1 orbit of a ball on a vibrating table (Holmes, J. Sound Vib. 84 (1982) 173; Luck &
    Mehta, Phys. Rev. E 48 (1993) 3988), for our table u = A cos(w t):

    An orbit with one impact per period T needs flight time T, so the ball leaves at g T/2 and
    returns at -g T/2; Newton's law w+ = (1+e) u' - e w- then needs the table velocity
    u' = g T (1-e) / (2 (1+e)), i.e. sin(phi) = -pi (1-e) / ((1+e) Gamma), Gamma = A w^2 / g.
    Linearising the exact impact map (impact time, take-off speed) about the orbit gives
    det J = e^2 and trace J = 1 + e^2 + (1+e)^2 u''/g; an eigenvalue -1 (period doubling) when
    Gamma cos(phi) = 2 (1+e^2)/(1+e)^2, so
    Gamma_pd = sqrt([pi (1-e)/(1+e)]^2 + [2 (1+e^2)/(1+e)^2]^2), the stable orbit having cos(phi) > 0.
    Bracketed within 1 %: period 1 at 0.99 Gamma_pd, period 2 at 1.01 Gamma_pd.
    """
    p, gamma, s1 = _table(0.99)
    r = simulate(p, series=False)
    assert r.tool_impacts == 0 and r.horn_impacts >= 2900
    phase = np.mod(2 * math.pi * p.freq * r.t, 2 * math.pi)
    last = phase[-50:]
    phi = 2 * math.pi - math.asin(s1 / gamma)                  # stable branch: cos(phi) > 0
    assert np.ptp(last) < 1e-6                                   # period 1: the same phase every impact
    assert last.mean() == pytest.approx(phi, abs=1e-6)
    assert np.allclose(np.diff(r.t[-50:]), 1 / p.freq, rtol=0, atol=1e-9)
    assert np.allclose(r.w_after[-50:], 9.81 / (2 * p.freq), rtol=1e-6)

    p, gamma, s1 = _table(1.01)
    r = simulate(p, series=False)
    phase = np.mod(2 * math.pi * p.freq * r.t, 2 * math.pi)[-50:]
    jump = np.abs(np.diff(phase))
    assert jump.min() > 1e-3                                     # alternates: not period 1
    assert np.ptp(phase[::2]) < 1e-6 and np.ptp(phase[1::2]) < 1e-6   # period 2
    assert np.allclose(np.diff(r.t[-50:]), 1 / p.freq, rtol=0.2)      # still about one impact a period


# --------------------------------------------------------------------------- CLI


def _cli(*args, cwd):
    return subprocess.run([sys.executable, "-m", "impact", *args], cwd=cwd, capture_output=True, text=True)


@pytest.mark.parametrize("args,field", [
    (("--m-free", "-0.002"), "m_free"), (("--e1", "1.5"), "e1"), (("--A0", "-1e-6"), "A0"),
    (("--freq", "0"), "freq"), (("--t-end", "0"), "t_end"), (("--gap", "0"), "gap"),
    (("--rel-tol", "nan"), "rel-tol"), (("--members", "0"), "members"), (("--gap", "3.1e-5"), "gap"),
    (("sweep", "--m-free", "0.004,nan"), "m_free"), (("sweep", "--m-free", "0.004", "--t-from", "0.2"), "t_from"),
])
def test_cli_bad_input_exit_2_one_line_no_file(tmp_path, args, field):
    out = tmp_path / "o.json"
    cp = _cli(*args, "--json", str(out), cwd=tmp_path)
    assert cp.returncode == 2, cp.stderr
    lines = cp.stderr.strip().splitlines()
    assert len(lines) == 1 and field in lines[0] and "Traceback" not in cp.stderr
    assert list(tmp_path.iterdir()) == []


def test_cli_statistics_json(tmp_path):
    out = tmp_path / "o.json"
    cp = _cli("--members", "8", "--m-free", "0.006", "--json", str(out), "--no-progress", cwd=tmp_path)
    assert cp.returncode == 0, cp.stderr
    d = json.loads(out.read_text())
    assert d["params"]["m_free"] == 0.006 and d["members"] == 8 and d["scenario"] == "article"
    rate = d["tool_impact_rate_hz"]
    assert rate["ci95"][0] < rate["mean"] < rate["ci95"][1]
    ev = d["sample_trajectory"]["events"]
    assert d["sample_trajectory"]["tool_impacts"] + d["sample_trajectory"]["horn_impacts"] == len(ev) > 0
    assert "±" in cp.stdout and "tool kinetic energy" in cp.stdout


def test_cli_sweep_one_mass_writes_json_and_csv(tmp_path):
    cp = _cli("sweep", "--m-free", "0.004", "--members", "4", "--json", "s.json", "--csv", "s.csv",
              "--no-progress", cwd=tmp_path)
    assert cp.returncode == 0, cp.stderr
    d = json.loads((tmp_path / "s.json").read_text())
    assert d["fit_ke_vs_mass"]["slope"] is None and "reason" in d["fit_ke_vs_mass"]
    assert (tmp_path / "s.csv").read_text().count("\n") == 2
    assert "absent" in cp.stdout
