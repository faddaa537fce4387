"""``python -m fem.modal``: the command line of :mod:`fem.modal` (options, checks, printing, files).

The physics lives in :mod:`fem.modal` (and :mod:`fem.cyclic` for ``--sectors``, run by
:mod:`fem.cyclic_cli`); this module only parses, validates, calls and writes.
"""

from __future__ import annotations

import contextlib
import logging
import os
from pathlib import Path

import numpy as np

from geometry.options import mesher_of
from rpud_common import ParameterError
from rpud_common.cli import check_given, echo_inputs, mesh_text, quantity

from .modal import ModalResult, modal_analysis

def format_table(res: ModalResult, errors: dict | None = None) -> str:
    """The modal table; ``errors`` (mode index -> ``{"f_r_err_hz": .., "f_a_err_hz": ..}``) adds the
    estimated discretisation error of those modes as a last column."""
    errors = errors or {}
    lines = [f"{'#':>3} {'f_r kHz':>10} {'f_a kHz':>10} {'k_eff':>7} {'MAC':>5}  "
             f"{'ax/tor/lat':>14}  motion" + ("   (discretisation error)" if errors else "")]
    for i in range(res.n_modes):
        fa = f"{res.f_a_hz[i] / 1e3:10.4f}" if np.isfinite(res.f_a_hz[i]) else f"{'-':>10}"
        ke = f"{res.k_eff[i]:7.4f}" if np.isfinite(res.k_eff[i]) else f"{'-':>7}"
        mc = f"{res.mac[i]:5.2f}" if np.isfinite(res.mac[i]) else f"{'-':>5}"
        sh = "/".join(f"{100 * s:.0f}" for s in res.shares[i])
        err = errors.get(i)
        tail = (f"   f_r +- {err['f_r_err_hz']:.2g} Hz, f_a +- {err['f_a_err_hz']:.2g} Hz" if err else "")
        lines.append(f"{i + 1:3d} {res.f_r_hz[i] / 1e3:10.4f} {fa} {ke} {mc}  {sh:>14}  {res.labels[i]}{tail}")
    from .cyclic_cli import own_note

    lines.extend(own_note(res.f_a_hz, res.system is not None and res.system.hot_dof is not None))
    t = res.timings
    lines.append(f"{res.ndof} DOFs, {res.backend}; assembly {t['assembly_s']:.2f} s, "
                 f"factorisation {t['factorisation_s']:.2f} s, eigen {t['eigen_s']:.2f} s"
                 + (f"; {len(res.rigid_hz)} rigid-body modes skipped" if len(res.rigid_hz) else ""))
    return "\n".join(lines)


