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

__all__ = ["operating_point_stage", "losses_bracket", "report_lines"]


def _tool_energy(base, ref_m: float, A0: float, stats_settings):
    """Device-scenario statistics of the tool at one free mass and amplitude (the headline's)."""
    from impact.sweeps import sweep

    row = sweep(base.with_(m_free=ref_m, A0=A0), [ref_m], scenario="device", settings=stats_settings,
                A0_values=[A0]).rows[0]
    return {q: row.estimates[q].to_dict() for q in ("mean_tool_ke_after_j", "tool_power_w")}


def losses_bracket(settings, system, modal, basis, f_w: float, surfaces, base, stats_settings, default: dict,
                   coupled_fn, say=None) -> dict:
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

    Returns
    -------
    dict
        ``losses`` (record of the default losses), ``rows`` (default, Q/2, 2Q) and ``note``.
    """
    from fem.harmonic import working_point
    from fem.harmonic import modal_basis
    from fem.losses import Q_BRACKET

    t0 = time.perf_counter()
    losses = settings.losses()
    out = {"losses": losses.record(), "rows": [{"factor": 1.0, **default}], "note": ""}
    if losses.q_mech is None:
        out["note"] = "datasheet losses: no single Q to bracket"
        return out
    ref_m = settings.reference_m_free
    omega = 2 * np.pi * f_w
    for factor in Q_BRACKET:
        loss = losses.scaled(factor).loss_model()
        b = modal_basis(system, f_w, loss=loss, modes=modal, reuse=basis)
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
                          device_sweep, coupled_fn, say=None) -> dict:
    """The operating-point record of the pipeline (``summary.json["operating_point"]``).

    ``wp`` is the unloaded working point at the default losses, ``ref`` the impact-loaded
    amplitude at the reference free mass (:class:`results.pipeline.CoupledAmplitude`),
    ``device_sweep`` the headline sweep (its row at the reference mass is the default's energy),
    ``coupled_fn`` the pipeline's A0 loop (:func:`losses_bracket`).
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
            "losses_text": losses.text(),
            "losses_bracket": losses_bracket(settings, system, modal, basis, f_w, surfaces, base, stats_settings,
                                             default, coupled_fn, say=say)}


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
    lines = ["## Operating point", "",
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
    return lines
