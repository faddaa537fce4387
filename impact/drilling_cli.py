"""``python -m impact --load rock --wob 7 ...``: drilling under load against free mass.

Prints per free mass: blow rate, penetration per blow, drilling rate (mm/min), depth after the
drilling time, energy transfer efficiency (95 % CIs over seeded members), and the no-load tool
KE (device scenario) beside it, with the model's assumptions and calibration status. ``--horn
fem`` drills on the compliant model (the default design's FE horn, Hertz contacts, a rigid tool;
built by :func:`results.drilling.fe_drill_horn`) with the kinematic model as its comparison.
SI options; bad input is one line on stderr, exit 2, no file.
"""

from __future__ import annotations

import math
from pathlib import Path

from rpud_common import (CliParser, ParameterError, check_output_paths, check_range, save_figure,
                         setup_logging, write_json)
from rpud_common.cli import check_given, check_usual, echo_inputs, quantity

from .options import REL_TOL_RANGE, add_output_flags, masses_text, real_number, set_threads, warn_first
from .drilling import DrillParams, DrillSettings, DrillSweep, drilling_sweep
from .params import ImpactParams
from .rock import RockLaw
from .rod import ToolRod


def _masses(text: str) -> list[float]:
    try:
        vals = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise ParameterError("m_free", text, "must be a comma-separated list of masses in kg") from None
    if not vals or len(vals) > 100 or not all(math.isfinite(v) and 0.0 <= v <= 1.0 for v in vals):
        raise ParameterError("m_free", text, "must list 1-100 masses in [0, 1] kg (0: no free mass)")
    return vals


def build_parser() -> CliParser:
    ap = CliParser(prog="python -m impact --load rock",
                   description="Drilling under load (article 5.2): the drill pressed on rock with a weight on bit; "
                               "the tool a rigid collar on an elastic rod, a bilinear bit-rock law with a crushing "
                               "threshold. Means with 95 %% CIs over seeded members; depth = rate x drilling time.")
    ap.add_argument("--load", choices=["rock"], required=True, help="load scenario (rock: bit on rock)")
    ap.add_argument("--horn", choices=["kinematic", "fem"], default="kinematic",
                    help="kinematic: the tip at A0, Newton impacts, elastic tool rod (default); fem: the default "
                         "design's FE horn with Hertz contacts and a rigid tool (~0.4 s CPU per member and mass, "
                         "plus ~30 s for the FE horn), the kinematic model beside it as the comparison")
    ap.add_argument("--members", type=int, default=16, metavar="N",
                    help="members per mass of the --horn fem model (a fixed count, default 16; its CIs as they come)")
    ap.add_argument("--wob", type=real_number, default=None, metavar="N",
                    help=f"weight on bit, N (default {WOB:g}, the article's)")
    ap.add_argument("--m-free", default="0,0.001,0.002,0.003,0.004,0.005,0.006,0.007,0.008", metavar="M1,M2,..",
                    help="free masses, kg; 0 = none (default 0-8 g in 1 g steps)")
    ap.add_argument("--a0", "--A0", dest="a0", type=real_number, default=15e-6, metavar="M",
                    help="horn-tip amplitude, m (default 15e-6, Table 1; the pipeline passes its loaded FE value)")
    ap.add_argument("--freq", type=real_number, default=19.95e3, metavar="HZ", help="drive frequency, Hz (default 19950)")
    ap.add_argument("--k-load", type=real_number, default=RockLaw().k_load, metavar="N/M", help="rock loading stiffness, N/m")
    ap.add_argument("--k-unload", type=real_number, default=RockLaw().k_unload, metavar="N/M", help="rock unloading stiffness, N/m")
    ap.add_argument("--f-threshold", type=real_number, default=RockLaw().f_threshold, metavar="N",
                    help="rock crushing threshold force, N")
    ap.add_argument("--rod-length", type=real_number, default=ToolRod().length, metavar="M", help="tool rod length, m")
    ap.add_argument("--rod-diameter", type=real_number, default=ToolRod().diameter, metavar="M", help="tool rod diameter, m")
    ap.add_argument("--cells", type=int, default=ToolRod().cells, metavar="N",
                    help="rod segments (time step = length / (cells c)); default 32")
    ap.add_argument("--drill-time", type=real_number, default=300.0, metavar="S", help="drilling time for the depth, s (300)")
    ap.add_argument("--t-from", type=real_number, default=0.02, metavar="S", help="start of the statistics window, s")
    ap.add_argument("--t-end", type=real_number, default=0.22, metavar="S", help="end of the statistics window, s")
    ap.add_argument("--rel-tol", type=real_number, default=0.05, metavar="R",
                    help="grow members until drilling and blow rates have 95%% CIs within R (default 0.05)")
    ap.add_argument("--max-members", type=int, default=512, metavar="N", help="member cap per mass (512)")
    ap.add_argument("--seed", type=int, default=20260, metavar="N", help="seed of the members (20260)")
    ap.add_argument("--threads", type=int, default=None, metavar="N", help="kernel threads (default: every core)")
    ap.add_argument("--no-load-ke", action="store_true", help="skip the no-load tool KE column")
    ap.add_argument("--json", metavar="PATH", help="write the table and parameters as JSON")
    ap.add_argument("--plots", metavar="DIR", help="write depth_vs_free_mass.png here")
    add_output_flags(ap)
    return ap


