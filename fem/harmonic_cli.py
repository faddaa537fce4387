"""``python -m fem.harmonic``: the command line of :mod:`fem.harmonic` (options, checks, printing, files).

The physics lives in :mod:`fem.harmonic`; this module only parses, validates, calls and writes.
"""

from __future__ import annotations

import numpy as np

from rpud_common import ParameterError, check_range, save_figure
from rpud_common.cli import check_given, check_usual, check_zero_or_range, echo_inputs, mesh_text, quantity

from .harmonic import basis_reach, harmonic_sweep, modal_basis, working_point
from .losses import add_loss_options, q_option_losses

def build_parser():
    from rpud_common import CliParser

    p = CliParser(prog="python -m fem.harmonic",
                  description="Harmonic response of a design driven by a voltage: horn-tip amplitude per volt, "
                              "admittance over a band with resonance/anti-resonance, input power, and the "
                              "ring-up under a sine switched on at t = 0.")
    from geometry.options import add_design_options

    add_design_options(p, include=("design", "materials"))
    from rpud_common.voltage import add_voltage_options

    add_voltage_options(p)
    p.add_argument("--freq", type=float, metavar="HZ",
                   help="working frequency, Hz (default: the working mode's resonance near the design's "
                        "target frequency, i.e. the matched frequency of a matched design)")
    p.add_argument("--band", metavar="LO,HI", help="admittance band, Hz (default: f_r - 3 %% .. f_a + 3 %%)")
    p.add_argument("--points", type=int, default=None, metavar="N",
                   help=f"frequencies in the band (default {POINTS})")
    add_loss_options(p, tan_delta=True)
    p.add_argument("--convection", type=float, default=None, metavar="H",
                   help="convective coefficient of the lumped thermal model, W/m^2/K (default 10: natural "
                        "convection in air; 5-25 is bracketed in the output)")
    p.add_argument("--duty", type=float, default=None, metavar="D",
                   help="fraction of the time the drive is on in the thermal model (default 1: continuous; "
                        "periods of 10 s)")
    p.add_argument("--surface", action="append", metavar="NAME",
                   help="surface(s) to report, the tip first (default horn_tip and teeth_tops when present)")
    add_design_options(p, include=("mesh_size", "refine", "grade", "mesher"))
    p.add_argument("--path", choices=("auto", "sector", "whole"), default="auto",
                   help="FE path: sector (the k = 0 swept sector, which holds every response to the stack's "
                        "voltage: converged at the default cost), whole (the whole drill, graded); auto (default): "
                        "the sector where the design can be swept and --mesher is auto, else the whole drill")
    p.add_argument("--modes", type=int, default=8, metavar="N",
                   help="modes in the superposition basis (default 8; a wide --band grows it as needed)")
    p.add_argument("--mode", type=int, metavar="K",
                   help="drive this mode (its number in the modal table, 1 = lowest computed); default: the "
                        "mode with the largest electromechanical coupling k_eff near the frequency")
    p.add_argument("--ring-up", type=float, metavar="S",
                   help="also integrate the ring-up for S seconds (0: six time constants)")
    p.add_argument("--error", action="store_true",
                   help="estimate the discretisation error of f_r, f_a, k_eff, the tip amplitude and the teeth "
                        "ellipse ratio from one extra solve on a mesh 1.4x coarser (fem.errors); prints value +- "
                        "error and adds X_error keys and a discretisation_error block to the JSON (on the sector "
                        "path every run without --freq/--mode does this)")
    p.add_argument("--converge", type=float, metavar="TOL",
                   help="mesh-convergence study instead: refine by 0.8 per level from --refine until f_r, f_a, "
                        "k_eff, the tip amplitude per volt and the teeth ellipse ratio change by less than TOL "
                        "(relative, 1e-7..0.1) between levels; prints each level, the observed order, the "
                        "Richardson estimate and the error; exit 1 if not converged within the DOF budget")
    p.add_argument("--json", metavar="OUT", help="write the results as JSON")
    p.add_argument("--plots", metavar="DIR", help="write admittance / tip response / ring-up PNGs into DIR")
    from .stress_cli import add_stress_options

    add_stress_options(p)
    p.add_argument("--allow-large", action="store_true",
                   help="solve even above the resource budget (geometry.guard.MAX_DOFS estimated DOFs)")
    p.add_argument("-v", "--verbose", action="count", default=0)
    p.add_argument("-q", "--quiet", action="store_true", help="no inputs line")
    return p


