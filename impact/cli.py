"""``python -m impact``: converged statistics of one case; ``sweep``: against free mass;
``article``: the article's figures.

All options in SI units. Bad input: one line on stderr, exit code 2, no output file.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from pathlib import Path

from rpud_common import (
    CliParser, ParameterError, atomic_folder, atomic_write_text, check_integer, check_output_paths, check_range,
    from_mapping, load_toml, save_figure, setup_logging, toml_section, write_json,
)
from rpud_common.cli import check_given, check_usual, echo_inputs, needs, quantity

from .params import ImpactParams

_D = ImpactParams()
_TINY = sys.float_info.min


def _real(text: str) -> float:
    """argparse type: a finite, normal number (NaN, inf and subnormals like 1e-320 are typos)."""
    try:
        x = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(x):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    if x != 0.0 and abs(x) < _TINY:
        raise argparse.ArgumentTypeError(f"{text!r} is below {_TINY:.3g} in magnitude: give 0 or a normal number")
    return x


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
    ("--v0", "v0", "free-mass speed leaving the horn at t = 0 (tool at rest), m/s; members spread it"),
]


def _add_params(ap, skip=()):
    g = ap.add_argument_group("model (SI units; defaults: Table 1 and the calibrated values)")
    for opt, name, text in _OPTS:
        if name in skip:
            continue
        g.add_argument(opt, dest=name, type=_real, default=None, metavar="X",
                       help=f"{text} (default {getattr(_D, name):g})")
    g.add_argument("--horn-law", dest="horn_law", choices=["kinematic", "article"], default=None,
                   help="horn impact law: kinematic = infinite-mass driver (default), article = eq. 21 as printed")
    g.add_argument("--config", metavar="TOML",
                   help="TOML file of model parameters (top-level keys or one [impact] table); options override it")
    s = ap.add_argument_group("scenario and statistics")
    s.add_argument("--scenario", choices=["article", "device"], default="article",
                   help="article: no restoring spring, first 50 ms (the article's Figs. 6-8; default); "
                        "device: 5 N restoring spring, steady operation (20 ms discarded, 200 ms window)")
    s.add_argument("--spring-force", dest="spring_force", type=_real, default=None, metavar="N",
                   help="restoring-spring force on the free mass toward the horn, N (default: the scenario's, 0 or 5)")
    s.add_argument("--t-from", dest="t_from", type=_real, default=None, metavar="S",
                   help="start of the statistics window, s: the transient before it is discarded (default: the scenario's)")
    s.add_argument("--t-end", dest="t_end", type=_real, default=None, metavar="S",
                   help="end of the statistics window = simulated time per member, s (default: the scenario's)")
    s.add_argument("--rel-tol", type=_real, default=None, metavar="R",
                   help=f"add members until every 95%% CI half-width is within R of its mean, in "
                        f"[{REL_TOL_RANGE[0]:g}, {REL_TOL_RANGE[1]:g}] (default {REL_TOL})")
    s.add_argument("--members", type=int, default=None, metavar="N",
                   help="run exactly N members instead of the adaptive rule (then no --rel-tol or --max-members)")
    s.add_argument("--max-members", type=int, default=None, metavar="N",
                   help=f"cap of the adaptive rule (default {MAX_MEMBERS_DEFAULT})")
    s.add_argument("--seed", type=int, default=20260, metavar="N", help="seed of the member launch speeds (default 20260)")
    s.add_argument("--threads", type=int, default=None, metavar="N", help="kernel threads (default: every core)")
    _add_output_flags(s)


def _add_output_flags(group) -> None:
    group.add_argument("--no-progress", action="store_true", help="no progress lines")
    group.add_argument("-q", "--quiet", action="store_true",
                       help="no inputs line and no progress lines (results and warnings still print)")


REL_TOL = 0.03
"""Default relative 95 % CI half-width of the adaptive rule."""

REL_TOL_RANGE = (1e-4, 1.0)
"""Accepted ``--rel-tol``: below 1e-4 no ensemble within the member cap gets there."""

MAX_MEMBERS_DEFAULT = 4096
"""Default cap of the adaptive rule's members."""

T_END_MIN = 1e-4
"""Shortest simulated time per member, s (two periods at 20 kHz: anything shorter is a typo)."""


def _load_config(path) -> dict:
    return dict(toml_section(load_toml(path), "impact", str(path)))


