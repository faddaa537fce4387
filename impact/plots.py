"""Figures: displacement histories (article Fig. 6/7), tool kinetic energy against free-mass
weight (Fig. 8) and the free-mass spectrum (Fig. 12 analogue).

Each function draws on the caller's Axes (``ax=``) or on a new figure and returns the Axes, so
the figures compose in a notebook; save one with :func:`rpud_common.save_figure`. matplotlib is
imported on first use, so ``import impact`` stays light. Positions in mm, times in ms, energies
in mJ, masses in g (SI inside).
"""

from __future__ import annotations

import numpy as np

from rpud_common.figures import axes_or_new

__all__ = ["plot_history", "plot_spectrum", "plot_ke_vs_mass", "plot_tool_ke_history", "ke_errorbars",
           "errorbars_on_top"]


def plot_history(result, t_max: float | None = None, title: str = "", *, ax=None):
    """Horn tip, free mass and tool face positions (mm) against time (ms) up to ``t_max`` (s).

    ``result`` is an :class:`impact.ImpactResult` with its time series (``simulate(...,
    series=True)``). Returns the Axes.
    """
    if result.t_grid is None:
        raise ValueError("the result holds no time series (simulate(..., series=True))")
    t_max = result.params.t_end if t_max is None else t_max
    sel = result.t_grid <= t_max * (1 + 1e-12)
    t = result.t_grid[sel] * 1e3
    ax = axes_or_new(ax, figsize=(9, 4.5), dpi=120)
    ax.plot(t, result.tool_face[sel] * 1e3, color="tab:green", lw=1.0, label="drill tool face L0 + v(t)")
    ax.plot(t, result.w[sel] * 1e3, color="tab:blue", lw=1.0, label="free mass w(t)")
    ax.plot(t, result.u[sel] * 1e3, color="tab:red", lw=0.5, label="horn tip u(t)")
    it = result.is_tool & (result.t <= t_max)
    ax.plot(result.t[it] * 1e3, result.x[it] * 1e3, "k.", ms=3, label="tool impacts")
    ax.set_xlabel("time (ms)")
    ax.set_ylabel("displacement along the drill (mm)")
    ax.set_xlim(0, t_max * 1e3)
    ax.set_title(title or f"First {t_max * 1e3:.0f} ms of the percussive system")
    ax.legend(loc="upper left", fontsize=8)
    ax.grid(alpha=0.3)
    return ax


def plot_spectrum(result, f_max: float = 2000.0, *, ax=None):
    """Amplitude spectrum of the free-mass displacement (mm) up to ``f_max`` (Hz). Returns the Axes."""
    f, amp = result.spectrum()
    sel = f <= f_max
    ax = axes_or_new(ax, figsize=(8, 4), dpi=120)
    ax.plot(f[sel], amp[sel] * 1e3, lw=0.8)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("amplitude (mm)")
    ax.set_title(f"Free-mass displacement spectrum ({result.params.t_end:g} s run)")
    ax.grid(alpha=0.3)
    return ax


def plot_tool_ke_history(histories: dict, *, ax=None):
    """Tool KE after each impact (mJ) vs time (ms), one sample trajectory per free mass
    (``histories``: mass in kg -> ImpactResult). One trajectory is one sample of a chaotic
    motion, and the title says so. Returns the Axes."""
    ax = axes_or_new(ax, figsize=(6, 4.5), dpi=120)
    for m, r in sorted(histories.items()):
        it = r.is_tool
        ax.plot(r.t[it] * 1e3, r.tool_ke_after * 1e3, ".", ms=3, label=f"{m * 1e3:g} g")
    ax.set_title("one sample trajectory per mass (chaotic)", fontsize=9)
    ax.set_xlabel("time (ms)")
    ax.set_ylabel("tool kinetic energy after impact (mJ)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return ax


def plot_ke_vs_mass(sweep_result, *, ax=None, label: str = "model", fmt: str = "o", zero: bool = False):
    """Fig. 8 analogue: mean tool KE after impact (mJ) vs free mass (g), error bars the 95 %
    confidence intervals, with the linear fit. Call it again on the same ``ax`` to compare
    sweeps. Returns the Axes."""
    ax = axes_or_new(ax, figsize=(6, 4.5), dpi=120)
    ke_errorbars(ax, sweep_result, fmt, label, zero=zero)
    ax.set_xlabel("free mass (g)")
    ax.set_ylabel("mean tool kinetic energy after impact (mJ)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return ax


def errorbars_on_top(container, zorder: float = 3.5) -> None:
    """Raise the bars and caps of an ``ax.errorbar`` result above its markers and line.

    A CI of a few percent is shorter than a marker is tall: drawn under a filled marker (the
    matplotlib default order) it disappears, and the figure looks as if it had no uncertainty.
    """
    _, caps, bars = container
    for artist in (*caps, *bars):
        artist.set_zorder(zorder)


def ke_errorbars(ax, sweep_result, fmt: str = "o", label: str = "model", zero: bool = False,
                 headline: bool = False):
    """Mean tool KE after impact (mJ) vs free mass (g) with 95 % CI error bars and the fitted line.

    Markers are hollow and the bars (with caps) drawn above them, so a CI smaller than a marker
    still shows. ``zero`` adds the point (0 g, 0 mJ): no free mass, no impact. ``headline`` marks
    the sweep whose numbers the report leads with: a heavier line and ``headline:`` in its legend
    label. Returns the Axes.
    """
    s = sweep_result
    ke, hw = s.column("mean_tool_ke_after_j")
    m = s.m_free * 1e3
    if zero:
        m, ke, hw = np.r_[0.0, m], np.r_[0.0, ke], np.r_[0.0, hw]
    n = [r.members for r in s.rows]
    text = f"{label} ({s.scenario.name}, {min(n)}-{max(n)} members per mass, 95 % CI)"
    line = ax.errorbar(m, ke * 1e3, yerr=np.nan_to_num(hw) * 1e3, fmt=fmt, capsize=4, capthick=1.2,
                       elinewidth=1.2, ms=6 if headline else 5, mfc="none", mew=1.2, lw=2.4 if headline else 1.2,
                       label=f"headline: {text}" if headline else text)
    errorbars_on_top(line)
    f = s.fit
    if np.isfinite(f.slope):
        xx = np.linspace(s.m_free.min() * 1e3, s.m_free.max() * 1e3, 10)   # the fitted range only
        ci = f" ± {f.slope_ci95:.2g}" if np.isfinite(f.slope_ci95) else ""
        r2 = f", R² = {f.r2:.3f}" if np.isfinite(f.r2) else ""
        ax.plot(xx, (f.slope * xx * 1e-3 + f.intercept) * 1e3, ls=":", color=line[0].get_color(),
                label=f"line fit: {f.slope:.3g}{ci} J/kg{r2}")
    return ax
