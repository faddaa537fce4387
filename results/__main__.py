"""``python -m results``: the end-to-end run from a design file to drill-tool kinetic energy."""

from __future__ import annotations

import sys

if __name__ == "__main__":
    # signal handling first: the imports below take a second and must end cleanly on SIGINT/SIGTERM
    from rpud_common.launch import launch

    sys.exit(launch("results.__main__", prog="results"))

from pathlib import Path

from rpud_common import (CliParser, ParameterError, atomic_folder, check_integer, check_output_paths,
                             check_range, setup_logging)
from rpud_common.cli import check_given, check_usual, check_zero_or_range, echo_inputs, needs, quantity

WOB = 7.0
"""Default weight on bit of the drilling stage, N (the article's)."""

COMPLIANT_OPTIONS = (
    ("--compliant-members", int, "N", "it and its convergence study start with N ensemble members per case "
                                      "(default 16; 0 skips the stage; it runs on the k = 0 sector path)"),
    ("--compliant-max-members", int, "N", "members are added until every driving 95 %% CI meets its target (the "
                                          "two options below) or N are reached (default 64)"),
    ("--compliant-rel-tol", float, "R", "95 %% CI target of the headline cases (full cut-off, nominal stiffness), "
                                        "relative to the mean, in (0, 1) (default 0.05)"),
    ("--compliant-study-rel-tol", float, "R", "95 %% CI target of the convergence study's cases (lower cut-offs, "
                                              "stiffness x0.5 / x2), in (0, 1) (default 0.1; their half-widths "
                                              "enter the model-form estimate)"),
    ("--face-radius", float, "M", "the free mass's crown radius, m (default: a steel sphere of each free mass's own "
                                  "mass); with --edge-radius the radius of its flat face, m; in [1e-4, 1] m"),
    ("--edge-radius", float, "M", "a flat face whose rim is rounded with this radius, m (needs --face-radius and "
                                  "--face-tilt; at most the face radius)"),
    ("--face-tilt", float, "DEG", "tilt of the flat face against the horn tip and tool, degrees, in (0, 90) (with "
                                  "--edge-radius)"),
    ("--contact", str, "TOML", "the contact faces from a [contact] table (face_radius, edge_radius, face_tilt_deg in "
                               "m and degrees, free_mass_material, tool_material); the options above override it"),
)
"""The compliant model's options: name, type, metavar, help."""


def build_parser() -> CliParser:
    p = CliParser(prog="python -m results",
                  description="End-to-end RPUD run: mesh -> resonance matching -> harmonic response at the "
                              "drive voltage -> horn-tip amplitude A0 (coupled with the free-mass impacts) -> "
                              "drill-tool kinetic energy vs free-mass weight. Writes summary.json, report.md, "
                              "figures/, renders/ and modes.vtu into the output folder. "
                              "'python -m results explore STUDY.toml' runs a design study instead "
                              "(--help after 'explore' for its options).")
    from geometry.options import add_design_options

    add_design_options(p, include=("design", "materials"))
    from rpud_common.voltage import add_voltage_options

    add_voltage_options(p)
    p.add_argument("--out", metavar="DIR",
                   help="output folder (default results/default for the built-in design, else results/<name>)")
    add_design_options(p, include=("mesh_size", "refine", "grade", "mesher"))
    p.add_argument("--path", choices=("auto", "sector", "whole"), default="auto",
                   help="auto (default): the k = 0 swept sector where the design can be swept (every response of "
                        "the stack on a sixth of the unknowns, working mode within ~0.03 %% on the article's drill), "
                        "else the whole drill, graded; sector / whole: that path (--mesher other than auto: whole)")
    from fem.losses import add_loss_options

    add_loss_options(p)
    p.add_argument("--no-match", action="store_true", help="analyse the design as it is, without resonance matching")
    p.add_argument("--no-couple", action="store_true", help="do not load the horn tip with the impacts (A0 unloaded)")
    p.add_argument("--rel-tol", type=float, default=0.03, metavar="R",
                   help="impact statistics: add ensemble members until every 95%% CI half-width is within R "
                        "of its mean (default 0.03)")
    p.add_argument("--max-members", type=int, default=4096, metavar="N",
                   help="impact statistics: cap of the members per free mass (default 4096)")
    p.add_argument("--seed", type=int, default=20260, metavar="N", help="seed of the ensemble members (default 20260)")
    p.add_argument("--no-coupled-model", action="store_true",
                   help="skip the coupled model (FE transducer in the impact loop); kinematic-horn results only")
    p.add_argument("--coupled-modes", type=int, default=None, metavar="N",
                   help="modes of the reduced transducer in the coupled model (default: tip-participation rule)")
    for opt, kind, meta, text in COMPLIANT_OPTIONS:
        p.add_argument(opt, type=kind, default=None, metavar=meta, help="compliant model (the headline): " + text)
    p.add_argument("--load", choices=["rock"], default=None,
                   help="also predict drilling under load: bit on sandstone, depth vs free mass (impact.drilling)")
    p.add_argument("--wob", type=float, default=None, metavar="N",
                   help=f"weight on bit with --load, N (default {WOB:g})")
    p.add_argument("--no-render", action="store_true", help="skip the mode-shape PNGs and the VTU")
    p.add_argument("--allow-large", action="store_true",
                   help="solve even above the resource budget (geometry.guard.MAX_DOFS estimated DOFs)")
    p.add_argument("-q", "--quiet", action="store_true", help="no inputs line and no stage progress")
    return p


