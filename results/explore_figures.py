"""Figures of a design study: main effects, a Pareto front, and a tolerance study.

Error bars: impact outputs carry their 95 % confidence interval (ensemble statistics); a main
effect's bar for them is the 95 % CI of the level mean (half-widths combined in quadrature). The
rotor's speeds and torque carry an error bound (``<name>_error``: the largest departure over the
teeth motion's error box); a level mean's bound is the mean of its points' bounds (bounds add
linearly). FE outputs are deterministic; their bars on a main-effect plot show the range over
the other parameters at that level (the spread the other parameters cause), not an uncertainty.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from rpud_common import axes_or_new, save_figure

from .study import OUTPUTS

__all__ = ["main_effects", "pareto_front", "tolerance_spread", "study_figures", "pareto_mask", "tolerance_table",
           "axis_label", "param_scale"]

_SCALE = {"m": (1e6, "um"), "m/V": (1e9, "nm/V"), "J": (1e3, "mJ"), "Hz": (1e-3, "kHz"), "N m": (1e3, "mN m")}

#: study output -> the words on a figure axis; the unit comes from :data:`results.study.OUTPUTS`
#: through :func:`_scale`, so a label and the numbers plotted against it use the same unit
_OUTPUT_NAMES = {
    "tetrahedra": "mesh tetrahedra", "nodes": "mesh nodes",
    "f_r_hz": "working-mode resonance f_r", "f_a_hz": "working-mode anti-resonance f_a",
    "k_eff": "coupling factor k_eff", "matched": "resonance matching converged, 1 = yes",
    "tip_per_volt_m": "tip amplitude per volt", "A0_unloaded_m": "tip amplitude A0, no impacts",
    "teeth_ellipse_ratio": "teeth ellipse ratio (tangential / axial)", "power_w": "electrical power, no impacts",
    "A0_m": "tip amplitude A0, impact-loaded", "tool_ke_j": "tool kinetic energy after impact",
    "ke_gain_j": "tool kinetic energy gain per impact", "tool_power_w": "power delivered to the tool",
    "tool_rate_hz": "tool impact rate", "horn_power_w": "work of the horn on the free mass per second",
    "rotor_no_load_rpm": "rotor speed without load", "rotor_stall_torque_n_m": "rotor stall torque",
    "rotor_load_rpm": "rotor speed under the bit's friction", "rotor_hovers": "rotor hovers on the teeth, 1 = yes",
}

#: varied parameter (``drive.*``, ``impact.*``) -> (factor from SI to the plotted unit, words, unit);
#: the units are those of :class:`impact.ImpactParams` and the drive settings
_PARAMS = {
    "drive.voltage": (1.0, "drive voltage", "V"), "drive.q_mech": (1.0, "mechanical quality factor Q_m", "-"),
    "impact.m_free": (1e3, "free mass", "g"), "impact.m_tool": (1e3, "drill-tool mass", "g"),
    "impact.e1": (1.0, "restitution free mass / tool e1", "-"),
    "impact.e2": (1.0, "restitution free mass / horn e2", "-"),
    "impact.k0": (1.0, "tool holder stiffness k0", "N/m"), "impact.c": (1.0, "tool damping c", "N s/m"),
    "impact.gap": (1e3, "free stroke L0", "mm"), "impact.v0": (1.0, "free-mass start velocity v0", "m/s"),
    "impact.spring_force": (1.0, "restoring spring force", "N"),
}

#: design fields (SI, metres) drawn in mm, recognised by the last part of their dotted path
_LENGTH_WORDS = ("length", "diameter", "radius", "thickness", "width", "depth", "height", "offset", "gap",
                 "chamfer", "fillet", "pitch")


def _scale(name: str) -> tuple[float, str]:
    unit = OUTPUTS[name][1] if name in OUTPUTS else ""
    if name.startswith("tool_rate") or name.startswith("horn_rate"):
        return 1.0, "Hz"
    return _SCALE.get(unit, (1.0, unit))


def param_scale(name: str) -> tuple[float, str]:
    """Factor from the stored (SI) value of a varied parameter to its axis, and the axis label
    ``'words (unit)'``: ``impact.m_free`` -> ``(1e3, 'free mass (g)')``, a design length such as
    ``horn.length`` -> ``(1e3, 'horn length (mm)')``, an angle ``..._deg`` in deg. A design field
    of unknown unit keeps its dotted path and says so: ``(1.0, 'stack.preload_model (design-file unit)')``."""
    if name in _PARAMS:
        k, words, unit = _PARAMS[name]
        return k, f"{words} ({unit})"
    part, _, field = name.rpartition(".")
    words = f"{part} {field.replace('_', ' ')}".strip()
    if field.endswith("_deg"):
        return 1.0, f"{part} {field[:-4].replace('_', ' ')} (deg)".strip()
    if field.startswith("n_"):
        return 1.0, f"{part} number of {field[2:].replace('_', ' ')} (count)".strip()
    if field.endswith("_fraction") or field.endswith("_ratio"):
        return 1.0, f"{words} (-)"
    if any(field.endswith(w) for w in _LENGTH_WORDS):
        return 1e3, f"{words} (mm)"
    return 1.0, f"{name} (design-file unit)"


def axis_label(name: str) -> str:
    """The axis label ``'words (unit)'`` of a study output or a varied parameter (the unit is the
    plotted one: ``tool_ke_j`` -> ``'tool kinetic energy after impact (mJ)'``)."""
    if name in OUTPUTS:
        _, unit = _scale(name)
        return f"{_OUTPUT_NAMES.get(name, name)} ({unit})"
    return param_scale(name)[1]


def _ok(rows):
    return [r for r in rows if r.get("status") == "ok"]


def _error_bars(rows, name):
    """Each row's error bar of output ``name`` and whether the bars are 95 % CIs (``<name>_ci95``,
    independent: a mean's combines them in quadrature) or error bounds (``<name>_error``: a
    mean's is their mean)."""
    ci = _values(rows, f"{name}_ci95")
    if np.isfinite(ci).any():
        return ci, True
    return _values(rows, f"{name}_error"), False