MAX_POINTS = 20_000
"""Most frequencies of one admittance sweep."""

POINTS = 200
"""Default number of frequencies of the admittance sweep."""

MIN_RING_UP = 1e-6
"""Shortest ring-up integrated, s (a fiftieth of a period at 20 kHz; 0 asks for six time constants)."""

MAX_RING_UP = 1.0
"""Longest ring-up integrated, s (20 000 drive periods at 20 kHz)."""


def _check_options(args) -> None:
    """Every option finite and inside its stated range, outputs usable, before meshing."""
    from rpud_common import check_integer, check_output_paths
    from geometry.options import check_design_options, design_inputs
    from geometry.validate import FREQUENCY_BAND

    from rpud_common.voltage import drive_voltage

    args.drive = drive_voltage(args)
    args.voltage = args.drive.amplitude_v
    if args.freq is not None:
        check_range("--freq", args.freq, *FREQUENCY_BAND, "Hz")
    if args.points is not None:
        check_integer("--points", args.points, 3, MAX_POINTS)
    check_integer("--modes", args.modes, 1, 200)
    if args.mode is not None:
        check_integer("--mode", args.mode, 1, args.modes)
    if args.q_mech is not None:
        check_zero_or_range("--q-mech", args.q_mech, 1.0, 1e6, "", "datasheet values")
    if args.tan_delta is not None:
        check_range("--tan-delta", args.tan_delta, 0.0, 1.0)
    from .thermal import ThermalSettings

    if args.convection is not None:
        check_range("--convection", args.convection, 0.1, 1e4, "W/m^2/K")
    if args.duty is not None:
        check_range("--duty", args.duty, 0.0, 1.0, lo_open=True)
    args.thermal = ThermalSettings(**{k: v for k, v in (("h_w_per_m2k", args.convection), ("duty", args.duty))
                                      if v is not None})
    args.bvd_fits = None
    if args.admittance is not None:
        from .bvd import fit_bvd, read_admittance

        for opt in ("q_mech", "tan_delta", "converge"):
            if getattr(args, opt) is not None:
                raise ParameterError("--admittance", args.admittance, f"sets the losses: drop --{opt.replace('_', '-')}")
        args.bvd_fits = fit_bvd(read_admittance(args.admittance))
    check_design_options(args)
    if args.ring_up is not None:
        check_zero_or_range("--ring-up", args.ring_up, MIN_RING_UP, MAX_RING_UP, "s", "six time constants")
    if args.converge is not None:
        check_range("--converge", args.converge, 1e-7, 0.1)
        for opt in ("error", "plots", "ring_up", "freq", "band", "mode", "points", "stress"):
            if getattr(args, opt) not in (None, False):
                raise ParameterError("--converge", args.converge, f"cannot be combined with --{opt.replace('_', '-')}")
    if args.error:
        # the estimate compares each mesh's own resonance and its driven mode (largest k_eff)
        for opt in ("freq", "mode"):
            if getattr(args, opt) is not None:
                raise ParameterError("--error", True, f"estimates the response at the mode's own f_r: drop --{opt}")
        if args.refine * 1.4 > 5.0:
            raise ParameterError("--refine", args.refine, "must be <= 3.5 with --error (its coarse mesh is 1.4x coarser)")
    if args.json is not None and not args.json.endswith(".json"):
        raise ParameterError("--json", args.json, "must end in .json")
    from .stress_cli import check_stress_options

    check_stress_options(args)
    check_output_paths(inputs=design_inputs(args), folders=("plots", "stress"), json=args.json, plots=args.plots,
                       stress=args.stress)