def check_options(args) -> None:
    """Every option usable, numbers finite and inside their stated ranges, options that depend on
    another only with it (before anything runs)."""
    if args.load is None:
        needs("--wob", args.wob, "--load rock", "the weight on bit of the drilling stage")
    if args.no_coupled_model and args.coupled_modes is not None:
        raise ParameterError("--coupled-modes", args.coupled_modes, "cannot be used with --no-coupled-model (it "
                                                                    "sets the modes of the coupled model it skips)")
    from rpud_common.voltage import drive_voltage

    args.drive = drive_voltage(args)
    if args.q_mech is not None:
        check_zero_or_range("--q-mech", args.q_mech, 1.0, 1e6, "", "datasheet values")
    if args.admittance is not None:
        from fem.bvd import fit_bvd, read_admittance

        if args.q_mech is not None:
            raise ParameterError("--admittance", args.admittance, "sets the losses: drop --q-mech")
        fit_bvd(read_admittance(args.admittance))          # a bad file ends here, before any solve
    from geometry.options import check_design_options

    check_design_options(args)
    from impact.options import REL_TOL_RANGE

    check_range("--rel-tol", args.rel_tol, *REL_TOL_RANGE)
    from impact.stats import MAX_MEMBERS

    check_integer("--max-members", args.max_members, 1, MAX_MEMBERS)
    check_integer("--seed", args.seed, 0, 2 ** 63 - 1)
    if args.coupled_modes is not None:
        check_integer("--coupled-modes", args.coupled_modes, 1, 12)
    if args.compliant_members == 0:
        for opt, *_ in COMPLIANT_OPTIONS[1:]:
            needs(opt, getattr(args, opt[2:].replace("-", "_")), "--compliant-members N > 0",
                  "it sets the compliant model, which --compliant-members 0 skips")
    elif args.compliant_members is not None:
        check_integer("--compliant-members", args.compliant_members, 2, 100_000)
    if args.compliant_max_members is not None:
        low = 16 if args.compliant_members is None else args.compliant_members
        check_integer("--compliant-max-members", args.compliant_max_members, low, 1_000_000)
    for opt in ("--compliant-rel-tol", "--compliant-study-rel-tol"):
        value = getattr(args, opt[2:].replace("-", "_"))
        if value is not None:
            check_range(opt, value, 0.0, 1.0, lo_open=True, hi_open=True)
    if args.wob is not None:
        check_range("--wob", args.wob, 0.0, 1e4, "N")
    args.faces = _faces(args)


FACE_OPTIONS = (("--face-radius", "face_radius"), ("--edge-radius", "edge_radius"), ("--face-tilt", "face_tilt_deg"))
"""The contact-face options and the :class:`results.contact_faces.ContactFaces` fields they set."""


def _faces(args):
    """The contact faces of ``--contact`` with the face options over them, checked (one line naming
    the option when an option is wrong, the field when the file is)."""
    from dataclasses import replace

    from .contact_faces import ContactFaces

    given = [(opt, field, getattr(args, field.replace("_deg", ""))) for opt, field in FACE_OPTIONS]
    given = [(opt, field, v) for opt, field, v in given if v is not None]
    faces = ContactFaces.from_toml(args.contact) if args.contact is not None else ContactFaces()
    limits = {"face_radius": (1e-4, 1.0, "m"), "edge_radius": (1e-6, 1.0, "m"), "face_tilt_deg": (0.0, 90.0, "degrees")}
    for opt, field, v in given:
        lo, hi, unit = limits[field]
        check_range(opt, v, lo, hi, unit, lo_open=field == "face_tilt_deg", hi_open=field == "face_tilt_deg")
    try:
        return replace(faces, **{field: v for _, field, v in given})
    except ParameterError as err:           # a combination of options: name the option
        opt = next((o for o, f, _ in given if f == err.name), None)
        if opt is None:
            raise
        raise ParameterError(opt, err.value, err.allowed.replace("face_radius", "--face-radius")
                             .replace("face_tilt_deg", "--face-tilt").replace("edge_radius", "--edge-radius")) from None


