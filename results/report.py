"""The report of an end-to-end run: headline numbers, tables, every figure, and where it came from.

Two files carry the same content: ``report.md`` (Markdown, links to the PNG files beside it) and
``report.html`` (one self-contained page: the figures embedded as ``data:`` URIs, no external
resource, so it opens anywhere and can be mailed as one file). The HTML is converted from the
same Markdown lines by :func:`markdown_to_html`, a converter for the small Markdown subset the
report uses, so the two cannot disagree and the pipeline needs no Markdown library.
"""

from __future__ import annotations

import base64
import html
import math
import re
from pathlib import Path

from rpud_common import atomic_write_text

from .errors import error_text as _pm
from .headline import HEADLINE_QUANTITIES, headline_record

__all__ = ["write_report", "write_report_html", "report_lines", "markdown_to_html", "escape_table_pipes",
           "table_cells", "headline_text", "headline_record", "ke_rows", "ci_text", "compliant_lines",
           "comparison_lines"]

#: a ``|x|`` inside a table cell (a magnitude such as ``|E|``): a pipe with a space before it and
#: a token after it; table separators are ``| `` or `` |`` (space inside) and never match
_CELL_PIPES = re.compile(r"(?<= )\|([^\s|\\]+)\|(?= )")


def _f(v, scale=1.0, fmt=".3g", unit=""):
    if v is None:
        return "-"
    return f"{v * scale:{fmt}}{(' ' + unit) if unit else ''}"


def ci_text(est: dict, scale: float = 1.0) -> str:
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


def escape_table_pipes(text: str) -> str:
    """Escape the pipes of ``|x|`` magnitudes in the Markdown table rows of ``text`` (``\\|E\\|``).

    A bare ``|E|`` in a cell splits it into extra columns, and the row no longer matches its
    header; GitHub, MyST and :func:`markdown_to_html` read ``\\|`` as a literal pipe. Lines that
    are not table rows are returned unchanged. Idempotent.
    """
    return "\n".join(_CELL_PIPES.sub(r"\\|\1\\|", ln) if ln.lstrip().startswith("|") else ln
                     for ln in text.split("\n"))