def driven_mode(modal, near_hz: float) -> int:
    """The mode a voltage drive near ``near_hz`` excites: the largest effective coupling
    ``k_eff`` among the elastic modes within 40 % of it (the largest axial share, as
    :func:`fem.modal.working_mode`, when no mode has a finite k_eff)."""
    from .modal import working_mode

    f = np.asarray(modal.f_r_hz, float)
    k = np.where(np.isfinite(modal.k_eff), modal.k_eff, -1.0)
    ok = (np.abs(f) > 0.01 * near_hz) & (np.abs(f - near_hz) < 0.4 * near_hz)
    if not ok.any() or np.max(k[ok]) <= 0:
        return working_mode(modal.system, modal.f_r_hz, modal.vectors, near_hz)
    return int(np.argmax(np.where(ok, k, -np.inf)))


def _parse_band(text: str) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in text.split(","))
    except ValueError:
        raise ParameterError("--band", text, "must be two frequencies in Hz, LO,HI") from None
    if not (100.0 <= lo < hi <= 1e6):
        raise ParameterError("--band", text, "must satisfy 100 <= LO < HI <= 1e6 (Hz)")
    return lo, hi


def resolve_path(args, design) -> str:
    """The FE path of ``--path`` for ``design`` (:func:`fem.sector_system.check_path`): ``auto``
    is the sector where the design can be swept and ``--mesher`` is auto (the stress table
    included: the pipeline's path); refused where the design cannot take it."""
    from .sector_system import check_path, default_path

    if args.path == "auto":
        whole = getattr(args, "mesher", "auto") != "auto"
        return "whole" if whole else default_path(design)
    if args.path == "sector" and getattr(args, "mesher", "auto") != "auto":
        raise ParameterError("--mesher", args.mesher, "applies to the whole drill (--path whole); the sector has its rule")
    return check_path(design, args.path)


def _mesh_label(args, design, path) -> str:
    from geometry.options import mesher_of

    from .sector_system import path_label

    if path == "sector":
        return path_label(design, "sector", refine=args.refine, grade=args.grade, mesh_size=args.mesh_size)
    return "whole drill, " + mesh_text(mesher_of(args, design), args.refine, args.grade, args.mesh_size)


def _inputs(args, design, band) -> dict:
    """The run's inputs for the inputs line."""
    from geometry.options import mesher_of

    items = {"design": design.name, "voltage": args.drive.text(),
             "f": "the driven mode's resonance" if args.freq is None else quantity(args.freq, "Hz")}
    if args.converge is None:
        items["band"] = ("f_r - 3 % .. f_a + 3 %" if band is None else
                         f"{quantity(band[0], 'Hz')} .. {quantity(band[1], 'Hz')}") + f", {args.points} points"
    items.update({"losses": args.losses.short() if args.admittance is None else
                  f"measured ({args.admittance}: {len(args.bvd_fits)} resonance(s) fitted)",
                  "modes": args.modes, "driven mode": "largest k_eff" if args.mode is None else args.mode,
                  "surfaces": ", ".join(args.surface) if args.surface else "horn_tip, teeth_tops",
                  "mesh": _mesh_label(args, design, args.fe_path)})
    items["thermal"] = f"h {quantity(args.thermal.h_w_per_m2k, 'W/m^2/K')}, duty {args.thermal.duty:g}"
    if args.ring_up is not None:
        items["ring-up"] = "six time constants" if args.ring_up == 0 else quantity(args.ring_up, "s")
    if args.stress:
        pre = "the design's bolt" if args.preload is None else quantity(args.preload, 'N')
        items["stress"] = f"{args.stress}, preload {pre}, {args.stress_points} band points"
    if args.converge is not None:
        items["convergence study"] = f"tolerance {args.converge:g}"
    elif args.error:
        items["discretisation error"] = "estimated"
    return items