def _params(ns) -> ImpactParams:
    data = ImpactParams().to_dict()
    if getattr(ns, "config", None) is not None:
        cfg = from_mapping(ImpactParams, _load_config(ns.config))   # validates the file on its own
        data.update(cfg.to_dict())
    for f in dataclasses.fields(ImpactParams):
        if f.name in ("t_end", "spring_force"):
            continue                  # set by the scenario (or its overrides)
        val = getattr(ns, f.name, None)
        if val is not None:
            data[f.name] = val
    return from_mapping(ImpactParams, data)


def _scenario(ns, params: ImpactParams):
    from .stats import SCENARIOS, Scenario

    sc = SCENARIOS[ns.scenario]
    if ns.spring_force is None and ns.t_from is None and ns.t_end is None:
        return sc
    t_end = sc.t_end if ns.t_end is None else ns.t_end
    t_from = sc.t_from if ns.t_from is None else ns.t_from
    for name, val in (("t_end", t_end), ("t_from", t_from)):
        if not math.isfinite(val):
            raise ParameterError(name, val, "must be a finite time in s")
    if 0 < t_end < T_END_MIN:
        raise ParameterError("t_end", t_end, f"must be >= {T_END_MIN:g} s (two drive periods at 20 kHz)")
    if not t_from < t_end:
        raise ParameterError("t_from", t_from, f"must be < t_end = {t_end:g} s")
    spring = sc.spring_force if ns.spring_force is None else ns.spring_force
    # validate through the parameters too (bounds on t_end and spring_force live there)
    params.with_(t_end=t_end, spring_force=spring)
    return Scenario(sc.name if (t_from, t_end, spring) == (sc.t_from, sc.t_end, sc.spring_force) else f"{sc.name} (modified)",
                    spring, t_from, t_end, sc.description + f"; window {t_from:g}-{t_end:g} s, spring {spring:g} N")


def _settings(ns):
    """The ensemble settings; ``--members`` (a fixed count) excludes the adaptive rule's options."""
    from .stats import MAX_MEMBERS, StatsSettings

    if ns.rel_tol is not None:
        check_range("--rel-tol", ns.rel_tol, *REL_TOL_RANGE)
    rel_tol = REL_TOL if ns.rel_tol is None else ns.rel_tol
    if ns.members is not None:
        check_integer("members", ns.members, 1, MAX_MEMBERS)
        needs("--rel-tol", ns.rel_tol, "the adaptive rule", "--members N runs exactly N members")
        needs("--max-members", ns.max_members, "the adaptive rule", "--members N runs exactly N members")
        return StatsSettings(rel_tol=rel_tol, n_start=ns.members, n_max=ns.members, seed=ns.seed)
    n_max = MAX_MEMBERS_DEFAULT if ns.max_members is None else ns.max_members
    check_integer("max_members", n_max, 1, MAX_MEMBERS)
    return StatsSettings(rel_tol=rel_tol, n_start=min(64, n_max), n_max=n_max, seed=ns.seed)


def _check_horn_mass(ns, p: ImpactParams) -> None:
    """``--m-horn`` enters the article's horn law only: refused under the kinematic law."""
    if getattr(ns, "m_horn", None) is not None and p.horn_law != "article":
        raise ParameterError("--m-horn", ns.m_horn, "applies only with --horn-law article (the kinematic horn "
                                                    "is an infinite-mass driver)")


def _quiet(ns) -> bool:
    return bool(getattr(ns, "quiet", False))


def _warn_unusual(prog: str, ns, p: ImpactParams, skip=()) -> None:
    """One stderr line per model value outside the drill's usual range (a likely unit slip; the
    gap is not among them: its slip, mm typed for m, is out of its physical range and refused)."""
    for opt, name, key in (("--m-free", "m_free", "m_free"), ("--A0", "A0", "A0"), ("--freq", "freq", "freq"),
                           ("--m-tool", "m_tool", "m_tool")):
        if name not in skip:
            check_usual(prog, opt if getattr(ns, name, None) is not None else f"{name} (--config)",
                        getattr(p, name), key)


def param_items(p: ImpactParams, skip=()) -> dict:
    """The model's inputs for the inputs line (label -> value with its unit)."""
    items = {"free mass": quantity(p.m_free, "kg"), "A0": quantity(p.A0, "m"), "f": quantity(p.freq, "Hz"),
             "e1": f"{p.e1:g}", "e2": f"{p.e2:g}", "tool mass": quantity(p.m_tool, "kg"),
             "k0": quantity(p.k0, "N/m"), "c": f"{p.c:.4g} N s/m", "gap": quantity(p.gap, "m"),
             "g": f"{p.g:.4g} m/s^2", "v0": f"{p.v0:.4g} m/s", "horn law": p.horn_law}
    if p.horn_law == "article":
        items["horn mass"] = quantity(p.m_horn, "kg")
    return {k: v for k, v in items.items() if k not in skip}