def build_parser(prog="python -m fem.modal"):
    from rpud_common import CliParser

    p = CliParser(prog=prog, description="Resonance (short-circuit) and anti-resonance (open-circuit) "
                  "modes of a design near a target frequency; with --match, tune the horn and coupler "
                  "lengths until both resonate together at the target.")
    from geometry.options import add_design_options

    g = p.add_argument_group("design")
    add_design_options(g, design_default="default")
    g.add_argument("--order", type=int, default=2, choices=(1, 2), help="field order (default 2)")
    g = p.add_argument_group("modal analysis")
    g.add_argument("--near", type=float, metavar="HZ",
                   help="target frequency in Hz (0: lowest modes; default: the design's target frequency)")
    g.add_argument("--modes", type=int, default=None, metavar="N",
                   help=f"number of modes, 1-{MAX_MODES} (default 12; with --match: modes per iteration, default 4)")
    g.add_argument("--clamp", action="append", default=[], metavar="SURFACE",
                   help="clamp the named surface (repeatable; default: free)")
    g.add_argument("--error", action="store_true",
                   help="estimate the working mode's discretisation error from one extra solve on a mesh "
                        "1.4x coarser (--refine x 1.4) and an assumed order in h (fem.convergence.estimator_order: "
                        "1 on an ungraded mesh with re-entrant edges, else 2); prints f_r +- err, f_a +- err and adds them to the JSON; "
                        "with --match: of the matched mode on the tuned design (and its teeth ellipse ratio)")
    g.add_argument("--converge", type=float, metavar="TOL",
                   help="mesh-convergence study of the working mode: refine by 0.8 per level from --refine until "
                        "f_r, f_a, the tip amplitude per volt and the teeth ellipse ratio change by less than TOL "
                        "(relative, 1e-7..0.1) between levels; prints each level, the observed order, the "
                        "Richardson estimate and the error (with or without --grade)")
    g.add_argument("--sectors", default="auto", metavar="auto|off|N",
                   help="cyclic symmetry: solve one of N identical sectors per circumferential harmonic "
                        "(fem.cyclic; exact for the symmetric drill, ~6x smaller solves). auto (default): the "
                        "coupler's symmetry order (6) for a plain modal run of a design that can be swept as a "
                        "sector, with a finer mesh per harmonic family; off: the whole drill")
    g.add_argument("--harmonics", default=None, metavar="K[,K..]|all",
                   help="with sectors: the harmonics solved (0: longitudinal, torsional and the electrically "
                        "driven modes; 1: bending pairs; 2..N/2: lobed modes of the coupler; default 0,1)")
    g.add_argument("--solver", choices=("auto", "pardiso", "superlu"), default=None,
                   help="sparse direct solver (default: pardiso if installed; env RPUD_SOLVER)")
    g = p.add_argument_group("resonance matching")
    g.add_argument("--match", action="store_true",
                   help="tune design lengths until the working longitudinal mode is at the target and the "
                        "horn and coupler sides resonate together")
    g.add_argument("--target", type=float, metavar="HZ",
                   help="matching target frequency in Hz (default: the design's target_frequency)")
    g.add_argument("--tune", metavar="A[,B]",
                   help="design lengths to tune: a horn/flange length, then a coupler/stack length "
                        "(default horn.length,coupler.length)")
    g.add_argument("--bracket", metavar="LO,HI", default=None,
                   help=f"search interval of each tuned length as factors of its start (default {BRACKET})")
    g.add_argument("--tol", type=float, default=None, metavar="REL",
                   help=f"relative frequency tolerance of the match, in [{MATCH_TOL_RANGE[0]:g}, {MATCH_TOL_RANGE[1]:g}] "
                        "(default 0.005 = 0.5 %%)")
    g.add_argument("--out-design", metavar="FILE",
                   help="write the tuned design as TOML (default: <design name>-tuned.toml beside --json, "
                        "else not written)")
    g = p.add_argument_group("output")
    g.add_argument("--json", metavar="OUT", help="write the result as JSON to OUT")
    g.add_argument("--render", metavar="DIR",
                   help="off-screen PNGs of the working mode and its neighbours into DIR")
    g.add_argument("--vtu", metavar="FILE", help="VTU file with every computed mode as point data (ParaView)")
    g.add_argument("--allow-large", action="store_true",
                   help="solve even above the resource budget (geometry.guard.MAX_DOFS estimated DOFs)")
    p.add_argument("-v", "--verbose", action="count", default=0)
    p.add_argument("-q", "--quiet", action="store_true", help="no inputs line")
    return p


BRACKET = "0.5,2.0"
"""Default search interval of ``--match`` (factors of each tuned length's start)."""

MAX_MODES = 200
"""Most modes one CLI run computes (shift-invert Lanczos cost grows with their square)."""

MATCH_TOL_RANGE = (1e-6, 0.2)
"""Accepted relative frequency tolerances of ``--match`` (``--tol``)."""


