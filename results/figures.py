"""Figures of the end-to-end run that join the FE model and the impacts (matplotlib PNG,
written atomically; axes in um, mJ, g). The harmonic and ring-up figures are
:mod:`fem.plots`'."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fem.plots import admittance, ring_up, tip_response  # noqa: F401  (re-exported)
from rpud_common.figures import subplots
from rpud_common import save_figure as _save


def impact_history(result, path) -> Path:
    """Horn, free mass and tool displacements of one sample run (article Fig. 6 with the FE A0)."""
    from impact.plots import plot_history

    return plot_history(result, path, result.params.t_end,
                        title=f"A0 = {result.params.A0 * 1e6:.1f} um (FE), f = {result.params.freq / 1e3:.3f} kHz, "
                              f"free mass {result.params.m_free * 1e3:g} g, spring {result.params.spring_force:g} N: "
                              f"one sample of a chaotic motion")


SWEEP_LABELS = {
    "device_fe": ("device: spring, steady; A0 from the FE model (impact-loaded)", "o-"),
    "article_fe": ("article scenario: first 50 ms; FE A0", "s--"),
    "article_15um": ("article scenario: first 50 ms; A0 = 15 um (article's assumption)", "^:"),
}


def kinetic_energy(sweeps: dict, with_zero: bool, path) -> Path:
    """Mean tool kinetic energy after impact vs free mass, each sweep with 95 % CI error bars."""
    from impact.plots import ke_errorbars
    fig, ax = subplots(figsize=(8, 5), dpi=120)
    for key, sw in sweeps.items():
        label, fmt = SWEEP_LABELS.get(key, (key, "o-"))
        ke_errorbars(ax, sw, fmt, label, zero=with_zero)
    ax.set_xlabel("free mass (g)")
    ax.set_ylabel("mean tool kinetic energy after impact (mJ)")
    ax.set_title("Drill-tool kinetic energy vs free-mass weight (article Fig. 8 / 13)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    return _save(fig, path)


def a0_coupling(coupled, path) -> Path:
    """Horn-tip amplitude with and without the impact load, per free mass."""
    fig, ax = subplots(figsize=(7, 4), dpi=120)
    m = np.array(sorted(coupled))
    ax.plot(m * 1e3, [coupled[k].A0 * 1e6 for k in m], "o-", label="loaded by the free-mass impacts")
    ax.plot(m * 1e3, [coupled[k].A0_unloaded * 1e6 for k in m], "k--", label="no impact load")
    ax.axhline(15.0, color="C3", ls=":", label="article's assumption, 15 um")
    ax.set_xlabel("free mass (g)")
    ax.set_ylabel("horn-tip amplitude A0 (um)")
    ax.set_title("A0 from the geometry, coupled with the impacts it drives")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, path)
