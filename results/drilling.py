"""Opt-in pipeline stage (``python -m results --load rock --wob 7``): drilling under load.

Two models (:mod:`impact.drilling`):

* **compliant** (when the pipeline has built the FE horn, i.e. its compliant stage ran): the FE
  transducer's k = 0 modes with the static residual, Hertz contacts at horn tip and tool (the
  compliant stage's laws per free mass), a rigid tool pressed on the rock; the headline;
* **kinematic**: the horn tip moving as ``A0 cos(W t)`` at the pipeline's loaded amplitude per
  free mass (the impact stage's hand-off), Newton impacts, a rigid collar on an elastic tool rod;
  the stated comparison beside the compliant model, the only model when there is no FE horn.
  0 g drills with the unloaded amplitude (no free mass, no blows; kinematic only).

Both print and write the model's assumptions and calibration status beside their numbers: the
rock law is assumed, so the depths are not credible as magnitudes."""

from __future__ import annotations

import logging

log = logging.getLogger(__name__)


def drill_horn(compliant: dict | None, design, base, masses):
    """The compliant drilling model's horn and contacts from the pipeline's compliant stage
    (:func:`results.stage_compliant.compliant_stage`'s ``drill_horn``), None without it.
    Returns (impact.drilling.CompliantHorn, masses it drills: the positive ones)."""
    if compliant is None or "drill_horn" not in compliant:
        return None, []
    from impact.drilling import CompliantHorn

    from .stage_compliant import contact_laws

    horn, g, settings = compliant["drill_horn"]
    pos = [m for m in masses if m > 0]
    laws = tuple(contact_laws(design, m, base.e2, base.e1, settings)[:2] for m in pos)
    return CompliantHorn(horn, g, laws), pos


def fe_drill_horn(design, masses, *, voltage: float = 225.0, q_mech: float = 100.0, say=None):
    """The compliant drilling model's horn of ``design`` outside the pipeline, as the pipeline's
    compliant stage builds it (:mod:`results.stage_compliant`): every k = 0 mode up to twice the
    inverse of the shortest Hertz contact of the lightest and heaviest free mass, with the static
    residual of the rest, driven at ``voltage`` (V amplitude) at the working resonance.

    Returns
    -------
    (float, float, impact.drilling.CompliantHorn)
        The working frequency (Hz, the drive), the mode cut-off (Hz) and the horn with one pair of
        contact laws per positive mass of ``masses`` (kg).
    """
    import numpy as np

    from fem.matching import working_mode
    from fem.sector_system import axial_sector
    from impact.drilling import CompliantHorn
    from impact.params import ImpactParams

    from .coupled import wideband_horn, wideband_modes
    from .stage_compliant import CompliantSettings, contact_laws, shortest_contact_time

    pos = [m for m in masses if m > 0]
    system = axial_sector(design)
    base = ImpactParams(spring_force=5.0)
    cs = CompliantSettings()
    t_c = shortest_contact_time(design, [min(pos), max(pos)], base, cs)
    cut = round(cs.cutoff_factors[-1] / t_c, -2)
    modes = wideband_modes(system, cut)
    w = working_mode(system, modes.f_r_hz, modes.vectors, float(design.target_frequency))
    f = float(np.round(modes.f_r_hz[w], 1))
    horn, g, _ = wideband_horn(system, f, cut, voltage, q_mech=q_mech, modes=modes, say=say)
    laws = tuple(contact_laws(design, m, base.e2, base.e1, cs)[:2] for m in pos)
    return f, cut, CompliantHorn(horn, g, laws)