def scenario_items(sc, settings) -> dict:
    """The scenario and ensemble rule for the inputs line."""
    members = (f"{settings.n_max}" if settings.n_start == settings.n_max else
               f"adaptive (95 % CI within {settings.rel_tol:.3g} of the mean, at most {settings.n_max})")
    return {"scenario": f"{sc.name} (window {sc.t_from * 1e3:g}-{sc.t_end * 1e3:g} ms, spring {sc.spring_force:g} N)",
            "members": members, "seed": settings.seed}


def masses_text(masses) -> str:
    """Free masses for the inputs line (the first 12)."""
    return ", ".join(quantity(m, "kg") for m in masses[:12]) + (", ..." if len(masses) > 12 else "")


def warn_first(prog: str, option: str, values, key: str) -> None:
    """The slip warning of the first unusual value of a list (one line, not one per value)."""
    for value in values:
        if check_usual(prog, option, value, key):
            return


def _threads(n):
    if n is None:
        return
    import numba

    top = numba.config.NUMBA_NUM_THREADS
    if not 1 <= n <= top:
        raise ParameterError("threads", n, f"must be an integer in [1, {top}] (cores here)")
    numba.set_num_threads(n)


def _progress(ns):
    if ns.no_progress or _quiet(ns):
        return None
    # stdout: stderr carries nothing but the one-line error of a failed run
    return lambda msg: print(msg, flush=True)


def _print_stats(st) -> None:
    from .stats import QUANTITIES

    unit_scale = {"J": (1e3, "mJ"), "W": (1.0, "W"), "Hz": (1.0, "Hz"), "-": (100.0, "%")}
    print(f"{st.scenario.name}: window {st.scenario.t_from * 1e3:g}-{st.scenario.t_end * 1e3:g} ms, "
          f"{st.members} members, {'converged' if st.converged else 'NOT converged'} "
          f"(95 % CI within {st.settings.rel_tol:.0%})" + (f"; {st.note}" if st.note else ""))
    for name, unit, text in QUANTITIES:
        scale, u = unit_scale[unit]
        e = st.estimates[name].scaled(scale)
        print(f"  {text:<66} {e} {u}")


def _run(argv):
    ap = CliParser(prog="python -m impact", description="Impact model of the RPUD percussive system (horn -> free "
                   "mass -> drill tool), reported as ensemble means with 95 % confidence intervals. "
                   "Subcommands: 'sweep', 'article' (see their --help).")
    _add_params(ap)
    ap.add_argument("--horn", choices=["kinematic", "fem"], default="kinematic",
                    help="kinematic: the tip moves as A0 cos(2 pi f t) whatever the impacts (default); fem: the "
                         "design's FE transducer in the loop (see python -m impact --horn fem --help)")
    ap.add_argument("--json", metavar="PATH", help="write params, statistics and one sample trajectory's events as JSON")
    ap.add_argument("--plots", metavar="DIR", help="write one sample trajectory's displacement history and spectrum PNGs here")
    ns = ap.parse_args(argv)
    check_given(ap, ns)
    p = _params(ns)
    _check_horn_mass(ns, p)
    sc = _scenario(ns, p)
    settings = _settings(ns)
    check_output_paths(inputs={"--config": ns.config}, folders=("plots",), json=ns.json, plots=ns.plots)
    _threads(ns.threads)
    _warn_unusual(ap.prog, ns, p)
    echo_inputs({**param_items(p), **scenario_items(sc, settings)}, _quiet(ns))
    from .model import SimulationError, simulate
    from .stats import ensemble_statistics

    st = ensemble_statistics(p, sc, settings, progress=_progress(ns))
    if st.failed:
        raise ParameterError("gap", p.gap, st.note)
    _print_stats(st)
    doc = {"params": st.params.to_dict(), **st.to_dict()}
    sample = None
    if ns.json or ns.plots:
        try:
            sample = simulate(st.params, series=bool(ns.plots))
            doc["sample_trajectory"] = {"note": "member with the base launch speed: one sample of a chaotic motion",
                                        **sample.summary(), "events": sample.events()}
        except SimulationError as exc:
            doc["sample_trajectory"] = {"error": str(exc)}
    if ns.json:
        write_json(ns.json, doc)
    if ns.plots and sample is not None:
        from .plots import plot_history, plot_spectrum

        d = Path(ns.plots)
        save_figure(plot_history(sample, title="one sample trajectory (chaotic: see the statistics)"),
                    d / "displacement.png")
        save_figure(plot_history(sample, min(0.02, sample.params.t_end)), d / "displacement_20ms.png")
        save_figure(plot_spectrum(sample), d / "free_mass_spectrum.png")
    return 0


