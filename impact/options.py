"""The command-line options every ``python -m impact`` command shares (one definition, one check).

``add_model_options(parser)`` adds the model parameters (``--m-free``, ``--A0``, ... as SI
numbers), the scenario and the ensemble rule; ``params_from_options``, ``scenario_from_options``
and ``settings_from_options`` turn the parsed namespace into :class:`~impact.params.ImpactParams`,
:class:`~impact.stats.Scenario` and :class:`~impact.stats.StatsSettings`, raising a one-line
:class:`~rpud_common.ParameterError` before any work. The kinematic-horn command
(:mod:`impact.__main__`), the drilling command (:mod:`impact.drilling_cli`) and the FE-horn
command (:mod:`results.coupled_cli`) all build on these, so an option means the same in each.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys

from rpud_common import ParameterError, check_integer, check_range, from_mapping, load_toml, toml_section
from rpud_common.cli import check_usual, needs, quantity

from .params import ImpactParams

__all__ = ["real_number", "MODEL_OPTIONS", "add_model_options", "add_output_flags", "REL_TOL", "REL_TOL_RANGE",
           "MAX_MEMBERS_DEFAULT", "T_END_MIN", "load_config", "params_from_options", "scenario_from_options",
           "settings_from_options", "check_horn_mass", "is_quiet", "warn_unusual", "param_items", "scenario_items",
           "masses_text", "warn_first", "set_threads", "progress_printer", "stats_lines"]

_DEFAULTS = ImpactParams()
_TINY = sys.float_info.min


def real_number(text: str) -> float:
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


MODEL_OPTIONS = (
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
)
"""(option, ImpactParams field, help) of each model option; the help shows the dataclass default."""


def add_model_options(ap, skip=()) -> None:
    """Add the model, scenario and ensemble options to ``ap``, except the fields named in ``skip``."""
    g = ap.add_argument_group("model (SI units; defaults: Table 1 and the calibrated values)")
    for opt, name, text in MODEL_OPTIONS:
        if name in skip:
            continue
        g.add_argument(opt, dest=name, type=real_number, default=None, metavar="X",
                       help=f"{text} (default {getattr(_DEFAULTS, name):g})")
    g.add_argument("--horn-law", dest="horn_law", choices=["kinematic", "article"], default=None,
                   help="horn impact law: kinematic = infinite-mass driver (default), article = eq. 21 as printed")
    g.add_argument("--config", metavar="TOML",
                   help="TOML file of model parameters (top-level keys or one [impact] table); options override it")
    s = ap.add_argument_group("scenario and statistics")
    s.add_argument("--scenario", choices=["article", "device"], default="article",
                   help="article: no restoring spring, first 50 ms (the article's Figs. 6-8; default); "
                        "device: 5 N restoring spring, steady operation (20 ms discarded, 200 ms window)")
    s.add_argument("--spring-force", dest="spring_force", type=real_number, default=None, metavar="N",
                   help="restoring-spring force on the free mass toward the horn, N (default: the scenario's, 0 or 5)")
    s.add_argument("--t-from", dest="t_from", type=real_number, default=None, metavar="S",
                   help="start of the statistics window, s: the transient before it is discarded (default: the scenario's)")
    s.add_argument("--t-end", dest="t_end", type=real_number, default=None, metavar="S",
                   help="end of the statistics window = simulated time per member, s (default: the scenario's)")
    s.add_argument("--rel-tol", type=real_number, default=None, metavar="R",
                   help=f"add members until every 95%% CI half-width is within R of its mean, in "
                        f"[{REL_TOL_RANGE[0]:g}, {REL_TOL_RANGE[1]:g}] (default {REL_TOL})")
    s.add_argument("--members", type=int, default=None, metavar="N",
                   help="run exactly N members instead of the adaptive rule (then no --rel-tol or --max-members)")
    s.add_argument("--max-members", type=int, default=None, metavar="N",
                   help=f"cap of the adaptive rule (default {MAX_MEMBERS_DEFAULT})")
    s.add_argument("--seed", type=int, default=20260, metavar="N", help="seed of the member launch speeds (default 20260)")
    s.add_argument("--threads", type=int, default=None, metavar="N", help="kernel threads (default: every core)")
    add_output_flags(s)


def add_output_flags(group) -> None:
    """Add ``--no-progress`` and ``-q/--quiet`` to ``group``."""
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


def load_config(path) -> dict:
    """The model parameters of a ``--config`` TOML file (top-level keys or one ``[impact]`` table)."""
    return dict(toml_section(load_toml(path), "impact", str(path)))


def params_from_options(ns) -> ImpactParams:
    """The model parameters: defaults, then ``--config``, then the options given (checked)."""
    data = ImpactParams().to_dict()
    if getattr(ns, "config", None) is not None:
        cfg = from_mapping(ImpactParams, load_config(ns.config))   # validates the file on its own
        data.update(cfg.to_dict())
    for f in dataclasses.fields(ImpactParams):
        if f.name in ("t_end", "spring_force"):
            continue                  # set by the scenario (or its overrides)
        val = getattr(ns, f.name, None)
        if val is not None:
            data[f.name] = val
    return from_mapping(ImpactParams, data)


def scenario_from_options(ns, params: ImpactParams):
    """The scenario of ``--scenario`` with the window and spring overrides, checked against ``params``."""
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


def settings_from_options(ns):
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


def check_horn_mass(ns, p: ImpactParams) -> None:
    """``--m-horn`` enters the article's horn law only: refused under the kinematic law."""
    if getattr(ns, "m_horn", None) is not None and p.horn_law != "article":
        raise ParameterError("--m-horn", ns.m_horn, "applies only with --horn-law article (the kinematic horn "
                                                    "is an infinite-mass driver)")


