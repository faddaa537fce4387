"""A rigid mass striking a modal body through a Hertz contact: the compliant impact of a reduced model.

An instantaneous (Newton) impact on a modal model transfers momentum to the effective end mass
``1 / sum s_i^2 / m_i`` of the modes kept; that mass falls without limit as modes are added (every
mode adds ``s_i^2 / m_i``), so the answer never converges in the cut-off. A compliant contact has a
duration ``tau``; the modes far above ``1 / tau`` answer it quasi-statically, as a static
compliance in series with the contact. So a body reduced to its modes up to a cut-off plus the
static residual of the rest converges as the cut-off grows (``tests/test_rod_impact.py`` shows it
against the wave solution of a rod).

Model (x along the strike; the body's contact point ``u = sum s_i q_i + g F``, g the residual
compliance of the modes left out, m/N)::

    m w'' = -F + m a,       m_i (q_i'' + 2 zeta_i omega_i q_i' + omega_i^2 q_i) = s_i F,
    F = law(d, d_m),        d + g F = D := w - sum s_i q_i,

the Hertz approach ``d`` the root of that monotone scalar equation (:func:`approach_of`). The contact
phase is integrated (``scipy.integrate.solve_ivp``, DOP853) in branches of the law
(:class:`impact.hertz.HertzLaw`): loading until the total approach ``D`` stops growing (its
largest value fixes ``d_m``), unloading until ``D`` returns to ``D_m`` (reloading) or to the
zero (separation).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rpud_common import ParameterError, check_nonnegative, check_positive

from .hertz import HertzLaw

__all__ = ["ModalBody", "Strike", "strike", "approach_of"]


@dataclass(frozen=True, eq=False)
class ModalBody:
    """A linear body seen from one contact point: modes kept plus the static residual.

    Attributes
    ----------
    omega : ndarray (n,)
        Natural angular frequencies, rad/s (>= 0; 0 for a rigid-body mode).
    zeta : ndarray (n,)
        Viscous damping ratios, in [0, 1).
    modal_mass : ndarray (n,)
        Modal masses, kg (> 0).
    participation : ndarray (n,)
        Contact-point displacement along the strike per unit modal coordinate (the force enters
        mode i as ``s_i F``).
    residual : float
        Static compliance of the modes left out at the contact point, m/N (>= 0).
    """

    omega: np.ndarray
    zeta: np.ndarray
    modal_mass: np.ndarray
    participation: np.ndarray
    residual: float = 0.0

    def __post_init__(self):
        arrs = [np.atleast_1d(np.asarray(getattr(self, k), dtype=float)) for k in
                ("omega", "zeta", "modal_mass", "participation")]
        n = arrs[0].size
        for name, a in zip(("omega", "zeta", "modal_mass", "participation"), arrs):
            if a.ndim != 1 or a.size != n or n == 0 or not np.all(np.isfinite(a)):
                raise ParameterError(name, a, f"must be a 1-D array of {max(n, 1)} finite numbers (one per mode)")
            object.__setattr__(self, name, a)
        if np.any(self.omega < 0):
            raise ParameterError("omega", self.omega, "must be >= 0 rad/s")
        if np.any(self.zeta < 0) or np.any(self.zeta >= 1):
            raise ParameterError("zeta", self.zeta, "must lie in [0, 1)")
        if np.any(self.modal_mass <= 0):
            raise ParameterError("modal_mass", self.modal_mass, "must be > 0 kg")
        check_nonnegative("residual", self.residual, "m/N")

    @property
    def n_modes(self) -> int:
        return int(self.omega.size)

    @property
    def end_mass(self) -> float:
        """Effective mass of the contact point under an impulse, ``1 / sum s_i^2 / m_i``, kg."""
        return float(1.0 / np.sum(self.participation ** 2 / self.modal_mass))

    def energy(self, q: np.ndarray, qd: np.ndarray) -> float:
        """Modal kinetic + strain energy, J."""
        m = self.modal_mass
        return float(0.5 * np.sum(m * qd * qd + m * self.omega ** 2 * q * q))


def approach_of(total: float, c: float, p: float = 1.5) -> float:
    """The root ``x >= 0`` of ``x + c x^p = total`` (0 if ``total <= 0``), c >= 0, p >= 1.

    Newton from ``min(total, (total / c)^{1/p})``, which lies right of the root of this convex
    increasing function, so the iterates fall monotonically onto it. (The square root for the
    Hertz loading's p = 1.5: the compiled engine solves this in every slope of a contact.)"""
    if total <= 0.0:
        return 0.0
    if c <= 0.0:
        return total
    x = total
    if c * (math.sqrt(x) if p == 1.5 else x ** (p - 1.0)) > 1.0:
        x = (total / c) ** (1.0 / p)
    for _ in range(200):
        xp = math.sqrt(x) if p == 1.5 else x ** (p - 1.0)
        step = (x + c * xp * x - total) / (1.0 + p * c * xp)
        x -= step
        if step <= 4e-16 * x:
            break
    return max(x, 0.0)


@dataclass(frozen=True)
class Strike:
    """One compliant impact (from first touch to separation).

    Attributes
    ----------
    t : ndarray
        Times of the force samples, s (from first touch).
    force : ndarray
        Contact force at ``t``, N.
    duration : float
        Contact duration, s.
    rebound_velocity : float
        Striking mass's velocity at separation, m/s (negative: it bounces back).
    peak_force : float
        Largest contact force, N.
    q, qd : ndarray (n,)
        Body modal state at separation.
    dissipated : float
        Energy lost in the contact, J (the law's closed form).
    residual_energy : float
        ``0.5 g F^2`` at separation (0: the force is zero there), J.
    """

    t: np.ndarray
    force: np.ndarray
    duration: float
    rebound_velocity: float
    peak_force: float
    q: np.ndarray
    qd: np.ndarray
    dissipated: float
    residual_energy: float = 0.0


class _Phase:
    """The force law on one branch: ``F = K d^p`` (:meth:`impact.hertz.HertzLaw.branch`)."""

    def __init__(self, law: HertzLaw, d_max: float | None):
        self.K, self.p = law.branch(d_max)

    def force(self, total: float, g: float) -> float:
        return self.K * approach_of(total, g * self.K, self.p) ** self.p


def _rhs(body: ModalBody, mass: float, accel: float, phase: _Phase):
    n = body.n_modes
    s, m = body.participation, body.modal_mass
    c2, w2 = 2.0 * body.zeta * body.omega, body.omega ** 2
    g = float(body.residual)

    def f(t, y):
        q, qd = y[2:2 + n], y[2 + n:]
        F = phase.force(y[0] - float(s @ q), g)
        return np.concatenate(([y[1], accel - F / mass], qd, s * F / m - c2 * qd - w2 * q))

    return f


def strike(body: ModalBody, law: HertzLaw, mass: float, speed: float, *, accel: float = 0.0,
           q0: np.ndarray | None = None, qd0: np.ndarray | None = None, t_max: float | None = None,
           rtol: float = 1e-10, samples: int = 400) -> Strike:
    """A mass ``mass`` (kg) touching the body's contact point at ``speed`` (m/s, > 0 toward the body).

    Parameters
    ----------
    body : ModalBody
    law : impact.hertz.HertzLaw
    mass, speed : float
        Striking mass, kg, and its approach speed relative to the contact point at first touch, m/s.
    accel : float
        Constant acceleration of the striking mass along the strike, m/s^2.
    q0, qd0 : ndarray, optional
        Body modal state at first touch (default: at rest; the contact point's displacement at
        touch is the origin of the approach).
    t_max : float, optional
        Longest contact integrated, s (default: 50 elastic contact times of ``mass`` on a rigid flat).
    rtol : float
        Relative tolerance of the integration.
    samples : int
        Force samples per branch of the law.

    Returns
    -------
    Strike
    """
    from scipy.integrate import solve_ivp

    check_positive("mass", mass, "kg")
    check_positive("speed", speed, "m/s")
    n = body.n_modes
    s = body.participation
    q = np.zeros(n) if q0 is None else np.asarray(q0, float).copy()
    qd = np.zeros(n) if qd0 is None else np.asarray(qd0, float).copy()
    tau = law.contact_time(mass, speed)
    if t_max is not None:
        check_positive("t_max", t_max, "s")
    t_max = 50.0 * tau if t_max is None else float(t_max)
    base = float(s @ q)                          # the approach is measured from first touch
    y = np.concatenate(([base, float(speed + s @ qd)], q, qd))
    d_scale = (1.25 * mass * speed * speed / law.stiffness) ** 0.4
    atol = np.concatenate(([d_scale, speed], d_scale / np.maximum(np.abs(s), 1e-30 + 1e-12 * np.abs(s).max()) *
                           np.ones(n), speed / np.maximum(np.abs(s), 1e-30 + 1e-12 * np.abs(s).max()))) * rtol
    g = float(body.residual)
    t0, d_max, total_max = 0.0, None, None
    ts, fs = [], []

    def total(yy):
        return yy[0] - float(s @ yy[2:2 + n]) - base

    def rate(yy):
        return yy[1] - float(s @ yy[2 + n:])

    while True:
        phase = _Phase(law, d_max)
        if d_max is None:                    # loading: ends where the approach stops growing
            ev = [lambda t, yy: rate(yy)]
            ev[0].direction = -1
        else:                                # unloading: back to D_m (reload) or to 0 (separation)
            ev = [lambda t, yy: total(yy) - total_max, lambda t, yy: total(yy)]
            ev[0].direction, ev[1].direction = 1, -1
        for e in ev:
            e.terminal = True
        sol = solve_ivp(_rhs(body, mass, accel, phase), (t0, t_max), y, method="DOP853", rtol=rtol, atol=atol,
                        events=ev, dense_output=True, first_step=min(tau * 1e-4, 0.5 * (t_max - t0)))
        t1 = float(sol.t[-1])
        grid = np.linspace(t0, t1, samples)
        ts.append(grid)
        fs.append(np.array([phase.force(total(sol.sol(tt)), g) for tt in grid]))
        y = sol.y[:, -1]
        hit = [k for k, te in enumerate(sol.t_events) if te.size]
        if not hit or t1 >= t_max:
            raise ParameterError("t_max", t_max, "is shorter than the contact (it has not separated)")
        if d_max is None:
            total_max = total(y)
            d_max = approach_of(total_max, g * law.stiffness, 1.5)
        elif hit[0] == 0:
            d_max = None                     # reloading: Hertz again from the largest approach
        else:
            break
        t0 = t1
    t, F = np.concatenate(ts), np.concatenate(fs)
    return Strike(t=t, force=F, duration=t1, rebound_velocity=float(y[1]), peak_force=float(F.max()),
                  q=y[2:2 + n].copy(), qd=y[2 + n:].copy(), dissipated=law.dissipated(d_max))