def _values(rows, name):
    return np.array([r.get(name, math.nan) if r.get(name) is not None else math.nan for r in rows], dtype=float)


def main_effects(result, outputs=None, axes=None):
    """Mean of each output against each varied parameter (one panel per pair)."""
    rows = _ok(result.rows)
    params = [p.name for p in result.study.parameters]
    outputs = list(outputs or result.study.outputs or [o for o in OUTPUTS if OUTPUTS[o][0] in result.study.stages][:3])
    n = len(params) * len(outputs)
    axes = np.atleast_1d(axes_or_new(axes, n, figsize=(6.4, 2.4 * n + 0.6))).ravel()
    for k, (out, par) in enumerate((o, p) for o in outputs for p in params):
        ax = axes[k]
        px, _ = param_scale(par)
        x = _values(rows, f"in.{par}") * px
        y = _values(rows, out)
        hw, is_ci = _error_bars(rows, out)
        s, _ = _scale(out)
        levels = np.unique(x[np.isfinite(x)])
        if 0 < len(levels) <= 12:
            sel = [(x == lv) & np.isfinite(y) for lv in levels]
            means = np.array([y[m].mean() if m.any() else math.nan for m in sel])
            if any(np.isfinite(hw[m]).any() for m in sel):
                # a level mean's 95 % CI: the members' half-widths in quadrature; its bound: their mean
                half = np.array([(math.sqrt(np.nansum(hw[m] ** 2)) if is_ci else np.nansum(hw[m])) / max(m.sum(), 1)
                                 for m in sel])
                ax.errorbar(levels, means * s, yerr=half * s, marker="o", capsize=3,
                            label="mean, 95 % CI" if is_ci else "mean, error bound")
            else:
                lo = np.array([y[m].min() if m.any() else math.nan for m in sel])
                hi = np.array([y[m].max() if m.any() else math.nan for m in sel])
                ax.plot(levels, means * s, "o-", label="mean over the other parameters")
                if len(params) > 1:
                    ax.fill_between(levels, lo * s, hi * s, alpha=0.2, label="range over the other parameters")
            ax.legend(fontsize=7)
        else:
            ax.errorbar(x, y * s, yerr=np.where(np.isfinite(hw), hw, 0) * s, fmt="o", ms=3, capsize=2)
        ax.set_xlabel(axis_label(par))
        ax.set_ylabel(axis_label(out))
        ax.grid(alpha=0.3)
    return tuple(axes)


