"""Figures of the end-to-end run that join the FE model and the impacts (matplotlib; axes in
um, mJ, g). The harmonic and ring-up figures are :mod:`fem.plots`'.

Each function draws on the caller's Axes (``ax=``) or on a new figure and returns the Axes;
:func:`rpud_common.save_figure` writes one.
"""

from __future__ import annotations

import numpy as np

from fem.plots import admittance, ring_up, tip_response  # noqa: F401  (re-exported)
from rpud_common.figures import axes_or_new

__all__ = ["impact_history", "kinetic_energy", "a0_coupling", "admittance", "ring_up", "tip_response",
           "SWEEP_LABELS"]


def impact_history(result, *, ax=None):
    """Horn, free mass and tool displacements of one sample run (article Fig. 6 with the FE A0)."""
    from impact.plots import plot_history

    p = result.params
    return plot_history(result, p.t_end, ax=ax,
                        title=f"A0 = {p.A0 * 1e6:.1f} um (FE), f = {p.freq / 1e3:.3f} kHz, "
                              f"free mass {p.m_free * 1e3:g} g, spring {p.spring_force:g} N: "
                              f"one sample of a chaotic motion")


SWEEP_LABELS = {
    "device_fe": ("device: spring, steady; A0 from the FE model (impact-loaded)", "o-"),
    "article_fe": ("article scenario: first 50 ms; FE A0", "s--"),
    "article_15um": ("article scenario: first 50 ms; A0 = 15 um (article's assumption)", "^:"),
}


def kinetic_energy(sweeps: dict, with_zero: bool = False, *, headline: str | None = "device_fe", ax=None):
    """Mean tool kinetic energy after impact vs free mass, each sweep (name -> SweepResult)
    with 95 % CI error bars (drawn above the markers) and its line fit; ``with_zero`` adds the
    (0 g, 0 mJ) point. The ``headline`` sweep (the report's headline model, ``summary.json``
    ``impacts.headline``) gets a heavy line and ``headline:`` in its legend label."""
    from impact.plots import ke_errorbars

    ax = axes_or_new(ax, figsize=(8, 5), dpi=120)
    for key, sw in sweeps.items():
        label, fmt = SWEEP_LABELS.get(key, (key, "o-"))
        ke_errorbars(ax, sw, fmt, label, zero=with_zero, headline=key == headline)
    ax.set_xlabel("free mass (g)")
    ax.set_ylabel("mean tool kinetic energy after impact (mJ)")
    ax.set_title("Drill-tool kinetic energy vs free-mass weight (article Fig. 8 / 13)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    return ax


def a0_coupling(coupled, rel_error: float | None = None, *, ax=None):
    """Horn-tip amplitude (um) with and without the impact load, per free mass (g)
    (``coupled``: mass in kg -> :class:`results.pipeline.CoupledAmplitude`); ``rel_error``, the
    relative discretisation error of the FE amplitude (:mod:`fem.errors`), draws error bars."""
    ax = axes_or_new(ax, figsize=(7, 4), dpi=120)
    m = np.array(sorted(coupled))
    a0 = np.array([coupled[k].A0 * 1e6 for k in m])
    if rel_error is not None and np.isfinite(rel_error):
        from impact.plots import errorbars_on_top

        errorbars_on_top(ax.errorbar(m * 1e3, a0, yerr=rel_error * a0, fmt="o-", capsize=4, mfc="none",
                                     label="loaded by the free-mass impacts (bars: FE discretisation error, "
                                           f"±{100 * rel_error:.2g} %)"))
    else:
        ax.plot(m * 1e3, a0, "o-", label="loaded by the free-mass impacts")
    ax.plot(m * 1e3, [coupled[k].A0_unloaded * 1e6 for k in m], "k--", label="no impact load")
    ax.axhline(15.0, color="C3", ls=":", label="article's assumption, 15 um")
    ax.set_xlabel("free mass (g)")
    ax.set_ylabel("horn-tip amplitude A0 (um)")
    ax.set_title("A0 from the geometry, coupled with the impacts it drives")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return ax