def _floats(text: str, name: str) -> list[float]:
    try:
        vals = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise ParameterError(name, text, "must be a comma-separated list of numbers (kg)") from None
    if not vals or not all(math.isfinite(v) and v > 0 for v in vals):
        raise ParameterError(name, text, "must list masses > 0 kg")
    if len(vals) > 1000:
        raise ParameterError(name, f"{len(vals)} values", "must list at most 1000 masses")
    return vals


def _sweep(argv):
    ap = CliParser(prog="python -m impact sweep", description="Drill-tool kinetic energy and impact rates against "
                   "free mass: converged ensemble means with 95 % confidence intervals, and the line of mean tool "
                   "KE against mass (slope J/kg).")
    ap.add_argument("--m-free", dest="m_list", required=True, metavar="M1,M2,...", help="free masses, kg (e.g. 0.002,0.004,0.006,0.008)")
    _add_params(ap, skip=("m_free",))
    ap.add_argument("--csv", metavar="PATH", help="write the table (means and CI half-widths) as CSV")
    ap.add_argument("--json", metavar="PATH", help="write table, fit, scenario and params as JSON")
    ap.add_argument("--plots", metavar="DIR", help="write the KE-vs-mass PNG (error bars: 95 %% CI) here")
    ns = ap.parse_args(argv)
    check_given(ap, ns)
    masses = _floats(ns.m_list, "m_free")
    p = _params(ns)
    for m in masses:
        p.with_(m_free=m)                          # bounds on every mass before any work
    _check_horn_mass(ns, p)
    sc = _scenario(ns, p)
    settings = _settings(ns)
    check_output_paths(inputs={"--config": ns.config}, folders=("plots",), csv=ns.csv, json=ns.json, plots=ns.plots)
    _threads(ns.threads)
    _warn_unusual(ap.prog, ns, p, skip=("m_free",))
    warn_first(ap.prog, "--m-free", masses, "m_free")
    echo_inputs({"free masses": masses_text(masses), **param_items(p, skip=("free mass",)),
                 **scenario_items(sc, settings)}, _quiet(ns))
    from .sweeps import sweep

    sw = sweep(p, masses, scenario=sc, settings=settings, progress=_progress(ns))
    bad = [r for r in sw.rows if r.failed]
    if bad:
        raise ParameterError("gap", p.gap, f"at m_free = {bad[0].params.m_free:g} kg: {bad[0].note}")
    print(f"{sw.scenario.name}: window {sc.t_from * 1e3:g}-{sc.t_end * 1e3:g} ms; means ± 95 % CI")
    print(f"{'m_free (g)':>10} {'tool KE after impact (mJ)':>26} {'tool rate (Hz)':>16} {'tool power (W)':>16} {'members':>8}")
    for r in sw.rows:
        ke = r.estimates["mean_tool_ke_after_j"].scaled(1e3)
        print(f"{r.params.m_free * 1e3:10.3g} {format(ke):>26} {format(r.estimates['tool_impact_rate_hz']):>16} "
              f"{format(r.estimates['tool_power_w']):>16} {r.members:8d}{'' if r.converged else '  (' + r.note + ')'}")
    f = sw.fit
    if f.reason and not math.isfinite(f.slope):
        print(f"linear fit: absent ({f.reason})")
    else:
        ci = f" ± {f.slope_ci95:.3g}" if math.isfinite(f.slope_ci95) else ""
        r2 = f", R^2 {f.r2:.4f}" if math.isfinite(f.r2) else f" ({f.reason})"
        print(f"linear fit: slope {f.slope:.4g}{ci} J/kg (= mJ/g), intercept {f.intercept * 1e3:.4g} mJ{r2}")
    if ns.csv:
        atomic_write_text(ns.csv, sw.csv())
    if ns.json:
        write_json(ns.json, sw.to_dict())
    if ns.plots:
        from .plots import plot_ke_vs_mass

        save_figure(plot_ke_vs_mass(sw), Path(ns.plots) / "tool_ke_vs_free_mass.png")
    return 0


