"""Figures of the harmonic and transient analyses (matplotlib PNG, written atomically).
Axes in kHz, mS, nm/V, um."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rpud_common.figures import subplots
from rpud_common import save_figure as _save



def admittance(res, f_r: float, f_a: float, path) -> Path:
    """|Y| (log) and phase over the band, with the modal f_r / f_a marked."""
    fig, (a1, a2) = subplots(2, 1, figsize=(7, 5.5), dpi=120, sharex=True)
    f = res.freqs_hz / 1e3
    a1.semilogy(f, np.abs(res.admittance) * 1e3, lw=1.5)
    a2.plot(f, np.degrees(np.angle(res.admittance)), lw=1.5)
    for ax in (a1, a2):
        ax.axvline(f_r / 1e3, color="C3", ls="--", lw=1, label=f"f_r (modal) {f_r / 1e3:.3f} kHz")
        if np.isfinite(f_a):
            ax.axvline(f_a / 1e3, color="C2", ls=":", lw=1.2, label=f"f_a (modal) {f_a / 1e3:.3f} kHz")
        ax.grid(alpha=0.3)
    a1.set_ylabel("|Y| (mS)")
    a1.set_title(f"Electrical admittance ({res.method} superposition, Q_m = {res.loss.q_mech or 'datasheet'})")
    a1.legend(fontsize=8)
    a2.set_ylabel("phase of Y (deg)")
    a2.set_xlabel("frequency (kHz)")
    return _save(fig, path)


def tip_response(res, f_w: float, path) -> Path:
    """Horn-tip axial amplitude per volt and phase (and the teeth's tangential/axial ratio)."""
    fig, (a1, a2) = subplots(2, 1, figsize=(7, 5.5), dpi=120, sharex=True)
    f = res.freqs_hz / 1e3
    tip = res.surfaces["horn_tip"]["axial"] / res.voltage
    a1.plot(f, np.abs(tip) * 1e9, lw=1.5, label="horn tip, axial")
    if "teeth_tops" in res.surfaces:
        a1.plot(f, np.abs(res.surfaces["teeth_tops"]["axial"]) / res.voltage * 1e9, lw=1.2, label="teeth, axial")
        a1.plot(f, np.abs(res.surfaces["teeth_tops"]["tangential"]) / res.voltage * 1e9, lw=1.2,
                label="teeth, tangential")
    a1.axvline(f_w / 1e3, color="C3", ls="--", lw=1, label=f"working {f_w / 1e3:.3f} kHz")
    a1.set_ylabel("amplitude per volt (nm/V)")
    a1.set_title("Tip and teeth response")
    a1.legend(fontsize=8)
    a2.plot(f, np.degrees(np.angle(tip)), lw=1.5)
    a2.set_ylabel("tip phase vs. voltage (deg)")
    a2.set_xlabel("frequency (kHz)")
    for ax in (a1, a2):
        ax.grid(alpha=0.3)
    return _save(fig, path)


def ring_up(res, harmonic_amplitude: float, path) -> Path:
    """Tip displacement during ring-up: envelope over the run and the last cycles."""
    fig, (a1, a2) = subplots(1, 2, figsize=(10, 4), dpi=120)
    surface = next(iter(res.surfaces))
    y = res.surfaces[surface]["axial"]
    step = max(1, len(y) // 20000)
    a1.plot(res.t[::step] * 1e3, y[::step] * 1e6, lw=0.3)
    tc, env = res.envelope(surface)
    a1.plot(tc * 1e3, env * 1e6, color="C1", lw=1.5, label="envelope")
    a1.axhline(harmonic_amplitude * 1e6, color="C3", ls="--", lw=1, label="harmonic amplitude")
    a1.set_xlabel("time (ms)")
    a1.set_ylabel("tip axial displacement (um)")
    a1.set_title(f"Ring-up at {res.freq_hz / 1e3:.3f} kHz, {res.v0:g} V")
    a1.legend(fontsize=8)
    last = res.t >= res.t[-1] - 5.0 / res.freq_hz
    a2.plot(res.t[last] * 1e3, y[last] * 1e6, lw=1.2, label="tip")
    a2.plot(res.t[last] * 1e3, res.voltage[last] / res.v0 * harmonic_amplitude * 1e6, lw=1, ls=":",
            label="drive voltage (scaled)")
    a2.set_xlabel("time (ms)")
    a2.set_title(f"last cycles: steady {res.steady_amplitude(surface) * 1e6:.2f} um")
    a2.legend(fontsize=8)
    for ax in (a1, a2):
        ax.grid(alpha=0.3)
    return _save(fig, path)
