"""``python -m geometry``: build, mesh and write a design (RPUD or generic coaxial stack).

Examples::

    python -m geometry --write-default design.toml
    python -m geometry --design design.toml --mesh rpud.msh --vtu rpud.vtu --json rpud.json --png rpud.png
    python -m geometry --design geometry/examples.toml --select k31_bar --json k31.json --order 1
    python -m geometry --export-step cad/          # cad/design.step + cad/design.toml (kind = "cad")
    python -m geometry --design cad/design.toml --json cad.json
"""

from __future__ import annotations

import sys

if __name__ == "__main__":
    # signal handling first: the imports below take a second and must end cleanly on SIGINT/SIGTERM
    from rpud_common.launch import launch

    sys.exit(launch("geometry.__main__", prog="python -m geometry"))

import logging
from pathlib import Path

from rpud_common import CliParser, ParameterError, check_output_paths, check_range, setup_logging, write_json

log = logging.getLogger("geometry")

_SUFFIX = {"mesh": ".msh", "vtu": ".vtu", "json": ".json", "png": ".png", "write_default": ".toml"}


def _parser() -> CliParser:
    p = CliParser(prog="python -m geometry", description=(
        "Build the Gmsh/OpenCASCADE geometry of a design (default: the RPUD composition), mesh it "
        "conformally with named regions and surfaces, and write mesh, report and picture. Units: SI "
        "(metres) in files and options; mm in the picture and the printed table."))
    from .options import add_design_options

    add_design_options(p, include=("design", "select", "materials"))
    p.add_argument("--write-default", metavar="FILE", help="write the default RPUD design as TOML and exit "
                   "(takes no design, output or meshing option)")
    p.add_argument("--export-step", metavar="DIR", help="write the design's solids as DIR/design.step (mm, solids "
                   "labelled by region) and DIR/design.toml, a kind = \"cad\" design with the rules that name its "
                   "regions, surfaces, electrodes, size caps and tuned lengths; then exit unless a mesh output is "
                   "given (the meshing options need one)")
    p.add_argument("--mesh", metavar="OUT.msh", help="write the tagged mesh (Gmsh 2.2 format, physical names)")
    p.add_argument("--vtu", metavar="OUT.vtu", help="write the mesh for ParaView (region/material/poling data)")
    p.add_argument("--json", metavar="OUT.json", help="write the report: parts (mesh volume, mass), groups, "
                   "counts, quality, timings")
    p.add_argument("--png", metavar="OUT.png", help="render the parts off screen (pyvista)")
    add_design_options(p, include=("mesh_size", "refine", "grade", "mesher"))
    p.add_argument("--epw", type=float, metavar="N", help="elements per shear wavelength at the target frequency")
    p.add_argument("--order", type=int, choices=(1, 2), default=2, help="tetrahedron order (default 2, curved)")
    p.add_argument("--algorithm", choices=("delaunay", "frontal", "hxt"), default="delaunay",
                   help="Gmsh 3-D algorithm (default delaunay)")
    p.add_argument("--allow-large", action="store_true", help="mesh even above the resource budget "
                   "(geometry.guard.MAX_ELEMENTS estimated tetrahedra)")
    p.add_argument("--gmsh-timeout", type=float, metavar="S", help="wall-clock limit of Gmsh, s (default "
                   "geometry.builder.GMSH_TIME_LIMIT = 600, or RPUD_GMSH_TIMEOUT)")
    p.add_argument("-v", "--verbose", action="count", default=0, help="log progress on stderr (-vv: debug "
                   "and Gmsh's own output too)")
    p.add_argument("-q", "--quiet", action="store_true", help="warnings only (the default; kept for scripts)")
    return p


