"""``python -m impact rotor``: the rotary unit's torque-speed curve and operating point.

Prints the contact data, no-load speed, stall torque, the largest mechanical power, the rotor
speed, power and efficiency under the load torque (given, or the drill bit's friction in rock
from the weight on bit), and whether the rotor hovers on the teeth as the model assumes (direct
integration). SI options; bad input is one line on stderr, exit 2, no file.
"""

from __future__ import annotations

import math
from pathlib import Path

from rpud_common import CliParser, ParameterError, check_output_paths, save_figure, setup_logging, write_json
from rpud_common.cli import check_given, echo_inputs, quantity

from .options import real_number
from .rotor import RotorParams, TeethMotion, bit_friction_torque, rotor_performance
from .rotor_box import OUTPUTS, TeethReport, error_box, rotor_text

_P = RotorParams()
FREQ, RATIO, PHASE = 20000.0, 0.2814, 172.88
"""Default drive frequency (Hz), teeth ellipse ratio and phase (deg): the default design's
matched working mode and harmonic response (``python -m results`` on the default design,
summary.json "working_mode" and "harmonic": 20 000 ± 20 Hz; the teeth motion on the sector one
level finer than the run's mesh, refine 0.8, 176 779 DOFs: 0.2814 ± 0.0070, 172.879 ± 0.077 deg)."""
WOB, BIT_DIAMETER, MU_ROCK = 7.0, 3e-3, 0.4
"""Default load: the article's 7 N weight on bit, its 3 mm tool, and an assumed rock/steel
friction coefficient (no measured value at hand)."""

# (option, dataclass, field, help)
_OPTS = [
    ("--freq", "teeth", "freq", "drive frequency, Hz"),
    ("--axial", "teeth", "axial", "teeth tips' axial amplitude, m"),
    ("--ratio", None, "ratio", "teeth ellipse ratio tangential/axial amplitude"),
    ("--phase-deg", "teeth", "phase_deg", "phase of the tangential relative to the axial motion, deg"),
    ("--preload", "rotor", "preload", "preload spring force, N"),
    ("--spring-stiffness", "rotor", "spring_stiffness", "preload spring stiffness, N/m"),
    ("--mu", "rotor", "mu", "friction coefficient teeth/rotor"),
    ("--radius", "rotor", "radius", "contact radius, m"),
    ("--tooth-area", "rotor", "tooth_area", "top face area of one tooth, m^2"),
    ("--rotor-mass", "rotor", "rotor_mass", "rotor mass, kg"),
    ("--rotor-inertia", "rotor", "rotor_inertia", "rotor polar moment of inertia, kg m^2"),
]


def build_parser() -> CliParser:
    ap = CliParser(prog="python -m impact rotor",
                   description="The rotary unit: the coupler's teeth (elliptic motion at the drive) turn a "
                               "preloaded rotor by Coulomb friction through an elastic contact. Torque-speed "
                               "curve, no-load speed, stall torque, power, efficiency and the speed under a "
                               "load torque. SI units.")
    g = ap.add_argument_group("teeth motion and rotor (defaults in brackets)")
    for opt, _, name, text in _OPTS:
        if name == "axial":
            g.add_argument(opt, dest=name, type=real_number, required=True, metavar="M",
                           help=f"{text} (required: the harmonic response's teeth_tops axial amplitude)")
            continue
        default = {"freq": FREQ, "ratio": RATIO, "phase_deg": PHASE}.get(name)
        default = getattr(_P, name) if default is None else default
        g.add_argument(opt, dest=name, type=real_number, default=None, metavar="X", help=f"{text} [{default:g}]")
    g.add_argument("--n-teeth", dest="n_teeth", type=int, default=None, metavar="N",
                   help=f"number of driving teeth [{_P.n_teeth}]")
    g.add_argument("--config", metavar="TOML", help="rotor data: top-level keys or a [rotor] table (RotorParams "
                                                    "fields, moduli included); options override it")
    e = ap.add_argument_group("the teeth motion's errors (each output then carries its largest departure over "
                              "the corners of the error box)")
    e.add_argument("--axial-error", type=real_number, default=0.0, metavar="M",
                   help="error of the axial amplitude, m (the pipeline's teeth_axial_per_volt_m relative error "
                        "times the amplitude) [0]")
    e.add_argument("--ratio-error", type=real_number, default=0.0, metavar="X", help="error of the ellipse ratio [0]")
    e.add_argument("--phase-error-deg", type=real_number, default=0.0, metavar="DEG", help="error of the phase, deg [0]")
    ld = ap.add_argument_group("load")
    ld.add_argument("--load-torque", type=real_number, default=None, metavar="NM",
                    help="resisting torque on the rotor, N m (default: the bit's friction in rock, below)")
    ld.add_argument("--wob", type=real_number, default=None, metavar="N", help=f"weight on bit, N [{WOB:g}]")
    ld.add_argument("--bit-diameter", type=real_number, default=None, metavar="M", help=f"bit diameter, m [{BIT_DIAMETER:g}]")
    ld.add_argument("--mu-rock", type=real_number, default=None, metavar="X",
                    help=f"bit/rock friction coefficient [{MU_ROCK:g}, assumed]")
    ld.add_argument("--electric-idle", type=real_number, default=0.0, metavar="W",
                    help="the rotary side's electrical loss without the rotor, W; its electrical input is this "
                         "plus the teeth's power into the contact [0]")
    o = ap.add_argument_group("output")
    o.add_argument("--points", type=int, default=41, metavar="N", help="speeds on the torque-speed curve [41]")
    o.add_argument("--json", metavar="PATH", help="write the results as JSON")
    o.add_argument("--plots", metavar="DIR", help="write torque_speed.png and contact_phases.png here")
    o.add_argument("-q", "--quiet", action="store_true", help="no inputs line")
    return ap


