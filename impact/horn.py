"""A modal horn: the transducer as a sum of damped oscillators under the harmonic drive.

The kinematic horn of the article (``u = A0 cos W t``, assumption 1) ignores the impacts. A
:class:`ModalHorn` is any transducer reduced to ``n`` modal oscillators (``fem.reduced`` builds
one from the FE model; ``impact`` never imports ``fem``)::

    m_i (q_i'' + 2 zeta_i omega_i q_i' + omega_i^2 q_i) = f_i(t),
    f_i(t) = V0 (Re(gamma_i) sin W t + Im(gamma_i) cos W t)       (drive V(t) = V0 sin W t)

with the horn-tip displacement (along the drill axis, toward the tool)::

    u(t) = sum_i s_i q_i(t) + r(t),   r(t) = V0 (Re(r) sin W t + Im(r) cos W t)

``s_i`` the tip participations (m per unit modal coordinate) and ``r`` the quasi-static residual
of everything not kept (m/V). Between impacts each ``q_i`` is the closed-form sum of its steady
harmonic response ``p_i = Re(q^_i e^{jWt})``, ``q^_i = F^_i / (m_i (omega_i^2 - W^2 + 2 j zeta_i
omega_i W))`` (``F^_i = V0 (Im gamma_i - j Re gamma_i)``), and a damped free oscillation
``h_i(s) = Re(C_i e^{mu_i s})``, ``mu_i = -zeta_i omega_i + j omega_i sqrt(1 - zeta_i^2)``. So ``u``,
``u'`` and ``u''`` are analytic and bounded by ``W^k |U^| + sum |s_i| |h_i^(k)|_max``
(``U^ = sum s_i q^_i + r^``), which keeps the guaranteed event search of the kernel.

A tip impulse ``J`` (N s, pushing the free mass toward the tool, the horn back) changes every
modal velocity by ``-s_i J / m_i``; the residual is a driven displacement that an impulse does not
change. The effective tip mass seen by an impact is ``1 / sum s_i^2 / m_i``.

Energy (per segment, closed form: :func:`segment_integrals`): the drive's work on the modes
``int sum f_i q_i' dt``, the modal damping loss ``int sum c_i q_i'^2 dt`` (``c_i = 2 zeta_i omega_i
m_i``) and the fundamental ``int u e^{-jWt} dt`` of the tip (the running amplitude).

Units: SI throughout (rad/s, kg, m, N/V, V, m/V, C/V).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from rpud_common import ParameterError, check_choice, check_range

__all__ = ["ModalHorn", "HORN_STARTS", "segment_integrals", "MAX_HORN_MODES"]

HORN_STARTS = ("rest", "steady")
MAX_HORN_MODES = 64

# columns of the packed per-mode table (ModalHorn.pack)
H_OMEGA, H_ZETA, H_MASS, H_TIP, H_A, H_B, H_FC, H_FS, H_GRE, H_GIM, H_JQ, H_JV = range(12)
N_HCOLS = 12
# packed scalars
X_W, X_UC, X_US, X_RC, X_RS, X_STEADY, X_V0, X_QBR, X_QBI, X_SERIES = range(10)
N_HX = 10

_ARRAYS = ("omega", "zeta", "modal_mass", "tip", "coupling_re", "coupling_im")


def _vec(name, v) -> np.ndarray:
    a = np.atleast_1d(np.asarray(v, dtype=float))
    if a.ndim != 1 or a.size == 0 or a.size > MAX_HORN_MODES:
        raise ParameterError(name, v, f"must be a 1-D array of 1 to {MAX_HORN_MODES} numbers")
    if not np.all(np.isfinite(a)):
        raise ParameterError(name, v, "must hold finite numbers")
    return a


@dataclass(frozen=True, eq=False)
class ModalHorn:
    """The horn as ``n`` damped modal oscillators driven by ``V(t) = voltage sin(W t)``.

    The drive frequency ``W / 2 pi`` is the impact model's ``ImpactParams.freq``.

    Attributes
    ----------
    omega : ndarray (n,)
        Natural angular frequencies, rad/s (> 0).
    zeta : ndarray (n,)
        Viscous damping ratios, in [0, 1) (under-damped modes).
    modal_mass : ndarray (n,)
        Modal masses (> 0; 1 for mass-normalised FE modes).
    tip : ndarray (n,)
        Tip displacement per unit modal coordinate, m (not all zero).
    coupling_re, coupling_im : ndarray (n,)
        Modal force per volt, in phase with ``V`` and with ``V' / W``, N/V.
    voltage : float
        Drive amplitude ``V0``, V (>= 0).
    residual_re, residual_im : float
        Quasi-static tip displacement per volt of the modes not kept, m/V.
    blocked_charge_re, blocked_charge_im : float
        Electrode charge per volt not carried by the kept modes (clamped capacitance,
        dielectric loss, truncated modes), C/V; used for the drive current only.
    start : {"rest", "steady"}
        Modal state at t = 0: at rest (ring-up with the drive switched on at t = 0) or on the
        steady harmonic response (no transient).
    series_resistance : float
        Source resistance in series with the electrodes, ohm; 0 (default): voltage drive (the
        electrode voltage is the source's). With R > 0 the electrode voltage is a state
        (:mod:`impact.drive`; ``coupling_im`` and the residual are then left out).
    """

    omega: np.ndarray
    zeta: np.ndarray
    modal_mass: np.ndarray
    tip: np.ndarray
    coupling_re: np.ndarray
    coupling_im: np.ndarray
    voltage: float
    residual_re: float = 0.0
    residual_im: float = 0.0
    blocked_charge_re: float = 0.0
    blocked_charge_im: float = 0.0
    start: str = "rest"
    series_resistance: float = 0.0

    def __post_init__(self):
        arrs = {}
        for name in _ARRAYS:
            arrs[name] = _vec(name, getattr(self, name))
            object.__setattr__(self, name, arrs[name])
        n = arrs["omega"].size
        for name in _ARRAYS:
            if arrs[name].size != n:
                raise ParameterError(name, f"{arrs[name].size} values",
                                     f"must have one value per mode ({n}, as omega)")
        if np.any(arrs["omega"] <= 0) or np.any(arrs["omega"] > 1e8):
            raise ParameterError("omega", self.omega, "must be in (0, 1e8] rad/s")
        if np.any(arrs["zeta"] < 0) or np.any(arrs["zeta"] >= 1):
            raise ParameterError("zeta", self.zeta, "must be in [0, 1) (under-damped modes)")
        if np.any(arrs["modal_mass"] <= 0):
            raise ParameterError("modal_mass", self.modal_mass, "must be > 0")
        if not np.any(arrs["tip"] != 0):
            raise ParameterError("tip", self.tip, "at least one mode must move the tip")
        check_range("voltage", self.voltage, 0.0, 1e5, "V")
        for name in ("residual_re", "residual_im", "blocked_charge_re", "blocked_charge_im"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float, np.floating)) and math.isfinite(v)):
                raise ParameterError(name, v, "must be a finite number")
        check_choice("start", self.start, HORN_STARTS)
        check_range("series_resistance", self.series_resistance, 0.0, 1e9, "ohm")

    # ------------------------------------------------------------------ derived
    @property
    def n_modes(self) -> int:
        return int(self.omega.size)

    @property
    def damping(self) -> np.ndarray:
        """Modal viscous damping ``c_i = 2 zeta_i omega_i m_i``."""
        return 2.0 * self.zeta * self.omega * self.modal_mass

    @property
    def tip_mass(self) -> float:
        """Effective mass of the tip under an impulse, ``1 / sum s_i^2 / m_i``, kg."""
        return float(1.0 / np.sum(self.tip ** 2 / self.modal_mass))

    def forcing(self) -> tuple[np.ndarray, np.ndarray]:
        """``(Fc, Fs)``: ``f_i(t) = Fc_i cos W t + Fs_i sin W t``, N."""
        return self.voltage * self.coupling_im, self.voltage * self.coupling_re

    def steady_modal(self, freq_hz: float) -> np.ndarray:
        """Complex steady modal amplitudes ``q^_i`` (``p_i = Re(q^_i e^{jWt})``)."""
        W = 2 * math.pi * freq_hz
        fc, fs = self.forcing()
        den = self.modal_mass * (self.omega ** 2 - W * W + 2j * self.zeta * self.omega * W)
        return (fc - 1j * fs) / den

    def residual_phasor(self) -> complex:
        """Complex tip residual ``Re(r^ e^{jWt})`` = ``V0 (Re r sin + Im r cos)``, m."""
        return complex(self.voltage * self.residual_im, -self.voltage * self.residual_re)

    def steady_tip(self, freq_hz: float) -> complex:
        """Complex steady tip displacement ``U^`` (``u = Re(U^ e^{jWt})``), m."""
        return complex(self.tip @ self.steady_modal(freq_hz)) + self.residual_phasor()

    def initial_state(self, freq_hz: float) -> tuple[np.ndarray, np.ndarray]:
        """Modal coordinates and velocities at t = 0 (``start``)."""
        if self.start == "rest":
            return np.zeros(self.n_modes), np.zeros(self.n_modes)
        q = self.steady_modal(freq_hz)
        W = 2 * math.pi * freq_hz
        return q.real.copy(), (1j * W * q).real.copy()

    def pack(self, freq_hz: float) -> tuple[np.ndarray, np.ndarray]:
        """``(table, scalars)`` for the compiled kernel: ``table`` (n, N_HCOLS) with columns
        ``H_*`` (omega, zeta, mass, tip, steady cos / sin coefficients a_i, b_i, force Fc, Fs, coupling
        per volt re / im, jumps of the coordinate and its velocity per unit impulse),
        ``scalars`` (N_HX,) with ``X_*`` (W, steady tip cos / sin coefficients, residual cos /
        sin coefficients, 1.0 if the start is steady, voltage, blocked charge per volt re / im)."""
        W = 2 * math.pi * freq_hz
        q = self.steady_modal(freq_hz)
        fc, fs = self.forcing()
        tab = np.empty((self.n_modes, N_HCOLS))
        tab[:, H_OMEGA], tab[:, H_ZETA], tab[:, H_MASS], tab[:, H_TIP] = (self.omega, self.zeta,
                                                                          self.modal_mass, self.tip)
        tab[:, H_A], tab[:, H_B] = q.real, -q.imag
        tab[:, H_FC], tab[:, H_FS] = fc, fs
        tab[:, H_GRE], tab[:, H_GIM] = self.coupling_re, self.coupling_im
        tab[:, H_JQ], tab[:, H_JV] = 0.0, -self.tip / self.modal_mass
        U = self.steady_tip(freq_hz)
        r = self.residual_phasor()
        x = np.array([W, U.real, -U.imag, r.real, -r.imag, 1.0 if self.start == "steady" else 0.0,
                      self.voltage, self.blocked_charge_re, self.blocked_charge_im, 0.0])
        return tab, x

    # ------------------------------------------------------------------ free response
    def free_response(self, freq_hz: float, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Tip displacement (m) and velocity (m/s) without impacts, closed form, at times ``t``."""
        t = np.asarray(t, dtype=float)
        W = 2 * math.pi * freq_hz
        q = self.steady_modal(freq_hz)
        q0, qd0 = self.initial_state(freq_hz)
        h0 = q0 - q.real
        hd0 = qd0 - (1j * W * q).real
        mu = -self.zeta * self.omega + 1j * self.omega * np.sqrt(1 - self.zeta ** 2)
        # h = Re(C e^{mu s}) with Re C = h0, Re(C mu) = hd0
        C = h0 - 1j * (hd0 - h0 * mu.real) / mu.imag
        e = np.exp(np.outer(t, mu))
        ew = np.exp(1j * W * t)
        U = self.steady_tip(freq_hz)
        u = (U * ew).real + (e * (C * self.tip)).real.sum(axis=1)
        ud = (1j * W * U * ew).real + (e * (C * mu * self.tip)).real.sum(axis=1)
        return u, ud

    def drive_current(self, freq_hz: float, t: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """Electrode current (A) from modal velocities ``qd`` and accelerations ``qdd`` (len(t), n):
        ``I = d/dt [sum (Re g_i q_i + Im g_i q_i' / W) + Re(Qb) V + Im(Qb) V' / W]``."""
        W = 2 * math.pi * freq_hz
        V = self.voltage * np.sin(W * t)
        Vd = self.voltage * W * np.cos(W * t)
        return (qd @ self.coupling_re + qdd @ self.coupling_im / W + self.blocked_charge_re * Vd
                - self.blocked_charge_im * W * V)

    # ------------------------------------------------------------------ plain data
    def to_dict(self) -> dict:
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            out[f.name] = v.tolist() if isinstance(v, np.ndarray) else v
        return out

    @classmethod
    def from_dict(cls, data: dict) -> "ModalHorn":
        return cls(**dict(data))

    def with_(self, **changes) -> "ModalHorn":
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        d.update(changes)
        return ModalHorn(**d)


# ----------------------------------------------------------------------------- integrals


def _expint(lam: np.ndarray, S: np.ndarray) -> np.ndarray:
    """``int_0^S exp(lam s) ds`` for complex lam (elementwise), without cancellation at small lam S."""
    lam = np.asarray(lam, dtype=complex)
    z = lam * S
    x, y = z.real, z.imag
    # expm1(x + jy) = expm1(x) cos y - 2 sin^2(y/2) + j e^x sin y
    em1 = np.expm1(x) * np.cos(y) - 2.0 * np.sin(0.5 * y) ** 2 + 1j * np.exp(x) * np.sin(y)
    small = np.abs(z) < 1e-6
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(small, S * (1 + z / 2 + z * z / 6), em1 / np.where(small, 1.0, lam))
    return out


def _pair(A, la, B, lb, S):
    """``int_0^S Re(A e^{la s}) Re(B e^{lb s}) ds``."""
    return 0.5 * (A * B * _expint(la + lb, S)).real + 0.5 * (A * np.conj(B) * _expint(la + np.conj(lb), S)).real


def segment_integrals(horn: ModalHorn, freq_hz: float, t0, q0, qd0, s_a, s_b) -> dict:
    """Closed-form integrals over parts ``[t0 + s_a, t0 + s_b]`` of free-evolution segments.

    Parameters
    ----------
    horn : ModalHorn
    freq_hz : float
        Drive frequency, Hz.
    t0 : ndarray (k,)
        Segment starts, s.
    q0, qd0 : ndarray (k, n)
        Modal coordinates and velocities at the segment starts.
    s_a, s_b : ndarray (k,)
        Integration limits relative to ``t0``, s (0 <= s_a <= s_b).

    Returns
    -------
    dict of ndarray (k,)
        ``drive_j``: work of the modal forces ``int sum f_i q_i'``, J; ``electric_j``: electrical
        energy drawn ``int V I dt`` (current of :meth:`ModalHorn.drive_current`), J; ``damping_j``: modal
        damping loss ``int sum c_i q_i'^2``, J; ``fundamental``: ``int u e^{-jWt} dt`` (complex,
        m s).
    """
    W = 2 * math.pi * freq_hz
    t0 = np.asarray(t0, float)[:, None]
    q0 = np.atleast_2d(q0)
    qd0 = np.atleast_2d(qd0)
    sa = np.asarray(s_a, float)[:, None]
    S = np.asarray(s_b, float)[:, None] - sa
    qs = horn.steady_modal(freq_hz)[None, :]
    fc, fs = horn.forcing()
    mu = (-horn.zeta * horn.omega + 1j * horn.omega * np.sqrt(1 - horn.zeta ** 2))[None, :]
    ew0 = np.exp(1j * W * t0)
    h0 = q0 - (qs * ew0).real
    hd0 = qd0 - (1j * W * qs * ew0).real
    C = h0 - 1j * (hd0 - h0 * mu.real) / mu.imag
    # shift the origin to t0 + s_a
    C = C * np.exp(mu * sa)
    ewa = np.exp(1j * W * (t0 + sa))
    jw = 1j * W
    G = jw * qs * ewa                 # steady velocity: Re(G e^{jWs})
    H = C * mu                        # transient velocity: Re(H e^{mu s})
    F = ((fc - 1j * fs)[None, :]) * ewa
    drive = _pair(F, jw, G, jw, S) + _pair(F, jw, H, mu, S)
    c = horn.damping[None, :]
    damp = c * (_pair(G, jw, G, jw, S) + 2 * _pair(G, jw, H, mu, S) + _pair(H, mu, H, mu, S))
    # electrical input int V I dt, I = sum (Re g_i q_i' + Im g_i q_i'' / W) + Re(Qb) V' - Im(Qb) W V
    Vc = -1j * horn.voltage * ewa
    vq1 = _pair(Vc, jw, G, jw, S) + _pair(Vc, jw, H, mu, S)
    vq2 = _pair(Vc, jw, jw * G, jw, S) + _pair(Vc, jw, mu * H, mu, S)
    elec = (horn.coupling_re[None, :] * vq1 + horn.coupling_im[None, :] / W * vq2).sum(axis=1)
    ta, tb = t0[:, 0] + sa[:, 0], t0[:, 0] + sa[:, 0] + S[:, 0]
    V0 = horn.voltage
    elec = elec + horn.blocked_charge_re * 0.5 * V0 ** 2 * (np.sin(W * tb) ** 2 - np.sin(W * ta) ** 2)
    elec = elec - horn.blocked_charge_im * W * V0 ** 2 * (0.5 * S[:, 0] - (np.sin(2 * W * tb) - np.sin(2 * W * ta)) / (4 * W))
    U = horn.steady_tip(freq_hz)
    # int Re(X e^{lam s}) e^{-jW s} ds = (X E(lam - jW) + conj(X) E(conj(lam) - jW)) / 2
    Uc = U * ewa[:, 0]
    fund = 0.5 * (Uc * S[:, 0] + np.conj(Uc) * _expint(-2j * W, S[:, 0]))
    Ct = C * horn.tip[None, :]
    fund = fund + 0.5 * (Ct * _expint(mu - jw, S) + np.conj(Ct) * _expint(np.conj(mu) - jw, S)).sum(axis=1)
    fund = fund * np.exp(-1j * W * (t0[:, 0] + sa[:, 0]))
    return {"drive_j": drive.sum(axis=1), "damping_j": damp.sum(axis=1), "fundamental": fund, "electric_j": elec}
