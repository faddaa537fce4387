"""``python -m impact --horn fem``: the impact model with the FE transducer in the loop.

``impact``'s library may not import ``fem``; its command (:mod:`impact.__main__`) hands
``--horn fem`` to this one, which builds the reduced transducer from the design
(:func:`results.coupled.build_transducer`) and runs the coupled model (:mod:`impact.coupled`). Outputs:

* the ring-up from rest with the free mass in place (``--history`` s): tip displacement history,
  running amplitude envelope (fundamental over 4-cycle windows), energy balance per interval,
  drive power and current;
* drill-tool statistics as in the statistics issue (converged ensemble means with 95 % CIs),
  with the tip amplitude, electrical power drawn and damping loss, in steady operation (modes
  started on their steady response; the scenario's window).

All options SI. Bad input: one line on stderr, exit 2, nothing written.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from rpud_common import (CliParser, ParameterError, atomic_write_text, check_integer, check_output_paths, check_range,
                         setup_logging, write_json)
from rpud_common.cli import check_given, check_usual, check_zero_or_range, echo_inputs, mesh_text, quantity

HISTORY = 0.05
"""Default length of the ring-up history, s."""


def _parser() -> CliParser:
    from impact.options import add_model_options, real_number

    ap = CliParser(prog="python -m impact --horn fem",
                   description="Impact model with the FE transducer in the loop: the design's modes that carry "
                               "tip motion, driven at V sin(2 pi f t), exchange impulses with the free mass (exact "
                               "event-driven coupling). Tool statistics as ensemble means with 95 % CIs.")
    ap.add_argument("--horn", choices=["fem"], required=True, help="fem: the reduced FE transducer (this command)")
    from geometry.options import add_design_options

    add_design_options(ap, include=("design", "materials"), metavar="TOML")
    from rpud_common.voltage import add_voltage_options

    add_voltage_options(ap, number_type=real_number)
    ap.add_argument("--series-resistance", dest="series_resistance", type=real_number, default=0.0, metavar="OHM",
                    help="source resistance in series with the electrodes, ohm (default 0: voltage drive; > 0: the "
                         "electrode voltage follows the charge, with the resistor's loss in the energy balance)")
    ap.add_argument("--freq", type=real_number, default=None, metavar="HZ",
                    help="drive frequency, Hz (default: the working mode's resonance)")
    from fem.losses import add_loss_options

    add_loss_options(ap, number_type=real_number)
    ap.add_argument("--modes", type=int, default=None, metavar="N",
                    help="modes kept (default: working mode + modes with tip participation s^2 >= 1 %% of its)")
    ap.add_argument("--match", action="store_true", help="run the resonance matching first (~35 s)")
    add_design_options(ap, include=("mesh_size", "refine", "grade"), number_type=real_number)
    ap.add_argument("--contact", choices=["newton", "hunt-crossley"], default="newton",
                    help="horn contact: newton = instantaneous impact with restitution e2 (default); hunt-crossley = "
                         "Hertz contact (horn material vs a steel sphere of the free mass) with Hunt-Crossley damping "
                         "matching e2, integrated through each contact (statistics only: no history)")
    ap.add_argument("--history", type=real_number, default=None, metavar="S",
                    help=f"length of the ring-up history from rest with the free mass in place, s (default "
                         f"{HISTORY:g}; not with --contact hunt-crossley)")
    add_model_options(ap, skip=("A0", "freq", "m_horn"))
    ap.add_argument("--json", metavar="PATH", help="write the reduced transducer, history summary, energy balance "
                                                   "and statistics as JSON")
    ap.add_argument("--history-csv", dest="history_csv", metavar="PATH",
                    help="write the ring-up history sampled every --sample-dt (tip, free mass, tool face, drive "
                         "voltage and current) as CSV")
    ap.add_argument("--sample-dt", dest="sample_dt", type=real_number, default=None, metavar="S",
                    help="sample spacing of the history, s (default 2.5e-6)")
    ap.add_argument("--plots", metavar="DIR", help="write tip_envelope.png and displacement.png here")
    return ap


def _check(ns):
    """Every option checked before any work: ``(params, scenario, settings)`` of the impacts."""
    from geometry.options import check_design_options

    from impact.options import check_horn_mass, params_from_options, scenario_from_options, settings_from_options

    from fem.losses import q_option_losses
    from rpud_common.voltage import drive_voltage

    ns.drive = drive_voltage(ns)
    ns.voltage = ns.drive.amplitude_v
    check_zero_or_range("--series-resistance", ns.series_resistance, 1e-3, 1e6, "ohm", "voltage drive")
    if ns.q_mech is not None:
        check_zero_or_range("--q-mech", ns.q_mech, 1.0, 1e6, "", "datasheet values")
    ns.losses = q_option_losses(ns.q_mech)
    ns.bvd_fits = None
    if ns.admittance is not None:
        from fem.bvd import fit_bvd, read_admittance

        if ns.q_mech is not None:
            raise ParameterError("--admittance", ns.admittance, "sets the losses: drop --q-mech")
        ns.bvd_fits = fit_bvd(read_admittance(ns.admittance))
    if ns.freq is not None:
        check_range("--freq", ns.freq, 1.0, 1e6, "Hz")
    if ns.modes is not None:
        check_integer("--modes", ns.modes, 1, 12)
    check_design_options(ns)
    if ns.history is not None:
        check_range("--history", ns.history, 1e-4, 1.0, "s")
    if ns.horn_law not in (None, "kinematic"):
        raise ParameterError("--horn-law", ns.horn_law, "must be kinematic with --horn fem (the modes carry the mass)")
    p = params_from_options(ns)
    check_horn_mass(ns, p)
    sc = scenario_from_options(ns, p)
    settings = settings_from_options(ns)
    if ns.sample_dt is not None:
        check_range("--sample-dt", ns.sample_dt, 1e-8, 1e-4, "s")
        p = p.with_(sample_dt=ns.sample_dt)
    p.with_(t_end=ns.history or HISTORY)       # at most 2e7 history samples (ImpactParams checks it)
    if ns.contact == "hunt-crossley":
        _check_compliant(ns)
    return p, sc, settings


def _check_compliant(ns) -> None:
    """``--contact hunt-crossley`` integrates its contact phases numerically: statistics only."""
    if ns.series_resistance > 0:
        raise ParameterError("--series-resistance", ns.series_resistance, "must be 0 with --contact hunt-crossley "
                             "(its contact phases integrate the voltage-driven modes)")
    for opt, val in (("--plots", ns.plots), ("--history-csv", ns.history_csv), ("--history", ns.history),
                     ("--sample-dt", ns.sample_dt)):
        if val is not None:
            raise ParameterError(opt, val, "not available with --contact hunt-crossley (its contact phases are "
                                 "integrated numerically, not closed-form segments): statistics only")


def _inputs(ns, design, p, sc, settings) -> dict:
    """The run's inputs for the inputs line."""
    from impact.options import param_items, scenario_items

    items = {"design": design.name, "voltage": ns.drive.text()}
    if ns.series_resistance > 0:
        items["behind"] = quantity(ns.series_resistance, "ohm")
    items.update({"f": "the working resonance" if ns.freq is None else quantity(ns.freq, "Hz"),
                  "losses": ns.losses.short() if ns.admittance is None else f"measured ({ns.admittance})",
                  "modes": "tip-participation rule" if ns.modes is None else ns.modes,
                  "matching": "on" if ns.match else "off",
                  "mesher": mesh_text("free", ns.refine, ns.grade, ns.mesh_size), "contact": ns.contact})
    if ns.contact == "newton":
        items["history"] = quantity(ns.history or HISTORY, "s")
    return {**items, **param_items(p, skip=("A0", "f", "horn law")), **scenario_items(sc, settings)}


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    setup_logging(-1)
    ap = _parser()
    ns = ap.parse_args(argv)
    check_given(ap, ns)
    from impact.options import is_quiet, progress_printer, set_threads, stats_lines, warn_unusual

    from geometry.options import design_from_options, design_inputs, mesh_options

    p, sc, settings = _check(ns)
    history = ns.history or HISTORY
    check_output_paths(inputs={"--config": ns.config, **design_inputs(ns)}, folders=("plots",), json=ns.json,
                       plots=ns.plots, history_csv=ns.history_csv)
    set_threads(ns.threads)
    from geometry.guard import check_budget

    from impact.coupled import COUPLED_QUANTITIES, coupled_batch

    from .coupled import build_transducer, contact_from_design, coupled_history, horn_from_reduced

    design = design_from_options(ns)
    check_budget(design, ns.mesh_size, **mesh_options(ns))
    warn_unusual(ap.prog, ns, p, skip=("A0", "freq"))
    check_usual(ap.prog, "--voltage", ns.voltage, "voltage")
    echo_inputs(_inputs(ns, design, p, sc, settings), is_quiet(ns))
    say = progress_printer(ns) or (lambda msg: None)
    say("[1/3] FE transducer")
    fe = build_transducer(design, voltage=ns.voltage, q_mech=ns.losses.q_mech, admittance_fits=ns.bvd_fits,
                          freq_hz=ns.freq, n_modes=ns.modes, match=ns.match, mesh_size=ns.mesh_size, progress=say,
                          **mesh_options(ns))
    p = p.with_(freq=fe.freq_hz)
    unloaded = _unloaded(ns, fe, say)
    contact = None
    hist = None
    if ns.contact == "hunt-crossley":
        contact = contact_from_design(design, p.m_free, p.e2)
        say(f"[2/3] compliant contact: Hertz k = {contact.stiffness:.4g} N/m^1.5, Hunt-Crossley chi = "
            f"{contact.chi:.4f} (e2 = {p.e2:g}); no history (contact phases are integrated numerically)")
    else:
        say(f"[2/3] ring-up from rest with the {p.m_free * 1e3:g} g free mass in place, {history * 1e3:g} ms")
        hist = coupled_history(fe, p.with_(spring_force=sc.spring_force), ns.voltage, history,
                               series_resistance=ns.series_resistance, unloaded=unloaded)
        for line in hist["lines"]:
            print(line)
    say(f"[3/3] statistics, {sc.name} scenario, steady operation")
    horn = horn_from_reduced(fe.reduced, ns.voltage, start="steady", series_resistance=ns.series_resistance)
    st = coupled_batch([p], horn, sc, settings, progress=progress_printer(ns), contact=contact)[0]
    if st.failed:
        raise ParameterError("gap", p.gap, st.note)
    if fe.info.get("losses"):
        from fem.losses import DriveLosses

        ns.losses = DriveLosses.from_record(fe.info["losses"])
    print(f"drive {ns.drive.text()}; losses {ns.losses.text()}")
    print("\n".join(stats_lines(st)))
    for name, unit, text in COUPLED_QUANTITIES:
        scale, u = {"m": (1e6, "um"), "W": (1.0, "W")}[unit]
        print(f"  {text:<66} {st.estimates[name].scaled(scale)} {u}")
    print(f"  unloaded ({'series-resistance drive' if ns.series_resistance > 0 else 'harmonic working point'}): tip "
          f"{unloaded['tip_amplitude_m'] * 1e6:.3f} um, power {unloaded['power_w']:.2f} W")
    _write_outputs(ns, fe, p, hist, st, unloaded, contact)
    if not math.isfinite(st.estimates["tool_impact_rate_hz"].mean):
        return 1
    return 0


