"""Transient ring-up: the transducer under a sinusoidal voltage switched on at t = 0.

The hot electrode gets ``V(t) = V0 sin(2 pi f t)`` for ``t >= 0`` (the body at rest before).
Losses are the hysteretic ones of the harmonic analysis (:class:`fem.harmonic.LossModel`),
converted to the equivalent viscous damping at the drive frequency, ``C = L / w_d``; at
``w_d`` this gives exactly the harmonic response, so the ring-up settles on the harmonic
amplitude.

Time integration: Newmark average acceleration (beta = 1/4, gamma = 1/2; unconditionally
stable, no numerical damping). Two implementations:

``direct``
    The full coupled system ``M x'' + C x' + K x = f(t)`` on the driven free set, with one
    factorisation of ``K + (2/dt) C + (4/dt^2) M`` and one solve per step. The massless
    potential unknowns are handled by the same step (their rows are the quasi-static Gauss
    law). Mechanical loss only: a dielectric loss tangent is a conductance in the time domain
    (``I = C V' + G V``), not a viscous term, and is left out here. Expensive; it is the
    reference the modal path is tested against.
``modal`` (default)
    Superposition on the short-circuit modes of :func:`fem.harmonic.modal_basis`:
    ``q_i'' + (eta_i lambda_i / w_d) q_i' + lambda_i q_i = Re(gamma_i) V + Im(gamma_i) V' / w_d``,
    (diagonal modal damping: the off-diagonal loss coupling that the harmonic analysis keeps is
    second order for the ring-up amplitude) plus the residual of the truncated modes responding
    quasi-statically,
    ``x_R(t) = Re(R) V(t) + Im(R) V'(t) / w_d``. Newmark average acceleration on a linear
    oscillator *is* the trapezoidal rule on its first-order form, i.e. the bilinear transform
    of its transfer function; each modal equation is therefore run as that digital filter
    (a biquad through ``scipy.signal.lfilter``), identical to stepping Newmark but in compiled
    code. With ``prewarp=True`` (default) each modal frequency is pre-warped,
    ``w_i' = (2/dt) tan(w_i dt / 2)``, which removes Newmark's period elongation
    (``(w dt)^2 / 12``, enough at high Q to detune a resonance); the drive is sampled as is.
    ``prewarp=False`` reproduces plain Newmark step for step (the equivalence test).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Iterable, Sequence

import numpy as np
import scipy.signal as signal

from rpud_common import ParameterError, check_positive
from rpud_common.result import Result

from .assembly import PiezoSystem
from .harmonic import COMPONENTS, LossModel, ModalBasis, loss_matrix, modal_basis, surface_functional
from .solvers import factorize

__all__ = ["TransientResult", "ring_up", "steady_amplitude"]

log = logging.getLogger(__name__)


@dataclass(eq=False, repr=False)
class TransientResult(Result):
    """Time histories of a ring-up.

    Attributes
    ----------
    t : (n,) s
    voltage : (n,) V, the applied hot-electrode voltage
    surfaces : dict name -> dict component -> (n,) mean displacement, m
    freq_hz, v0 : drive frequency (Hz) and amplitude (V)
    dt : time step, s
    method : "modal" or "direct"
    steady_amplitude_m : dict name -> axial steady amplitude (m), fitted over the last cycles
    timings : dict, s
    """

    t: np.ndarray
    voltage: np.ndarray
    surfaces: dict
    freq_hz: float
    v0: float
    dt: float
    method: str
    timings: dict = field(default_factory=dict)

    def _surface(self, surface: str | None) -> str:
        surface = next(iter(self.surfaces)) if surface is None else surface
        if surface not in self.surfaces:
            raise ParameterError("surface", surface, "not computed; computed: " + ", ".join(self.surfaces))
        return surface

    def steady_amplitude(self, surface: str | None = None, component: str = "axial", cycles: int = 10) -> float:
        """Amplitude (m) of a sine at the drive frequency fitted over the last ``cycles``
        (``surface``: the first one computed, by default ``horn_tip``)."""
        surface = self._surface(surface)
        return steady_amplitude(self.t, self.surfaces[surface][component], self.freq_hz, cycles)

    def envelope(self, surface: str | None = None, component: str = "axial") -> tuple[np.ndarray, np.ndarray]:
        """Per-cycle peak of the displacement modulus (m) and the cycle centre times (s) (``surface``: the
        first one computed, by default ``horn_tip``)."""
        y = self.surfaces[self._surface(surface)][component]
        n = max(int(round(1.0 / (self.freq_hz * self.dt))), 1)
        m = len(y) // n
        peaks = np.abs(y[: m * n]).reshape(m, n).max(axis=1)
        return self.t[: m * n].reshape(m, n).mean(axis=1), peaks

    def _headline(self) -> str:
        s = next(iter(self.surfaces))
        return (f"{self.method} ring-up at {self.freq_hz:.1f} Hz, {self.v0:g} V, {self.t[-1] * 1e3:.3g} ms: "
                f"steady {s} amplitude {self.steady_amplitude(s) * 1e6:.3g} um")

    def _arrays(self) -> dict:
        out = {"t_s": self.t, "voltage_v": self.voltage}
        for s, comps in self.surfaces.items():
            out.update({f"{s}_{c}_m": v for c, v in comps.items()})
        return out

    def _record(self) -> dict:
        first = self._surface(None)
        tc, env = self.envelope(first)
        return {"method": self.method, "freq_hz": self.freq_hz, "voltage_v": self.v0, "dt_s": self.dt,
                "n_steps": int(len(self.t) - 1), "t_end_s": float(self.t[-1]),
                "steady_amplitude_m": {s: self.steady_amplitude(s) for s in self.surfaces},
                "envelope": {"t_s": tc.tolist(), f"{first}_axial_m": env.tolist()},
                "timings": self.timings}


def steady_amplitude(t: np.ndarray, y: np.ndarray, freq_hz: float, cycles: int = 10) -> float:
    """Least-squares amplitude of ``a sin(wt) + b cos(wt) + c`` over the last ``cycles`` periods."""
    w = 2 * np.pi * freq_hz
    sel = t >= t[-1] - cycles / freq_hz
    A = np.column_stack([np.sin(w * t[sel]), np.cos(w * t[sel]), np.ones(sel.sum())])
    coef, *_ = np.linalg.lstsq(A, y[sel], rcond=None)
    return float(np.hypot(coef[0], coef[1]))


def _biquad(c: float, lam: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Bilinear transform of ``1 / (s^2 + c s + lam)`` with ``s = (2/dt)(z-1)/(z+1)``.

    Written out rather than through ``scipy.signal.bilinear``, whose normalisation drops the
    numerator as "badly conditioned" at MHz sampling rates.
    """
    k = 2.0 / dt
    a = np.array([k * k + c * k + lam, 2 * (lam - k * k), k * k - c * k + lam])
    return np.array([1.0, 2.0, 1.0]) / a[0], a / a[0]


