"""The pipeline's operating point: drive, losses and what they move.

Everything downstream of the transducer scales with the drive voltage (its convention:
:mod:`rpud_common.voltage`) and with the assembled-transducer losses (:mod:`fem.losses`). This
stage states both and measures how far the losses move the headline: the working point, the
impact-loaded amplitude ``A0`` and the device-scenario tool energy at the reference free mass are
recomputed at Q/2 and 2Q (:data:`fem.losses.Q_BRACKET`) beside the default. The bracket is a
model-form range (the Q of the assembled drill is not known to better than that), not a
confidence interval; the tool energies in it carry their own 95 % CIs.
"""

from __future__ import annotations

import logging
import time

import numpy as np

log = logging.getLogger(__name__)

__all__ = ["operating_point_stage", "losses_bracket", "bracket_bases", "measured_settings", "preload_stage", "preload_unit",
           "preload_state", "bolt_row",
           "thermal_stage", "report_lines"]


def _tool_energy(base, ref_m: float, A0: float, stats_settings):
    """Device-scenario statistics of the tool at one free mass and amplitude (the headline's)."""
    from impact.sweeps import sweep

    row = sweep(base.with_(m_free=ref_m, A0=A0), [ref_m], scenario="device", settings=stats_settings,
                A0_values=[A0]).rows[0]
    return {q: row.estimates[q].to_dict() for q in ("mean_tool_ke_after_j", "tool_power_w")}


def _bracketed(settings) -> str:
    """Why the run has no Q/2, 2Q bracket ("" when it has one)."""
    losses = settings.losses()
    if not settings.losses_bracket:
        return "not computed (the run's losses_bracket setting is off)"
    if losses.q_mech is None:
        return "datasheet losses: no single Q to bracket"
    if losses.origin == "measured":
        return "measured losses (their CI in the source): no assumption to bracket"
    return ""


def bracket_bases(settings, system, modal, basis, f_w: float) -> dict:
    """The modal bases (:func:`fem.harmonic.modal_basis`) at the losses of :data:`fem.losses.Q_BRACKET`,
    factor -> basis, on ``basis``'s factorisation (empty when the losses have no bracket). Only
    the FE system enters, so the pipeline builds them beside the impact stages."""
    from fem.harmonic import modal_basis
    from fem.losses import Q_BRACKET

    if _bracketed(settings):
        return {}
    losses = settings.losses()
    return {factor: modal_basis(system, f_w, loss=losses.scaled(factor).loss_model(), modes=modal, reuse=basis)
            for factor in Q_BRACKET}


def losses_bracket(settings, system, modal, basis, f_w: float, surfaces, base, stats_settings, default: dict,
                   coupled_fn, say=None, bases: dict | None = None) -> dict:
    """The headline at Q/2 and 2Q beside the default losses.

    Parameters
    ----------
    settings : results.pipeline.PipelineSettings
    system, modal, basis : the pipeline's FE system, modes and modal basis (default losses)
    f_w : working frequency, Hz
    surfaces : the working point's surfaces, tip first
    base : impact.params.ImpactParams of the headline (frequency and horn mass of the FE run)
    stats_settings : impact.stats.StatsSettings
    default : the default's row (``q_mech``, ``tip_amplitude_m``, ``power_w``, ``A0_m``, tool statistics)
    coupled_fn : :func:`results.pipeline.coupled_amplitudes` (the pipeline's A0 <-> impacts loop)
    bases : :func:`bracket_bases` of these arguments, when already built (else built here)

    Returns
    -------
    dict
        ``losses`` (record of the default losses), ``rows`` (default, Q/2, 2Q) and ``note``.
    """
    from fem.harmonic import working_point

    t0 = time.perf_counter()
    losses = settings.losses()
    out = {"losses": losses.record(), "rows": [{"factor": 1.0, **default}], "note": _bracketed(settings)}
    if out["note"]:
        return out
    bases = bases if bases is not None else bracket_bases(settings, system, modal, basis, f_w)
    ref_m = settings.reference_m_free
    omega = 2 * np.pi * f_w
    for factor, b in bases.items():
        loss = b.loss
        wp = working_point(system, f_w, settings.voltage, loss=loss, surfaces=surfaces, basis=b)

        def point(c, b=b, loss=loss):
            return working_point(system, f_w, settings.voltage, loss=loss, surfaces=surfaces[:1], basis=b,
                                 tip_damping=c).tip_amplitude_m

        if settings.couple_impacts:
            amp = coupled_fn(point, base, [ref_m], omega=omega, scenario="device", settings=stats_settings,
                                     digits=settings.handoff_digits)[ref_m].A0
        else:
            from .coupled import round_sig

            amp = round_sig(wp.tip_amplitude_m, settings.handoff_digits)
        row = {"factor": factor, "q_mech": loss.q_mech, "tip_amplitude_m": wp.tip_amplitude_m,
               "power_w": wp.power_w, "A0_m": amp, **_tool_energy(base, ref_m, amp, stats_settings)}
        out["rows"].append(row)
        if say is not None:
            ke = row["mean_tool_ke_after_j"]
            say(f"      Q_mech {loss.q_mech:g}: tip {wp.tip_amplitude_m * 1e6:.2f} um unloaded, {wp.power_w:.1f} W, "
                f"A0 {amp * 1e6:.2f} um, tool KE {ke['mean'] * 1e3:.3g} ± {ke['ci95_half_width'] * 1e3:.2g} mJ")
    out["seconds"] = time.perf_counter() - t0
    return out


