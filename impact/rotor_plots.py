"""Figures of the rotary unit: the torque-speed curve (with power and efficiency) and the contact
forces of one tooth over a drive cycle with its stick and slip phases. matplotlib on first use."""

from __future__ import annotations

import math

import numpy as np

from rpud_common.figures import axes_or_new

__all__ = ["plot_torque_speed", "plot_contact_phases"]

_RPM = 30.0 / math.pi


def plot_torque_speed(res, *, ax=None):
    """``res``: :class:`impact.rotor.RotorResult`. Torque (mN m) against speed (rpm); mechanical
    power (mW) and efficiency (%) on a twin axis; the operating point under the load marked."""
    ax = axes_or_new(ax, figsize=(7, 4.5), dpi=120)
    c = res.curve
    rpm = np.asarray(c["speed_rad_s"]) * _RPM
    ax.plot(rpm, np.asarray(c["torque_n_m"]) * 1e3, "-", color="tab:blue", label="mean driving torque")
    ax.axhline(res.torque_bound * 1e3, color="tab:blue", ls=":", lw=1, label="bound mu F r")
    ax.plot([res.load_speed * _RPM], [res.load_torque * 1e3], "o", color="k",
            label=f"under load {res.load_torque * 1e3:.3g} mN m")
    ax.set_xlabel("rotor speed (rpm)")
    ax.set_ylabel("torque (mN m)", color="tab:blue")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax2 = ax.twinx()
    ax2.plot(rpm, np.asarray(c["power_w"]) * 1e3, "--", color="tab:red", label="mechanical power (mW)")
    ax2.plot(rpm, np.asarray(c["efficiency"]) * 100, "-.", color="tab:green", label="contact efficiency (%)")
    ax2.set_ylabel("power (mW), efficiency (%)")
    ax2.set_ylim(bottom=0)
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, fontsize=8, loc="upper right")
    ax.set_title(f"Rotary unit: torque-speed curve ({res.params.n_teeth} teeth, preload {res.params.preload:g} N, "
                 f"mu {res.params.mu:g})", fontsize=10)
    return ax


_COLOURS = {"stick": "tab:green", "slip+": "tab:orange", "slip-": "tab:purple"}


def plot_contact_phases(res, *, ax=None):
    """Normal and tangential force of one tooth over the drive cycle at the operating point
    (phase in degrees), the stick and slip phases shaded."""
    ax = axes_or_new(ax, figsize=(7, 4.5), dpi=120)
    cyc = res.load_cycle
    x, p, q = cyc.force_samples
    order = np.argsort(x)
    deg = np.degrees(x[order])
    ax.plot(deg, p[order], "-", color="k", label="normal force p")
    ax.plot(deg, q[order], "-", color="tab:blue", label="tangential force q")
    ax.plot(deg, res.params.mu * p[order], ":", color="k", lw=1, label="friction limit mu p")
    seen = set()
    for s, e, kind in cyc.phases:
        ax.axvspan(math.degrees(s), math.degrees(e), color=_COLOURS[kind], alpha=0.15,
                   label=kind if kind not in seen else None)
        seen.add(kind)
    ax.set_xlabel("drive phase (deg; 0 = crest of the axial stroke)")
    ax.set_ylabel("force per tooth (N)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"Contact of one tooth over a cycle at {res.load_speed * _RPM:.3g} rpm "
                 f"(contact {cyc.fraction('contact') * 100:.1f} % of the cycle)", fontsize=10)
    return ax