def _check_options(args) -> dict:
    """Validate every option before the design is meshed; returns the checked output paths."""
    from rpud_common import check_integer, check_output_paths, check_range
    from geometry.options import check_design_options, design_inputs
    from geometry.validate import FREQUENCY_BAND

    if args.near is not None and args.near != 0:
        check_range("--near", args.near, *FREQUENCY_BAND, "Hz")
    if args.modes is not None:
        check_integer("--modes", args.modes, 1, MAX_MODES)
    if args.converge is not None:
        check_range("--converge", args.converge, 1e-7, 0.1)
        for opt in ("match", "error", "render", "vtu"):
            if getattr(args, opt):
                raise ParameterError("--converge", args.converge, f"cannot be combined with --{opt}")
        if args.clamp:
            raise ParameterError("--converge", args.converge, "studies the free-free working mode: drop --clamp")
    if args.error and args.clamp:
        raise ParameterError("--error", True, "applies to the free-free working mode (not with --clamp)")
    if args.error and args.refine * 1.4 > 5.0:
        raise ParameterError("--refine", args.refine, "must be <= 3.5 with --error (its coarse mesh is 1.4x coarser)")
    if args.target is not None:
        check_range("--target", args.target, *FREQUENCY_BAND, "Hz")
    if args.tol is not None:
        # below 1e-6 (0.02 Hz at 20 kHz) the FE frequency itself is not that exact: unattainable
        check_range("--tol", args.tol, *MATCH_TOL_RANGE)
    for opt, suffix in (("json", ".json"), ("vtu", ".vtu"), ("out_design", ".toml")):
        val = getattr(args, opt)
        if val is not None and not str(val).endswith(suffix):
            raise ParameterError("--" + opt.replace("_", "-"), val, f"must end in {suffix}")
    check_design_options(args)
    if not args.match:
        for opt in ("target", "tune", "out_design", "tol", "bracket"):
            if getattr(args, opt) is not None:
                raise ParameterError("--" + opt.replace("_", "-"), getattr(args, opt), "applies to --match only")
    else:
        # matching is free-free with its own nodal-plane cut and shift: refuse what it cannot honour
        if args.clamp:
            raise ParameterError("--clamp", args.clamp[0], "cannot be used with --match (the match is free-free)")
        if args.near is not None:
            raise ParameterError("--near", args.near, "cannot be used with --match; give --target HZ")
    if args.solver not in (None, "auto"):
        from .solvers import backend_name

        backend_name(args.solver)                  # pardiso without MKL: refused before meshing
    tuned = None
    if args.match and args.out_design is None and args.json is not None:
        tuned = "beside --json"
    outputs = check_output_paths(inputs=design_inputs(args), folders=("render",), json=args.json, vtu=args.vtu, out_design=args.out_design,
                                 render=args.render)
    outputs["tuned"] = tuned
    return outputs


def _factors(text: str, name: str) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in text.split(","))
    except ValueError:
        raise ParameterError(name, text, "must be two numbers LO,HI") from None
    if not (0.05 <= lo < 1 < hi <= 20):
        raise ParameterError(name, text, "must be two factors with 0.05 <= LO < 1 < HI <= 20")
    return lo, hi


def _outputs(args, mesh, res, working: int) -> None:
    """--render and --vtu: the working mode and two neighbours each side; every mode."""
    if args.render:
        from .render import around, render_modes

        paths = render_modes(mesh, res.shapes, args.render, modes=around(working, res.n_modes, 2),
                             frequencies=res.f_r_hz, labels=res.labels)
        print(f"renders: {', '.join(str(p) for p in paths)}")
    if args.vtu:
        from .render import write_modes_vtu

        print(f"modes: {write_modes_vtu(mesh, res.shapes, args.vtu, frequencies=res.f_r_hz)}")


def _sectors(args, design) -> int | None:
    """The sectors of ``--sectors`` (None: the whole drill); ``--harmonics`` only with sectors,
    its default applied after the check."""
    from .cyclic_cli import HARMONICS, parse_harmonics, sectors_for

    sectors = sectors_for(args, design)            # cyclic symmetry: refused before any meshing
    if sectors is None and args.harmonics is not None:
        raise ParameterError("--harmonics", args.harmonics, "applies with sectors only (--sectors)")
    args.harmonics = HARMONICS if args.harmonics is None else args.harmonics
    if sectors is not None:
        parse_harmonics(args.harmonics, sectors)
    return sectors


def _inputs(args, design, sectors, settings) -> dict:
    """The run's inputs for the inputs line (``settings``: the match's, if matching)."""
    items = {"design": design.name}
    if settings is not None:
        items.update({"match": f"{', '.join(settings.tune)} to {quantity(settings.target_hz, 'Hz')} within "
                               f"{settings.tolerance:g}, bracket {args.bracket or BRACKET}",
                      "modes per iteration": settings.n_modes})
    else:
        near = args.near if args.near is not None else getattr(design, "target_frequency", 20e3)
        items.update({"near": "the lowest modes" if near == 0 else quantity(near, "Hz"),
                      "modes": 12 if args.modes is None else args.modes})
    mesh = mesh_text(mesher_of(args, design), args.refine, args.grade, args.mesh_size, order=args.order)
    items.update({"mesher": mesh, "clamp": ", ".join(args.clamp) if args.clamp else "free",
                  "sectors": f"{sectors} (harmonics {args.harmonics})" if sectors else "off (the whole model)"})
    if args.converge is not None:
        items["convergence study"] = f"tolerance {args.converge:g}"
    elif args.error:
        items["discretisation error"] = "estimated"
    if args.solver not in (None, "auto"):
        items["solver"] = args.solver
    return items