def operating_point_stage(settings, system, modal, basis, f_w: float, surfaces, base, stats_settings, wp, ref,
                          device_sweep, coupled_fn, say=None, bases: dict | None = None) -> dict:
    """The operating-point record of the pipeline (``summary.json["operating_point"]``).

    ``wp`` is the unloaded working point at the default losses, ``ref`` the impact-loaded
    amplitude at the reference free mass (:class:`results.pipeline.CoupledAmplitude`),
    ``device_sweep`` the headline sweep (its row at the reference mass is the default's energy),
    ``coupled_fn`` the pipeline's A0 loop and ``bases`` the bracket's modal bases if built
    (:func:`losses_bracket`).
    """
    drive = settings.drive()
    losses = settings.losses()
    row = next((r for r in device_sweep.rows if np.isclose(r.params.m_free, settings.reference_m_free)), None)
    energy = (_tool_energy(base, settings.reference_m_free, ref.A0, stats_settings) if row is None else
              {q: row.estimates[q].to_dict() for q in ("mean_tool_ke_after_j", "tool_power_w")})
    default = {"q_mech": settings.q_mech, "tip_amplitude_m": wp.tip_amplitude_m, "power_w": wp.power_w,
               "A0_m": ref.A0, **energy}
    if say is not None:
        say(f"      operating point: {drive.text()} at {f_w:.1f} Hz; {losses.short()}")
    return {"drive": {**drive.record(), "text": drive.text(), "freq_hz": f_w},
            "thermal": thermal_stage(settings, system, basis, f_w, surfaces, ref, say),
            "losses_text": losses.text(),
            "losses_bracket": losses_bracket(settings, system, modal, basis, f_w, surfaces, base, stats_settings,
                                             default, coupled_fn, say=say, bases=bases)}


def thermal_stage(settings, system, basis, f_w: float, surfaces, ref, say=None) -> dict:
    """Heat and temperature at the drill's operating state: the working point loaded by the
    impacts of the reference free mass (the tip damper of the A0 loop), continuous drive
    (:func:`fem.thermal.thermal_summary`); the heat is the input minus the power the impacts take."""
    from fem.harmonic import working_point
    from fem.thermal import thermal_summary

    wp = working_point(system, f_w, settings.voltage, loss=basis.loss, surfaces=surfaces[:1], basis=basis,
                       tip_damping=ref.tip_damping)
    delivered = 0.5 * ref.tip_damping * (2 * np.pi * f_w * wp.tip_amplitude_m) ** 2
    rec = thermal_summary(system, wp.x, f_w, basis.L, wp.power_w, delivered)
    for line in rec.pop("lines"):
        if say is not None:
            say(f"      {line}")
    rec["state"] = (f"working point loaded by the impacts of the {settings.reference_m_free * 1e3:g} g free mass "
                    f"(tip damper {ref.tip_damping:.3g} N s/m), continuous drive")
    return rec


def measured_settings(settings, system, modal, w: int, say=None):
    """``settings`` with the losses of its measured admittance sweep (``settings.admittance``): the
    Butterworth-Van Dyke fit nearest the working mode ``w``, calibrated on the FE mode
    (:func:`fem.bvd.measured_losses`)."""
    import dataclasses

    from fem.bvd import fit_bvd, measured_losses, read_admittance

    losses, fit = measured_losses(system, modal, w, fit_bvd(read_admittance(settings.admittance)))
    if say is not None:
        say(f"      admittance fit ({settings.admittance}): {fit.text()}")
    return dataclasses.replace(settings, q_mech=losses.q_mech, tan_delta=losses.tan_delta, losses_origin="measured",
                               losses_source=losses.source)


