"""``python -m impact``: converged statistics of one case; ``sweep``: against free mass;
``article``: the article's figures; ``rotor``: the rotary unit (:mod:`impact.rotor_cli`);
``--load rock``: drilling under load (:mod:`impact.drilling_cli`);
``--horn fem``: the FE transducer in the loop (:mod:`results.coupled_cli`).

All options in SI units. Bad input: one line on stderr, exit code 2, no output file.
"""

from __future__ import annotations

import math
import sys

if __name__ == "__main__":
    # signal handling first: the imports below take a moment and must end cleanly on SIGINT/SIGTERM
    from rpud_common.launch import launch

    sys.exit(launch("impact.__main__", prog="python -m impact"))

from pathlib import Path

from rpud_common import (CliParser, ParameterError, atomic_folder, atomic_write_text, check_output_paths, from_mapping,
                         save_figure, setup_logging, write_json)
from rpud_common.cli import check_given, echo_inputs, needs

from .options import (add_model_options, add_output_flags, check_horn_mass, is_quiet, load_config, masses_text,
                      param_items, params_from_options, progress_printer, scenario_from_options, scenario_items,
                      set_threads, settings_from_options, stats_lines, warn_first, warn_unusual)
from .params import ImpactParams


def _run(argv):
    ap = CliParser(prog="python -m impact", description="Impact model of the RPUD percussive system (horn -> free "
                   "mass -> drill tool), reported as ensemble means with 95 % confidence intervals. "
                   "Subcommands: 'sweep', 'article', 'rotor' (see their --help).")
    add_model_options(ap)
    ap.add_argument("--horn", choices=["kinematic", "fem"], default="kinematic",
                    help="kinematic: the tip moves as A0 cos(2 pi f t) whatever the impacts (default); fem: the "
                         "design's FE transducer in the loop (see python -m impact --horn fem --help)")
    ap.add_argument("--json", metavar="PATH", help="write params, statistics and one sample trajectory's events as JSON")
    ap.add_argument("--plots", metavar="DIR", help="write one sample trajectory's displacement history and spectrum PNGs here")
    ns = ap.parse_args(argv)
    check_given(ap, ns)
    p = params_from_options(ns)
    check_horn_mass(ns, p)
    sc = scenario_from_options(ns, p)
    settings = settings_from_options(ns)
    check_output_paths(inputs={"--config": ns.config}, folders=("plots",), json=ns.json, plots=ns.plots)
    set_threads(ns.threads)
    warn_unusual(ap.prog, ns, p)
    echo_inputs({**param_items(p), **scenario_items(sc, settings)}, is_quiet(ns))
    from .model import SimulationError, simulate
    from .stats import ensemble_statistics

    st = ensemble_statistics(p, sc, settings, progress=progress_printer(ns))
    if st.failed:
        raise ParameterError("gap", p.gap, st.note)
    print("\n".join(stats_lines(st)))
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
    add_model_options(ap, skip=("m_free",))
    ap.add_argument("--csv", metavar="PATH", help="write the table (means and CI half-widths) as CSV")
    ap.add_argument("--json", metavar="PATH", help="write table, fit, scenario and params as JSON")
    ap.add_argument("--plots", metavar="DIR", help="write the KE-vs-mass PNG (error bars: 95 %% CI) here")
    ns = ap.parse_args(argv)
    check_given(ap, ns)
    masses = _floats(ns.m_list, "m_free")
    p = params_from_options(ns)
    for m in masses:
        p.with_(m_free=m)                          # bounds on every mass before any work
    check_horn_mass(ns, p)
    sc = scenario_from_options(ns, p)
    settings = settings_from_options(ns)
    check_output_paths(inputs={"--config": ns.config}, folders=("plots",), csv=ns.csv, json=ns.json, plots=ns.plots)
    set_threads(ns.threads)
    warn_unusual(ap.prog, ns, p, skip=("m_free",))
    warn_first(ap.prog, "--m-free", masses, "m_free")
    echo_inputs({"free masses": masses_text(masses), **param_items(p, skip=("free mass",)),
                 **scenario_items(sc, settings)}, is_quiet(ns))
    from .sweeps import sweep

    sw = sweep(p, masses, scenario=sc, settings=settings, progress=progress_printer(ns))
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
        ici = f" ± {f.intercept_ci95 * 1e3:.3g}" if math.isfinite(f.intercept_ci95) else ""
        print(f"linear fit: slope {f.slope:.4g}{ci} J/kg (= mJ/g), intercept {f.intercept * 1e3:.4g}{ici} mJ{r2} "
              "(95 % intervals from the points' scatter about the line)")
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
    add_output_flags(ap)
    ns = ap.parse_args(argv)
    check_given(ap, ns)
    p = from_mapping(ImpactParams, load_config(ns.config)) if ns.config is not None else ImpactParams()
    check_output_paths(inputs={"--config": ns.config}, folders=("out",), out=ns.out)
    set_threads(ns.threads)
    warn_unusual(ap.prog, ns, p)
    echo_inputs({**param_items(p), "parameters from": ns.config or "Table 1 and the calibration", "seed": ns.seed},
                is_quiet(ns))
    from .article import reproduce
    from .stats import StatsSettings

    settings = StatsSettings(seed=ns.seed)
    with atomic_folder(ns.out) as tmp:
        s = reproduce(tmp, p, settings=settings, progress=progress_printer(ns))
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

_FEM_ONLY = ("--voltage", "--voltage-rms", "--series-resistance", "--q-mech", "--admittance", "--modes", "--match", "--contact", "--history",
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
    if argv and argv[0] == "rotor":
        from .rotor_cli import main as rotor_main

        return rotor_main(argv[1:])
    loaded = any(a == "--load" or a.startswith("--load=") for a in argv)
    fem = bool(argv) and argv[0] not in ("sweep", "article") and _wants_fem_horn(argv)
    if not loaded:
        _refuse_foreign(argv, _DRILLING_ONLY, "--load rock")
    if not (loaded or fem):
        _refuse_foreign(argv, _FEM_ONLY, "--horn fem")
    if loaded:
        from .drilling_cli import main as drilling_main

        return drilling_main(argv)
    if fem:
        # the FE transducer is built outside impact (whose library never imports fem): a command
        # sits on top of every package, so this one hands over to results' command
        from results.coupled_cli import main as coupled_main

        return coupled_main(argv)
    setup_logging(-1)
    if argv and argv[0] == "sweep":
        return _sweep(argv[1:])
    if argv and argv[0] == "article":
        return _article(argv[1:])
    return _run(argv)