def _match_settings(args, design, bracket, outputs):
    """The match's settings and the tuned design's path (None: not written), checked before any work."""
    from rpud_common import check_output_paths
    from geometry.options import design_inputs, mesh_options

    from .matching import MatchSettings, default_tune

    extra = {"n_modes": args.modes} if args.modes is not None else {}
    settings = MatchSettings(
        target_hz=float(args.target or getattr(design, "target_frequency", 20e3)),
        tolerance=0.005 if args.tol is None else args.tol,
        tune=tuple(args.tune.split(",")) if args.tune else default_tune(design),
        bracket=bracket, mesh_size=args.mesh_size, order=args.order,
        **mesh_options(args), **extra)
    out_design = args.out_design
    if out_design is None and outputs["tuned"]:
        out_design = str(Path(args.json).parent / f"{design.name}-tuned.toml")
        check_output_paths(inputs={**design_inputs(args), "--json": args.json}, out_design=out_design)
    return settings, out_design


def main(argv=None) -> int:
    from rpud_common import setup_logging
    from geometry.guard import check_budget
    from geometry.options import design_from_options, mesh_options

    parser = build_parser()
    args = parser.parse_args(argv)
    setup_logging(args.verbose - 1)
    if args.verbose < 2:
        logging.getLogger("skfem").setLevel(logging.WARNING)
    check_given(parser, args)
    outputs = _check_options(args)
    bracket = _factors(args.bracket or BRACKET, "--bracket") if args.match else None
    design = design_from_options(args)
    sectors = _sectors(args, design)
    check_budget(design, args.mesh_size, args.order, allow_large=args.allow_large, sectors=sectors,
                 **mesh_options(args, design))
    if args.match:
        settings, out_design = _match_settings(args, design, bracket, outputs)
        echo_inputs(_inputs(args, design, None, settings), args.quiet)
        return _run_match(args, settings, out_design, design)
    echo_inputs(_inputs(args, design, sectors, None), args.quiet)
    return _run_modal(args, design, sectors)


def _run_match(args, settings, out_design, design) -> int:
    """``--match``: tune, print, write; exit status 1 if the match did not converge."""
    from rpud_common import atomic_write_text, json_text

    from .matching import match

    print(f"matching {', '.join(settings.tune)} to {settings.target_hz:.1f} Hz", flush=True)

    def show(rec):
        print(f"  [{rec['stage']:5s}] {rec['parameter']} = "
              f"{rec['value_m'] * 1e3:9.4f} mm -> {rec['f_hz']:10.2f} Hz  ({rec['seconds']:5.1f} s)",
              flush=True)

    with _solver(args.solver):
        res_m = match(design, settings, progress=show)
    res = res_m.modal
    print(format_table(res))
    print(f"matched {res_m.matched_hz:.2f} Hz (target {res_m.target_hz:.1f} Hz, "
          f"{'converged' if res_m.converged else 'NOT converged'}) in {len(res_m.iterations)} iterations, "
          f"{res_m.timings['total_s']:.1f} s; tuned: "
          + ", ".join(f"{k} = {v * 1e3:.4f} mm (start {res_m.start[k] * 1e3:.4f})" for k, v in res_m.tuned.items()))
    if res_m.teeth:
        print(f"teeth: axial {res_m.teeth['axial']:.3g}, tangential {res_m.teeth['tangential']:.3g} "
              f"(ellipse ratio {res_m.teeth['ellipse_ratio']:.3f}); flange/tip axial {res_m.node_ratio:.3f}")
    est = _match_error(args, res_m) if args.error else None
    if est is None:
        print(_mesh_note(args, res_m.design))
    # NaN marks "not available" here (a stack design has no flange/tip ratio, unpaired modes no f_a)
    record = {**_match_record(res_m, est), "mesher": settings.mesher}
    text = json_text(record, nonfinite="null") if args.json else None
    if out_design:
        res_m.design.save(out_design)
        print(f"tuned design: {out_design}")
    else:
        print("tuned design not written (give --out-design FILE or --json)")
    _outputs(args, res_m.mesh, res, res_m.working_index)
    if text is not None:
        atomic_write_text(args.json, text)
    return 0 if res_m.converged else 1


