"""Figures of the coupled model (transducer in the impact loop): tip amplitude envelope with the
impacts marked, tool kinetic energy vs free mass for the three horn models, drive power vs free
mass. Each function draws on the caller's Axes (``ax=``) or on a new figure and returns the Axes
(save one with :func:`rpud_common.save_figure`); axes in um, mJ, g, W (SI inside)."""

from __future__ import annotations

import numpy as np

from rpud_common.figures import axes_or_new

__all__ = ["tip_envelope", "ke_three_models", "drive_power", "compliant_energy_power"]


def tip_envelope(res, unloaded_m: float | None = None, *, ax=None):
    """Tip displacement (um) and its running amplitude (fundamental over 4 cycles) vs time (ms),
    horn and tool impacts marked. ``res``: an :class:`impact.coupled.CoupledResult` with series."""
    ax = axes_or_new(ax, figsize=(9, 4.5), dpi=120)
    ax.plot(res.t_grid * 1e3, res.u * 1e6, color="0.75", lw=0.3, label="tip displacement u(t)")
    tc, env = res.envelope(4)
    ax.plot(tc * 1e3, env * 1e6, color="tab:red", lw=1.2, label="running amplitude (4-cycle fundamental)")
    imp = res.impact
    top = float(np.max(env)) * 1e6 if env.size else 1.0
    h = ~imp.is_tool
    ax.plot(imp.t[h] * 1e3, np.full(h.sum(), 1.08 * top), "|", color="tab:blue", ms=6, label="horn impacts")
    ax.plot(imp.t[imp.is_tool] * 1e3, np.full(imp.is_tool.sum(), 1.15 * top), "|", color="tab:green", ms=6,
            label="tool impacts")
    if unloaded_m is not None:
        ax.axhline(unloaded_m * 1e6, color="k", ls="--", lw=0.8, label="unloaded steady amplitude")
    ax.set_xlabel("time (ms)")
    ax.set_ylabel("horn tip (um)")
    ax.set_title(f"Ring-up from rest with the {imp.params.m_free * 1e3:g} g free mass in place "
                 f"({res.horn.n_modes} modes, {res.horn.voltage:g} V): one sample of a chaotic motion")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower right")
    return ax


def _errorbar(ax, stats_list, key, scale, fmt, label):
    m = np.array([s.params.m_free for s in stats_list]) * 1e3
    mean = np.array([s.estimates[key].mean for s in stats_list]) * scale
    hw = np.array([s.estimates[key].half_width for s in stats_list]) * scale
    from impact.plots import errorbars_on_top

    errorbars_on_top(ax.errorbar(m, mean, yerr=hw, fmt=fmt, capsize=4, ms=5, mfc="none", label=label,
                                 lw=2.4 if label.startswith("headline:") else 1.2))


def ke_three_models(kinematic, damper, coupled, *, damper_is_headline: bool = False, ax=None):
    """Mean tool KE after impact (mJ) vs free mass (g), 95 % CI error bars: kinematic horn at the
    unloaded FE amplitude, kinematic horn at the damper-corrected amplitude (``headline:`` in its
    label when ``damper_is_headline``: the report's headline when the compliant model did not run),
    coupled model. Each argument: list of :class:`impact.stats.EnsembleStats`, one per free mass."""
    ax = axes_or_new(ax, figsize=(8, 5), dpi=120)
    _errorbar(ax, kinematic, "mean_tool_ke_after_j", 1e3, "k^:", "kinematic horn, unloaded FE amplitude")
    _errorbar(ax, damper, "mean_tool_ke_after_j", 1e3, "s--", ("headline: " if damper_is_headline else "") +
              "kinematic horn, damper-corrected amplitude (the report's device scenario)")
    _errorbar(ax, coupled, "mean_tool_ke_after_j", 1e3, "o-", "coupled model (FE modes in the loop)")
    ax.set_xlabel("free mass (g)")
    ax.set_ylabel("mean tool kinetic energy after impact (mJ)")
    ax.set_title("Tool kinetic energy vs free mass, three horn models (device scenario, 95 % CI)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return ax


def drive_power(coupled, unloaded_w: float | None = None, *, ax=None):
    """Electrical power drawn, modal damping loss and the horn's work on the free mass (W) vs free
    mass (g), coupled model, 95 % CI."""
    ax = axes_or_new(ax, figsize=(7, 4), dpi=120)
    _errorbar(ax, coupled, "drive_power_w", 1.0, "o-", "electrical power drawn (mean V I)")
    _errorbar(ax, coupled, "damping_power_w", 1.0, "s--", "modal damping loss")
    _errorbar(ax, coupled, "horn_power_w", 1.0, "^:", "work of the horn on the free mass")
    if unloaded_w is not None:
        ax.axhline(unloaded_w, color="k", ls="--", lw=0.8, label="unloaded (harmonic working point)")
    ax.set_xlabel("free mass (g)")
    ax.set_ylabel("power (W)")
    ax.set_title("Drive power vs free mass (coupled model, device scenario)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return ax


def compliant_energy_power(doc: dict):
    """The compliant model's answer against free mass (g): tool KE per impact (mJ, left) and tool
    power, the tool's KE gained per second (W, right), each with two error bars: the 95 % sampling CI
    (thick) and the CI plus the model-form estimate of the convergence study (thin, wide caps).
    ``doc``: the ``compliant_model`` block of ``summary.json``. Returns the figure's Axes."""
    from rpud_common.figures import subplots

    fig, axes = subplots(1, 2, figsize=(12, 4.5), dpi=120)
    rows = doc["rows"]
    m = np.array([r["m_free_kg"] for r in rows]) * 1e3
    for ax, key, scale, unit in ((axes[0], "mean_tool_ke_after_j", 1e3, "mJ"), (axes[1], "tool_power_w", 1.0, "W")):
        mean = np.array([r[key]["mean"] for r in rows]) * scale
        ci = np.array([r[key]["ci95_half_width"] for r in rows]) * scale
        mf = np.array([r["model_form"][key] for r in rows]) * scale
        ax.errorbar(m, mean, yerr=ci + mf, fmt="none", ecolor="0.55", capsize=7, lw=1.0,
                    label="95 % CI + model form (cut-off, contact stiffness)")
        ax.errorbar(m, mean, yerr=ci, fmt="o-", capsize=3, lw=2.0, ms=5, mfc="none", label="mean, 95 % sampling CI")
        ax.set_xlabel("free mass (g)")
        ax.set_ylabel(("tool kinetic energy after impact" if key.startswith("mean") else
                       "tool power: KE gained per second") + f" ({unit})")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_title(f"Compliant contacts, modes to {doc['cutoffs_hz'][-1] / 1e3:.0f} kHz (device scenario)")
    axes[1].set_title("Tool power against free mass")
    return axes[0]