def pareto_mask(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Points not dominated when both ``a`` and ``b`` are maximised (NaN points never are)."""
    ok = np.isfinite(a) & np.isfinite(b)
    mask = np.zeros(len(a), dtype=bool)
    for i in np.flatnonzero(ok):
        dominated = ok & (a >= a[i]) & (b >= b[i]) & ((a > a[i]) | (b > b[i]))
        mask[i] = not dominated.any()
    return mask


def pareto_front(result, first: str, second: str, ax=None):
    """Both outputs maximised: every point, the non-dominated ones joined."""
    ax = axes_or_new(ax, 1)
    rows = _ok(result.rows)
    a, b = _values(rows, first), _values(rows, second)
    (ea, _), (eb, _) = _error_bars(rows, first), _error_bars(rows, second)
    (sa, _), (sb, _) = _scale(first), _scale(second)
    ax.errorbar(a * sa, b * sb, xerr=np.nan_to_num(ea) * sa, yerr=np.nan_to_num(eb) * sb, fmt="o", ms=4,
                color="0.6", capsize=2, label="points (95 % CI where statistical, error bound where estimated)")
    m = pareto_mask(a, b)
    order = np.argsort(a[m])
    ax.plot(a[m][order] * sa, b[m][order] * sb, "o-", color="C3", label="Pareto front (both maximised)")
    ax.set_xlabel(axis_label(first))
    ax.set_ylabel(axis_label(second))
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return ax


def tolerance_table(result) -> dict:
    """Spread of each output over a tolerance study: nominal, mean, std, min, max, relative spread."""
    rows = result.rows
    out = {}
    nominal = rows[0] if rows and rows[0].get("status") == "ok" else None
    for name in OUTPUTS:
        if OUTPUTS[name][0] not in result.study.stages:
            continue
        y = _values(_ok(rows), name)
        y = y[np.isfinite(y)]
        if len(y) < 2:
            continue
        nom = nominal.get(name) if nominal else math.nan
        out[name] = {"nominal": nom, "mean": float(y.mean()), "std": float(y.std(ddof=1)), "min": float(y.min()),
                     "max": float(y.max()),
                     "rel_spread": float((y.max() - y.min()) / abs(nom)) if nom not in (None, 0) and np.isfinite(nom)
                     else math.nan, "n": int(len(y))}
    return out


def tolerance_spread(result, outputs=None, axes=None):
    """Each output over the tolerance points relative to the nominal design (box + points)."""
    table = tolerance_table(result)
    outputs = [o for o in (outputs or ("f_r_hz", "A0_m", "A0_unloaded_m", "tool_ke_j")) if o in table]
    axes = np.atleast_1d(axes_or_new(axes, max(len(outputs), 1))).ravel()
    rows = _ok(result.rows)
    for ax, name in zip(axes, outputs):
        y = _values(rows, name)
        nom = table[name]["nominal"]
        rel = (y[np.isfinite(y)] / nom - 1) * 100
        ax.boxplot(rel, widths=0.5)
        ax.plot(np.ones_like(rel) + np.linspace(-0.1, 0.1, len(rel)), rel, "o", ms=3, alpha=0.6)
        ax.axhline(0, color="k", lw=0.8)
        ax.set_xticks([1], [axis_label(name)])
        ax.set_ylabel("change from nominal (%)")
        ax.grid(alpha=0.3)
        if name in ("tool_ke_j",):
            hw = _values(rows, f"{name}_ci95")
            ax.set_title(f"(statistical 95 % CI ±{np.nanmean(hw / y) * 100:.1f} %)", fontsize=8)
    return tuple(axes)


def study_figures(result, folder: str | Path) -> dict[str, Path]:
    """Write the study's figures into ``folder`` (created); returns name -> path."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    made = {}
    if _ok(result.rows):
        made["main_effects"] = save_figure(main_effects(result), folder / "main_effects.png")
        if len(result.study.pareto) == 2:
            made["pareto"] = save_figure(pareto_front(result, *result.study.pareto), folder / "pareto.png")
        if result.study.sampling == "tolerance" and tolerance_table(result):
            made["tolerance"] = save_figure(tolerance_spread(result), folder / "tolerance.png")
    return made
