"""Figures of the harmonic and transient analyses (matplotlib; axes in kHz, mS, nm/V, um).

Each function draws on the caller's Axes (``axes=(top, bottom)`` or ``(left, right)``) or on a
new figure, and returns the Axes, so the figures compose in a notebook; save one with
:func:`rpud_common.save_figure` (it takes the returned Axes).
"""

from __future__ import annotations

import numpy as np

from rpud_common.figures import axes_or_new

__all__ = ["admittance", "tip_response", "ring_up"]


def admittance(res, f_r: float, f_a: float = float("nan"), *, axes=None):
    """Modulus of Y (log, mS) and phase of Y (deg) over the band, with the modal f_r / f_a (Hz) marked.

    Parameters
    ----------
    res : fem.harmonic.HarmonicResult
    f_r, f_a : float
        Resonance and anti-resonance (Hz) to mark; a non-finite ``f_a`` is not drawn.
    axes : (Axes, Axes), optional
        Magnitude and phase panels; new ones (shared frequency axis) when omitted.

    Returns
    -------
    (Axes, Axes)
    """
    a1, a2 = axes_or_new(axes, 2, figsize=(7, 5.5), dpi=120, sharex=True)
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
    return a1, a2


def tip_response(res, f_w: float, *, axes=None):
    """Horn-tip axial amplitude per volt (nm/V) and its phase, with the teeth's axial and
    tangential amplitudes when the result has them; the working frequency ``f_w`` (Hz) marked.

    Returns the two Axes (amplitude, phase); ``axes`` draws on the caller's pair.
    """
    a1, a2 = axes_or_new(axes, 2, figsize=(7, 5.5), dpi=120, sharex=True)
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
    return a1, a2


def ring_up(res, harmonic_amplitude: float = float("nan"), *, axes=None):
    """Tip displacement during ring-up (um): the whole run with its envelope, and the last cycles.

    Parameters
    ----------
    res : fem.transient.TransientResult
    harmonic_amplitude : float
        Steady amplitude of the harmonic analysis (m), drawn as the target; omitted if not finite.
    axes : (Axes, Axes), optional
        Left (whole run) and right (last five cycles) panels.

    Returns
    -------
    (Axes, Axes)
    """
    a1, a2 = axes_or_new(axes, 2, side_by_side=True, figsize=(10, 4), dpi=120)
    surface = next(iter(res.surfaces))
    y = res.surfaces[surface]["axial"]
    step = max(1, len(y) // 20000)
    a1.plot(res.t[::step] * 1e3, y[::step] * 1e6, lw=0.3)
    tc, env = res.envelope(surface)
    a1.plot(tc * 1e3, env * 1e6, color="C1", lw=1.5, label="envelope")
    scale = harmonic_amplitude if np.isfinite(harmonic_amplitude) else res.steady_amplitude(surface)
    if np.isfinite(harmonic_amplitude):
        a1.axhline(harmonic_amplitude * 1e6, color="C3", ls="--", lw=1, label="harmonic amplitude")
    a1.set_xlabel("time (ms)")
    a1.set_ylabel("tip axial displacement (um)")
    a1.set_title(f"Ring-up at {res.freq_hz / 1e3:.3f} kHz, {res.v0:g} V")
    a1.legend(fontsize=8)
    last = res.t >= res.t[-1] - 5.0 / res.freq_hz
    a2.plot(res.t[last] * 1e3, y[last] * 1e6, lw=1.2, label="tip")
    a2.plot(res.t[last] * 1e3, res.voltage[last] / res.v0 * scale * 1e6, lw=1, ls=":",
            label="drive voltage (scaled)")
    a2.set_xlabel("time (ms)")
    a2.set_title(f"last cycles: steady {res.steady_amplitude(surface) * 1e6:.2f} um")
    a2.legend(fontsize=8)
    for ax in (a1, a2):
        ax.grid(alpha=0.3)
    return a1, a2