def table_cells(row: str) -> list[str]:
    """The cells of one Markdown table row (split on unescaped pipes, ``\\|`` kept as ``|``)."""
    body = row.strip()
    body = body[1:] if body.startswith("|") else body
    body = body[:-1] if body.endswith("|") and not body.endswith("\\|") else body
    return [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", body)]


def headline_text(s: dict) -> str | None:
    """One sentence with the headline result (:func:`headline_record`, or the summary's
    ``headline`` block): tool kinetic energy, impact rate and power at the reference free mass,
    mean ± 95 % CI ± model form on the compliant model; on the kinematic horn (the compliant stage
    skipped) mean ± 95 % CI with the horn-tip amplitude A0 it used and why. None when the summary
    has no such row."""
    rec = s.get("headline") or headline_record(s)
    if rec is None:
        return None
    m = rec["m_free_kg"]
    if rec["model"] == "compliant_model":
        ke, rate, pw = (_pm2(rec[q], rec[q]["model_form"], k) for q, k, _ in HEADLINE_QUANTITIES)
        return (f"Headline (compliant contacts, device scenario, {m * 1e3:g} g free mass): tool kinetic energy "
                f"{ke} mJ per impact at {rate} Hz, {pw} W to the tool (mean ± 95 % CI ± model form).")
    a0 = s["A0"]
    return (f"Headline (device scenario, {m * 1e3:g} g free mass): tool kinetic energy "
            f"{ci_text(rec['mean_tool_ke_after_j'], 1e3)} mJ per impact at {ci_text(rec['tool_impact_rate_hz'])} Hz, "
            f"{ci_text(rec['tool_power_w'])} W to the tool; horn-tip amplitude A0 "
            f"{_pm(a0['used_m'], a0.get('used_m_error'), 'um', 1e6)} (kinematic horn, 95 % CI; "
            f"{rec['model_form_note']}).")


def _provenance_lines(s: dict) -> list[str]:
    """The provenance table: the summary's record when it has one, else this process's."""
    prov = s.get("provenance")
    if not prov:
        from rpud_common import provenance_record

        prov = provenance_record()
    names = (("rpud_version", "rpud version"), ("git_commit", "git commit"), ("command", "command line"),
             ("date_utc", "date (UTC)"), ("python", "Python"))
    rows = [f"| {label} | `{prov[k]}` |" if prov.get(k) is not None else f"| {label} | unknown |"
            for k, label in names if k in prov]
    return ["## Provenance", "", "| item | value |", "|---|---|", *rows, ""]


def write_report(s: dict, path, *, html_path=None, asset_dir=None) -> Path:
    """Write ``report.md`` and, beside it, the self-contained ``report.html`` from the run summary.

    Parameters
    ----------
    s : dict
        The run summary (see :func:`results.pipeline.run_pipeline`).
    path : path-like
        The Markdown file.
    html_path : path-like, optional
        The HTML file; default ``report.html`` in the folder of ``path``.
    asset_dir : path-like, optional
        The folder the summary's figure paths are relative to (default: the folder of ``path``).

    Returns
    -------
    Path
        The Markdown file.
    """
    path = Path(path)
    lines = report_lines(s)
    out = atomic_write_text(path, "\n".join(lines))
    write_report_html(s, path.with_name("report.html") if html_path is None else html_path,
                      asset_dir=path.parent if asset_dir is None else asset_dir, lines=lines)
    return out


def write_report_html(s: dict, path, *, asset_dir, lines: list[str] | None = None) -> Path:
    """Write the self-contained HTML report: the Markdown report's content, tables as HTML tables,
    every figure embedded from ``asset_dir`` as a base64 ``data:image/png`` URI."""
    lines = report_lines(s) if lines is None else lines
    title = lines[0].lstrip("# ").strip() if lines else "RPUD report"
    return atomic_write_text(path, markdown_to_html(lines, asset_dir, title=title))


def report_lines(s: dict) -> list[str]:
    """The Markdown lines of the report (see :func:`write_report`)."""
    from .rotor_stage import report_lines as rotor_report_lines
    from .stress_stage import report_lines as stress_lines

    lines = _heading_lines(s) + _summary_table_lines(s)
    if s.get("compliant_model"):           # the headline first, then the models it replaces
        lines += compliant_lines(s["compliant_model"], s.get("files", {}).get("figures", {}).get(
            "compliant_energy_power")) + comparison_lines(s)
    lines += _kinetic_energy_lines(s) + _coupled_model_lines(s.get("coupled_model"))
    if s.get("drilling"):                      # opt-in stage (python -m results --load rock)
        from .drilling import report_lines as drilling_lines

        lines += drilling_lines(s["drilling"])
    lines += [""] + stress_lines(s.get("stress"))
    lines += rotor_report_lines(s.get("rotor"))
    lines += _figure_lines(s) + _timing_lines(s["timings"]) + _provenance_lines(s)
    return escape_table_pipes("\n".join(lines)).split("\n")


def _heading_lines(s: dict) -> list[str]:
    """The title, the headline, the operating point and the resonance matching."""
    from .operating_point import report_lines as operating_point_lines

    lines = [f"# RPUD end-to-end run: {s['design'].get('name', 'design')}", ""]
    head = headline_text(s)
    if head:
        name, _, rest = head.partition(": ")
        lines += [f"**{name}:** {rest}", ""]
    lines += operating_point_lines(s)
    m = s["matching"]
    if m:
        tuned = ", ".join(f"`{k}` {v * 1e3:.3f} mm (start {m['start'][k] * 1e3:.3f})" for k, v in m["tuned"].items())
        lines += [f"**Resonance matching** to {m['target_hz'] / 1e3:.3f} kHz: {tuned}; "
                  f"{m['n_iterations']} iterations, {'converged' if m['converged'] else 'NOT converged'} "
                  f"(error {m['error_rel'] * 100:+.3f} %). Flange axial motion / tip: "
                  f"{m['flange_to_tip_axial_ratio']:.3f}.", ""]
    return lines


def _teeth_mesh(h: dict) -> str:
    """Where the teeth motion was solved when not on the run's mesh (results.stage_teeth)."""
    tm = h.get("teeth_mesh") or {}
    return f"; on {tm['label']}, {tm['ndof']} DOFs" if tm.get("ndof") else ""


def _summary_table_lines(s: dict) -> list[str]:
    """The quantity / value table of the transducer (mesh, working mode, drive, A0) and its error note."""
    wm, h, a0 = s["working_mode"], s["harmonic"], s["A0"]
    return [
        "| quantity | value |", "|---|---|",
        f"| mesh | {s['mesh'].get('label') or s['mesh'].get('mesher')}: {s['mesh']['tetrahedra']} second-order "
        f"tetrahedra, {s['mesh']['ndof']} DOFs |",
        f"| working mode | #{wm['index'] + 1} {wm['label']}: f_r {_pm(wm['f_r_hz'], wm.get('f_r_hz_error'), 'Hz')}, "
        f"f_a {_pm(wm['f_a_hz'], wm.get('f_a_hz_error'), 'Hz')}, k_eff {_pm(wm['k_eff'], wm.get('k_eff_error'))} |",
        f"| tip amplitude per volt (Q_m {h['q_mech']}, {h.get('losses', {}).get('origin', 'given')}) | {_pm(h['tip_per_volt_m'], h.get('tip_per_volt_m_error'), 'nm/V', 1e9)} |",
        f"| tip amplitude per volt (datasheet losses, unloaded) | "
        f"{_pm(h['tip_per_volt_datasheet_losses_m'], h.get('tip_per_volt_datasheet_losses_m_error'), 'nm/V', 1e9)} |",
        f"| drive | {h['voltage_v']:g} V amplitude at {wm['f_r_hz'] / 1e3:.3f} kHz: {h['current_a']:.2f} A, {h['power_w']:.1f} W |",
        f"| teeth ellipse (tangential/axial, phase{_teeth_mesh(h)}) | {_pm(h['teeth_ellipse_ratio'], h.get('teeth_ellipse_ratio_error'))}, "
        f"{_pm(h['teeth_phase_deg'], h.get('teeth_phase_deg_error'), 'deg')} |",
        f"| admittance peak / dip | {_f(h['admittance_f_r_hz'], 1e-3, '.3f', 'kHz')} / {_f(h['admittance_f_a_hz'], 1e-3, '.3f', 'kHz')} |",
        f"| ring-up | time constant {h['ring_up_tau_s'] * 1e3:.2f} ms, steady {h['ring_up_steady_m'] * 1e6:.2f} um |",
        f"| **A0 used** ({a0['reference_m_free_kg'] * 1e3:g} g free mass, impact-loaded) | "
        f"**{_pm(a0['used_m'], a0.get('used_m_error'), 'um', 1e6)}** "
        f"(unloaded {_pm(a0['unloaded_m'], a0.get('unloaded_m_error'), 'um', 1e6)}; "
        f"article: {a0['article_assumption_m'] * 1e6:g} um) |",
        f"| impact load on the tip | {a0['impact_tip_damping_ns_per_m']:.2f} N s/m, {a0['impact_power_w']:.1f} W |",
        "", _error_note(s), "",
    ]


def _kinetic_energy_lines(s: dict) -> list[str]:
    """The drill-tool kinetic energy table against the free mass and its line fits."""
    rec = s.get("headline") or headline_record(s) or {}
    compliant = rec.get("model") == "compliant_model"
    lines = [
        "## " + ("Comparison rows: the kinematic horn" if compliant else "Drill-tool kinetic energy vs free mass"), "",
        "The horn as an infinite-mass driver at a given amplitude (the article's assumption 1). "
        "Means over converged ensembles with their 95 % confidence intervals "
        f"(members added until every CI is within {100 * s['settings']['impact_rel_tol']:g} % of its mean). " +
        ("These rows are comparisons: the headline is the compliant model's, above. **The device scenario "
         "leads**" if compliant else f"**Headline: the device scenario** ({rec.get('why', 'no compliant model')})") +
        " (restoring spring ~5 N on the free mass, steady operation: "
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
                     f"| {ci_text(r['device_fe']['mean_tool_ke_after_j'], 1e3)} | {ci_text(r['device_fe']['tool_impact_rate_hz'])} "
                     f"| {ci_text(r['device_fe']['tool_power_w'])} | {ci_text(r['article_fe']['mean_tool_ke_after_j'], 1e3)} "
                     f"| {ci_text(r['article_15um']['mean_tool_ke_after_j'], 1e3)} | {ci_text(r['article_fe']['tool_impact_rate_hz'])} |")
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
    return lines


def _coupled_model_lines(cm: dict | None) -> list[str]:
    """The coupled transducer / impact model's table and ring-up (nothing without that stage)."""
    if not cm:
        return []
    red = cm["reduced_transducer"]
    modes = ", ".join(f"{w / 2e3 / math.pi:.2f} kHz" for w in red["omega"])
    lines = ["", "## Comparison rows: the transducer in the impact loop with instantaneous impacts", "",
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
        lines.append(f"| {r['m_free_kg'] * 1e3:g} | {ci_text(c['tip_amplitude_m'], 1e6)} | {r['damper']['A0_m'] * 1e6:.2f} "
                     f"| {ci_text(c['mean_tool_ke_after_j'], 1e3)} | {ci_text(r['damper']['mean_tool_ke_after_j'], 1e3)} "
                     f"| {ci_text(r['kinematic_unloaded']['mean_tool_ke_after_j'], 1e3)} | {ci_text(c['drive_power_w'])} "
                     f"| {ci_text(c['horn_power_w'])} |")
    tail = cm["history"]["tail"]
    lines += ["", f"Ring-up from rest with the reference free mass in place ({cm['history']['t_end_s'] * 1e3:g} ms, "
              f"one sample): tip amplitude over the last {(tail['t_to_s'] - tail['t_from_s']) * 1e3:.0f} ms "
              f"{tail['tip_amplitude_m'] * 1e6:.2f} um, drive {tail['drive_power_w']:.1f} W, "
              f"{tail['drive_current_rms_a']:.3f} A rms; energy balance per interval in `summary.json`."]
    return lines


def _two_digits(x: float) -> str:
    """An uncertainty to 2 significant digits, without an exponent up to 10^5 (110, not 1.1e+02)."""
    if not math.isfinite(x) or x == 0 or not 100 <= abs(x) < 1e5:
        return f"{x:.2g}"
    return f"{float(f'{x:.2g}'):.0f}"


def _study_tol(settings: dict) -> str:
    """The study's own CI target in the compliant paragraph ('' when it has none)."""
    tol = settings.get("study_rel_tol")
    return "" if tol is None else f" ({tol:.0%} for the study's cases)"


def _pm2(est: dict, mf: float, scale: float, fmt: str = ".3g") -> str:
    """'mean ± CI ± model form' of an estimate's dict and its model-form estimate."""
    if est["mean"] is None:
        return "n/a"
    return (f"{est['mean'] * scale:{fmt}} ± {_two_digits(est['ci95_half_width'] * scale)} "
            f"± {_two_digits(mf * scale)}")


def _faces_text(ct: dict) -> str:
    """The contact faces of the compliant model's ``contact`` record, in words with units."""
    if ct.get("face") == "flat":
        return f"{ct['geometry']}, given"
    if ct.get("face_radius_from") == "given":
        return f"crowned face R = {ct['face_radius_m'] * 1e3:.2f} mm, given"
    return (f"crowned faces, R = {ct['face_radius_m'] * 1e3:.2f} mm at the heaviest free mass: "
            f"{ct['face_radius_from']}")


def compliant_lines(doc: dict | None, figure: str | None = None) -> list[str]:
    """The report's headline section, the compliant model: the answer per free mass with its two
    uncertainties (and ``figure``, its path relative to the report, below the table), the
    convergence study, and what is assumed and calibrated."""
    if not doc:
        return []
    cuts = ", ".join(f"{c / 1e3:.0f}" for c in doc["cutoffs_hz"])
    ct = doc["contact"]
    lines = ["", "## Headline: drill-tool kinetic energy vs free mass (compliant contacts)", "",
             f"The FE transducer's axial modes up to {doc['cutoffs_hz'][-1] / 1e3:.0f} kHz "
             f"({len(doc['modes_hz']) - 1} modes with the rigid translation left out, static residual "
             f"{doc['residual_m_per_n']:.3g} m/N of the rest) drive the free mass through Hertz contacts at the tip "
             f"and at the tool ({_faces_text(ct)}; "
             f"restitutions {ct['e_horn']:g} / {ct['e_tool']:g}). The cut-off is "
             f"{doc['cutoff_factors'][-1]:g} / t_c with t_c = {doc['contact_time_s'] * 1e6:.1f} us, the shortest "
             f"contact of the study. Device scenario ({doc['scenario']['spring_force_n']:g} N spring, "
             f"{doc['scenario']['t_from_s'] * 1e3:g} ms discarded, window to {doc['scenario']['t_end_s'] * 1e3:g} ms); "
             f"members from {doc['settings']['members']} per case, added until the CIs are within "
             f"{doc['settings']['rel_tol']:.0%}{_study_tol(doc['settings'])} or {doc['settings']['max_members']} are "
             "reached. Each value: mean ± 95 % sampling CI ± model-form estimate (the change between the two highest "
             "cut-offs plus half the spread between contact stiffness x0.5 and x2, each with its 95 % sampling "
             "half-width added).", "",
             "| free mass (g) | tool KE after impact (mJ) | tool impact rate (Hz) | tool power (W) | members "
             "| model form from |", "|---|---|---|---|---|---|"]
    for r in doc["rows"]:
        mf = r["model_form"]
        lines.append(f"| {r['m_free_kg'] * 1e3:g} | {_pm2(r['mean_tool_ke_after_j'], mf['mean_tool_ke_after_j'], 1e3)} "
                     f"| {_pm2(r['tool_impact_rate_hz'], mf['tool_impact_rate_hz'], 1.0)} "
                     f"| {_pm2(r['tool_power_w'], mf['tool_power_w'], 1.0)} | {r['members']} | {r['model_form_from']} |")
    if figure:
        lines += ["", f"![compliant_energy_power]({figure})"]
    lines += ["", f"Convergence study (mode cut-offs {cuts} kHz; contact stiffness x"
              f"{' and x'.join(f'{f:g}' for f in doc['settings']['stiffness_factors'])} at the highest cut-off):", "",
              "| free mass | case | tool KE after impact (mJ) | tool impact rate (Hz) |", "|---|---|---|---|"]
    for mass, st in doc["study"].items():
        for c in st["cutoff"]:
            lines.append(f"| {mass} | modes to {c['cutoff_hz'] / 1e3:.0f} kHz | {ci_text(c['mean_tool_ke_after_j'], 1e3)} "
                         f"| {ci_text(c['tool_impact_rate_hz'])} |")
        for c in st["stiffness"]:
            lines.append(f"| {mass} | contact stiffness x{c['stiffness_factor']:g} | "
                         f"{ci_text(c['mean_tool_ke_after_j'], 1e3)} | {ci_text(c['tool_impact_rate_hz'])} |")
    lines += ["", "Assumed: " + "; ".join(doc["assumed"]) + ". Calibrated: " + "; ".join(doc["calibrated"]) + "."]
    return lines



def comparison_lines(s: dict) -> list[str]:
    """One paragraph setting the headline (the compliant model at the headline free mass) beside
    the horn models it replaces, and why they differ (nothing without the compliant stage)."""
    rec = s.get("headline") or headline_record(s)
    if not rec or rec["model"] != "compliant_model":
        return []
    m, cmp_ = rec["m_free_kg"], rec["comparison_tool_ke_j"]
    parts = [f"**Comparison at {m * 1e3:g} g** (tool KE after impact, mJ, device scenario): compliant contacts "
             f"{_pm2(rec['mean_tool_ke_after_j'], rec['mean_tool_ke_after_j']['model_form'], 1e3)} "
             "(95 % CI, model form)"]
    names = {"kinematic_damper_a0": "kinematic horn at the impact-loaded amplitude (the damper variant: the "
                                    "device-scenario rows below)",
             "kinematic_unloaded_a0": "kinematic horn at the unloaded amplitude (the article's assumption 1, "
                                      "an immovable driver)",
             "newton_working_band": "FE modes of the working band with instantaneous (Newton) impacts"}
    parts += [f"{names[k]} {ci_text(v, 1e3)}" for k, v in cmp_.items() if v is not None]
    return ["", "; ".join(parts) + ". Why they differ: a kinematic horn has infinite mass and cannot recoil, "
            "so every knock returns the free mass as if from an immovable wall; the damper variant only "
            "lowers that horn's amplitude by the power an infinite-mass horn would spend on the free mass "
            "(its amplitude resembles the coupled model's by coincidence, and the tip meets the free mass "
            "above the window's mean amplitude, not below it). With instantaneous impacts every mode "
            "answers a knock, so the tip the free mass meets keeps getting lighter as modes are added and the "
            "answer does not converge; the working-band model keeps only the modes near the drive and treats "
            "the rest as rigid. A compliant contact lasts a finite time: the modes well above its contact "
            "frequency answer quasi-statically (the residual), those below it dynamically, so the answer "
            "converges with the cut-off, and the study above measures how far it still moves."]


def _figure_lines(s: dict) -> list[str]:
    """The reproducibility note, the figures, the mode-shape renders and the ParaView file."""
    lines = ["", "The same command on the same machine repeats these numbers exactly: seeded ensembles, "
             f"and A0 handed to the impacts rounded to {s['impacts']['handoff']['A0_digits']} significant digits.", "",
             "## Figures", ""]
    shown = {"compliant_energy_power"} if s.get("compliant_model") else set()   # in the headline section
    for name, rel in s["files"]["figures"].items():
        if name in shown:
            continue
        lines.append(f"![{name}]({rel})")
        lines.append("")
    if s["files"]["renders"]:
        lines += ["## Mode shapes", ""]
        lines += [f"![{Path(r).stem}]({r})" for r in s["files"]["renders"]]
        lines.append("")
    if s["files"]["vtu"]:
        lines += [f"Every computed mode as point data for ParaView: `{s['files']['vtu']}` (not committed).", ""]
    return lines


def _timing_lines(t: dict) -> list[str]:
    """The stage timings, s, as a one-row table."""
    return ["## Timings (s)", "", "| " + " | ".join(t) + " |", "|" + "---|" * len(t),
            "| " + " | ".join(f"{v:.1f}" for v in t.values()) + " |", ""]


def _error_note(s: dict) -> str:
    """How the ``±`` of the table above were obtained (or that they were not)."""
    e = s.get("discretisation_error")
    if not e:
        return f"FE values without a discretisation-error estimate ({s.get('discretisation_error_note', 'none made')})."
    return (f"± : estimated discretisation error of the FE values ({e['method']}). The amplitudes carry the relative "
            "error of the tip amplitude per volt; the impact statistics below have their own 95 % CIs.")


_IMG = re.compile(r"^!\[([^\]]*)\]\(([^)\s]+)\)$")
_CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; max-width: 72rem; margin: 2rem auto;
       padding: 0 1rem; line-height: 1.45; color: #1b1b1b; background: #ffffff; }
h1 { font-size: 1.6rem; border-bottom: 2px solid #1f5f99; padding-bottom: .3rem; }
h2 { font-size: 1.25rem; margin-top: 2rem; color: #1f5f99; }
.headline { background: #eef5fb; border-left: 5px solid #1f5f99; padding: .6rem 1rem; font-size: 1.05rem; }
table { border-collapse: collapse; margin: .8rem 0; font-size: .85rem; }
th, td { border: 1px solid #c8c8c8; padding: .25rem .5rem; text-align: left; vertical-align: top; }
th { background: #f0f0f0; }
tr:nth-child(even) td { background: #fafafa; }
code { background: #f3f3f3; padding: 0 .2rem; border-radius: 3px; font-size: .9em; }
figure { margin: 1rem 0; }
figure img { max-width: 100%; height: auto; border: 1px solid #e0e0e0; }
figcaption { font-size: .8rem; color: #555; }
"""


def _inline(text: str) -> str:
    """HTML of one line of report Markdown: ``**bold**``, ```code```, ``\\|`` as a pipe; the rest escaped."""
    parts = re.split(r"(`[^`]*`)", text)
    out = []
    for p in parts:
        if len(p) >= 2 and p.startswith("`") and p.endswith("`"):
            out.append(f"<code>{html.escape(p[1:-1])}</code>")
        else:
            t = html.escape(p.replace("\\|", "|"), quote=False)
            out.append(re.sub(r"\*\*(.+?)\*\*", r"<strong>\1</strong>", t))
    return "".join(out)


def _data_uri(src: str, asset_dir) -> str:
    """The image file ``asset_dir/src`` as a ``data:`` URI (PNG, SVG, JPEG by suffix)."""
    f = Path(asset_dir) / src
    mime = {".png": "image/png", ".svg": "image/svg+xml", ".jpg": "image/jpeg",
            ".jpeg": "image/jpeg"}.get(f.suffix.lower(), "application/octet-stream")
    return f"data:{mime};base64,{base64.b64encode(f.read_bytes()).decode('ascii')}"


def markdown_to_html(lines: list[str], asset_dir, *, title: str = "RPUD report") -> str:
    """A self-contained HTML page from the report's Markdown lines.

    The subset the report writes: ``#``/``##`` headings, pipe tables (header, separator, rows),
    ``- `` bullets with indented continuation lines, images alone on a line (embedded from
    ``asset_dir`` as base64 data URIs), paragraphs with ``**bold**`` and ```code```. The first
    bold-led paragraph after the title (the headline) is set apart in a box.

    Raises
    ------
    FileNotFoundError
        A figure named in the report is missing from ``asset_dir``: a report must not show a
        broken image.
    """
    body: list[str] = []
    i, n = 0, len(lines)
    headline_done = False
    while i < n:
        ln = lines[i]
        s = ln.strip()
        if not s:
            i += 1
        elif s.startswith("## "):
            body.append(f"<h2>{_inline(s[3:])}</h2>")
            i += 1
        elif s.startswith("# "):
            body.append(f"<h1>{_inline(s[2:])}</h1>")
            i += 1
        elif s.startswith("|"):
            rows = []
            while i < n and lines[i].strip().startswith("|"):
                rows.append(table_cells(lines[i]))
                i += 1
            has_head = len(rows) > 1 and all(re.fullmatch(r":?-{3,}:?", c) for c in rows[1])
            head, data = (rows[0], rows[2:]) if has_head else (None, rows)
            t = ["<table>"]
            if head is not None:
                t.append("<thead><tr>" + "".join(f"<th>{_inline(c)}</th>" for c in head) + "</tr></thead>")
            t.append("<tbody>" + "".join("<tr>" + "".join(f"<td>{_inline(c)}</td>" for c in r) + "</tr>"
                                         for r in data) + "</tbody></table>")
            body.append("".join(t))
        elif _IMG.match(s):
            while i < n and _IMG.match(lines[i].strip()):
                alt, src = _IMG.match(lines[i].strip()).groups()
                body.append(f'<figure><img src="{_data_uri(src, asset_dir)}" alt="{html.escape(alt)}">'
                            f"<figcaption>{html.escape(alt)} ({html.escape(src)})</figcaption></figure>")
                i += 1
        elif s.startswith("- "):
            items = []
            while i < n and (lines[i].strip().startswith("- ") or (lines[i].startswith("  ") and lines[i].strip())):
                if lines[i].strip().startswith("- "):
                    items.append(lines[i].strip()[2:])
                else:
                    items[-1] += " " + lines[i].strip()
                i += 1
            body.append("<ul>" + "".join(f"<li>{_inline(t)}</li>" for t in items) + "</ul>")
        else:
            para = []
            while i < n and lines[i].strip() and not lines[i].strip().startswith(("#", "|", "- ")) \
                    and not _IMG.match(lines[i].strip()):
                para.append(lines[i].strip())
                i += 1
            text = " ".join(para)
            if not headline_done and text.startswith("**Headline"):
                body.append(f'<p class="headline" id="headline">{_inline(text)}</p>')
                headline_done = True
            else:
                body.append(f"<p>{_inline(text)}</p>")
    return ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
            f"<title>{html.escape(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n"
            + "\n".join(body) + "\n</body>\n</html>\n")