def drilling_stage(base, masses, amplitudes: dict, wob: float, seed: int, say=None, settings=None,
                   window=(0.02, 0.22), horn=None, horn_members: int = 16) -> dict:
    """Run the drilling sweep. ``base``: the impact stage's ImpactParams (freq, horn mass);
    ``amplitudes``: free mass (kg) -> A0 (m), the others (0 g) get ``base.A0``; ``settings``: a
    :class:`impact.drilling.DrillSettings` (default: 5 %% rule, the given seed); ``window``:
    statistics window (s); ``horn``: ``(CompliantHorn, masses)`` of :func:`drill_horn` to drill on
    the compliant model too (``horn_members`` members per mass, a fixed count: its CIs are
    reported as they come), with the kinematic sweep as its comparison. Returns {"json", "result"}."""
    from impact.drilling import DrillParams, DrillSettings, DrillSweep, drilling_sweep, status_line

    p = DrillParams(impact=base.with_(spring_force=5.0), wob=wob, t_from=window[0], t_end=window[1])
    a0 = [amplitudes.get(m, base.A0) for m in masses]
    kin = DrillSweep(rows=drilling_sweep(p, masses, settings or DrillSettings(seed=seed), A0_values=a0), params=p)
    res = kin
    if horn is not None and horn[0] is not None and horn[1]:
        st = DrillSettings(seed=seed, n_start=horn_members, n_max=horn_members)
        rows = drilling_sweep(p, horn[1], st, horn=horn[0])
        res = DrillSweep(rows=rows, params=p, comparison=kin)
    if say is not None:
        top = res.rows[-1]
        say(f"      drilling at WOB {wob:g} N ({res.model} model): {top.m_free * 1e3:g} g -> "
            f"{top['drilling_rate_m_s'].scaled(6e4)} mm/min, depth after {p.drill_time:g} s "
            f"{top.depth_m.scaled(1e3)} mm (95 % CI); {status_line(res.model)}")
    return {"json": res.to_dict(), "result": res}


def _table(d: dict, ci) -> list[str]:
    amp = "free tip, FE horn (um)" if d.get("model") == "compliant" else "A0 (um)"
    lines = [f"| free mass (g) | {amp} | blows (Hz) | penetration per blow (um) | drilling rate (mm/min) "
             "| depth (mm) | efficiency (%) | members |", "|---|---|---|---|---|---|---|---|"]
    for r in d["rows"]:
        lines.append(f"| {r['m_free_kg'] * 1e3:g} | {r['A0_m'] * 1e6:.2f} | {ci(r['blow_rate_hz'])} "
                     f"| {ci(r['penetration_per_blow_m'], 1e6)} | {ci(r['drilling_rate_m_s'], 6e4)} "
                     f"| {ci(r['depth_after_drill_time_m'], 1e3)} | {ci(r['efficiency'], 100)} | {r['members']}"
                     + ("" if r["converged"] else " (cap)") + " |")
    return lines


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
    model = d.get("model", "kinematic")
    lines = ["", "## Drilling under load (bit on sandstone)", "",
             f"WOB {p['wob_n']:g} N, rock k_load {p['rock']['k_load_n_per_m']:.3g} N/m, k_unload "
             f"{p['rock']['k_unload_n_per_m']:.3g} N/m, threshold {p['rock']['f_threshold_n']:g} N (assumed sandstone "
             f"values); depth = drilling rate x {p['drill_time_s']:g} s; means with 95 % CIs over seeded members. The "
             "absolute depths rest on the assumed rock law; the trend with the free mass is the result to compare "
             "with the article's Fig. 14.", "",
             f"**Model ({model}):** {d['model_status'].get('model', model)}. **Status:** {d['model_status']['calibration']}. "
             f"Assumptions: {d['model_status']['assumptions']}. Use: {d['model_status']['use']}.", ""]
    lines += _table(d, _ci)
    cmp = d.get("comparison")
    if cmp is not None:
        lines += ["", f"Comparison, the kinematic model ({cmp['model_status'].get('model', 'kinematic')}, tool rod "
                  f"{p['rod']['diameter_m'] * 1e3:g} x {p['rod']['length_m'] * 1e3:g} mm, the horn at the loaded "
                  f"amplitude per free mass). Status: {cmp['model_status']['calibration']}.", ""]
        lines += _table(cmp, _ci)
    return lines