def preload_unit(system):
    """The bolt's static state under a unit preload (:func:`fem.preload.preload_solve` at 1 N) of
    ``system``, or the ParameterError of a design without two stack end electrodes (no bolt to
    model). Only the FE system enters, so the pipeline solves it beside the harmonic stage."""
    from fem.preload import preload_solve
    from rpud_common import ParameterError

    try:
        return preload_solve(system, 1.0)
    except ParameterError as exc:
        return exc


def preload_stage(design, system, wp, say=None, unit=None):
    """The bolt's static state and the preload window of every ring at the working point.

    Returns ``(state, record)``: the :class:`fem.preload.PreloadState` of the design's bolt
    (None without one; the stress stage adds it) and ``summary.json["operating_point"]
    ["preload"]`` (the windows, the largest drive with a window, and a verdict that says why a
    failing design fails and what would fix it). ``unit``: :func:`preload_unit` of ``system``
    when already solved (else solved here)."""
    from fem.preload import design_preload, preload_windows
    from rpud_common import ParameterError

    t0 = time.perf_counter()
    unit = preload_unit(system) if unit is None else unit
    if isinstance(unit, ParameterError):         # a design without two stack end electrodes has no bolt to model
        return None, {"verdict": f"no preload window: {unit}", "ok": None}
    win = preload_windows(system, wp.x, wp.voltage, wp.tip_amplitude_m, design_preload(design), unit_state=unit)
    rec = {**win.record(), "bolt_prestress_pa": getattr(getattr(design, "stack", None), "bolt_prestress", None),
           "seconds": time.perf_counter() - t0}
    if say is not None:
        say(f"      preload: {win.verdict()}")
    return preload_state(design, unit), rec


def preload_state(design, unit):
    """The :class:`fem.preload.PreloadState` of the design's bolt from the unit state ``unit``
    (:func:`preload_unit`), or None: no bolt preload, or no bolt to model."""
    from fem.preload import design_preload
    from rpud_common import ParameterError

    force = design_preload(design)
    return None if isinstance(unit, ParameterError) or not force > 0 else unit.scaled(force)


def _ci(d: dict, scale: float = 1.0) -> str:
    if d.get("mean") is None:
        return "n/a"
    hw = d.get("ci95_half_width")
    return f"{d['mean'] * scale:.3g}" + ("" if hw is None else f" ± {hw * scale:.2g}")


def report_lines(s: dict) -> list[str]:
    """The report's operating-point section (empty without an operating-point record)."""
    op = s.get("operating_point")
    if not op:
        return []
    drive = op["drive"]
    br = op["losses_bracket"]
    lines = ["## Operating point", ""] + summary_lines(s) + [
             f"**Drive:** {drive['text']} at {drive['freq_hz'] / 1e3:.3f} kHz (the voltage is read as an "
             "amplitude unless given with --voltage-rms).", "",
             f"**Losses:** {op['losses_text']}.", ""]
    if len(br["rows"]) > 1:
        lines += ["How far the assumed losses move the headline (device scenario, reference free mass; the "
                  "tool energies with their 95 % CIs):", "",
                  "| Q_mech | tip amplitude, unloaded (um) | input power, unloaded (W) | A0, impact-loaded (um) "
                  "| tool KE (mJ) | tool power (W) |", "|---|---|---|---|---|---|"]
        for r in br["rows"]:
            tag = " (default)" if r["factor"] == 1.0 else f" ({r['factor']:g} Q)"
            lines.append(f"| {r['q_mech']:g}{tag} | {r['tip_amplitude_m'] * 1e6:.3g} | {r['power_w']:.3g} "
                         f"| {r['A0_m'] * 1e6:.3g} | {_ci(r['mean_tool_ke_after_j'], 1e3)} "
                         f"| {_ci(r['tool_power_w'])} |")
        lines.append("")
    elif br.get("note"):
        lines += [f"Losses bracket: {br['note']}.", ""]
    return lines + _preload_lines(op.get("preload")) + _thermal_lines(op.get("thermal"))