def _drive(t: np.ndarray, freq_hz: float, v0: float) -> tuple[np.ndarray, np.ndarray]:
    w = 2 * np.pi * freq_hz
    return v0 * np.sin(w * t), v0 * w * np.cos(w * t) * (t > 0)


def _check(freq_hz, voltage, t_end, steps_per_cycle):
    check_positive("freq", freq_hz, "Hz")
    check_positive("voltage", voltage, "V")
    check_positive("t_end", t_end, "s")
    if not isinstance(steps_per_cycle, (int, np.integer)) or steps_per_cycle < 8:
        raise ParameterError("steps_per_cycle", steps_per_cycle, "must be an integer >= 8")
    n = int(np.ceil(t_end * freq_hz * steps_per_cycle))
    if n > 20_000_000:
        raise ParameterError("t_end", t_end, f"needs {n} steps; at most 2e7 (shorten t_end)")
    return n


def ring_up(system: PiezoSystem, freq_hz: float, voltage: float, t_end: float, *,
            clamp: Iterable[str] = (), loss: LossModel = LossModel(),
            surfaces: Sequence[str] = ("horn_tip",), method: str = "modal",
            basis: ModalBasis | None = None, n_modes: int = 12, steps_per_cycle: int = 200,
            prewarp: bool = True, backend: str | None = None) -> TransientResult:
    """Integrate the ring-up under ``V(t) = voltage * sin(2 pi freq_hz t)``.

    Parameters
    ----------
    system : PiezoSystem
    freq_hz : drive frequency, Hz
    voltage : drive amplitude, V
    t_end : duration, s
    clamp, loss, surfaces : as in :func:`fem.harmonic.harmonic_sweep`
    method : "modal" (default) or "direct"
    basis : a :class:`fem.harmonic.ModalBasis` to reuse (modal method)
    steps_per_cycle : time steps per drive period (dt = 1 / (f * steps_per_cycle))
    prewarp : pre-warp the modal frequencies (modal method; see the module docstring)
    """
    t0 = time.perf_counter()
    n = _check(freq_hz, voltage, t_end, steps_per_cycle)
    clamp = (clamp,) if isinstance(clamp, str) else tuple(clamp)
    dt = 1.0 / (freq_hz * steps_per_cycle)
    t = np.arange(n + 1) * dt
    V, Vdot = _drive(t, freq_hz, voltage)
    wd = 2 * np.pi * freq_hz
    funcs = [surface_functional(system, s) for s in surfaces]
    out = {}
    if method == "modal":
        if basis is None:
            basis = modal_basis(system, freq_hz, n_modes, clamp=clamp, loss=loss, backend=backend)
        elif basis.loss != loss or basis.clamp != clamp:
            raise ParameterError("basis", "mismatch", "was built for another loss model or clamp")
        free = basis.free
        lam = basis.lam
        if prewarp:
            lam = ((2 / dt) * np.tan(np.sqrt(lam) * dt / 2)) ** 2
        c = basis.eta * basis.lam / wd
        Q = np.empty((len(lam), n + 1))
        for i in range(len(lam)):
            force = basis.gamma[i].real * V + basis.gamma[i].imag * Vdot / wd
            bz, az = _biquad(c[i], lam[i], dt)
            Q[i] = signal.lfilter(bz, az, force)
        full = np.zeros((system.ndof, len(lam) + 2))
        full[free, :-2] = basis.Phi
        full[free, -2] = basis.R.real
        full[free, -1] = basis.R.imag
        coef = np.vstack([Q, V, Vdot / wd])
        for s in funcs:
            rows = s.rows @ full                      # (3, n_modes + 2)
            vals = rows @ coef
            out[s.name] = {comp: vals[k] for k, comp in enumerate(COMPONENTS)}
    elif method == "direct":
        split = system.split(clamp)
        free = split.free
        # mechanical loss only: a dielectric loss tangent is a conductance (I = G V) in the
        # time domain; written as a viscous term on the (negative) potential block it would be
        # anti-damped. The modal path keeps it per mode, where it is a positive modal damping.
        mech = LossModel(loss.q_mech, 0.0)
        Lfull = loss_matrix(system, mech)
        C = (Lfull[free][:, free] / wd).tocsr()
        lh = np.asarray(Lfull[:, [system.hot_dof]].toarray()).ravel()[free]
        a0, a1 = 4 / dt ** 2, 2 / dt
        F = factorize((split.K + a1 * C + a0 * split.M).tocsr(), backend=backend)
        nf = len(free)
        x = np.zeros(nf)
        v = np.zeros(nf)
        a = np.zeros(nf)
        rows = [s.rows[:, free] for s in funcs]
        hist = [np.zeros((3, n + 1)) for _ in funcs]
        kh = split.k_hot / system.phi_scale
        lh = lh / system.phi_scale
        for k in range(1, n + 1):
            f = -(kh * V[k] + lh * Vdot[k] / wd)
            rhs = f + split.M @ (a0 * x + (4 / dt) * v + a) + C @ (a1 * x + v)
            xn = F(rhs)
            an = a0 * (xn - x) - (4 / dt) * v - a
            v = v + (dt / 2) * (a + an)
            x, a = xn, an
            for h, r in zip(hist, rows):
                h[:, k] = r @ x
        for s, h in zip(funcs, hist):
            out[s.name] = {comp: h[k] for k, comp in enumerate(COMPONENTS)}
    else:
        raise ParameterError("method", method, "must be 'modal' or 'direct'")
    timings = {"transient_s": time.perf_counter() - t0}
    log.info("ring-up: %s, %d steps of %.3g s, %.2f s", method, n, dt, timings["transient_s"])
    return TransientResult(t, V, out, float(freq_hz), float(voltage), dt, method, timings)
