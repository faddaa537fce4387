"""The Markdown report of an end-to-end run: headline numbers, tables, links to every figure."""

from __future__ import annotations

import math
from pathlib import Path


from rpud_common import atomic_write_text

from .errors import error_text as _pm


def _f(v, scale=1.0, fmt=".3g", unit=""):
    if v is None:
        return "-"
    return f"{v * scale:{fmt}}{(' ' + unit) if unit else ''}"


def _ci(est: dict, scale: float = 1.0) -> str:
    """'mean ± half-width' of an ``Estimate.to_dict()``: the half-width to 2 significant digits."""
    from impact.stats import Estimate

    if est["mean"] is None:
        return "n/a"
    hw = est["ci95_half_width"]
    return format(Estimate(est["mean"] * scale, math.nan if hw is None else hw * scale, est["members"]))


def ke_rows(sweeps: dict, with_zero: bool, coupled: dict | None = None) -> list[dict]:
    """The kinetic-energy table: one row per free mass, each sweep's statistics (JSON-safe)."""
    rows = [{"m_free_kg": 0.0, "note": "no free mass: no impacts, zero tool energy"}] if with_zero else []
    first = next(iter(sweeps.values()))
    for i, r in enumerate(first.rows):
        m = r.params.m_free
        row = {"m_free_kg": m, "A0_fe_m": coupled[m].A0 if coupled else r.params.A0}
        for key, sw in sweeps.items():
            e = sw.rows[i]
            row[key] = {"members": e.members, "converged": e.converged,
                        **{q: e.estimates[q].to_dict() for q in ("mean_tool_ke_after_j", "tool_impact_rate_hz",
                                                                 "tool_power_w", "mean_ke_gain_j")}}
        rows.append(row)
    return rows