def teeth_errors(ns, teeth: TeethMotion) -> TeethReport | None:
    """The teeth motion with the errors of the options, or None when none is given."""
    for opt, v in (("--axial-error", ns.axial_error), ("--ratio-error", ns.ratio_error),
                   ("--phase-error-deg", ns.phase_error_deg)):
        if v < 0:
            raise ParameterError(opt, v, "must be >= 0")
    if ns.axial_error >= 0.99 * teeth.axial:
        raise ParameterError("--axial-error", ns.axial_error, f"must be below 0.99 x --axial ({0.99 * teeth.axial:g} m)")
    if not (ns.axial_error or ns.ratio_error or ns.phase_error_deg):
        return None
    return TeethReport(teeth.freq, teeth.axial, ns.axial_error, teeth.tangential / teeth.axial, ns.ratio_error,
                       teeth.phase_deg, ns.phase_error_deg)


def params_from(ns) -> tuple[TeethMotion, RotorParams, float]:
    """The teeth motion, rotor data and load torque (N m) of the parsed options."""
    base = RotorParams() if ns.config is None else RotorParams.from_toml(ns.config, "--config")
    given = {name: getattr(ns, name) for _, where, name, _ in _OPTS if where == "rotor" and getattr(ns, name) is not None}
    if ns.n_teeth is not None:
        given["n_teeth"] = ns.n_teeth
    rotor = base.with_(**given)
    teeth = TeethMotion.from_ellipse(FREQ if ns.freq is None else ns.freq, ns.axial,
                                     RATIO if ns.ratio is None else ns.ratio,
                                     PHASE if ns.phase_deg is None else ns.phase_deg)
    if ns.load_torque is not None:
        for opt, v in (("--wob", ns.wob), ("--bit-diameter", ns.bit_diameter), ("--mu-rock", ns.mu_rock)):
            if v is not None:
                raise ParameterError(opt, v, "applies only without --load-torque (it sets the load instead)")
        load = ns.load_torque
    else:
        load = bit_friction_torque(WOB if ns.wob is None else ns.wob,
                                   BIT_DIAMETER if ns.bit_diameter is None else ns.bit_diameter,
                                   MU_ROCK if ns.mu_rock is None else ns.mu_rock)
    return teeth, rotor, load


