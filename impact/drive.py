"""A drive source with series resistance: the modal horn's electrical port as a state.

With ``ModalHorn.series_resistance = R > 0`` the source ``V_s(t) = V0 sin W t`` drives the electrodes
through ``R``; the electrode voltage ``V_p`` is not imposed (as it is with ``R = 0``) but follows the charge::

    m_i (q_i'' + 2 zeta_i omega_i q_i' + omega_i^2 q_i) = theta_i V_p
    C0 V_p' = i - G V_p - sum theta_i q_i',       i = (V_s - V_p) / R

``theta_i`` the modal coupling (``coupling_re``: force per volt = charge per unit coordinate),
``C0 = blocked_charge_re`` the clamped capacitance and ``G = -W blocked_charge_im`` the dielectric
conductance at the drive. The frequency-domain loss parts of the voltage drive (``coupling_im``,
the quasi-static tip ``residual``) have no time-domain counterpart here and are left out: keep
more modes instead (their size is logged).

The state ``x = (q, q', V_p)`` (``N = 2n + 1``) obeys ``x' = A x + b V_s``. ``A`` has ``n`` complex
pairs ``lambda_k`` (the damped, electrically loaded modes) and one real pole (the ``R C0`` charging
of the electrodes). Each pair is written as one *pseudo-mode* ``y_k = Re(zhat_k)``, ``zhat_k`` its
eigen-coordinate turned so that the tip contribution is ``s_k y_k`` (``s_k >= 0``); the real pole
is a pseudo-mode ``y_r = z_r``. Between events every pseudo-mode is the steady harmonic part plus a
free ``Re(C_k e^{lambda_k s})``: the damped-oscillator closed forms of the compiled kernel
(``omega = |lambda|``, ``zeta = -Re lambda / |lambda|``; the real pole as an over-damped record with
roots ``lambda_r`` and ``4 lambda_r`` whose fast root is never excited). A tip impulse changes the
physical velocities ``q_i'`` by ``-s_i J / m_i``; in pseudo coordinates it is a jump of both ``y_k``
and ``y_k'`` (``jq``, ``jv`` per unit impulse), the physical tip position staying continuous.

Energies (closed form per segment, :func:`impact.kernel_energy.segment_energy_series`): every rate is a
quadratic form of ``(x, V_s)``: the source's work ``V_s i``, the resistor and dielectric loss ``R i^2
+ G V_p^2``, the conversion to mechanics ``V_p sum theta_i q_i'`` and the modal damping ``sum c_i
q_i'^2``; with the stored ``1/2 C0 V_p^2`` and the modal energy they close the balance.

Units: SI (rad/s, kg, m, N/V, V, ohm, F, S).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from rpud_common import ParameterError

log = logging.getLogger(__name__)

__all__ = ["SeriesModel", "series_model", "physical_states", "Q_SOURCE", "Q_LOSS", "Q_CONVERT", "Q_DAMP"]

#: rows of the quadratic-form tables: source work, resistor + dielectric loss, conversion, modal damping
Q_SOURCE, Q_LOSS, Q_CONVERT, Q_DAMP = range(4)

#: the real pole's record is over-damped with its second root this many times faster (never excited)
FAST_ROOT_RATIO = 4.0


@dataclass(frozen=True, eq=False)
class SeriesModel:
    """The modal horn with a series-resistance source, in pseudo-modal form (see the module docstring).

    Attributes
    ----------
    A : ndarray (N, N)
        State matrix of ``x = (q, q', V_p)``, SI.
    b : ndarray (N,)
        Input of the source voltage (``x' = A x + b V_s``): ``1 / (R C0)`` in the V_p row, 1/s.
    lam : ndarray (M,) complex
        Pseudo-mode eigenvalues (``n`` pairs with Im > 0, then the real pole), 1/s.
    tip : ndarray (M,)
        Tip displacement per unit pseudo coordinate, m.
    modes : ndarray (M, N) complex
        Physical free state ``x = Re(sum_k zhat_k modes_k)``.
    steady : ndarray (M,) complex
        Steady pseudo coordinates ``y_k = Re(steady_k e^{jWt})``.
    X : ndarray (N,) complex
        Steady physical state ``x = Re(X e^{jWt})``.
    jq, jv : ndarray (M,)
        Jumps of ``y_k`` and ``y_k'`` per unit impulse on the free mass, per N s.
    C0, G, R : float
        Clamped capacitance (F), dielectric conductance (S), series resistance (ohm).
    freq_hz : float
        Drive frequency, Hz.
    n : int
        Number of modes (``N = 2n + 1``, ``M = n + 1``).
    """

    A: np.ndarray
    b: np.ndarray
    lam: np.ndarray
    tip: np.ndarray
    modes: np.ndarray
    steady: np.ndarray
    X: np.ndarray
    jq: np.ndarray
    jv: np.ndarray
    C0: float
    G: float
    R: float
    freq_hz: float
    n: int

    @property
    def n_pseudo(self) -> int:
        return int(self.lam.size)

    def quadratic_forms(self, horn) -> np.ndarray:
        """``Q`` (4, N + 1, N + 1): the energy rates as ``xt^T Q xt`` of ``xt = (x, V_s)``."""
        n, N = self.n, self.A.shape[0]
        vp, vs = N - 1, N
        Q = np.zeros((4, N + 1, N + 1))
        Q[Q_SOURCE, vs, vs] = 1.0 / self.R
        Q[Q_SOURCE, vs, vp] = Q[Q_SOURCE, vp, vs] = -0.5 / self.R
        Q[Q_LOSS, vs, vs] = 1.0 / self.R
        Q[Q_LOSS, vp, vp] = 1.0 / self.R + self.G
        Q[Q_LOSS, vs, vp] = Q[Q_LOSS, vp, vs] = -1.0 / self.R
        Q[Q_CONVERT, vp, n:2 * n] = Q[Q_CONVERT, n:2 * n, vp] = 0.5 * horn.coupling_re
        Q[Q_DAMP, np.arange(n, 2 * n), np.arange(n, 2 * n)] = horn.damping
        return Q

    def kernel_tables(self, horn) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(lam, G1, G2)`` for the kernel's closed-form energy integrals: ``lam`` (M + 1,) with the
        drive ``jW`` last; ``G1[a, j, l] = w_j^T Q_a w_l``, ``G2[a, j, l] = w_j^T Q_a conj(w_l)`` over the
        augmented vectors ``w`` (pseudo-modes, then the steady state with the source phasor)."""
        W = 2 * math.pi * self.freq_hz
        M, N = self.n_pseudo, self.A.shape[0]
        w = np.zeros((M + 1, N + 1), complex)
        w[:M, :N] = self.modes
        w[M, :N] = self.X
        w[M, N] = -1j * horn.voltage
        Q = self.quadratic_forms(horn)
        G1 = np.einsum("jp,apq,lq->ajl", w, Q, w)
        G2 = np.einsum("jp,apq,lq->ajl", w, Q, np.conj(w))
        lam = np.append(self.lam, 1j * W)
        return lam, np.ascontiguousarray(G1), np.ascontiguousarray(G2)

    def unloaded(self, horn) -> dict:
        """Steady operation without impacts: tip amplitude (m), electrode voltage amplitude (V), mean
        source power (W) and RMS source current (A)."""
        n = self.n
        vs = -1j * horn.voltage
        i = (vs - self.X[2 * n]) / self.R
        return {"tip_amplitude_m": float(abs(horn.tip @ self.X[:n])), "electrode_voltage_v": float(abs(self.X[2 * n])),
                "source_power_w": float(0.5 * (vs * np.conj(i)).real), "source_current_rms_a": float(abs(i) / math.sqrt(2))}

    def modal_energy(self, horn, x: np.ndarray) -> np.ndarray:
        """Modal kinetic + strain energy of physical states (k, N), J."""
        n = self.n
        q, qd = x[..., :n], x[..., n:2 * n]
        m = horn.modal_mass
        return 0.5 * (m * qd ** 2 + m * horn.omega ** 2 * q ** 2).sum(axis=-1)


def _check_losses(horn, W: float) -> tuple[float, float]:
    C0 = float(horn.blocked_charge_re)
    G = float(-W * horn.blocked_charge_im)
    if not C0 > 0:
        raise ParameterError("blocked_charge_re", C0, "must be > 0 (the clamped capacitance, F/V) with a series "
                             "resistance: the electrode voltage is then a state")
    if G < 0:
        raise ParameterError("blocked_charge_im", horn.blocked_charge_im, "must be <= 0 with a series resistance "
                             "(a dielectric loss; > 0 would be a gain)")
    return C0, G


def series_model(horn, freq_hz: float) -> SeriesModel:
    """Build the pseudo-modal form of a :class:`impact.horn.ModalHorn` with ``series_resistance > 0``.

    Raises
    ------
    ParameterError
        No clamped capacitance, a dielectric gain, or a resistance that makes a mechanical mode
        over-damped (the pseudo-modes need ``n`` complex pairs and one real pole).
    """
    R = float(horn.series_resistance)
    if not R > 0:
        raise ParameterError("series_resistance", R, "must be > 0 for a series-resistance drive")
    W = 2 * math.pi * freq_hz
    C0, G = _check_losses(horn, W)
    n = horn.n_modes
    N = 2 * n + 1
    th, m = horn.coupling_re, horn.modal_mass
    A = np.zeros((N, N))
    A[:n, n:2 * n] = np.eye(n)
    A[n:2 * n, :n] = -np.diag(horn.omega ** 2)
    A[n:2 * n, n:2 * n] = -np.diag(2 * horn.zeta * horn.omega)
    A[n:2 * n, 2 * n] = th / m
    A[2 * n, n:2 * n] = -th / C0
    A[2 * n, 2 * n] = -(1.0 / R + G) / C0
    b = np.zeros(N)
    b[2 * n] = 1.0 / (R * C0)

    ev, V = np.linalg.eig(A)
    scale = np.max(np.abs(ev))
    cplx = np.flatnonzero(ev.imag > 1e-9 * scale)
    real = np.flatnonzero(np.abs(ev.imag) <= 1e-9 * scale)
    if cplx.size != n or real.size != 1:
        raise ParameterError("series_resistance", R, f"makes {n - cplx.size} mechanical mode(s) over-damped "
                             "(the pseudo-modal form needs every mode under-damped); choose another resistance")
    cplx = cplx[np.argsort(ev[cplx].imag)]
    U = np.linalg.inv(V)
    c = np.zeros(N)
    c[:n] = horn.tip
    BJ = np.zeros(N)
    BJ[n:2 * n] = -horn.tip / m
    dz = U @ BJ
    X = np.linalg.solve(1j * W * np.eye(N) - A, b * (-1j * horn.voltage))

    M = n + 1
    lam = np.empty(M, complex)
    tip = np.empty(M)
    modes = np.empty((M, N), complex)
    steady = np.empty(M, complex)
    jq, jv = np.empty(M), np.empty(M)
    kap = np.array([c @ V[:, p] for p in cplx])
    kmax = float(np.max(np.abs(kap))) if kap.size else 0.0
    for k, p in enumerate(cplx):
        ka = kap[k]
        phi = ka / abs(ka) if abs(ka) > 1e-12 * kmax else 1.0 + 0j
        lam[k] = ev[p]
        tip[k] = 2.0 * abs(ka) if abs(ka) > 1e-12 * kmax else 0.0
        modes[k] = 2.0 * V[:, p] / phi
        u = phi * U[p]
        steady[k] = 0.5 * (u @ X) + 0.5 * np.conj(u @ np.conj(X))
        d = phi * dz[p]
        jq[k], jv[k] = d.real, (ev[p] * d).real
    r = real[0]
    vr = V[:, r].real
    ur = U[r].real
    # the real pole's right and left vectors are real (a real eigenvalue of a real matrix), ur . vr = 1
    lam[n] = ev[r].real
    tip[n] = float(c @ vr)
    modes[n] = vr
    steady[n] = ur @ X
    jq[n] = float(ur @ BJ)
    jv[n] = lam[n].real * jq[n]
    left = abs(horn.residual_phasor()) + horn.voltage * np.sum(np.abs(horn.tip * horn.coupling_im)
                                                            / np.abs(horn.modal_mass * horn.omega ** 2))
    log.info("series drive R = %g ohm, RC0 = %.3g s: left out of the voltage drive's model the residual and the "
             "loss coupling, up to %.2g of the steady tip amplitude (keep more modes to reduce it)", R, R * C0,
             left / max(abs(complex(tip @ steady)), 1e-300))
    return SeriesModel(A=A, b=b, lam=lam, tip=tip, modes=modes, steady=steady, X=X, jq=jq, jv=jv, C0=C0, G=G, R=R,
                       freq_hz=float(freq_hz), n=n)


def pack_series(horn, model: SeriesModel):
    """The kernel's per-row table and scalars for the pseudo-modes (see :meth:`ModalHorn.pack`)."""
    from .horn import (H_A, H_B, H_JQ, H_JV, H_MASS, H_OMEGA, H_TIP, H_ZETA, N_HCOLS, N_HX, X_SERIES, X_STEADY, X_UC,
                       X_US, X_V0, X_W)

    M = model.n_pseudo
    n = model.n
    W = 2 * math.pi * model.freq_hz
    tab = np.zeros((M, N_HCOLS))
    om = np.abs(model.lam[:n])
    tab[:n, H_OMEGA] = om
    tab[:n, H_ZETA] = -model.lam[:n].real / om
    lr = abs(model.lam[n].real)
    # over-damped record with roots -lr and -FAST_ROOT_RATIO lr: omega^2 = ratio lr^2, 2 zeta omega = (1 + ratio) lr
    om_r = math.sqrt(FAST_ROOT_RATIO) * lr
    tab[n, H_OMEGA] = om_r
    tab[n, H_ZETA] = (1.0 + FAST_ROOT_RATIO) * lr / (2.0 * om_r)
    tab[:, H_MASS] = 1.0
    tab[:, H_TIP] = model.tip
    tab[:, H_A], tab[:, H_B] = model.steady.real, -model.steady.imag
    tab[:, H_JQ], tab[:, H_JV] = model.jq, model.jv
    U = complex(model.tip @ model.steady)
    xs = np.zeros(N_HX)
    xs[X_W], xs[X_UC], xs[X_US] = W, U.real, -U.imag
    xs[X_STEADY] = 1.0 if horn.start == "steady" else 0.0
    xs[X_V0] = horn.voltage
    xs[X_SERIES] = 1.0
    return tab, xs


def initial_pseudo(model: SeriesModel, start: str) -> tuple[np.ndarray, np.ndarray]:
    """Pseudo coordinates and velocities at t = 0: at rest, or on the steady response."""
    W = 2 * math.pi * model.freq_hz
    if start == "steady":
        return model.steady.real.copy(), (1j * W * model.steady).real.copy()
    return np.zeros(model.n_pseudo), np.zeros(model.n_pseudo)


def _free_coefficients(model: SeriesModel, t0, y0, yd0):
    """Complex amplitudes ``C`` (k, M) of the free pseudo parts at segment starts ``t0`` (k,)."""
    W = 2 * math.pi * model.freq_hz
    e0 = np.exp(1j * W * np.asarray(t0, float))[:, None]
    h0 = y0 - (model.steady[None, :] * e0).real
    hd0 = yd0 - (1j * W * model.steady[None, :] * e0).real
    lam = model.lam[None, :]
    C = h0.astype(complex)
    pair = np.abs(model.lam.imag) > 0
    C[:, pair] = h0[:, pair] - 1j * (hd0[:, pair] - h0[:, pair] * lam.real[:, pair]) / lam.imag[:, pair]
    return C


def physical_states(model: SeriesModel, seg_t0, seg_y, seg_yd, t, order: int = 1):
    """Physical state ``x = (q, q', V_p)`` and its derivatives up to ``order`` at sorted times ``t``.

    Parameters
    ----------
    model : SeriesModel
    seg_t0 : ndarray (k,)
        Segment starts, s; ``seg_y``, ``seg_yd`` (k, M) the pseudo coordinates there.
    t : ndarray (p,)
        Times, s (>= seg_t0[0]).
    order : int
        Highest time derivative returned.

    Returns
    -------
    list of ndarray (p, N)
        ``[x, x', ...]``.
    """
    t = np.asarray(t, float)
    W = 2 * math.pi * model.freq_hz
    idx = np.searchsorted(seg_t0, t, side="right") - 1
    idx = np.clip(idx, 0, len(seg_t0) - 1)
    C = _free_coefficients(model, np.asarray(seg_t0)[idx], np.asarray(seg_y)[idx], np.asarray(seg_yd)[idx])
    es = C * np.exp(model.lam[None, :] * (t - np.asarray(seg_t0)[idx])[:, None])
    ew = np.exp(1j * W * t)[:, None]
    out = []
    for k in range(order + 1):
        lk = model.lam ** k
        out.append((ew * (1j * W) ** k * model.X[None, :]).real + ((es * lk[None, :]) @ model.modes).real)
    return out