WOB = 7.0
"""Default weight on bit, N (the article's)."""


def params_from(ns) -> DrillParams:
    ip = ImpactParams(A0=ns.a0, freq=ns.freq, spring_force=5.0)
    return DrillParams(impact=ip, rod=ToolRod(diameter=ns.rod_diameter, length=ns.rod_length, cells=ns.cells),
                       rock=RockLaw(ns.k_load, ns.k_unload, ns.f_threshold), wob=WOB if ns.wob is None else ns.wob,
                       t_from=ns.t_from, t_end=ns.t_end, drill_time=ns.drill_time)


def print_table(rows, no_load=None) -> None:
    ke = {}
    if no_load is not None:
        ke = {round(r.params.m_free, 9): r.estimates["mean_tool_ke_after_j"].scaled(1e3) for r in no_load.rows}
    print(f"{'m_free g':>8} {'blows Hz':>12} {'pen/blow um':>14} {'rate mm/min':>14} {'depth mm':>14} "
          f"{'efficiency %':>14} {'peak F N':>10} {'contact %':>10} {'no-load KE mJ':>14} {'members':>8}")
    for r in rows:
        e = r.estimates
        k = ke.get(round(r.m_free, 9))
        print(f"{r.m_free * 1e3:8.3g} {format(e['blow_rate_hz']):>12} {format(e['penetration_per_blow_m'].scaled(1e6)):>14} "
              f"{format(e['drilling_rate_m_s'].scaled(6e4)):>14} {format(r.depth_m.scaled(1e3)):>14} "
              f"{format(e['efficiency'].scaled(100)):>14} {format(e['peak_force_per_blow_n']):>10} "
              f"{format(e['contact_fraction'].scaled(100)):>10} "
              f"{format(k) if k is not None else '-':>14} {r.members:8d}"
              + ("" if r.converged else "  (NOT converged)"))


def _inputs(p: DrillParams, masses, settings, ns) -> dict:
    """The run's inputs for the inputs line."""
    return {"load": "rock", "WOB": quantity(p.wob, "N"), "free masses": masses_text(masses),
            "A0": quantity(p.impact.A0, "m"), "f": quantity(p.impact.freq, "Hz"),
            "rock k_load": quantity(p.rock.k_load, "N/m"),
            "k_unload": quantity(p.rock.k_unload, "N/m"), "threshold": quantity(p.rock.f_threshold, "N"),
            "rod": f"{quantity(p.rod.length, 'm')} x {quantity(p.rod.diameter, 'm')} diameter, {p.rod.cells} cells",
            "window": f"{p.t_from * 1e3:g}-{p.t_end * 1e3:g} ms", "drilling time": f"{p.drill_time:g} s",
            "members": f"95 % CI within {settings.rel_tol:.3g}, at most {settings.n_max} per mass",
            "horn": "kinematic (A0 cos 2 pi f t)" if ns.horn == "kinematic" else
            f"FE (default design, Hertz contacts, rigid tool, {ns.members} members per mass) beside the kinematic",
            "seed": settings.seed}


