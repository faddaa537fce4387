"""The Markdown report of an end-to-end run: headline numbers, tables, links to every figure."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from geometry.common import atomic_write_text


def _f(v, scale=1.0, fmt=".3g", unit=""):
    if v is None:
        return "-"
    return f"{v * scale:{fmt}}{(' ' + unit) if unit else ''}"


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
        f"| mesh | {s['mesh']['tetrahedra']} second-order tetrahedra, {s['mesh']['ndof']} DOFs |",
        f"| working mode | #{wm['index'] + 1} {wm['label']}: f_r {wm['f_r_hz'] / 1e3:.3f} kHz, "
        f"f_a {_f(wm['f_a_hz'], 1e-3, '.3f', 'kHz')}, k_eff {wm['k_eff']:.3f} |",
        f"| tip amplitude per volt (Q_m {h['q_mech']}) | {h['tip_per_volt_m'] * 1e9:.1f} nm/V |",
        f"| tip amplitude per volt (datasheet losses, unloaded) | {h['tip_per_volt_datasheet_losses_m'] * 1e9:.1f} nm/V |",
        f"| drive | {h['voltage_v']:g} V at {wm['f_r_hz'] / 1e3:.3f} kHz: {h['current_a']:.2f} A, {h['power_w']:.1f} W |",
        f"| teeth ellipse (tangential/axial, phase) | {_f(h['teeth_ellipse_ratio'])}, {_f(h['teeth_phase_deg'], 1, '.1f', 'deg')} |",
        f"| admittance peak / dip | {_f(h['admittance_f_r_hz'], 1e-3, '.3f', 'kHz')} / {_f(h['admittance_f_a_hz'], 1e-3, '.3f', 'kHz')} |",
        f"| ring-up | time constant {h['ring_up_tau_s'] * 1e3:.2f} ms, steady {h['ring_up_steady_m'] * 1e6:.2f} um |",
        f"| **A0 used** ({a0['reference_m_free_kg'] * 1e3:g} g free mass, impact-loaded) | **{a0['used_m'] * 1e6:.2f} um** "
        f"(unloaded {a0['unloaded_m'] * 1e6:.2f} um; article: {a0['article_assumption_m'] * 1e6:g} um) |",
        f"| impact load on the tip | {a0['impact_tip_damping_ns_per_m']:.2f} N s/m, {a0['impact_power_w']:.1f} W |",
        "",
        "## Drill-tool kinetic energy vs free mass", "",
        "| free mass (g) | A0 (um) | tool KE, FE A0 (mJ) | tool KE, A0 = 15 um (mJ) | tool impact rate (Hz) |",
        "|---|---|---|---|---|",
    ]
    for r in s["kinetic_energy_table"]:
        sem = r.get("sem_tool_ke_j")
        ke = f"{r['mean_tool_ke_j'] * 1e3:.2f}" + (f" ± {sem * 1e3:.2f}" if sem is not None and np.isfinite(sem) else "")
        lines.append(f"| {r['m_free_kg'] * 1e3:g} | {_f(r['A0_m'], 1e6, '.2f')} | {ke} | "
                     f"{r['mean_tool_ke_article_j'] * 1e3:.2f} | {_f(r.get('tool_impact_rate_hz'), 1, '.0f')} |")
    imp = s["impacts"]
    lines += ["", "± is the standard error of the mean over the ensemble members (launch speeds spread "
              "±5 %). Reruns scatter by more than that: the free-mass bouncing is chaotic, so an "
              "amplitude that differs only in its last digits (threaded linear algebra does not "
              "round identically every run) gives other trajectories, and the impact-loaded A0 "
              "comes from a fixed point converged to 3 %.",
              "", f"Linear fit of KE against mass: {imp['fit_fe']['slope_j_per_kg']:.3g} J/kg "
              f"(R² {imp['fit_fe']['r2']:.3f}) with the FE amplitude; {imp['fit_article']['slope_j_per_kg']:.3g} J/kg "
              f"(R² {imp['fit_article']['r2']:.3f}) with the article's 15 um.", "", "## Figures", ""]
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