def is_quiet(ns) -> bool:
    """True under ``-q/--quiet`` (no inputs line, no progress lines)."""
    return bool(getattr(ns, "quiet", False))


def warn_unusual(prog: str, ns, p: ImpactParams, skip=()) -> None:
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


def set_threads(n) -> None:
    """Set the compiled kernels' thread count from ``--threads`` (None: every core)."""
    if n is None:
        return
    import numba

    top = numba.config.NUMBA_NUM_THREADS
    if not 1 <= n <= top:
        raise ParameterError("threads", n, f"must be an integer in [1, {top}] (cores here)")
    numba.set_num_threads(n)


def progress_printer(ns):
    """A callback printing progress lines on stdout, or None under ``--no-progress`` or ``--quiet``."""
    if ns.no_progress or is_quiet(ns):
        return None
    # stdout: stderr carries nothing but the one-line error of a failed run
    return lambda msg: print(msg, flush=True)


def stats_lines(st) -> list[str]:
    """The printed table of an ensemble's statistics: a heading line, then one line per quantity.

    Parameters
    ----------
    st : impact.stats.EnsembleStats
        Converged (or capped) ensemble statistics.

    Returns
    -------
    list of str
        Energies in mJ, rates in Hz, powers in W, fractions in %, each mean with its 95 % CI.
    """
    from .stats import QUANTITIES

    unit_scale = {"J": (1e3, "mJ"), "W": (1.0, "W"), "Hz": (1.0, "Hz"), "-": (100.0, "%")}
    lines = [f"{st.scenario.name}: window {st.scenario.t_from * 1e3:g}-{st.scenario.t_end * 1e3:g} ms, "
             f"{st.members} members, {'converged' if st.converged else 'NOT converged'} "
             f"(95 % CI within {st.settings.rel_tol:.0%})" + (f"; {st.note}" if st.note else "")]
    for name, unit, text in QUANTITIES:
        scale, u = unit_scale[unit]
        lines.append(f"  {text:<66} {st.estimates[name].scaled(scale)} {u}")
    return lines
