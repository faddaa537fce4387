"""``python -m impact``: one simulation; ``python -m impact sweep``; ``python -m impact article``.

All options in SI units. Bad input: one line on stderr, exit code 2, no output file.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path

from geometry.common import CliParser, ParameterError, atomic_write_text, from_mapping, setup_logging, write_json

from .params import ImpactParams

_D = ImpactParams()
# (option, field, help) -- defaults shown from the dataclass
_OPTS = [
    ("--m-free", "m_free", "free mass, kg"),
    ("--A0", "A0", "horn-tip vibration amplitude, m"),
    ("--freq", "freq", "horn vibration frequency, Hz"),
    ("--e1", "e1", "restitution free mass/tool, [0, 1]"),
    ("--e2", "e2", "restitution free mass/horn, [0, 1]"),
    ("--m-horn", "m_horn", "horn mass (used by --horn-law article), kg"),
    ("--m-tool", "m_tool", "drill-tool mass, kg"),
    ("--k0", "k0", "drill-tool axial stiffness, N/m (calibrated)"),
    ("--c", "c", "drill-tool viscous damping, N s/m (calibrated)"),
    ("--gap", "gap", "free stroke L0 horn tip to tool face at rest, m (calibrated)"),
    ("--g", "g", "gravity along horn->tool, m/s^2 (0 in space, <0 drill pointing up)"),
    ("--v0", "v0", "free-mass speed leaving the horn at t = 0 (tool at rest), m/s"),
    ("--t-end", "t_end", "simulated time, s"),
    ("--spring-force", "spring_force", "restoring-spring force on the free mass toward the horn, N (0 = off; device ~5)"),
]


def _add_params(ap, skip=()):
    for opt, name, text in _OPTS:
        if name in skip:
            continue
        ap.add_argument(opt, dest=name, type=float, default=None, metavar="X",
                        help=f"{text} (default {getattr(_D, name):g})")
    ap.add_argument("--horn-law", dest="horn_law", choices=["kinematic", "article"], default=None,
                    help="horn impact law: kinematic = infinite-mass driver (default), article = eq. 21 as printed")
    ap.add_argument("--config", metavar="TOML", help="TOML file of parameters (top level or [impact] table); options override it")


def _params(ns) -> ImpactParams:
    data = ImpactParams().to_dict()
    if ns.config:
        cfg = ImpactParams.from_toml(ns.config)   # validates the file on its own
        data.update(cfg.to_dict())
    for f in dataclasses.fields(ImpactParams):
        val = getattr(ns, f.name, None)
        if val is not None:
            data[f.name] = val
    return from_mapping(ImpactParams, data)


def _check_out(path):
    if path is not None and Path(path).is_dir():
        raise ParameterError("json", str(path), "is a directory; give a file path")


def _run(argv):
    ap = CliParser(prog="python -m impact", description="Event-driven impact model of the RPUD percussive "
                   "system (horn -> free mass -> drill tool). Subcommands: 'sweep', 'article' (see their --help).")
    _add_params(ap)
    ap.add_argument("--json", metavar="PATH", help="write params, counts, rates, mean tool KE and all events as JSON")
    ap.add_argument("--plots", metavar="DIR", help="write displacement history and spectrum PNGs here")
    ns = ap.parse_args(argv)
    p = _params(ns)
    _check_out(ns.json)
    from .model import simulate

    r = simulate(p, series=bool(ns.plots))
    s = r.summary()
    print(f"simulated {p.t_end * 1e3:g} ms, m_free {p.m_free * 1e3:g} g, A0 {p.A0 * 1e6:g} µm, f {p.freq / 1e3:g} kHz")
    print(f"  tool impacts      {s['tool_impacts']:8d}   rate {s['tool_impact_rate_hz']:9.1f} Hz")
    print(f"  horn impacts      {s['horn_impacts']:8d}   rate {s['horn_impact_rate_hz']:9.1f} Hz")
    print(f"  mean tool KE after impact  {s['mean_tool_ke_after_impact_j'] * 1e3:.4g} mJ")
    if ns.json:
        write_json(ns.json, r.to_json_dict())
    if ns.plots:
        from .plots import plot_history, plot_spectrum

        d = Path(ns.plots)
        plot_history(r, d / "displacement.png")
        plot_history(r, d / "displacement_20ms.png", min(0.02, p.t_end))
        plot_spectrum(r, d / "free_mass_spectrum.png")
    return 0


def _floats(text: str, name: str) -> list[float]:
    try:
        vals = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise ParameterError(name, text, "must be a comma-separated list of numbers (kg)") from None
    if not vals or not all(math.isfinite(v) and v > 0 for v in vals):
        raise ParameterError(name, text, "must list masses > 0 kg")
    return vals


def _sweep(argv):
    ap = CliParser(prog="python -m impact sweep", description="Mean drill-tool kinetic energy after impact "
                   "against free mass, in parallel, with the linear fit (slope J/kg, R^2).")
    ap.add_argument("--m-free", dest="m_list", required=True, metavar="M1,M2,...", help="free masses, kg (e.g. 0.002,0.004,0.006,0.008)")
    _add_params(ap, skip=("m_free", "t_end"))
    ap.add_argument("--t-end", dest="t_end", type=float, default=1.0, metavar="X",
                    help="simulated time per member, s (default 1: the trend needs long runs)")
    ap.add_argument("--ensemble", type=int, default=4, help="members per mass, launch speed spread +-5%% (default 4)")
    ap.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    ap.add_argument("--csv", metavar="PATH", help="write the table as CSV")
    ap.add_argument("--json", metavar="PATH", help="write table, fit and params as JSON")
    ap.add_argument("--plots", metavar="DIR", help="write the KE-vs-mass PNG here")
    ap.add_argument("--no-progress", action="store_true", help="no progress bar")
    ns = ap.parse_args(argv)
    masses = _floats(ns.m_list, "m_free")
    p = _params(ns)
    _check_out(ns.json)
    from .sweep import sweep

    sw = sweep(p, masses, ensemble=ns.ensemble, t_end=p.t_end, workers=ns.workers, progress=not ns.no_progress)
    print(f"{'m_free (g)':>10} {'mean tool KE (mJ)':>18} {'sem (mJ)':>9} {'rate (Hz)':>10} {'ok':>4}")
    for row in sw.table():
        print(f"{row['m_free_kg'] * 1e3:10.3g} {row['mean_tool_ke_j'] * 1e3:18.4g} "
              f"{row['sem_tool_ke_j'] * 1e3:9.3g} {row['tool_impact_rate_hz']:10.1f} {row['members_ok']:4d}")
    print(f"linear fit: slope {sw.slope:.4g} J/kg ({sw.slope:.4g} mJ/g), intercept {sw.intercept * 1e3:.4g} mJ, R^2 {sw.r2:.4f}")
    if ns.csv:
        atomic_write_text(ns.csv, sw.csv())
    if ns.json:
        write_json(ns.json, sw.to_json_dict())
    if ns.plots:
        from .plots import plot_ke_vs_mass

        plot_ke_vs_mass(sw, Path(ns.plots) / "tool_ke_vs_free_mass.png")
    return 0


def _article(argv):
    ap = CliParser(prog="python -m impact article", description="Reproduce the article's Fig. 6, 7, 8 and the "
                   "free-mass spectrum, plus impact_summary.json.")
    ap.add_argument("--out", required=True, metavar="DIR", help="output folder")
    ap.add_argument("--config", metavar="TOML", help="TOML file of parameters")
    ap.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    ns = ap.parse_args(argv)
    p = ImpactParams.from_toml(ns.config) if ns.config else ImpactParams()
    from .article import reproduce

    s = reproduce(ns.out, p, workers=ns.workers)
    print(f"wrote {', '.join(s['figures'])} and impact_summary.json to {ns.out}")
    print(f"50 ms: {s['run_50ms']['tool_impacts']} tool impacts ({s['run_50ms']['tool_impact_rate_hz']:.0f} Hz); "
          f"Fig. 8 fit slope {s['fig8']['fit']['slope_j_per_kg']:.4g} J/kg, R^2 {s['fig8']['fit']['r2']:.3f}")
    return 0


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    setup_logging(-1)
    if argv and argv[0] == "sweep":
        return _sweep(argv[1:])
    if argv and argv[0] == "article":
        return _article(argv[1:])
    return _run(argv)