def _unloaded(ns, fe, say) -> dict:
    """The unloaded working point: the harmonic one, or behind ``--series-resistance``."""
    unloaded = {"tip_amplitude_m": fe.tip_amplitude_m, "power_w": fe.power_w}
    if ns.series_resistance > 0:
        from impact.drive import series_model

        from .coupled import horn_from_reduced

        horn_r = horn_from_reduced(fe.reduced, ns.voltage, series_resistance=ns.series_resistance)
        u = series_model(horn_r, fe.freq_hz).unloaded(horn_r)
        unloaded = {"tip_amplitude_m": u["tip_amplitude_m"], "power_w": u["source_power_w"],
                    "electrode_voltage_v": u["electrode_voltage_v"], "source_current_rms_a": u["source_current_rms_a"]}
        say(f"      behind {ns.series_resistance:g} ohm, unloaded: tip {u['tip_amplitude_m'] * 1e6:.3f} um, electrodes "
            f"{u['electrode_voltage_v']:.1f} V amplitude, source {u['source_power_w']:.2f} W, "
            f"{u['source_current_rms_a']:.3f} A rms (voltage drive: tip {fe.tip_amplitude_m * 1e6:.3f} um)")
    return unloaded


def _write_outputs(ns, fe, p, hist, st, unloaded, contact) -> None:
    """--json, --history-csv and --plots."""
    from .coupled import history_csv

    if ns.json:
        doc = {"reduced_transducer": fe.reduced.to_dict(), "fe": fe.info, "losses": ns.losses.record(),
               "drive": {"voltage_v": ns.voltage, "voltage": ns.drive.record(),
               "freq_hz": fe.freq_hz, "series_resistance_ohm": ns.series_resistance, "f_r_hz": fe.f_r_hz, "f_a_hz": fe.f_a_hz,
               "unloaded_tip_amplitude_m": unloaded["tip_amplitude_m"], "unloaded_power_w": unloaded["power_w"],
               "unloaded": unloaded},
               "params": p.to_dict(), "history": hist["json"] if hist else None, "statistics": st.to_dict(),
               "contact": ({"law": "hunt-crossley", "stiffness_n_per_m1p5": contact.stiffness, "chi": contact.chi,
                            "restitution": contact.restitution} if contact else {"law": "newton"})}
        write_json(ns.json, doc)
    if ns.history_csv:
        atomic_write_text(ns.history_csv, history_csv(hist["result"]))
    if ns.plots:
        from impact.plots import plot_history
        from rpud_common import save_figure

        from .coupled_figures import tip_envelope

        d = Path(ns.plots)
        save_figure(tip_envelope(hist["result"], unloaded["tip_amplitude_m"]), d / "tip_envelope.png")
        save_figure(plot_history(hist["result"].impact,
                                 title=f"coupled model, {fe.reduced.n_modes} modes, {ns.voltage:g} V: one sample "
                                       f"(chaotic)"), d / "displacement.png")