def main(argv: list[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    # warnings only by default, as every rpud CLI: stderr carries the one line of a failed run
    setup_logging(-1 if args.quiet else args.verbose - 1)
    from .design_rpud import default_design
    from .options import design_from_options, design_inputs, mesh_options

    for key, suffix in _SUFFIX.items():
        value = getattr(args, key)
        if value is not None and Path(value).suffix.lower() != suffix:
            raise ParameterError(f"--{key.replace('_', '-')}", value, f"must end in {suffix}")
    check_options(args)
    check_combinations(args, parser)
    check_output_paths(inputs=design_inputs(args), folders=("export_step",), mesh=args.mesh, vtu=args.vtu,
                       json=args.json, png=args.png, write_default=args.write_default, export_step=args.export_step)
    if args.export_step and Path(args.export_step).is_dir():
        from .cad_export import STEP_NAME, TOML_NAME

        folder = Path(args.export_step)
        check_output_paths(inputs=design_inputs(args), **{"--export-step": folder / STEP_NAME},
                           **{"--export-step ": folder / TOML_NAME})
    if args.write_default:
        default_design().save(args.write_default)
        log.info("wrote %s", args.write_default)
        return 0
    design = design_from_options(args)
    meshing = _meshes(args)
    if meshing:
        # every refusal before the first file: the export below is written for good
        from .guard import check_budget
        from .revolve import resolve_mesher

        opts = mesh_options(args, design)
        resolve_mesher(design, opts.get("mesher", "free"))
        check_budget(design, args.mesh_size, args.order, args.epw, solve=False, allow_large=args.allow_large,
                     **opts)
    if args.export_step:
        from .cad_export import export_cad

        step, toml = export_cad(design, args.export_step)
        sys.stdout.write(f"wrote {step} and {toml}\n")
        if not meshing:
            return 0

    from .report import build_report

    tm, report = build_report(design, mesh_size=args.mesh_size, order=args.order,
                              elements_per_wavelength=args.epw, algorithm=args.algorithm,
                              verbose=args.verbose >= 2, time_limit=args.gmsh_timeout, **opts)
    sys.stdout.write(format_table(report) + "\n")
    if args.mesh:
        tm.write(args.mesh)
    if args.vtu:
        tm.write(args.vtu)
    if args.png:
        from .render import design_title, render_png

        render_png(tm, args.png, title=design_title(design))
    if args.json:
        write_json(args.json, report)
    return 0


def check_options(args) -> None:
    """Numeric options: finite and inside their stated ranges (before anything is built)."""
    from .options import check_design_options

    check_design_options(args)  # --mesh-size, --refine, --select
    if args.epw is not None:
        check_range("--epw", args.epw, 1.0, 200.0)
    if args.gmsh_timeout is not None:
        check_range("--gmsh-timeout", args.gmsh_timeout, 0.1, 86400.0, "s")  # builder.GMSH_TIME_RANGE


_MESH_OPTIONS = ("mesh_size", "refine", "grade", "mesher", "epw", "order", "algorithm", "allow_large", "gmsh_timeout")
"""Options that only act on meshing: without a mesh to build they would be ignored silently."""

_MESH_OUTPUTS = ("mesh", "vtu", "json", "png")


def _meshes(args) -> bool:
    """True when the run meshes: always, unless it only exports STEP (or writes the default)."""
    if args.write_default:
        return False
    return not args.export_step or any(getattr(args, k) is not None for k in _MESH_OUTPUTS)


def _given(args, parser, dest: str) -> bool:
    return getattr(args, dest) != parser.get_default(dest)


def check_combinations(args, parser) -> None:
    """Options that do not apply to the run are refused, not ignored: ``--write-default``
    writes a file and exits, so it takes no other option; ``--export-step`` alone meshes nothing,
    so the meshing options need a mesh output beside it."""
    def flag(dest):
        return "--" + dest.replace("_", "-")

    if args.write_default:
        others = ("design", "select", "materials", "export_step") + _MESH_OUTPUTS + _MESH_OPTIONS
        for dest in others:
            if _given(args, parser, dest):
                raise ParameterError(flag(dest), getattr(args, dest), "does not apply with --write-default "
                                     "(it writes the default design and exits): give one or the other")
    if not _meshes(args):
        for dest in _MESH_OPTIONS:
            if _given(args, parser, dest):
                raise ParameterError(flag(dest), getattr(args, dest), "acts on meshing only: with --export-step "
                                     "give a mesh output too (--mesh, --vtu, --json or --png), or leave it out")


def format_table(report: dict) -> str:
    """A plain-text summary of a build report (mm, g)."""
    lines = [f"{report['design']['name']} ({report['design']['kind']}): {report['mesh']['n_elements']} order-"
             f"{report['mesh']['order']} tetrahedra ({report['mesh'].get('mesher', 'free')} mesher), "
             f"{report['mesh']['n_nodes']} nodes, "
             f"meshed in {report['timings_s']['total']:.2f} s; min SICN {report['quality']['min_sicn']:.3f}"]
    lines.append(f"{'part':<12} {'z0 mm':>8} {'z1 mm':>8} {'volume cm3':>11} {'closed form':>11} {'error %':>8} {'mass g':>8}")
    for name, p in report["parts"].items():
        lines.append(f"{name:<12} {p['z0_m'] * 1e3:8.2f} {p['z1_m'] * 1e3:8.2f} {p['volume_m3'] * 1e6:11.4f} "
                     f"{p['volume_closed_form_m3'] * 1e6:11.4f} {p['volume_error'] * 100:8.4f} {p['mass_kg'] * 1e3:8.2f}")
    lines.append(f"{'total':<12} {'':>8} {'':>8} {'':>11} {'':>11} {'':>8} {report['total_mass_kg'] * 1e3:8.2f}")
    q = report["quality"]
    if q.get("layer_elements"):
        lines.append(f"thin layers meshed as structured extrusions: {q['layer_elements']} of the tetrahedra, "
                     f"min SICN {q['layer_min_sicn']:.3f} (flat by design; the min SICN above is of the rest)")
    lines += _onedim_lines(report.get("onedim"))
    return "\n".join(lines)


def _onedim_lines(od: dict | None) -> list[str]:
    """The 1-D reference: its number with what it is and its estimated error, or why it is left out."""
    if not od:
        return []
    if not od["valid"]:
        return [f"1-D reference left out ({od['meaning']}), it does not apply here: " + "; ".join(od["reasons"])]
    notes = [f"estimated 3-D corrections: lateral inertia {100 * od['rayleigh_love_rel']:+.1f} %, "
             f"electrode stiffening {100 * od['electrode_stiffening_rel']:+.1f} %"] + od["caveats"]
    return [f"1-D first longitudinal mode: {od['f1_hz']:.0f} Hz ({od['meaning']}; " + "; ".join(notes) + ")"]
