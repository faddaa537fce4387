"""Figure of the drilling prediction: depth after the drilling time against free mass (mm vs g,
95 % CI error bars; the kinematic model's beside the compliant one's as its comparison), beside
the no-load tool kinetic energy (device scenario) on a second axis:
the article's Fig. 14 against its Fig. 13 trend. matplotlib on first use."""

from __future__ import annotations

import numpy as np

from rpud_common.figures import axes_or_new

__all__ = ["plot_depth_vs_mass"]


def plot_depth_vs_mass(sweep, *, ax=None, no_load_ke=None):
    """``sweep``: :class:`impact.drilling.DrillSweep`. Returns the Axes (depth); the no-load KE is
    on its twin axis when the sweep carries it, or as given by ``no_load_ke``: ``(m_free (kg),
    mean (J), 95 % CI half-width (J), label)`` arrays, so the depth of one model is drawn beside
    that same model's no-load energy."""
    ax = axes_or_new(ax, figsize=(7, 4.5), dpi=120)
    rows = sweep.rows
    m = np.array([r.m_free for r in rows]) * 1e3
    d = np.array([r.depth_m.mean for r in rows]) * 1e3
    hw = np.nan_to_num(np.array([r.depth_m.half_width for r in rows])) * 1e3
    p = sweep.params
    ax.errorbar(m, d, yerr=hw, fmt="o-", color="tab:blue", capsize=3,
                label=f"predicted depth after {p.drill_time:g} s, {sweep.model} model (WOB {p.wob:g} N, 95 % CI)")
    cmp = sweep.comparison
    if cmp is not None:
        ax.errorbar([r.m_free * 1e3 for r in cmp.rows], [r.depth_m.mean * 1e3 for r in cmp.rows],
                    yerr=np.nan_to_num([r.depth_m.half_width * 1e3 for r in cmp.rows]), fmt="^:", color="tab:gray",
                    capsize=3, label=f"comparison: {cmp.model} model (kinematic horn, elastic tool rod)")
    ax.set_xlabel("free mass (g)")
    ax.set_ylabel("predicted drilling depth (mm)", color="tab:blue")
    ax.grid(alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    if no_load_ke is None and sweep.no_load is not None:
        ke, kh = sweep.no_load.column("mean_tool_ke_after_j")
        no_load_ke = (sweep.no_load.m_free, ke, kh, "no-load tool KE after impact (device scenario)")
    if no_load_ke is not None:
        ax2 = ax.twinx()
        m_nl, ke, kh, label = no_load_ke
        ax2.errorbar(np.asarray(m_nl) * 1e3, np.asarray(ke) * 1e3, yerr=np.nan_to_num(np.asarray(kh, float)) * 1e3,
                     fmt="s--", color="tab:red", capsize=3, label=label)
        ax2.set_ylabel("no-load tool kinetic energy (mJ)", color="tab:red")
        h2, l2 = ax2.get_legend_handles_labels()
        handles, labels = handles + h2, labels + l2
    ax.legend(handles, labels, fontsize=8, loc="upper left")
    ax.set_title("Drilling under load vs free mass (article Fig. 14 case)")
    import textwrap

    from .drilling import status_line

    ax.text(0.99, 0.02, textwrap.fill(status_line(sweep.model), 90), transform=ax.transAxes, ha="right", va="bottom", fontsize=6,
            color="0.3")
    return ax