def _inputs(design, settings, out) -> dict:
    """The run's inputs for the inputs line."""
    from .stage_teeth import teeth_mesh_text

    on = {True: "on", False: "off"}
    items = {"design": design.name, "voltage": settings.drive().text(),
             "losses": settings.losses().short() if not settings.admittance else f"measured ({settings.admittance})",
             "mesh": settings.mesh_options().resolved(design).label(design),
             "teeth motion": teeth_mesh_text(design, settings.mesh_options().resolved(design)),
             "matching": on[settings.match], "impact load on the tip": on[settings.couple_impacts],
             "coupled model": (f"{settings.coupled_modes} modes" if settings.coupled_model and settings.coupled_modes
                               else on[settings.coupled_model]),
             "compliant model": (f"{settings.compliant_members}-{settings.compliant_max_members} members per case, "
                                 f"95 % CI within {settings.compliant_rel_tol:g} (study {settings.compliant_study_rel_tol:g}), "
                                 f"{settings.faces.text()}" if settings.compliant_members else "off"),
             "statistics": f"95 % CI within {settings.impact_rel_tol:g}, at most {settings.impact_max_members} "
                           f"members, seed {settings.seed}"}
    if settings.load:
        items["load"] = f"{settings.load}, WOB {quantity(settings.wob, 'N')}"
    items["out"] = str(out)
    return items


def _settings(args):
    """The pipeline settings of the (checked) options, defaults applied."""
    from .pipeline import PipelineSettings

    from fem.losses import q_option_losses

    losses = q_option_losses(args.q_mech)
    return PipelineSettings(voltage=args.drive.amplitude_v, voltage_given_as=args.drive.convention,
                            q_mech=losses.q_mech, losses_origin=losses.origin, losses_source=losses.source,
                            admittance=args.admittance,
                            mesh_size=args.mesh_size, refine=1.0 if args.refine is None else args.refine,
                            grade=True if args.grade else None, mesher=args.mesher,
                            path=None if args.path == "auto" else args.path, match=not args.no_match,
                            couple_impacts=not args.no_couple, impact_rel_tol=args.rel_tol,
                            impact_max_members=args.max_members, seed=args.seed, render=not args.no_render,
                            coupled_model=not args.no_coupled_model, coupled_modes=args.coupled_modes,
                            **{f"compliant_{k}": getattr(args, f"compliant_{k}") for k in
                               ("members", "max_members", "rel_tol", "study_rel_tol")
                               if getattr(args, f"compliant_{k}") is not None},
                            faces=args.faces, load=args.load, wob=WOB if args.wob is None else args.wob)


def _out_folder(args, design) -> Path:
    """``--out``, or the default folder (ours to create; a user's --out must have an existing parent)."""
    if args.out is not None:
        return Path(args.out)
    out = Path("results") / ("default" if args.design is None else design.name)
    out.parent.mkdir(exist_ok=True)
    return out


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["explore"]:
        from .explore_cli import main as explore_main

        return explore_main(argv[1:])
    from geometry.guard import check_budget
    from geometry.options import design_from_options, design_inputs

    from .pipeline import run_pipeline

    parser = build_parser()
    args = parser.parse_args(argv)
    setup_logging(-1)
    check_given(parser, args)
    check_options(args)
    settings = _settings(args)
    design = design_from_options(args)
    out = _out_folder(args, design)
    check_output_paths(inputs=design_inputs(args), folders=("out",), out=out)
    if args.design is not None and out.exists() and Path(args.design).resolve().is_relative_to(out.resolve()):
        raise ParameterError("--out", str(out), "holds the input --design; it would be replaced by the results")
    check_budget(design, args.mesh_size, allow_large=args.allow_large, **settings.mesh_options().budget(design))
    check_usual(parser.prog, "--voltage", settings.voltage, "voltage")
    if settings.load:
        check_usual(parser.prog, "--wob", settings.wob, "wob")
    # progress on stdout: stderr carries only the one-line error of a failed run (and tqdm bars)
    echo_inputs(_inputs(design, settings, out), args.quiet)
    say = (lambda msg: None) if args.quiet else (lambda msg: print(msg, flush=True))
    # built beside the target and swapped in whole: an interrupted or failed run leaves the
    # previous results untouched and no temporary folder behind
    with atomic_folder(out) as tmp:
        run_pipeline(design, settings, tmp, progress=say)
    if not args.quiet:
        print(f"results: {out}", flush=True)
    return 0