def _warn_unusual(prog: str, p: DrillParams, masses) -> None:
    """One stderr line per value outside the drill's usual range (a likely unit slip)."""
    check_usual(prog, "--wob", p.wob, "wob")
    check_usual(prog, "--a0", p.impact.A0, "A0")
    check_usual(prog, "--freq", p.impact.freq, "freq")
    warn_first(prog, "--m-free", [m for m in masses if m > 0], "m_free")


def _fem_sweep(p: DrillParams, masses, ns, say) -> DrillSweep:
    """The compliant model on the default design's FE horn (a command sits on top of every
    package: the FE horn is built by results)."""
    import geometry
    from results.drilling import fe_drill_horn

    pos = [m for m in masses if m > 0]
    f, cut, ch = fe_drill_horn(geometry.default_design(), pos)
    if say is not None:
        say(f"FE horn: {ch.horn.n_modes} k = 0 modes to {cut / 1e3:.0f} kHz, drive {f:.1f} Hz")
    pf = p.with_(impact=p.impact.with_(freq=f))
    st = DrillSettings(n_start=ns.members, n_max=ns.members, seed=ns.seed)
    return DrillSweep(rows=drilling_sweep(pf, pos, st, progress=say, horn=ch), params=pf)


def main(argv) -> int:
    setup_logging(-1)
    ap = build_parser()
    ns = ap.parse_args(argv)
    check_given(ap, ns)
    masses = _masses(ns.m_free)
    check_range("--rel-tol", ns.rel_tol, *REL_TOL_RANGE)
    p = params_from(ns)
    for m in masses:
        if m > 0 and p.housing_mass(m) <= 0:      # drilling_sweep's own check, before the inputs line
            raise ParameterError("m_free", m, f"must leave a positive housing mass (m_drill {p.m_drill:g} kg)")
    settings = DrillSettings(rel_tol=ns.rel_tol, n_start=min(16, ns.max_members), n_max=ns.max_members, seed=ns.seed)
    if ns.horn == "fem":
        check_range("--members", ns.members, 2, 4096)
        if not any(m > 0 for m in masses):
            raise ParameterError("m_free", ns.m_free, "must list a positive mass with --horn fem")
    check_output_paths(folders=("plots",), json=ns.json, plots=ns.plots)
    set_threads(ns.threads)
    _warn_unusual(ap.prog, p, masses)
    echo_inputs(_inputs(p, masses, settings, ns), ns.quiet)
    say = None if ns.no_progress or ns.quiet else (lambda m: print(m, flush=True))
    fem = _fem_sweep(p, masses, ns, say) if ns.horn == "fem" else None
    rows = drilling_sweep(p, masses, settings, progress=say)
    no_load = None
    pos = [m for m in masses if m > 0]
    if not ns.no_load_ke and pos:
        from .stats import StatsSettings
        from .sweeps import sweep

        no_load = sweep(p.impact, pos, scenario="device", settings=StatsSettings(seed=ns.seed))
    from .drilling import status_line

    res = DrillSweep(rows=rows, no_load=no_load, params=p)
    if fem is not None:
        print(f"compliant model (FE horn, f {fem.params.impact.freq:g} Hz, free tip {fem.rows[0].A0 * 1e6:.3g} um), "
              f"WOB {p.wob:g} N; window {p.t_from * 1e3:g}-{p.t_end * 1e3:g} ms, depth = rate x {p.drill_time:g} s; "
              "means ± 95 % CI")
        print_table(fem.rows)
        print(status_line("compliant"))
        print("comparison: ", end="")
        res = DrillSweep(rows=fem.rows, no_load=no_load, params=fem.params, comparison=res)
    print(f"kinematic model: WOB {p.wob:g} N, A0 {p.impact.A0 * 1e6:.3g} um, {p.impact.freq:g} Hz; window "
          f"{p.t_from * 1e3:g}-{p.t_end * 1e3:g} ms, depth = rate x {p.drill_time:g} s; means ± 95 % CI")
    print_table(rows, no_load)
    print(status_line("kinematic"))
    if ns.json:
        write_json(ns.json, res.to_dict())
    if ns.plots:
        from .drilling_plots import plot_depth_vs_mass

        save_figure(plot_depth_vs_mass(res), Path(ns.plots) / "depth_vs_free_mass.png")
    return 0