def _run_modal(args, design, sectors) -> int:
    """The modal table near ``--near`` (whole drill, sectors or a convergence study)."""
    import geometry
    from rpud_common import atomic_write_text, json_text
    from geometry.options import mesh_options

    from .assembly import assemble

    near = float(args.near if args.near is not None else getattr(design, "target_frequency", 20e3))
    if args.converge is not None:
        return _converge(args, design, near, sectors)
    if sectors is not None:
        from .cyclic_cli import run as run_cyclic

        with _solver(args.solver):
            return run_cyclic(args, design, near, sectors)
    mesh = geometry.build_mesh(design, mesh_size=args.mesh_size, order=args.order, **mesh_options(args, design))
    for name in args.clamp:
        mesh.facets(name)
    system = assemble(mesh, order=args.order)
    n_modes = 12 if args.modes is None else args.modes
    if n_modes > system.ndof // 4:
        raise ParameterError("--modes", n_modes, f"must be <= {system.ndof // 4} for this mesh ({system.ndof} DOFs)")
    res = modal_analysis(system, near, n_modes, clamp=args.clamp,
                         backend=None if args.solver in (None, "auto") else args.solver)
    errors, err_json = {}, None
    if args.error:
        errors, err_json = _error_estimate(args, design, system, res, near)
    print(format_table(res, errors))
    if not args.error:
        print(_mesh_note(args, design))
    data = json_text(_modal_record(args, design, res, err_json), nonfinite="null") if args.json else None
    if args.render or args.vtu:
        from .matching import working_mode

        _outputs(args, mesh, res, working_mode(system, res.f_r_hz, res.vectors, max(near, 1.0)) if near > 0 else 0)
    if data is not None:
        atomic_write_text(args.json, data)
    return 0


def _modal_record(args, design, res, err_json) -> dict:
    """The ``--json`` record of a modal run (``err_json``: the ``--error`` block or None)."""
    data = res.to_dict()
    data["design"] = str(args.design)
    if err_json is not None:
        data["discretisation_error"] = err_json
        # the convention of fem.errors: X_error beside the working mode's X
        mode = data["modes"][err_json["mode"] - 1]
        for key, err in (("f_r_hz", "f_r_err_hz"), ("f_a_hz", "f_a_err_hz"), ("k_eff", "k_eff_err")):
            mode[f"{key}_error"] = err_json[err]
    data["mesh_size"] = args.mesh_size
    data["refine"] = args.refine
    data["grade"] = args.grade
    data["mesher"] = mesher_of(args, design)
    return data


def _mesh_note(args, design) -> str:
    """One line on the mesh and what is known of its discretisation error (without --error)."""
    from fem.errors import has_reentrant_edges

    if mesher_of(args, design) == "revolve":
        if args.refine <= 1 and args.mesh_size is None and args.order == 2 and args.grade:
            return ("mesh: swept (r, z) section, coupler free with its notch edges graded; measured at refine 1 on "
                    "the article's drill: working mode f_r / f_a ~0.08 % / ~0.06 % high, first bending and torsion "
                    "~0.20 % / ~0.20 % high; --error estimates this design's")
        if args.refine <= 1 and args.mesh_size is None and args.order == 2:
            return ("mesh: swept (r, z) section, coupler free; measured at refine 1 on the article's drill: working "
                    "mode f_r / f_a ~0.10 % / ~0.08 % high (+0.041 % / +0.044 % without slots and teeth; the "
                    "coupler's notch edges hold the rest, --grade grades them), first bending and torsion ~0.20 % / "
                    "~0.28 % high; --error estimates this design's")
        return ("mesh: swept (r, z) section, coupler free, other than the checked rule (refine 1, order 2); --error "
                "estimates its error")
    if has_reentrant_edges(design, args.mesh_size, args.refine):
        return ("mesh: free; its working mode is high by ~0.1 % (--grade) to ~0.5 % (ungraded) at the re-entrant "
                "edges (the article's drill); --mesher revolve brings it to ~0.1 % (+0.04 % without slots and teeth), --error "
                "estimates it")
    return "mesh: free; --error estimates the working mode's discretisation error"


