"""``python -m results``: the end-to-end run from a design file to drill-tool kinetic energy."""

from __future__ import annotations

import sys
from pathlib import Path

from geometry.common import CliParser, ParameterError, run_cli, setup_logging


def build_parser() -> CliParser:
    p = CliParser(prog="python -m results",
                  description="End-to-end RPUD run: mesh -> resonance matching -> harmonic response at the "
                              "drive voltage -> horn-tip amplitude A0 (coupled with the free-mass impacts) -> "
                              "drill-tool kinetic energy vs free-mass weight. Writes summary.json, report.md, "
                              "figures/, renders/ and modes.vtu into the output folder.")
    p.add_argument("--design", metavar="FILE", help="design TOML (default: the built-in RPUD design)")
    p.add_argument("--voltage", type=float, default=225.0, metavar="V",
                   help="drive voltage amplitude on the hot electrodes, V (default 225, the article's)")
    p.add_argument("--out", metavar="DIR",
                   help="output folder (default results/default for the built-in design, else results/<name>)")
    p.add_argument("--mesh-size", type=float, metavar="M", help="mesh size, m (default: elements-per-wavelength rule)")
    p.add_argument("--q-mech", type=float, default=100.0, metavar="Q",
                   help="mechanical quality factor of the assembled transducer (default 100); 0 = datasheet values")
    p.add_argument("--no-match", action="store_true", help="analyse the design as it is, without resonance matching")
    p.add_argument("--no-couple", action="store_true", help="do not load the horn tip with the impacts (A0 unloaded)")
    p.add_argument("--impact-time", type=float, default=1.0, metavar="S",
                   help="simulated time per impact run, s (default 1)")
    p.add_argument("--ensemble", type=int, default=8, metavar="N", help="impact runs per free mass (default 8)")
    p.add_argument("--no-render", action="store_true", help="skip the mode-shape PNGs and the VTU")
    p.add_argument("-q", "--quiet", action="store_true", help="no stage progress")
    return p


def main(argv=None) -> int:
    import geometry

    from .pipeline import PipelineSettings, run_pipeline

    args = build_parser().parse_args(argv)
    setup_logging(-1)
    if args.q_mech is not None and args.q_mech < 0:
        raise ParameterError("--q-mech", args.q_mech, "must be > 0 (0 = datasheet values)")
    settings = PipelineSettings(voltage=args.voltage, q_mech=None if args.q_mech == 0 else args.q_mech,
                                mesh_size=args.mesh_size, match=not args.no_match,
                                couple_impacts=not args.no_couple, impact_t_end=args.impact_time,
                                ensemble=args.ensemble, render=not args.no_render)
    design = geometry.load_design(args.design) if args.design else geometry.default_design()
    out = Path(args.out) if args.out else Path("results") / ("default" if not args.design else design.name)
    # progress on stdout: stderr carries only the one-line error of a failed run (and tqdm bars)
    say = (lambda msg: None) if args.quiet else (lambda msg: print(msg, flush=True))
    run_pipeline(design, settings, out, progress=say)
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main, prog="results"))
