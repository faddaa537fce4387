"""Compliant horn contact: Hertz stiffness with Hunt-Crossley damping (an option of the coupled model).

Newton's law makes a horn impact instantaneous. A steel free mass of a few grams on a titanium
tip touches for tens of microseconds (Hertz: 45 us for 8 g at 1 m/s), comparable to the 50 us
drive period, so during the contact the tip moves on and the modes feel the force. The option
replaces the horn impact by a contact phase with the force on the free mass (penetration
``d = u - w >= 0``, approach speed at first touch ``v_in``)::

    F = k d^{3/2} (1 + chi d' / v_in),     F >= 0 (clipped)

(Hunt & Crossley 1975: damping proportional to the elastic force and to the penetration rate),
with ``k = (4/3) E* sqrt(R)`` (Hertz, sphere on a flat: R the free mass's contact radius,
``1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2``).

Mapping e <-> chi. Scaled by ``L = (m v_in^2 / k)^{2/5}`` and ``T = L / v_in``, an impact on a
rigid wall is ``X'' = -X^{3/2} (1 + chi X')``, ``X(0) = 0``, ``X'(0) = 1``: the coefficient of
restitution ``e = -X'(end)`` depends on chi alone (not on k, m or v_in). :func:`chi_for_restitution`
inverts it numerically (DOP853, rtol 1e-12, Brent), so the compliant contact reproduces Newton's
law with the same e2 in the limit k -> inf (its duration ~ k^{-2/5} -> 0). For small chi,
``1 - e = (2/3) chi + O(chi^2)`` (Hunt & Crossley's own estimate); the approximate closed forms
in the literature (e.g. ``chi = 8 (1 - e) / (5 e)``) are not used.

The contact phase is integrated numerically (``scipy.integrate.solve_ivp``, DOP853, rtol 1e-11)
on the free mass and the modes; it ends where the penetration returns to zero. This is the one
time-stepped part of the coupled model, and it runs in the Python reference engine only
(``simulate_coupled(..., engine="python", contact=...)``).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from rpud_common import ParameterError, check_positive, check_range

__all__ = ["HuntCrossley", "chi_for_restitution", "restitution_of", "hertz_stiffness", "hertz_contact_time"]


def hertz_stiffness(E1: float, nu1: float, E2: float, nu2: float, radius: float) -> float:
    """Hertz contact stiffness ``k = (4/3) E* sqrt(R)`` of a sphere of radius R on a flat, N/m^1.5
    (:func:`impact.hertz.hertz_stiffness` of a crowned face).

    Parameters
    ----------
    E1, nu1, E2, nu2 : float
        Young's moduli (Pa) and Poisson ratios of the two bodies.
    radius : float
        Sphere radius, m.
    """
    from .hertz import ContactGeometry, effective_modulus, hertz_stiffness as stiffness

    check_positive("radius", radius, "m")
    return stiffness(effective_modulus(E1, nu1, E2, nu2), ContactGeometry.crowned(radius))


def hertz_contact_time(mass: float, k: float, v_in: float) -> float:
    """Duration of an elastic Hertz impact (force ``k d^{3/2}``) of a mass on a rigid flat, s:
    ``t = 2 (5/4)^{2/5} (2 sqrt(pi) / 5) Gamma(2/5) / Gamma(9/10) (m^2 / (k^2 v))^{1/5}``
    (~= 3.218 (m^2/(k^2 v))^{1/5}; the energy integral of ``m d'' = -k d^{3/2}``)."""
    check_positive("mass", mass, "kg")
    check_positive("k", k, "N/m^1.5")
    check_positive("v_in", v_in, "m/s")
    c = 2.0 * 1.25 ** 0.4 * (2.0 * math.sqrt(math.pi) / 5.0) * math.gamma(0.4) / math.gamma(0.9)
    return c * (mass * mass / (k * k * v_in)) ** 0.2


def restitution_of(chi: float) -> float:
    """Coefficient of restitution of the scaled Hunt-Crossley impact with damping ``chi`` (>= 0)."""
    from scipy.integrate import solve_ivp

    if chi == 0.0:
        return 1.0

    def rhs(t, y):
        x = max(y[0], 0.0)
        f = x ** 1.5 * (1.0 + chi * y[1])
        return [y[1], -max(f, 0.0)]

    def out(t, y):
        return y[0]

    out.terminal, out.direction = True, -1
    sol = solve_ivp(rhs, (0.0, 50.0), [0.0, 1.0], method="DOP853", rtol=1e-12, atol=1e-14, events=out,
                    first_step=1e-6)
    if not sol.t_events[0].size:
        return 0.0           # never separates within the horizon: a plastic contact
    return float(-sol.y_events[0][0][1])


@functools.lru_cache(maxsize=64)
def chi_for_restitution(e: float) -> float:
    """The Hunt-Crossley damping ``chi`` whose scaled impact has restitution ``e`` (0 < e <= 1)."""
    from scipy.optimize import brentq

    check_range("e", e, 0.0, 1.0, lo_open=True)
    if e == 1.0:
        return 0.0
    hi = 1.0
    while restitution_of(hi) > e:
        hi *= 2.0
        if hi > 1e4:
            raise ParameterError("e", e, "too small for a Hunt-Crossley contact (chi > 1e4)")
    return float(brentq(lambda c: restitution_of(c) - e, 0.0, hi, xtol=1e-13, rtol=1e-13))


@dataclass(frozen=True)
class HuntCrossley:
    """Compliant horn contact (see the module docstring).

    Attributes
    ----------
    stiffness : float
        Hertz stiffness k, N/m^1.5 (:func:`hertz_stiffness`).
    restitution : float
        Coefficient of restitution the damping reproduces, in (0, 1] (the Newton law's e2).
    """

    stiffness: float
    restitution: float

    def __post_init__(self):
        check_range("stiffness", self.stiffness, 1e3, 1e20, "N/m^1.5")
        check_range("restitution", self.restitution, 0.0, 1.0, lo_open=True)

    @property
    def chi(self) -> float:
        return chi_for_restitution(float(self.restitution))

    def force(self, d: float, dd: float, v_in: float) -> float:
        """Contact force (N) at penetration d (m), penetration rate dd (m/s), first-touch speed v_in."""
        if d <= 0.0:
            return 0.0
        return max(self.stiffness * d ** 1.5 * (1.0 + self.chi * dd / v_in), 0.0)


def contact_phase(hc: HuntCrossley, horn_tab: dict, t0: float, w: float, wd: float, q: np.ndarray, qd: np.ndarray,
                  m_free: float, a: float, W: float, rc: float, rs: float, t_max: float):
    """Integrate one horn contact from first touch at t0 (free mass w, w'; modes q, q').

    Returns ``(t1, w1, wd1, q1, qd1, impulse, dissipated)`` at separation (penetration back to 0),
    or the state at ``t_max`` if the contact lasts beyond it (``t1 = t_max``). ``impulse`` is the
    contact force's impulse on the free mass (N s), ``dissipated`` the energy lost in the contact
    (J: the Hunt-Crossley damping's work while the force pushes, the unloading spring's energy
    where the damping would pull and the force is clipped to 0)."""
    from scipy.integrate import solve_ivp

    n = q.size
    om, ze, m, s = horn_tab["omega"], horn_tab["zeta"], horn_tab["mass"], horn_tab["tip"]
    fc, fs = horn_tab["fc"], horn_tab["fs"]
    k = hc.stiffness
    chi = hc.chi
    ud0 = float(s @ qd + W * (-rc * math.sin(W * t0) + rs * math.cos(W * t0)))
    v_in = ud0 - wd
    if v_in <= 0.0:
        raise ValueError("contact_phase needs an approaching free mass")
    c2 = 2.0 * ze * om

    def pen(t, y):
        c, sn = math.cos(W * t), math.sin(W * t)
        u = float(s @ y[2:2 + n]) + rc * c + rs * sn
        ud = float(s @ y[2 + n:2 + 2 * n]) + W * (-rc * sn + rs * c)
        return u - y[0], ud - y[1]

    def rhs(t, y):
        d, dd = pen(t, y)
        F = k * d ** 1.5 * (1.0 + chi * dd / v_in) if d > 0.0 else 0.0
        # F on the free mass; F d' (the power into the contact) less the elastic energy's rate
        # k d^1.5 d' is lost: k chi d^1.5 d'^2 / v_in, or -k d^1.5 d' where F is clipped to 0
        lost = (k * chi * d ** 1.5 * dd * dd / v_in if F >= 0.0 else -k * d ** 1.5 * dd) if d > 0.0 else 0.0
        F = max(F, 0.0)
        qq, qv = y[2:2 + n], y[2 + n:2 + 2 * n]
        f = fc * math.cos(W * t) + fs * math.sin(W * t)
        acc = (f - s * F) / m - c2 * qv - om * om * qq
        return np.concatenate(([y[1], a + F / m_free], qv, acc, [F, lost]))

    def sep(t, y):
        return pen(t, y)[0]

    sep.terminal, sep.direction = True, -1
    # the time scale of the contact: the Hertz time at the reduced mass
    m_eff = 1.0 / (1.0 / m_free + float(np.sum(s * s / m)))
    tc = hertz_contact_time(m_eff, k, v_in)
    y0 = np.concatenate(([w, wd], q, qd, [0.0, 0.0]))
    t_end = min(t_max, t0 + 50.0 * tc)
    sol = solve_ivp(rhs, (t0, t_end), y0, method="DOP853", rtol=1e-11, atol=1e-22, events=sep,
                    first_step=tc * 1e-4, max_step=tc / 20.0)
    # the penetration starts at zero with d' > 0: an event at t0 itself is not the separation
    hits = [i for i, t in enumerate(sol.t_events[0]) if t > t0 + 1e-3 * tc]
    if hits:
        t1, y1 = float(sol.t_events[0][hits[0]]), sol.y_events[0][hits[0]]
    else:
        t1, y1 = float(sol.t[-1]), sol.y[:, -1]
    return (t1, float(y1[0]), float(y1[1]), y1[2:2 + n].copy(), y1[2 + n:2 + 2 * n].copy(), float(y1[-2]),
            float(y1[-1]))