def main(argv=None) -> int:
    import geometry
    from rpud_common import setup_logging
    from geometry.guard import check_budget
    from geometry.options import design_from_options, mesh_options

    parser = build_parser()
    args = parser.parse_args(argv)
    setup_logging(args.verbose - 1)
    check_given(parser, args)
    _check_options(args)
    band = _parse_band(args.band) if args.band is not None else None
    if band and args.freq is not None and not band[0] <= args.freq <= band[1]:
        raise ParameterError("--freq", args.freq, f"lies outside the band [{band[0]:g}, {band[1]:g}] Hz")
    args.points = POINTS if args.points is None else args.points
    args.losses = q_option_losses(args.q_mech, args.tan_delta)
    loss = args.losses.loss_model()
    design = design_from_options(args)
    args.fe_path = resolve_path(args, design)
    sectors = _sectors(design) if args.fe_path == "sector" else None
    check_budget(design, args.mesh_size, allow_large=args.allow_large, sectors=sectors, **mesh_options(args, design))
    check_usual(parser.prog, "--voltage", args.voltage, "voltage")
    echo_inputs(_inputs(args, design, band), args.quiet)
    if args.fe_path == "sector":
        from .sector_system import axial_sector

        system = axial_sector(design, refine=args.refine, grade=args.grade, mesh_size=args.mesh_size)
        mesh = system.mesh
    else:
        mesh, system = geometry.build_mesh(design, mesh_size=args.mesh_size, **mesh_options(args, design)), None
    surfaces = tuple(args.surface) if args.surface else tuple(
        s for s in ("horn_tip", "teeth_tops") if s in mesh.facet_sets)
    for s in surfaces:
        mesh.facets(s)                                  # unknown names: a clear error before solving
    if not surfaces:
        raise ParameterError("--surface", None, "the design has no horn_tip; name a surface")
    near = float(args.freq or getattr(design, "target_frequency", 20e3))
    if args.converge is not None:
        return _converge(args, design, near, loss, surfaces)
    if system is None:
        from .assembly import assemble

        system = assemble(mesh)
    return _run(args, design, system, surfaces, near, loss, band)


def _sectors(design) -> int:
    from geometry.sector import symmetry_order

    return symmetry_order(design) or 6