def _inputs(teeth: TeethMotion, p: RotorParams, load: float, ns) -> dict:
    return {"f": quantity(teeth.freq, "Hz"), "teeth axial": quantity(teeth.axial, "m"),
            "tangential": quantity(teeth.tangential, "m"), "phase": f"{teeth.phase_deg:g} deg",
            "teeth": p.n_teeth, "tooth area": f"{p.tooth_area * 1e6:.4g} mm^2", "radius": quantity(p.radius, "m"),
            "preload": quantity(p.preload, "N"), "spring": quantity(p.spring_stiffness, "N/m"), "mu": f"{p.mu:g}",
            "rotor": f"{quantity(p.rotor_mass, 'kg')}, {p.rotor_inertia:.3g} kg m^2",
            "moduli": f"tooth {p.e_tooth / 1e9:.4g} GPa/{p.nu_tooth:g}, rotor {p.e_rotor / 1e9:.4g} GPa/{p.nu_rotor:g}",
            "load": f"{load * 1e3:.4g} mN m" + ("" if ns.load_torque is not None else " (bit friction in rock)"),
            "idle loss": quantity(ns.electric_idle, "W"), "points": ns.points,
            "errors": (f"axial {quantity(ns.axial_error, 'm')}, ratio {ns.ratio_error:g}, phase {ns.phase_error_deg:g} deg"
                       if ns.axial_error or ns.ratio_error or ns.phase_error_deg else "none")}


def print_result(res) -> None:
    rpm = 30.0 / math.pi
    pmax, wmax = res.max_power
    cyc = res.load_cycle
    print(f"contact per tooth: k_n {res.k_normal:.4g} N/m, k_t {res.k_tangential:.4g} N/m (flat punch unless given); "
          f"peak penetration {res.peak_penetration * 1e9:.3g} nm; rotation sense {'+' if res.teeth.sense > 0 else '-'}")
    print(f"no-load speed {res.no_load_speed * rpm:.4g} rpm ({res.no_load_speed:.4g} rad/s); stall torque "
          f"{res.stall_torque * 1e3:.4g} mN m (bound mu F r {res.torque_bound * 1e3:.4g} mN m); "
          f"largest power {pmax * 1e3:.4g} mW at {wmax * rpm:.4g} rpm")
    print(f"under {res.load_torque * 1e3:.4g} mN m: {res.load_speed * rpm:.4g} rpm, power {res.load_power * 1e3:.4g} mW, "
          f"teeth power {res.load_teeth_power * 1e3:.4g} mW, efficiency {res.load_efficiency:.3g}"
          + (" (STALLED)" if res.stalled else ""))
    print(f"cycle at the load: contact {cyc.fraction('contact') * 100:.2f} %, stick {cyc.fraction('stick') * 100:.2f} %, "
          f"slip forward {cyc.fraction('slip+') * 100:.2f} %, slip back {cyc.fraction('slip-') * 100:.2f} % of the cycle")
    hover = "confirmed by direct integration" if res.hover["holds"] else "NOT confirmed: the rotor bounces"
    print(f"assumption checks: rotor axial ripple {res.axial_ripple * 1e9:.3g} nm = "
          f"{res.axial_ripple / res.peak_penetration:.2g} of the peak penetration, constant axial position {hover}; "
          f"speed ripple {res.speed_ripple:.3g} rad/s")
    for note in res.notes:
        print(f"note: {note}")


def main(argv) -> int:
    setup_logging(-1)
    ap = build_parser()
    ns = ap.parse_args(argv)
    check_given(ap, ns)
    teeth, rotor, load = params_from(ns)
    if not 3 <= ns.points <= 2001:
        raise ParameterError("--points", ns.points, "must be in [3, 2001]")
    if ns.electric_idle < 0:
        raise ParameterError("--electric-idle", ns.electric_idle, "must be >= 0 W")
    report = teeth_errors(ns, teeth)
    check_output_paths(inputs={"--config": ns.config}, folders=("plots",), json=ns.json, plots=ns.plots)
    echo_inputs(_inputs(teeth, rotor, load, ns), ns.quiet)
    res = rotor_performance(teeth, rotor, load, points=ns.points, electric_idle_w=ns.electric_idle)
    print_result(res)
    record = res.to_dict()
    if report is not None:
        _, values, errors = error_box(report, rotor, load, ns.points, nominal=res)
        print("with the teeth motion's errors (largest departure over the corners of the error box): "
              + rotor_text(values, errors, load, res.hover["holds"], res.torque_bound))
        record["errors"] = {f"{k}_error": errors[k] for k, _, _ in OUTPUTS}
    if ns.json:
        write_json(ns.json, record)
    if ns.plots:
        from .rotor_plots import plot_contact_phases, plot_torque_speed

        save_figure(plot_torque_speed(res), Path(ns.plots) / "torque_speed.png")
        save_figure(plot_contact_phases(res), Path(ns.plots) / "contact_phases.png")
    return 0
