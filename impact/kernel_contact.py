"""Compliant (Hunt-Crossley) horn contact of the coupled model, compiled (numba).

A contact law with a duration: from first touch the free mass and the modal horn are integrated
together under the Hertz + Hunt-Crossley force (:mod:`impact.contact`) by an adaptive
Dormand-Prince 5(4) scheme (rtol 1e-10) until the penetration returns to zero, the separation
located by bisection of the last step; the window integrals of the coupled model are integrated
along. :func:`hc_contact` is the law the loop of :mod:`impact.kernel_modal` applies in place of
Newton's.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .columns import C_DAMP, C_DRIVE, C_ELEC, C_FUND_IM, C_FUND_RE
from .horn import H_FC, H_FS, H_GIM, H_GRE, H_MASS, H_OMEGA, H_TIP, H_ZETA, X_QBI, X_QBR, X_RC, X_RS, X_V0, X_W
from .kernel_blocks import DP_C, dp_combine, dp_stage

__all__ = ["hc_contact"]

_HC_RTOL = 1e-10


@njit(cache=True)
def _hc_rhs(t, y, tab, xs, n, k, chi, v_in, m_free, a, out):
    """Contact phase: free mass y[0], y[1]; modes y[2:2+n], y[2+n:2+2n]; integrals after them
    (impulse, HC dissipation, drive work, damping loss, fundamental re / im, electrical energy, work of
    the residual's driven displacement on the free mass)."""
    W = xs[X_W]
    c = math.cos(W * t)
    s = math.sin(W * t)
    Rc, Rs = xs[X_RC], xs[X_RS]
    u = Rc * c + Rs * s
    ud = W * (-Rc * s + Rs * c)
    for i in range(n):
        u += tab[i, H_TIP] * y[2 + i]
        ud += tab[i, H_TIP] * y[2 + n + i]
    d = u - y[0]
    dd = ud - y[1]
    F = 0.0
    diss = 0.0
    if d > 0.0:
        # the power into the contact, F d', less the elastic energy's rate k d^1.5 d' is lost:
        # k chi d^1.5 d'^2 / v_in while F > 0; where the damping would pull (F clipped to 0) the
        # unloading spring's energy, -k d^1.5 d', is lost instead
        d15 = d * math.sqrt(d)
        F = k * d15 * (1.0 + chi * dd / v_in)
        if F < 0.0:
            F = 0.0
            diss = -k * d15 * dd
        else:
            diss = k * chi * d15 * dd * dd / v_in
    out[0] = y[1]
    out[1] = a + F / m_free
    V0 = xs[X_V0]
    V = V0 * s
    Vd = V0 * W * c
    drive = 0.0
    damp = 0.0
    cur = xs[X_QBR] * Vd - xs[X_QBI] * W * V
    for i in range(n):
        om, ze, m = tab[i, H_OMEGA], tab[i, H_ZETA], tab[i, H_MASS]
        qv = y[2 + n + i]
        f = tab[i, H_FC] * c + tab[i, H_FS] * s
        acc = (f - tab[i, H_TIP] * F) / m - 2.0 * ze * om * qv - om * om * y[2 + i]
        out[2 + i] = qv
        out[2 + n + i] = acc
        drive += f * qv
        damp += 2.0 * ze * om * m * qv * qv
        cur += tab[i, H_GRE] * qv + tab[i, H_GIM] / W * acc
    j = 2 + 2 * n
    out[j] = F
    out[j + 1] = diss
    out[j + 2] = drive
    out[j + 3] = damp
    out[j + 4] = u * c
    out[j + 5] = -u * s
    out[j + 6] = V * cur
    # the residual is a driven displacement: the source works on the free mass through it
    out[j + 7] = F * W * (-Rc * s + Rs * c)
    return d


@njit(cache=True)
def _dp_step(t, y, h, tab, xs, n, k, chi, v_in, m_free, a, K, y5, y4):
    """One Dormand-Prince step of size h from (t, y): fifth-order y5, fourth-order y4."""
    tmp = np.empty(y.size)
    _hc_rhs(t, y, tab, xs, n, k, chi, v_in, m_free, a, K[0])
    for st in range(1, 7):
        dp_stage(st, y, h, K, tmp)
        _hc_rhs(t + DP_C[st] * h, tmp, tab, xs, n, k, chi, v_in, m_free, a, K[st])
    dp_combine(y, h, K, y5, y4)


@njit(cache=True)
def _pen(t, y, tab, xs, n):
    W = xs[X_W]
    u = xs[X_RC] * math.cos(W * t) + xs[X_RS] * math.sin(W * t)
    for i in range(n):
        u += tab[i, H_TIP] * y[2 + i]
    return u - y[0]


@njit(cache=True)
def _accept_step(t, hh, y, y5, j0, t_from, stats):
    """Take the step y -> y5 of length hh from t: the window integrals (their increments over the
    step, inside the statistics window) go into ``stats``. Returns the new time."""
    if t >= t_from:
        stats[C_DRIVE] += y5[j0 + 2] - y[j0 + 2] + y5[j0 + 7] - y[j0 + 7]
        stats[C_DAMP] += y5[j0 + 3] - y[j0 + 3]
        stats[C_FUND_RE] += y5[j0 + 4] - y[j0 + 4]
        stats[C_FUND_IM] += y5[j0 + 5] - y[j0 + 5]
        stats[C_ELEC] += y5[j0 + 6] - y[j0 + 6]
    y[:] = y5
    return t + hh


@njit(cache=True)
def hc_contact(t0, w, wd, q, qd, tab, xs, n, k, chi, m_free, a, v_in, t_end, t_from, stats):
    """Integrate a Hunt-Crossley contact from first touch at t0 until the penetration returns to
    zero (or t_end). Updates q, qd in place and the window integrals in ``stats``; returns
    (t1, w1, wd1, impulse, dissipated, ok); ok is False if 1e6 steps did not reach either."""
    m = 2 + 2 * n + 8
    y = np.zeros(m)
    y[0], y[1] = w, wd
    for i in range(n):
        y[2 + i] = q[i]
        y[2 + n + i] = qd[i]
    K = np.empty((7, m))
    y5 = np.empty(m)
    y4 = np.empty(m)
    # scales of the error norm: positions to 1e-16 m, velocities to 1e-12 m/s (modes through |s|)
    smax = 0.0
    for i in range(n):
        smax = max(smax, abs(tab[i, H_TIP]))
    sc = np.empty(2 + 2 * n)
    sc[0], sc[1] = 1e-16, 1e-12
    for i in range(n):
        sc[2 + i] = 1e-16 / smax
        sc[2 + n + i] = 1e-12 / smax
    Sg = 0.0
    for i in range(n):
        Sg += tab[i, H_TIP] * tab[i, H_TIP] / tab[i, H_MASS]
    m_eff = 1.0 / (1.0 / m_free + Sg)
    tc = 3.218 * (m_eff * m_eff / (k * k * v_in)) ** 0.2
    h = 1e-3 * tc
    t = t0
    j0 = 2 + 2 * n
    ok = False
    for _ in range(1000000):
        if t >= t_end:
            ok = True
            break
        hh = min(h, t_end - t)
        if t < t_from:
            hh = min(hh, t_from - t)
        _dp_step(t, y, hh, tab, xs, n, k, chi, v_in, m_free, a, K, y5, y4)
        err = 0.0
        for j in range(2 + 2 * n):
            e = abs(y5[j] - y4[j]) / (sc[j] + _HC_RTOL * max(abs(y[j]), abs(y5[j])))
            err = max(err, e)
        if err > 1.0 and hh > 1e-9 * tc:
            h = hh * max(0.2, 0.9 * err ** -0.2)
            continue
        d1 = _pen(t + hh, y5, tab, xs, n)
        if d1 <= 0.0 and t + hh > t0 + 1e-3 * tc:
            # separation inside the step: bisect the step length (one fifth-order step per trial)
            lo, hi = 0.0, hh
            for _ in range(200):
                mid = 0.5 * (lo + hi)
                if mid <= lo or mid >= hi:
                    break
                _dp_step(t, y, mid, tab, xs, n, k, chi, v_in, m_free, a, K, y5, y4)
                if _pen(t + mid, y5, tab, xs, n) > 0.0:
                    lo = mid
                else:
                    hi = mid
            _dp_step(t, y, hi, tab, xs, n, k, chi, v_in, m_free, a, K, y5, y4)
            t = _accept_step(t, hi, y, y5, j0, t_from, stats)
            ok = True
            break
        t = _accept_step(t, hh, y, y5, j0, t_from, stats)
        h = hh * min(5.0, max(0.2, 0.9 * (err if err > 1e-300 else 1e-300) ** -0.2))
    for i in range(n):
        q[i] = y[2 + i]
        qd[i] = y[2 + n + i]
    return t, y[0], y[1], y[j0], y[j0 + 1], ok