def _run(args, design, system, surfaces, near: float, loss, band) -> int:
    """Solve, print and write the harmonic response of ``system`` (a whole drill or a k = 0 sector)."""
    from rpud_common import atomic_write_text, json_text

    from .modal import modal_analysis

    modal = modal_analysis(system, near, args.modes)
    if args.mode is not None and args.mode > modal.n_modes:
        raise ParameterError("--mode", args.mode, f"must be <= {modal.n_modes}, the modes computed")
    w = args.mode - 1 if args.mode is not None else driven_mode(modal, near)
    f_w = float(args.freq or modal.f_r_hz[w])
    f_a = float(modal.f_a_hz[w])
    if band is None:
        band = (f_w * 0.97, (f_a if np.isfinite(f_a) else f_w) * 1.03)
    elif not band[0] <= f_w <= band[1]:
        raise ParameterError("--band", args.band, f"does not contain the working frequency {f_w:.1f} Hz")
    if args.bvd_fits:
        from .bvd import measured_losses

        args.losses, fit = measured_losses(system, modal, w, args.bvd_fits)
        loss = args.losses.loss_model()
        print(f"admittance fit ({args.admittance}): {fit.text()}")
    basis = modal_basis(system, f_w, loss=loss, modes=modal)
    freqs = np.linspace(band[0], band[1], args.points)
    # a band wider than these modes represent gets its own, larger basis (see harmonic_sweep)
    res = harmonic_sweep(system, freqs, args.voltage, loss=loss, surfaces=surfaces, n_modes=args.modes,
                         basis=basis if basis_reach(basis, freqs) <= 0.5 else None)
    wp = working_point(system, f_w, args.voltage, loss=loss, surfaces=surfaces, basis=basis)
    ring = None
    if args.ring_up is not None:
        from .transient import ring_up

        tau = 2.0 / (basis.eta[w] * 2 * np.pi * f_w)
        ring = ring_up(system, f_w, args.voltage, args.ring_up or 6 * tau, loss=loss, basis=basis,
                       surfaces=surfaces[:1])
    _print_response(args, modal, w, f_w, wp, res, band, ring, surfaces)
    from .thermal import thermal_summary

    thermal = thermal_summary(system, wp.x, f_w, basis.L, wp.power_w, settings=args.thermal)
    print("\n".join(thermal.pop("lines")))
    print(f"mesh: {_mesh_label(args, design, args.fe_path)}, {system.ndof} DOFs", flush=True)
    # on the sector path the estimate is cheap (a coarser sector): every run states it
    auto = args.fe_path == "sector" and args.freq is None and args.mode is None and args.refine * 1.4 <= 5.0
    hook = None
    if args.stress:
        from .stress_cli import coarse_hook

        hook = coarse_hook(args, design, wp)
    run_est = args.error or auto or hook is not None
    from .operating_errors import CoarseOperatingPoint, annotate_operating_point, operating_quantities
    from .operating_errors import error_lines as operating_error_lines

    fine = operating_quantities(system, wp, loss) if run_est and system.has_piezo else None
    est = (_error(args, design, modal, w, wp, system, near, loss, surfaces,
                  extra=CoarseOperatingPoint(loss, hook) if fine else hook) if run_est else None)
    stress = None
    if args.stress:
        from .stress_cli import run_stress

        stress = run_stress(args, system, basis, wp, band, est=est, mesh=_mesh_label(args, design, args.fe_path))
    # the window's and the temperature's two-level errors (fem.operating_errors)
    op = {"operating_point": {"thermal": thermal, "preload": (stress or {}).get("preload_window") or {}}}
    annotate_operating_point(op, fine, est)
    for line in operating_error_lines(op):
        print(line)
    text = None
    if args.json:
        text = json_text({**_record(args, design, modal, w, f_w, wp, res, ring, system, est, stress),
                          "thermal": thermal}, nonfinite="null")
    if args.plots:
        _plots(args, modal, w, f_w, res, ring, wp)
    if text is not None:
        atomic_write_text(args.json, text)
    return 0


def _print_response(args, modal, w, f_w, wp, res, band, ring, surfaces) -> None:
    f_a = float(modal.f_a_hz[w])
    drive = f"drive {f_w:.1f} Hz; " if args.freq is not None else ""
    print(f"{drive}working mode {w + 1} ({modal.labels[w]}): f_r {modal.f_r_hz[w]:.1f} Hz, f_a {f_a:.1f} Hz, "
          f"k_eff {modal.k_eff[w]:.3f}")
    print(f"drive {args.drive.text()}; losses {args.losses.text()}")
    print(f"{surfaces[0]} axial amplitude: {wp.tip_per_volt_m * 1e9:.2f} nm/V, {wp.tip_amplitude_m * 1e6:.3f} um "
          f"at {args.voltage:.4g} V amplitude; current {abs(wp.current_a):.3f} A amplitude, input power "
          f"{wp.power_w:.2f} W")
    if "teeth_tops" in wp.surfaces:
        print(f"teeth: tangential/axial {wp.teeth_ellipse_ratio:.3f}, phase {wp.teeth_phase_deg:.1f} deg")
    print(f"admittance: peak {res.f_r_hz:.1f} Hz, dip {res.f_a_hz:.1f} Hz (band {band[0]:.0f}-{band[1]:.0f} Hz, "
          f"{args.points} points, modal superposition of {res.basis_modes} modes + residual)")
    if ring is not None:
        print(f"ring-up: steady {ring.steady_amplitude(surfaces[0]) * 1e6:.3f} um after {ring.t[-1] * 1e3:.2f} ms")