def _article(argv):
    ap = CliParser(prog="python -m impact article", description="Reproduce the article's Fig. 6, 7, 8 and the "
                   "free-mass spectrum (article scenario, converged ensembles), plus impact_summary.json.")
    ap.add_argument("--out", required=True, metavar="DIR", help="output folder")
    ap.add_argument("--config", metavar="TOML", help="TOML file of model parameters")
    ap.add_argument("--seed", type=int, default=20260, metavar="N", help="seed of the member launch speeds")
    ap.add_argument("--threads", type=int, default=None, metavar="N", help="kernel threads (default: every core)")
    _add_output_flags(ap)
    ns = ap.parse_args(argv)
    check_given(ap, ns)
    p = from_mapping(ImpactParams, _load_config(ns.config)) if ns.config is not None else ImpactParams()
    check_output_paths(inputs={"--config": ns.config}, folders=("out",), out=ns.out)
    _threads(ns.threads)
    _warn_unusual(ap.prog, ns, p)
    echo_inputs({**param_items(p), "parameters from": ns.config or "Table 1 and the calibration", "seed": ns.seed},
                _quiet(ns))
    from .article import reproduce
    from .stats import StatsSettings

    settings = StatsSettings(seed=ns.seed)
    with atomic_folder(ns.out) as tmp:
        s = reproduce(tmp, p, settings=settings, progress=_progress(ns))
    fig8 = s["fig8"]["fit_ke_vs_mass"]
    r50 = s["article_8g"]
    print(f"wrote {', '.join(s['figures'])} and impact_summary.json to {ns.out}")
    print(f"8 g, first 50 ms: tool-impact rate {r50['tool_impact_rate_hz']['mean']:.0f} ± "
          f"{r50['tool_impact_rate_hz']['ci95_half_width']:.0f} Hz ({r50['members']} members); "
          f"Fig. 8 slope {fig8['slope']:.4g} J/kg, R^2 {fig8['r2']:.3f}")
    return 0


def _wants_fem_horn(argv) -> bool:
    for i, a in enumerate(argv):
        if a == "--horn" and i + 1 < len(argv) and argv[i + 1] == "fem":
            return True
        if a == "--horn=fem":
            return True
    return False


_DRILLING_ONLY = ("--wob", "--k-load", "--k-unload", "--f-threshold", "--rod-length", "--rod-diameter", "--cells",
                  "--drill-time", "--no-load-ke")
"""Options of the drilling command (``--load rock``) that this one does not take."""

_FEM_ONLY = ("--voltage", "--series-resistance", "--q-mech", "--modes", "--match", "--contact", "--history",
             "--history-csv", "--sample-dt", "--design", "--materials", "--select", "--mesh-size", "--refine",
             "--grade")
"""Options of the FE-transducer command (``--horn fem``) that the kinematic horn does not take."""


def _refuse_foreign(argv, names, requirement: str) -> None:
    """Refuse the first option of ``names`` in ``argv``, naming the option it needs."""
    for i, arg in enumerate(argv):
        name, eq, value = arg.partition("=")
        if name not in names:
            continue
        if not eq:
            following = argv[i + 1] if i + 1 < len(argv) else "--"
            value = True if following.startswith("--") else following
        needs(name, value, requirement)


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    loaded = any(a == "--load" or a.startswith("--load=") for a in argv)
    fem = bool(argv) and argv[0] not in ("sweep", "article") and _wants_fem_horn(argv)
    if not loaded:
        _refuse_foreign(argv, _DRILLING_ONLY, "--load rock")
    if not (loaded or fem):
        _refuse_foreign(argv, _FEM_ONLY, "--horn fem")
    if loaded:
        # drilling under load; named, not imported: drilling_cli uses this module's helpers
        import importlib

        return importlib.import_module("impact.drilling_cli").main(argv)
    if fem:
        # the FE transducer: built outside impact (which never imports fem); the module is named,
        # not imported, as rpud_common.launch names every entry point
        import importlib

        return importlib.import_module("results.coupled_cli").main(argv)
    setup_logging(-1)
    if argv and argv[0] == "sweep":
        return _sweep(argv[1:])
    if argv and argv[0] == "article":
        return _article(argv[1:])
    return _run(argv)