def _converge(args, design, near, sectors=None) -> int:
    """``--converge TOL``: the refinement study of the working mode (fem.convergence), on the
    ``k = 0`` sector with ``sectors``, else on the whole drill."""
    from rpud_common import atomic_write_text, json_text
    from geometry.guard import MAX_DOFS, estimate, sector_estimate

    from .convergence import study, working_mode_level
    from .sector_system import path_label

    mesher = mesher_of(args, design)
    path = "sector" if sectors else "whole"
    print(f"mesh: {path_label(design, path, refine=args.refine, grade=args.grade, mesh_size=args.mesh_size, order=args.order)}"
          ", refined by 0.8 per level", flush=True)

    def size(F):
        if sectors:
            return sector_estimate(design, sectors, args.mesh_size, F).dofs
        return estimate(design, args.mesh_size, args.order, refine=F, grade=args.grade, mesher=mesher).dofs

    def level(refine):
        lev = working_mode_level(design, refine, mesh_size=args.mesh_size, order=args.order, near_hz=near,
                                 n_modes=8 if args.modes is None else args.modes, grade=args.grade, mesher=mesher,
                                 path=path)
        print(f"  refine {refine:.4f}: {lev.ndof} DOFs, f_r {lev.values['f_r_hz']:.2f} Hz, "
              f"f_a {lev.values['f_a_hz']:.2f} Hz ({lev.seconds:.1f} s)", flush=True)
        return lev

    with _solver(args.solver):
        st = study(level, tol=args.converge, start=args.refine,
                   estimate_dofs=size, max_dofs=None if args.allow_large else MAX_DOFS)
    print(st.table())
    if args.json:
        atomic_write_text(args.json, json_text({"design": str(args.design), "mesh_size": args.mesh_size,
                                                "grade": args.grade, "mesher": mesher, "path": path,
                                                "convergence": st.to_dict()},
                                               nonfinite="null"))
    return 0 if st.converged else 1


def _match_error(args, res_m):
    """``--match --error``: the two-level estimate of the matched working mode (modal values and
    the mode shape's teeth ellipse ratio, as the match reports them) on the tuned design."""
    from .errors import estimate
    from .errors_cli import error_lines

    w, res = res_m.working_index, res_m.modal
    values = {"f_r_hz": float(res.f_r_hz[w]), "f_a_hz": float(res.f_a_hz[w]), "k_eff": float(res.k_eff[w])}
    if res_m.teeth:
        values["teeth_ellipse_ratio"] = float(res_m.teeth["ellipse_ratio"])
    with _solver(args.solver):
        est = estimate(res_m.design, values, res_m.system.ndof, refine=args.refine, mesh_size=args.mesh_size,
                       grade=args.grade, order=args.order, near_hz=res_m.target_hz, harmonic=False,
                       mesher=mesher_of(args, res_m.design))
    print("\n".join(error_lines(est, teeth="teeth ellipse ratio (mode shape)")))
    return est


def _match_record(res_m, est) -> dict:
    """The match JSON with the ``X_error`` keys (None without ``--error``) and the method block."""
    from .errors import annotate
    from .errors_cli import MODE_KEYS

    data = res_m.to_dict()
    annotate(data["modes"][res_m.working_index], est, MODE_KEYS)
    data["matched_hz_error"] = est.error("f_r_hz") if est is not None else None
    if data.get("teeth_tops"):
        annotate(data["teeth_tops"], est, {"ellipse_ratio": "teeth_ellipse_ratio"})
    data["discretisation_error"] = est.to_dict() if est is not None else None
    return data


def _error_estimate(args, design, system, res, near):
    """``--error``: one coarser solve, the two-level estimate of the working mode's error
    (:func:`fem.errors.estimate`; the JSON block keeps its earlier keys beside the new ones)."""
    from .errors import estimate
    from .modal import working_mode

    def pick(r, n):
        return working_mode(r.system, r.f_r_hz, r.vectors, max(n, 1.0))

    w = pick(res, near)
    values = {"f_r_hz": float(res.f_r_hz[w]), "f_a_hz": float(res.f_a_hz[w]), "k_eff": float(res.k_eff[w])}
    with _solver(args.solver):
        est = estimate(design, values, system.ndof, refine=args.refine, mesh_size=args.mesh_size, grade=args.grade,
                       order=args.order, near_hz=near, harmonic=False, n_modes=8, select=pick,
                       mesher=mesher_of(args, design))
    err = {"mode": int(w + 1), "f_r_err_hz": est.error("f_r_hz"), "f_a_err_hz": est.error("f_a_hz"),
           "k_eff_err": est.error("k_eff"), "coarse_f_r_hz": est.coarse["f_r_hz"],
           "coarse_f_a_hz": est.coarse["f_a_hz"], **est.to_dict()}
    return {w: err}, err


@contextlib.contextmanager
def _solver(name):
    """The sparse solver for code that picks it from ``RPUD_SOLVER`` (the matching loop)."""
    if name in (None, "auto"):
        yield
        return
    old = os.environ.get("RPUD_SOLVER")
    os.environ["RPUD_SOLVER"] = name
    try:
        yield
    finally:
        if old is None:
            os.environ.pop("RPUD_SOLVER", None)
        else:
            os.environ["RPUD_SOLVER"] = old