def _error(args, design, modal, w, wp, system, near, loss, surfaces, extra=None):
    """``--error``: the two-level estimate of the driven mode's values, printed (``extra``: the
    stress table's hook, :func:`fem.stress_cli.coarse_hook`)."""
    from geometry.options import mesher_of

    from .errors import estimate, harmonic_quantities
    from .errors_cli import error_lines

    values = {"f_r_hz": float(modal.f_r_hz[w]), "f_a_hz": float(modal.f_a_hz[w]), "k_eff": float(modal.k_eff[w]),
              **harmonic_quantities(wp)}
    est = estimate(design, values, system.ndof, refine=args.refine, mesh_size=args.mesh_size, grade=args.grade,
                   near_hz=near, loss=loss, surfaces=surfaces, n_modes=args.modes, select=driven_mode,
                   mesher=mesher_of(args, design), path=args.fe_path, extra=extra)
    print("\n".join(error_lines(est, tip_surface=surfaces[0], voltage=args.voltage)))
    return est


def _record(args, design, modal, w, f_w, wp, res, ring, system, est, stress) -> dict:
    """The ``--json`` record."""
    from geometry.options import mesher_of

    from .errors import annotate
    from .errors_cli import MODE_KEYS, POINT_KEYS

    return {"design": str(args.design or "default"), "working_mode": annotate({
        "index": w, "f_r_hz": float(modal.f_r_hz[w]), "f_a_hz": float(modal.f_a_hz[w]), "k_eff": float(modal.k_eff[w]),
        "label": modal.labels[w]}, est, MODE_KEYS), "drive_hz": f_w, "drive_voltage": args.drive.record(),
        "losses": args.losses.record(),
        "working_point": annotate(wp.to_dict(), est, POINT_KEYS), "sweep": res.to_dict(),
        "ring_up": ring.to_dict() if ring is not None else None, "ndof": system.ndof,
        "mesher": mesher_of(args, design), "path": args.fe_path, "mesh": _mesh_label(args, design, args.fe_path),
        "discretisation_error": est.to_dict() if est is not None else None, "stress": stress}


def _plots(args, modal, w, f_w, res, ring, wp) -> None:
    """``--plots``: admittance, tip response and ring-up PNGs."""
    from pathlib import Path

    from . import plots

    out = Path(args.plots)
    save_figure(plots.admittance(res, float(modal.f_r_hz[w]), float(modal.f_a_hz[w])), out / "admittance.png")
    if "horn_tip" in res.surfaces:
        save_figure(plots.tip_response(res, f_w), out / "tip_response.png")
    if ring is not None:
        save_figure(plots.ring_up(ring, wp.tip_amplitude_m), out / "ring_up.png")


def _converge(args, design, near: float, loss, surfaces) -> int:
    """``--converge TOL``: the refinement study of the driven mode with its harmonic response."""
    from geometry.options import mesher_of

    from .convergence import working_mode_level
    from .errors_cli import run_study

    mesher = mesher_of(args, design)

    def level(refine):
        return working_mode_level(design, refine, mesh_size=args.mesh_size, near_hz=near, n_modes=args.modes,
                                  grade=args.grade, loss=loss, surfaces=surfaces, select=driven_mode,
                                  mesher=mesher, path=args.fe_path)

    def describe(lev):
        v = lev.values
        return (f"f_r {v['f_r_hz']:.2f} Hz, f_a {v['f_a_hz']:.2f} Hz, {surfaces[0]} {v['tip_per_volt_m'] * 1e9:.3f} nm/V"
                + (f", ellipse {v['teeth_ellipse_ratio']:.4f}" if "teeth_ellipse_ratio" in v else ""))

    return run_study(args, design, near, level, describe,
                     {"design": str(args.design or "default"), "voltage_v": args.voltage,
                      "drive_voltage": args.drive.record(), "losses": args.losses.record(),
                      "surfaces": list(surfaces)})
