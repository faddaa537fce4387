"""Opt-in pipeline stage (``python -m results --load rock --wob 7``): drilling under load with the
horn amplitude the FE chain computed.

Each free mass drills with the pipeline's loaded tip amplitude for that mass (A0 from the FE
working point under the no-load impact load, the same hand-off as the impact stage) at the
working frequency; 0 g drills with the unloaded amplitude (no free mass, no blows). The model,
its assumptions and the rock values are in :mod:`impact.drilling`."""

from __future__ import annotations

import logging

log = logging.getLogger(__name__)


def drilling_stage(base, masses, amplitudes: dict, wob: float, seed: int, say=None, settings=None,
                   window=(0.02, 0.22)) -> dict:
    """Run the drilling sweep. ``base``: the impact stage's ImpactParams (freq, horn mass);
    ``amplitudes``: free mass (kg) -> A0 (m), the others (0 g) get ``base.A0``; ``settings``: a
    :class:`impact.drilling.DrillSettings` (default: 5 %% rule, the given seed); ``window``:
    statistics window (s). Returns {"json", "result"}."""
    from impact.drilling import DrillParams, DrillSettings, DrillSweep, drilling_sweep

    p = DrillParams(impact=base.with_(spring_force=5.0), wob=wob, t_from=window[0], t_end=window[1])
    a0 = [amplitudes.get(m, base.A0) for m in masses]
    rows = drilling_sweep(p, masses, settings or DrillSettings(seed=seed), A0_values=a0)
    res = DrillSweep(rows=rows, params=p)
    if say is not None:
        top = rows[-1]
        say(f"      drilling at WOB {wob:g} N: {top.m_free * 1e3:g} g -> "
            f"{top['drilling_rate_m_s'].scaled(6e4)} mm/min, depth after {p.drill_time:g} s "
            f"{top.depth_m.scaled(1e3)} mm (95 % CI)")
    return {"json": res.to_dict(), "result": res}


def report_lines(d: dict) -> list[str]:
    """Markdown section of ``report.md`` from ``summary.json``'s ``drilling`` block."""
    import math

    from impact.stats import Estimate

    def _ci(est, scale=1.0):          # as results.report._ci (which imports this module)
        if est["mean"] is None:
            return "n/a"
        hw = est["ci95_half_width"]
        return format(Estimate(est["mean"] * scale, math.nan if hw is None else hw * scale, est["members"]))

    p = d["params"]
    lines = ["", "## Drilling under load (bit on sandstone)", "",
             f"WOB {p['wob_n']:g} N, tool rod {p['rod']['diameter_m'] * 1e3:g} x {p['rod']['length_m'] * 1e3:g} mm, "
             f"rock k_load {p['rock']['k_load_n_per_m']:.3g} N/m, k_unload {p['rock']['k_unload_n_per_m']:.3g} N/m, "
             f"threshold {p['rock']['f_threshold_n']:g} N (assumed sandstone values); depth = drilling rate x "
             f"{p['drill_time_s']:g} s; means with 95 % CIs over seeded members. The absolute depths rest on the "
             "assumed rock law (see the README); the trend with the free mass is the result to compare with the "
             "article's Fig. 14.", "",
             f"**Model status:** {d['model_status']['calibration']}. Assumptions: {d['model_status']['assumptions']}. "
             f"Use: {d['model_status']['use']}.", "",
             "| free mass (g) | A0 (um) | blows (Hz) | penetration per blow (um) | drilling rate (mm/min) "
             "| depth (mm) | efficiency (%) | members |", "|---|---|---|---|---|---|---|---|"]
    for r in d["rows"]:
        lines.append(f"| {r['m_free_kg'] * 1e3:g} | {r['A0_m'] * 1e6:.2f} | {_ci(r['blow_rate_hz'])} "
                     f"| {_ci(r['penetration_per_blow_m'], 1e6)} | {_ci(r['drilling_rate_m_s'], 6e4)} "
                     f"| {_ci(r['depth_after_drill_time_m'], 1e3)} | {_ci(r['efficiency'], 100)} | {r['members']}"
                     + ("" if r["converged"] else " (cap)") + " |")
    return lines