def _thermal_lines(th: dict | None) -> list[str]:
    """Heat and the lumped temperature."""
    if not th:
        return []
    h = th["heat"]
    lines = [f"**Heat** ({th['state']}): {h['total_w']:.3g} W (mechanical {h['mechanical_w']:.3g} W, dielectric "
             f"{h['dielectric_w']:.2g} W) of {th['input_w']:.3g} W drawn, {th['delivered_w']:.3g} W to the impacts "
             f"(balance residual {th['balance_residual_w']:.2g} W: the modal solution's).", ""]
    t = th.get("temperature")
    if t is None:
        return lines
    reach = "; ".join(f"{m} rated {t['rated_c'][m]:g} °C " + ("not reached" if v is None else f"reached after {v:.0f} s")
                      for m, v in t["time_to_rated_s"].items())
    hr = th["final_c_h_range"]
    lines += [f"**Temperature** (one lumped body: {t['mass_kg'] * 1e3:.0f} g, {t['heat_capacity_j_per_k']:.0f} J/K, "
              f"{t['area_m2'] * 1e4:.0f} cm², natural convection h {t['h_w_per_m2k']:g} W/m²/K, ambient "
              f"{t['ambient_c']:g} °C, duty {t['duty']:g}): {t['final_c']:.0f} °C after {t['duration_s']:g} s "
              f"({' / '.join(f'{v:.0f} °C at h {k}' for k, v in hr.items())}); time constant {t['tau_s']:.0f} s, "
              f"steady {t['steady_c']:.0f} °C; {reach}. The ceramic, in the middle of the stack, runs hotter "
              "than this mean.", "", f"**{th['verdict']}**", ""]
    return lines


def _pm(v, err, unit: str, scale: float = 1.0, fmt: str = ".3g") -> str:
    if v is None:
        return "n/a"
    return f"{v * scale:{fmt}}" + ("" if err is None else f" ± {err * scale:.2g}") + f" {unit}"


def summary_lines(s: dict) -> list[str]:
    """The operating point in one table: every number with its uncertainty (discretisation error,
    95 % CI or the model-form bracket of the least known input)."""
    op, h, a0 = s["operating_point"], s["harmonic"], s["A0"]
    rows = {r["factor"]: r for r in op["losses_bracket"]["rows"]}
    lo, hi = rows.get(0.5), rows.get(2.0)

    def brk(key, scale, unit, fmt=".3g"):
        if lo is None or hi is None:
            return op["losses_bracket"].get("note") or "-"
        a, b = (r[key]["mean"] if isinstance(r[key], dict) else r[key] for r in (lo, hi))
        if a is None or b is None:
            return "n/a"
        return f"{a * scale:{fmt}} .. {b * scale:{fmt}} {unit} at Q_mech {lo['q_mech']:g} .. {hi['q_mech']:g}"

    d, pre, th = op["drive"], op.get("preload") or {}, op.get("thermal") or {}
    ke = rows[1.0]["mean_tool_ke_after_j"]
    lines = ["| operating point | value | uncertainty / range |", "|---|---|---|",
             f"| drive | {d['text']} at {d['freq_hz'] / 1e3:.3f} kHz | input (convention stated) |",
             f"| losses | Q_mech {h['q_mech'] if h['q_mech'] is not None else 'datasheet'} "
             f"({h.get('losses', {}).get('origin', '')}) "
             f"| {'Q/2 .. 2Q below' if lo else op['losses_bracket'].get('note', '-')} |",
             f"| tip amplitude, unloaded | {_pm(h['tip_amplitude_m'], h.get('tip_amplitude_m_error'), 'um', 1e6)} "
             f"(discretisation) | {brk('tip_amplitude_m', 1e6, 'um')} |",
             f"| A0, loaded by the impacts | {_pm(a0['used_m'], a0.get('used_m_error'), 'um', 1e6)} | "
             f"{brk('A0_m', 1e6, 'um')} |",
             f"| input power, unloaded | {h['power_w']:.3g} W | {brk('power_w', 1, 'W')} |"]
    if pre.get("rings"):
        hi_n = "-" if pre["p_max_n"] is None else _pm(pre["p_max_n"], pre.get("p_max_n_error"), "", 1e-3, ".1f").strip()
        vmax = ("-" if pre["voltage_max_v"] is None else
                _pm(pre["voltage_max_v"], pre.get("voltage_max_v_error"), "V amplitude", 1.0, ".4g"))
        lines.append(f"| preload window (every ring; ± discretisation) | "
                     f"{_pm(pre['p_min_n'], pre.get('p_min_n_error'), '', 1e-3, '.1f').strip()} .. {hi_n} kN, bolt "
                     f"{pre['preload_n'] * 1e-3:.1f} kN: {'inside' if pre['ok'] else 'NOT inside'} | largest drive "
                     f"with a window {vmax} |")
    bolt = bolt_row(s.get("design", {}).get("stack", {}))
    if bolt:
        lines.append(bolt)
    t = th.get("temperature")
    if t:
        hr = " / ".join(f"{v:.0f} °C at h {k}" for k, v in th["final_c_h_range"].items())
        lines.append(f"| temperature after {t['duration_s']:g} s (lumped mean) | "
                     f"{_pm(t['final_c'], t.get('final_c_error'), '°C', 1.0, '.1f')} (discretisation) | {hr} W/m²/K |")
    return lines + [_headline_energy_row(s, ke, brk('mean_tool_ke_after_j', 1e3, 'mJ') if lo else '-'), ""]