def write_report(s: dict, path) -> Path:
    """Write ``report.md`` from the run summary (see :func:`results.pipeline.run_pipeline`)."""
    d, wm, h, a0 = s["design"], s["working_mode"], s["harmonic"], s["A0"]
    lines = [f"# RPUD end-to-end run: {d.get('name', 'design')}", ""]
    m = s["matching"]
    if m:
        tuned = ", ".join(f"`{k}` {v * 1e3:.3f} mm (start {m['start'][k] * 1e3:.3f})" for k, v in m["tuned"].items())
        lines += [f"**Resonance matching** to {m['target_hz'] / 1e3:.3f} kHz: {tuned}; "
                  f"{m['n_iterations']} iterations, {'converged' if m['converged'] else 'NOT converged'} "
                  f"(error {m['error_rel'] * 100:+.3f} %). Flange axial motion / tip: "
                  f"{m['flange_to_tip_axial_ratio']:.3f}.", ""]
    lines += [
        "| quantity | value |", "|---|---|",
        f"| mesh | {s['mesh']['tetrahedra']} second-order tetrahedra, {s['mesh']['ndof']} DOFs "
        f"({'stack, flange and horn swept' if s['mesh'].get('mesher') == 'revolve' else 'free'}) |",
        f"| working mode | #{wm['index'] + 1} {wm['label']}: f_r {_pm(wm['f_r_hz'], wm.get('f_r_hz_error'), 'Hz')}, "
        f"f_a {_pm(wm['f_a_hz'], wm.get('f_a_hz_error'), 'Hz')}, k_eff {_pm(wm['k_eff'], wm.get('k_eff_error'))} |",
        f"| tip amplitude per volt (Q_m {h['q_mech']}) | {_pm(h['tip_per_volt_m'], h.get('tip_per_volt_m_error'), 'nm/V', 1e9)} |",
        f"| tip amplitude per volt (datasheet losses, unloaded) | "
        f"{_pm(h['tip_per_volt_datasheet_losses_m'], h.get('tip_per_volt_datasheet_losses_m_error'), 'nm/V', 1e9)} |",
        f"| drive | {h['voltage_v']:g} V at {wm['f_r_hz'] / 1e3:.3f} kHz: {h['current_a']:.2f} A, {h['power_w']:.1f} W |",
        f"| teeth ellipse (tangential/axial, phase) | {_pm(h['teeth_ellipse_ratio'], h.get('teeth_ellipse_ratio_error'))}, "
        f"{_f(h['teeth_phase_deg'], 1, '.1f', 'deg')} |",
        f"| admittance peak / dip | {_f(h['admittance_f_r_hz'], 1e-3, '.3f', 'kHz')} / {_f(h['admittance_f_a_hz'], 1e-3, '.3f', 'kHz')} |",
        f"| ring-up | time constant {h['ring_up_tau_s'] * 1e3:.2f} ms, steady {h['ring_up_steady_m'] * 1e6:.2f} um |",
        f"| **A0 used** ({a0['reference_m_free_kg'] * 1e3:g} g free mass, impact-loaded) | "
        f"**{_pm(a0['used_m'], a0.get('used_m_error'), 'um', 1e6)}** "
        f"(unloaded {_pm(a0['unloaded_m'], a0.get('unloaded_m_error'), 'um', 1e6)}; "
        f"article: {a0['article_assumption_m'] * 1e6:g} um) |",
        f"| impact load on the tip | {a0['impact_tip_damping_ns_per_m']:.2f} N s/m, {a0['impact_power_w']:.1f} W |",
        "", _error_note(s), "",
        "## Drill-tool kinetic energy vs free mass", "",
        "Means over converged ensembles with their 95 % confidence intervals "
        f"(members added until every CI is within {100 * s['settings']['impact_rel_tol']:g} % of its mean). "
        "**Headline: the device scenario** (restoring spring ~5 N on the free mass, steady operation: "
        "20 ms discarded, 200 ms window), because it is how the drill runs; the article scenario "
        "(no spring, first 50 ms from the start) is the article's Fig. 8 model.", "",
        "| free mass (g) | A0 FE (um) | device: tool KE (mJ) | device: tool rate (Hz) | device: tool power (W) "
        "| article, FE A0: tool KE (mJ) | article, 15 um: tool KE (mJ) | article, FE A0: rate (Hz) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in s["kinetic_energy_table"]:
        if "device_fe" not in r:
            lines.append(f"| {r['m_free_kg'] * 1e3:g} | - | 0 | - | 0 | 0 | 0 | - |")
            continue
        lines.append(f"| {r['m_free_kg'] * 1e3:g} | {_pm(r['A0_fe_m'], r.get('A0_fe_m_error'), scale=1e6)} "
                     f"| {_ci(r['device_fe']['mean_tool_ke_after_j'], 1e3)} | {_ci(r['device_fe']['tool_impact_rate_hz'])} "
                     f"| {_ci(r['device_fe']['tool_power_w'])} | {_ci(r['article_fe']['mean_tool_ke_after_j'], 1e3)} "
                     f"| {_ci(r['article_15um']['mean_tool_ke_after_j'], 1e3)} | {_ci(r['article_fe']['tool_impact_rate_hz'])} |")
    imp = s["impacts"]
    lines += [""]
    for key, text in (("device_fe", "device, FE A0"), ("article_fe", "article scenario, FE A0"),
                      ("article_15um", "article scenario, A0 = 15 um")):
        fit = imp[key]["fit_ke_vs_mass"]
        if fit["slope"] is None:
            lines.append(f"- line fit of tool KE against mass ({text}): absent ({fit.get('reason', '')})")
        else:
            ci = f" ± {fit['slope_ci95_half_width']:.2g}" if fit["slope_ci95_half_width"] is not None else ""
            r2 = f", R² {fit['r2']:.3f}" if fit["r2"] is not None else f" ({fit.get('reason', '')})"
            lines.append(f"- line fit of tool KE against mass ({text}): {fit['slope']:.3g}{ci} J/kg{r2}")
        if not imp[key]["converged"]:
            lines.append("  (not every mass reached the CI target: see `summary.json`)")
    cm = s.get("coupled_model")
    if cm:
        red = cm["reduced_transducer"]
        modes = ", ".join(f"{w / 2e3 / math.pi:.2f} kHz" for w in red["omega"])
        lines += ["", "## Coupled model: the transducer in the impact loop", "",
                  f"The FE modes that carry tip motion ({red['rule']}: {modes}; effective tip mass "
                  f"{cm['tip_mass_kg'] * 1e3:.1f} g) driven at the working voltage exchange impulses with the free "
                  "mass, event by event (exact closed-form modal motion between impacts). Device scenario, modes "
                  "started on their steady response; means with 95 % CIs. Beside it: the kinematic horn at the "
                  "unloaded FE amplitude, and at the damper-corrected amplitude of the A0 loop above.", "",
                  "| free mass (g) | tip amplitude, coupled (um) | A0, damper (um) | tool KE: coupled (mJ) "
                  "| tool KE: damper A0 (mJ) | tool KE: kinematic, unloaded A0 (mJ) | drive power (W) | horn -> free mass (W) |",
                  "|---|---|---|---|---|---|---|---|"]
        for r in cm["rows"]:
            c = r["coupled"]
            lines.append(f"| {r['m_free_kg'] * 1e3:g} | {_ci(c['tip_amplitude_m'], 1e6)} | {r['damper']['A0_m'] * 1e6:.2f} "
                         f"| {_ci(c['mean_tool_ke_after_j'], 1e3)} | {_ci(r['damper']['mean_tool_ke_after_j'], 1e3)} "
                         f"| {_ci(r['kinematic_unloaded']['mean_tool_ke_after_j'], 1e3)} | {_ci(c['drive_power_w'])} "
                         f"| {_ci(c['horn_power_w'])} |")
        tail = cm["history"]["tail"]
        lines += ["", f"Ring-up from rest with the reference free mass in place ({cm['history']['t_end_s'] * 1e3:g} ms, "
                  f"one sample): tip amplitude over the last {(tail['t_to_s'] - tail['t_from_s']) * 1e3:.0f} ms "
                  f"{tail['tip_amplitude_m'] * 1e6:.2f} um, drive {tail['drive_power_w']:.1f} W, "
                  f"{tail['drive_current_rms_a']:.3f} A rms; energy balance per interval in `summary.json`."]
    if s.get("drilling"):                      # opt-in stage (python -m results --load rock)
        from .drilling import report_lines as drilling_lines

        lines += drilling_lines(s["drilling"])
    from .stress_stage import report_lines

    lines += [""] + report_lines(s.get("stress"))
    lines += ["", "The same command on the same machine repeats these numbers exactly: seeded ensembles, "
              f"and A0 handed to the impacts rounded to {imp['handoff']['A0_digits']} significant digits.", "",
              "## Figures", ""]
    for name, rel in s["files"]["figures"].items():
        lines.append(f"![{name}]({rel})")
        lines.append("")
    if s["files"]["renders"]:
        lines += ["## Mode shapes", ""]
        lines += [f"![{Path(r).stem}]({r})" for r in s["files"]["renders"]]
        lines.append("")
    if s["files"]["vtu"]:
        lines += [f"Every computed mode as point data for ParaView: `{s['files']['vtu']}` (not committed).", ""]
    t = s["timings"]
    lines += ["## Timings (s)", "", "| " + " | ".join(t) + " |", "|" + "---|" * len(t),
              "| " + " | ".join(f"{v:.1f}" for v in t.values()) + " |", ""]
    return atomic_write_text(path, "\n".join(lines))


def _error_note(s: dict) -> str:
    """How the ``±`` of the table above were obtained (or that they were not)."""
    e = s.get("discretisation_error")
    if not e:
        return f"FE values without a discretisation-error estimate ({s.get('discretisation_error_note', 'none made')})."
    return (f"± : estimated discretisation error of the FE values ({e['method']}). The amplitudes carry the relative "
            "error of the tip amplitude per volt; the impact statistics below have their own 95 % CIs.")