def bolt_row(stack: dict) -> str | None:
    """The table's row on the stack bolt's model form: without a bolt part, the stiffness a bolt
    part adds (measured on the article's drill); with one, how much the joint's model moves f_r
    (measured on the bolted example) and what neither joint model holds."""
    if "bolt_diameter" not in stack:
        return None
    from fem.preload import BOLT_JOINT_FR_SHIFT, ELASTIC_BOLT_FR_SHIFT

    if not stack["bolt_diameter"]:
        shift, err, faces = ELASTIC_BOLT_FR_SHIFT
        return (f"| stack bolt | its prestress only, no elastic part | model form: an M12 part threaded 1.5 d "
                f"into the coupler and the horn raises the article's drill's f_r by {100 * shift:+.2f} ± "
                f"{100 * err:.2f} % at its matched lengths (bonded at the stack's faces {100 * faces:+.1f} %; "
                f"docs: operating point) |")
    joint = stack.get("bolt_joint", "faces")
    shift, err = BOLT_JOINT_FR_SHIFT
    other, sign = ("bonded at the stack's faces", -1) if joint == "thread" else ("threaded 1.5 d", 1)
    return (f"| stack bolt | elastic part, {stack['bolt_diameter'] * 1e3:g} mm, joint '{joint}' | model form: "
            f"the bolt {other} moves f_r by {100 * sign * shift:+.2f} ± {100 * err:.2f} % (the bolted example at "
            f"fixed lengths); the thread flanks' compliance is not modelled (both joints are upper bounds of "
            f"its stiffness; docs: operating point) |")


def _headline_energy_row(s: dict, kinematic: dict, bracket: str) -> str:
    """The table's tool-energy row: the headline's (``summary.json`` ``headline``, the compliant model
    with its two uncertainties) and, as the loss range, the Q/2 .. 2Q bracket that the kinematic
    horn measured (the compliant model is not re-run at Q/2 and 2Q: that is said)."""
    from .headline import headline_record

    rec, m = s.get("headline") or headline_record(s), s["A0"]["reference_m_free_kg"]
    if not rec or rec.get("model") != "compliant_model":
        return f"| tool kinetic energy (headline, {m * 1e3:g} g) | {_ci(kinematic, 1e3)} mJ (95 % CI) | {bracket} |"
    ke = rec["mean_tool_ke_after_j"]
    rng = "-" if bracket == "-" else (f"kinematic horn: {bracket} (the loss range on the comparison model; the "
                                      f"compliant model is run at Q_mech {s['harmonic']['q_mech']} only)")
    return (f"| tool kinetic energy (headline: compliant contacts, {rec['m_free_kg'] * 1e3:g} g) | "
            f"{_ci(ke, 1e3)} ± {ke['model_form'] * 1e3:.2g} mJ (95 % CI ± model form) | {rng} |")


def _preload_lines(pre: dict | None) -> list[str]:
    """The preload window per ring, the largest drive with a window, and the verdict."""
    if not pre or not pre.get("rings"):
        return [f"**Bolt preload:** {pre['verdict']}.", ""] if pre else []
    kn = 1e-3
    lines = [f"**Bolt preload:** {pre['verdict']}.", "",
             "Preload window per ring at the drive (unloaded tip: the larger amplitude): the least preload that "
             "keeps the ring's mean axial stress compressive over the cycle, the most whose static stress plus "
             "the dynamic compression stays within the rated static compressive stress (mean stresses: the "
             "section force over the area; the singular peaks at the bonded ring edges are in the stress table).",
             "", "| ring | mean axial stress amplitude (MPa) | field amplitude (V/mm) | window (kN) "
             "| largest drive with a window (V amplitude) |", "|---|---|---|---|---|"]
    for r in pre["rings"]:
        hi = "-" if r["p_max_n"] is None else f"{r['p_max_n'] * kn:.1f}"
        vmax = "-" if r["drive_factor_max"] is None else f"{r['drive_factor_max'] * pre['voltage_v']:.4g}"
        lines.append(f"| {r['region']} | {r['sigma_dyn_pa'] * 1e-6:.1f} | {r['efield_v_per_m'] * 1e-3:.0f} "
                     f"| {r['p_min_n'] * kn:.1f} .. {hi} | {vmax} |")
    return lines + [""]
