"""Compiled event kernel of the coupled model (modal horn; numba).

The algorithm of :class:`impact.coupled._ModalSim`, written with scalars for numba, on the
primitives of :mod:`impact.kernel` (oscillator closed forms, interval tests, parabola zones,
sticking rule). The kinematic kernel is untouched: this module adds a second event loop whose
horn tip is ``u = Uc cos Wt + Us sin Wt + sum_i s_i h_i(t - t0)``, each ``h_i`` the free
oscillation of mode i over the current segment (an ``impact.kernel`` oscillator record).

Entry points: :func:`run_events` (one run, every event and segment) and
:func:`ensemble_coupled` (window statistics of many members in parallel, the columns of
:func:`impact.kernel.ensemble_stats` followed by ``C_DRIVE`` (work of the drive on the modes and
the residual, J), ``C_DAMP`` (modal damping loss, J), ``C_FUND_RE``/``C_FUND_IM``
(``int u e^{-jWt} dt`` over the window, m s), ``C_ELEC`` (electrical energy drawn ``int V I dt``,
J): closed-form integrals per segment) and ``C_SOURCE_LOSS`` (resistor and dielectric loss of a
series-resistance drive, J; 0 with the voltage drive).

With a series-resistance drive (``X_SERIES``, :mod:`impact.drive`) the rows of the table are
pseudo-modes: an impulse jumps both a row's coordinate and its velocity (columns ``H_JQ``,
``H_JV``), and the energy integrals are quadratic forms over every pair of rows
(:func:`_integrals_series`): ``C_ELEC`` the source's work, ``C_DRIVE`` the conversion to mechanics,
``C_DAMP`` the modal damping, ``C_SOURCE_LOSS`` the resistor and dielectric loss.
"""

from __future__ import annotations

import cmath
import math

import numpy as np
from numba import njit, prange

from .horn import (H_A, H_B, H_FC, H_FS, H_GIM, H_GRE, H_JQ, H_JV, H_MASS, H_OMEGA, H_TIP, H_ZETA, X_QBI, X_QBR,
                   X_RC, X_RS, X_SERIES, X_STEADY, X_UC, X_US, X_V0, X_W,
                   ModalHorn)
from .kernel import (_O_B0, _O_B2, _O_B4, _O_DELTA, _O_N, CONTACT_TOL, _H_MIN, _RTOL,
                     _XTOL, BODY_HORN, BODY_TOOL, FREE, KIND_HORN, KIND_TOOL, N_PARAMS, N_STATS, ON_TOOL, P_C, P_E1, P_E2, P_GAP,
                     P_K0, P_M_FREE, P_M_TOOL, P_V0, P_V_STICK, P_G, P_SPRING_FORCE, ON_HORN, S_HORN_WORK, S_KE_AFTER,
                     S_KE_GAIN, S_N_EVENTS, S_N_HORN, S_N_TOOL, S_STATUS, S_T_ON_HORN, S_T_ON_TOOL, STATUS_MAX_EVENTS, STATUS_OK,
                     STATUS_PINCHED, _E_N, _grid_step, _grow1, _grow2, _osc_eval, _osc_make, _osc_pv,
                     _plan_flight, _safe, _sticks, pack)
from .params import ImpactParams

__all__ = ["run_events", "ensemble_coupled", "N_CSTATS", "STATUS_CONTACT"]

#: status of a run whose compliant contact was not resolved in 1e6 integration steps
STATUS_CONTACT = 4
C_DRIVE, C_DAMP, C_FUND_RE, C_FUND_IM, C_ELEC, C_SOURCE_LOSS = range(N_STATS, N_STATS + 6)
N_CSTATS = N_STATS + 6

_FN_HORN, _FN_TOOL, _FN_PINCH, _FN_RELEASE, _FN_HREL = 0, 1, 2, 3, 4
# contact record: t0, w0, wd0, a, L0, W, Uc, Us
_C_N = 8


# ----------------------------------------------------------------------------- horn tip


@njit(cache=True)
def _tip(tt, cp, tab, ho, n, order):
    """Tip derivatives ``order`` and ``order + 1`` at absolute time tt (order 0 or 2)."""
    W, Uc, Us = cp[5], cp[6], cp[7]
    ph = W * tt
    c = math.cos(ph)
    s = math.sin(ph)
    if order == 0:
        u = Uc * c + Us * s
        ud = W * (-Uc * s + Us * c)
    else:
        u = -W * W * (Uc * c + Us * s)
        ud = -W * W * W * (-Uc * s + Us * c)
    sl = tt - cp[0]
    for i in range(n):
        y, yd = _osc_eval(ho[i], sl, order)
        u += tab[i, H_TIP] * y
        ud += tab[i, H_TIP] * yd
    return u, ud


@njit(cache=True)
def _fn(kind, tt, cp, o, tab, ho, n):
    t0, w0, wd0, a, L0 = cp[0], cp[1], cp[2], cp[3], cp[4]
    if kind == _FN_HORN:
        s = tt - t0
        u, ud = _tip(tt, cp, tab, ho, n, 0)
        return w0 + s * (wd0 + 0.5 * a * s) - u, wd0 + a * s - ud
    if kind == _FN_TOOL:
        s = tt - t0
        vv, vvd = _osc_pv(o, s)
        return L0 + vv - (w0 + s * (wd0 + 0.5 * a * s)), vvd - (wd0 + a * s)
    if kind == _FN_PINCH:
        vv, vvd = _osc_pv(o, tt - t0)
        u, ud = _tip(tt, cp, tab, ho, n, 0)
        return L0 + vv - u, vvd - ud
    if kind == _FN_HREL:
        # riding on the horn: the contact force per mass (u'' - a) falls to zero at the release
        u2, u3 = _tip(tt, cp, tab, ho, n, 2)
        return u2 - a, u3
    acc, jerk = _osc_eval(o, tt - t0, 2)
    return a - acc, -jerk


@njit(cache=True)
def _brent(kind, cp, o, tab, ho, n, xa, xb, fa, fb):
    xpre, xcur, fpre, fcur = xa, xb, fa, fb
    xblk = 0.0
    fblk = 0.0
    spre = 0.0
    scur = 0.0
    for _ in range(200):
        if fpre != 0.0 and fcur != 0.0 and (fpre < 0.0) != (fcur < 0.0):
            xblk, fblk = xpre, fpre
            spre = xcur - xpre
            scur = spre
        if abs(fblk) < abs(fcur):
            xpre, xcur, xblk = xcur, xblk, xcur
            fpre, fcur, fblk = fcur, fblk, fcur
        delta = 0.5 * (_XTOL + _RTOL * abs(xcur))
        sbis = 0.5 * (xblk - xcur)
        if fcur == 0.0 or abs(sbis) < delta:
            return xcur
        if abs(spre) > delta and abs(fcur) < abs(fpre):
            if xpre == xblk:
                stry = -fcur * (xcur - xpre) / (fcur - fpre)
            else:
                dpre = (fpre - fcur) / (xpre - xcur)
                dblk = (fblk - fcur) / (xblk - xcur)
                stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre))
            if 2.0 * abs(stry) < min(abs(spre), 3.0 * abs(sbis) - delta):
                spre, scur = scur, stry
            else:
                spre = sbis
                scur = sbis
        else:
            spre = sbis
            scur = sbis
        xpre, fpre = xcur, fcur
        if abs(scur) > delta:
            xcur += scur
        else:
            xcur += delta if sbis > 0.0 else -delta
        fcur = _fn(kind, xcur, cp, o, tab, ho, n)[0]
    return xcur


@njit(cache=True)
def _refine(kind, cp, o, tab, ho, n, a, b, fa, fpa, fb, fpb, B, tol, stack):
    sp = 0
    stack[0, 0], stack[0, 1], stack[0, 2], stack[0, 3], stack[0, 4], stack[0, 5] = a, b, fa, fpa, fb, fpb
    sp = 1
    while sp > 0:
        sp -= 1
        a, b, fa, fpa, fb, fpb = (stack[sp, 0], stack[sp, 1], stack[sp, 2], stack[sp, 3],
                                  stack[sp, 4], stack[sp, 5])
        h = b - a
        if fb <= -tol:
            if fpa + fpb + B * h < 0.0 or h < _H_MIN:
                if fa <= 0.0:
                    return True, a
                return True, _brent(kind, cp, o, tab, ho, n, a, b, fa, fb)
        else:
            c2 = B * h * h
            if (min(fa, fb) - 0.125 * c2 > -tol or fa + fpa * h - 0.5 * c2 > -tol
                    or fb - fpb * h - 0.5 * c2 > -tol or h < _H_MIN):
                continue
        m = 0.5 * (a + b)
        fm, fpm = _fn(kind, m, cp, o, tab, ho, n)
        stack[sp, 0], stack[sp, 1], stack[sp, 2], stack[sp, 3], stack[sp, 4], stack[sp, 5] = \
            m, b, fm, fpm, fb, fpb
        sp += 1
        stack[sp, 0], stack[sp, 1], stack[sp, 2], stack[sp, 3], stack[sp, 4], stack[sp, 5] = \
            a, m, fa, fpa, fm, fpm
        sp += 1
    return False, 0.0


@njit(cache=True)
def _search(kind, cp, o, tab, ho, n, B, lo, hi, h, stack):
    nn = 32
    a = lo
    while a < hi:
        b = min(a + nn * h, hi)
        k = max(1, int(math.ceil((b - a) / h)))
        hh = (b - a) / k
        fa, fpa = _fn(kind, a, cp, o, tab, ho, n)
        if fa <= -CONTACT_TOL and fpa < 0.0:
            return True, a
        ta = a
        for i in range(k):
            tb = b if i == k - 1 else a + (i + 1) * hh
            fb, fpb = _fn(kind, tb, cp, o, tab, ho, n)
            if not _safe(fa, fpa, fb, fpb, B, hh, CONTACT_TOL):
                found, r = _refine(kind, cp, o, tab, ho, n, ta, tb, fa, fpa, fb, fpb, B, CONTACT_TOL, stack)
                if found:
                    return True, r
            ta, fa, fpa = tb, fb, fpb
        a = b
        nn = min(nn * 2, 4096)
    return False, 0.0


# ----------------------------------------------------------------------------- integrals


@njit(cache=True)
def _expint(lam, S):
    """int_0^S exp(lam s) ds (complex lam), as impact.horn._expint."""
    z = lam * S
    if abs(z) < 1e-6:
        return S * (1.0 + z / 2.0 + z * z / 6.0)
    x, y = z.real, z.imag
    em1 = complex(math.expm1(x) * math.cos(y) - 2.0 * math.sin(0.5 * y) ** 2, math.exp(x) * math.sin(y))
    return em1 / lam


@njit(cache=True)
def _expint_e(lam, S, e):
    """_expint(lam, S) given e = exp(lam S): (e - 1) / lam when |lam S| >= 0.5 (no cancellation
    there), else the cancellation-free form."""
    if abs(lam * S) >= 0.5:
        return (e - 1.0) / lam
    return _expint(lam, S)


@njit(cache=True)
def _integrals(tab, xs, n, t0, q, qd, sa, sb):
    """(drive work, damping loss, fundamental, electrical energy) over [t0 + sa, t0 + sb] of a free
    segment: the integrals of impact.horn.segment_integrals, with the exponential integrals shared
    between the products (per mode E(jW + mu), E(mu - jW), E(2 mu), E(2 Re mu); E(jW + conj mu) =
    conj E(mu - jW) and E(conj mu - jW) = conj E(mu + jW))."""
    W = xs[X_W]
    jw = 1j * W
    S = sb - sa
    ta = t0 + sa
    ewa = cmath.exp(jw * ta)
    eW = cmath.exp(jw * S)
    E2w = _expint_e(2.0 * jw, S, eW * eW)
    drive = 0.0
    damp = 0.0
    U = complex(xs[X_UC], -xs[X_US])
    Uc = U * ewa
    fund = 0.5 * (Uc * S + Uc.conjugate() * E2w.conjugate())
    e0 = cmath.exp(jw * t0)
    V0 = xs[X_V0]
    Vc = -1j * V0 * ewa
    tb = ta + S
    elec = xs[X_QBR] * 0.5 * V0 * V0 * (math.sin(W * tb) ** 2 - math.sin(W * ta) ** 2)
    elec -= xs[X_QBI] * W * V0 * V0 * (0.5 * S - (math.sin(2.0 * W * tb) - math.sin(2.0 * W * ta)) / (4.0 * W))
    for i in range(n):
        om, ze, m = tab[i, H_OMEGA], tab[i, H_ZETA], tab[i, H_MASS]
        qs = complex(tab[i, H_A], -tab[i, H_B])
        mu = complex(-ze * om, om * math.sqrt(1.0 - ze * ze))
        h0 = q[i] - (qs * e0).real
        hd0 = qd[i] - (jw * qs * e0).real
        C = complex(h0, -(hd0 - h0 * mu.real) / mu.imag) * cmath.exp(mu * sa)
        eM = cmath.exp(mu * S)
        Ep = _expint_e(jw + mu, S, eM * eW)
        Em = _expint_e(mu - jw, S, eM * eW.conjugate())
        E2m = _expint_e(2.0 * mu, S, eM * eM)
        E2r = _expint_e(complex(2.0 * mu.real, 0.0), S, complex(abs(eM) ** 2, 0.0))
        cEm = Em.conjugate()
        G = jw * qs * ewa
        H = C * mu
        F = complex(tab[i, H_FC], -tab[i, H_FS]) * ewa
        # int Re(A e^{la s}) Re(B e^{lb s}) ds = Re(A B E(la + lb)) / 2 + Re(A conj(B) E(la + conj lb)) / 2
        drive += 0.5 * ((F * G * E2w).real + (F * G.conjugate()).real * S + (F * H * Ep).real
                        + (F * H.conjugate() * cEm).real)
        gg = 0.5 * ((G * G * E2w).real + (G * G.conjugate()).real * S)
        gh = 0.5 * ((G * H * Ep).real + (G * H.conjugate() * cEm).real)
        hh = 0.5 * ((H * H * E2m).real + (H * H.conjugate() * E2r).real)
        damp += 2.0 * ze * om * m * (gg + 2.0 * gh + hh)
        G2 = jw * G
        H2 = mu * H
        vq1 = 0.5 * ((Vc * G * E2w).real + (Vc * G.conjugate()).real * S + (Vc * H * Ep).real
                     + (Vc * H.conjugate() * cEm).real)
        vq2 = 0.5 * ((Vc * G2 * E2w).real + (Vc * G2.conjugate()).real * S + (Vc * H2 * Ep).real
                     + (Vc * H2.conjugate() * cEm).real)
        elec += tab[i, H_GRE] * vq1 + tab[i, H_GIM] / W * vq2
        Ct = C * tab[i, H_TIP]
        fund += 0.5 * (Ct * Em + Ct.conjugate() * Ep.conjugate())
    fund = fund * cmath.exp(-jw * ta)
    return drive, damp, fund, elec


@njit(cache=True)
def _integrals_series(tab, xs, n, t0, q, qd, sa, sb, lam, G1, G2, cw):
    """(source work, resistor + dielectric loss, conversion to mechanics, modal damping, fundamental)
    over [t0 + sa, t0 + sb] of a free segment of a series-resistance drive (:mod:`impact.drive`).

    Over the segment the augmented state is ``Re(sum_j C_j w_j e^{lam_j s})`` (the pseudo-modes, then
    the steady state with ``lam = jW``), so ``int xt^T Q xt ds = sum_jl Re(C_j C_l G1_jl E(lam_j +
    lam_l)) / 2 + Re(C_j conj(C_l) G2_jl E(lam_j + conj lam_l)) / 2``; the (j, l) and (l, j) terms
    are equal, so only l >= j is summed. ``cw`` is work space (n + 1,) complex."""
    W = xs[X_W]
    jw = 1j * W
    S = sb - sa
    ta = t0 + sa
    e0 = cmath.exp(jw * t0)
    for k in range(n):
        P = complex(tab[k, H_A], -tab[k, H_B])
        h0 = q[k] - (P * e0).real
        hd0 = qd[k] - (jw * P * e0).real
        lk = lam[k]
        if lk.imag != 0.0:
            C = complex(h0, -(hd0 - h0 * lk.real) / lk.imag)
        else:
            C = complex(h0, 0.0)
        cw[k] = C * cmath.exp(lk * sa)
    ewa = cmath.exp(jw * ta)
    cw[n] = ewa
    acc = np.zeros(4)
    for j in range(n + 1):
        for l in range(j, n + 1):
            f = 0.5 if l == j else 1.0
            x1 = cw[j] * cw[l] * _expint(lam[j] + lam[l], S)
            x2 = cw[j] * cw[l].conjugate() * _expint(lam[j] + lam[l].conjugate(), S)
            for a in range(4):
                acc[a] += f * ((G1[a, j, l] * x1).real + (G2[a, j, l] * x2).real)
    U = complex(xs[X_UC], -xs[X_US]) * ewa
    fund = 0.5 * (U * S + U.conjugate() * _expint(2.0 * jw, S).conjugate())
    for k in range(n):
        Ct = cw[k] * tab[k, H_TIP]
        fund += 0.5 * (Ct * _expint(lam[k] - jw, S) + Ct.conjugate() * _expint(lam[k].conjugate() - jw, S))
    fund = fund * cmath.exp(-jw * ta)
    return acc[0], acc[1], acc[2], acc[3], fund


@njit(cache=True)
def _window_integrals(tab, xs, n, t0, t1, q, qd, t_from, t_end, stats, lam, G1, G2, cw):
    lo = max(t0, t_from)
    hi = min(t1, t_end)
    if hi > lo:
        if xs[X_SERIES] == 1.0:
            src, loss, conv, dm, f = _integrals_series(tab, xs, n, t0, q, qd, lo - t0, hi - t0, lam, G1, G2, cw)
            stats[C_ELEC] += src
            stats[C_SOURCE_LOSS] += loss
            stats[C_DRIVE] += conv
            stats[C_DAMP] += dm
        else:
            d, dm, f, el = _integrals(tab, xs, n, t0, q, qd, lo - t0, hi - t0)
            stats[C_ELEC] += el
            stats[C_DRIVE] += d
            stats[C_DAMP] += dm
        stats[C_FUND_RE] += f.real
        stats[C_FUND_IM] += f.imag


# ----------------------------------------------------------------------------- compliant contact

# Dormand-Prince 5(4) tableau
_DP_C = np.array([0.0, 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0, 1.0])
_DP_A = np.array([
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [1.0 / 5.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [3.0 / 40.0, 9.0 / 40.0, 0.0, 0.0, 0.0, 0.0],
    [44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0, 0.0, 0.0, 0.0],
    [19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0, 0.0, 0.0],
    [9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0, 0.0],
    [35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0]])
_DP_B5 = np.array([35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0, 0.0])
_DP_B4 = np.array([5179.0 / 57600.0, 0.0, 7571.0 / 16695.0, 393.0 / 640.0, -92097.0 / 339200.0, 187.0 / 2100.0,
                   1.0 / 40.0])
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
    m = y.size
    tmp = np.empty(m)
    _hc_rhs(t, y, tab, xs, n, k, chi, v_in, m_free, a, K[0])
    for st in range(1, 7):
        for j in range(m):
            acc = y[j]
            for r in range(st):
                acc += h * _DP_A[st, r] * K[r, j]
            tmp[j] = acc
        _hc_rhs(t + _DP_C[st] * h, tmp, tab, xs, n, k, chi, v_in, m_free, a, K[st])
    for j in range(m):
        s5 = 0.0
        s4 = 0.0
        for r in range(7):
            s5 += _DP_B5[r] * K[r, j]
            s4 += _DP_B4[r] * K[r, j]
        y5[j] = y[j] + h * s5
        y4[j] = y[j] + h * s4


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
def _hc_contact(t0, w, wd, q, qd, tab, xs, n, k, chi, m_free, a, v_in, t_end, t_from, stats):
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


# ----------------------------------------------------------------------------- main loop


@njit(cache=True)
def _make_horn(ho, tab, n, W, t0, q, qd):
    """Free-oscillation records of every mode at t0; returns bounds (|u|, |u''|) minus the steady part."""
    c = math.cos(W * t0)
    s = math.sin(W * t0)
    b0 = 0.0
    b2 = 0.0
    b4 = 0.0
    for i in range(n):
        a_, b_ = tab[i, H_A], tab[i, H_B]
        p = a_ * c + b_ * s
        pd = W * (-a_ * s + b_ * c)
        m = tab[i, H_MASS]
        om = tab[i, H_OMEGA]
        _osc_make(ho[i], m, m * om * om, 2.0 * tab[i, H_ZETA] * om * m, 0.0, q[i] - p, qd[i] - pd)
        b0 += abs(tab[i, H_TIP]) * ho[i, _O_B0]
        b2 += abs(tab[i, H_TIP]) * ho[i, _O_B2]
        b4 += abs(tab[i, H_TIP]) * ho[i, _O_B4]
    return b0, b2, b4


@njit(cache=True)
def _modal_at(ho, tab, n, W, t0, tt, q, qd):
    c = math.cos(W * tt)
    s = math.sin(W * tt)
    for i in range(n):
        y, yd = _osc_eval(ho[i], tt - t0, 0)
        q[i] = tab[i, H_A] * c + tab[i, H_B] * s + y
        qd[i] = W * (-tab[i, H_A] * s + tab[i, H_B] * c) + yd


@njit(cache=True)
def _core(pv, tab, xs, hc, t_end, max_events, record, t_from, stats, lam, G1, G2):
    m_free, e1, e2 = pv[P_M_FREE], pv[P_E1], pv[P_E2]
    m_tool, k0, c, L0 = pv[P_M_TOOL], pv[P_K0], pv[P_C], pv[P_GAP]
    v_stick = pv[P_V_STICK]
    a = pv[P_G] - pv[P_SPRING_FORCE] / m_free
    M = m_tool + m_free
    n = tab.shape[0]
    W = xs[X_W]
    Ua = math.hypot(xs[X_UC], xs[X_US])
    series = xs[X_SERIES] == 1.0
    Sg = 0.0
    for i in range(n):
        if series:
            Sg -= tab[i, H_TIP] * tab[i, H_JV]
        else:
            Sg += tab[i, H_TIP] * tab[i, H_TIP] / tab[i, H_MASS]
    cw = np.empty(n + 1, np.complex128)

    cap = 1024 if record else 1
    ev = np.empty((cap, _E_N + 3))
    kinds = np.empty(cap, np.int8)
    segs = np.empty((cap, 6 + 2 * n))
    stk = np.empty((cap, 3))
    n_rec = 0
    n_seg = 0
    n_stk = 0

    o = np.empty(_O_N)
    o2 = np.empty(_O_N)
    ho = np.empty((n, _O_N))
    cp = np.empty(_C_N)
    stack = np.empty((128, 6))
    fkind = np.empty(4, np.int64)
    fB = np.empty(4)
    fstart = np.empty(4)
    fh = np.empty(4)
    fend = np.empty(4)
    q = np.empty(n)
    qd = np.empty(n)
    for j in range(stats.shape[0]):
        stats[j] = 0.0
    w_from = 0.0
    w_last = 0.0

    steady = xs[X_STEADY] == 1.0
    for i in range(n):
        if steady:
            q[i] = tab[i, H_A]
            qd[i] = W * tab[i, H_B]
        else:
            q[i] = 0.0
            qd[i] = 0.0
    cp[0], cp[5], cp[6], cp[7] = 0.0, W, xs[X_UC], xs[X_US]
    _make_horn(ho, tab, n, W, 0.0, q, qd)
    u0, ud0 = _tip(0.0, cp, tab, ho, n, 0)
    t = 0.0
    mode = FREE
    w = u0
    wd = ud0 + pv[P_V0]
    v = 0.0
    vd = 0.0
    skip_rel = 2.0 * pv[P_V0]
    skip_h = 0.0
    skip_t = 0.0
    E0 = 0.5 * m_free * wd * wd - m_free * a * w + 0.5 * m_tool * vd * vd + 0.5 * k0 * v * v
    work = 0.0
    stick_start = 0.0
    stick_E = 0.0
    n_ev = 0
    status = STATUS_OK
    t_status = 0.0
    Rc, Rs = xs[X_RC], xs[X_RS]
    while t < t_end:
        if mode == ON_TOOL:
            _osc_make(o, M, k0, c, m_free * a / k0, v, vd)
        else:
            _osc_make(o, m_tool, k0, c, 0.0, v, vd)
        hb0, hb2, hb4 = _make_horn(ho, tab, n, W, t, q, qd)
        B0 = Ua + hb0
        B2 = Ua * W * W + hb2
        Bh = abs(a) + B2
        if skip_rel > 0.0:
            skip_h = t + skip_rel / Bh
            skip_rel = 0.0
        if record:
            if n_seg == segs.shape[0]:
                segs = _grow2(segs, n_seg)
            segs[n_seg, 0], segs[n_seg, 1], segs[n_seg, 2] = t, mode, w
            segs[n_seg, 3], segs[n_seg, 4], segs[n_seg, 5] = wd, v, vd
            for i in range(n):
                segs[n_seg, 6 + i] = q[i]
                segs[n_seg, 6 + n + i] = qd[i]
            n_seg += 1
        t0, w0, wd0 = t, w, wd
        cp[0], cp[1], cp[2], cp[3], cp[4] = t0, w0, wd0, a, L0
        Bv = o[_O_B2]
        nf = 0
        if mode == FREE:
            Bt = Bv + abs(a)
            nf = _plan_flight(t0, w0, wd0, a, L0, B0, o[_O_B0], skip_h, skip_t, Bh, Bt, t_end,
                              fkind, fB, fh, fstart, fend, nf)
        elif mode == ON_HORN:
            B = Bv + B2
            if L0 - o[_O_B0] - B0 <= 0.0:
                fkind[nf], fB[nf] = _FN_PINCH, B
                fstart[nf] = max(t0, skip_t)
                fh[nf] = _grid_step(B, t_end, 1e-7)
                fend[nf] = math.inf
                nf += 1
            B4 = Ua * W * W * W * W + hb4
            fkind[nf], fB[nf] = _FN_HREL, B4
            fstart[nf] = t0
            fh[nf] = _grid_step(B4, t_end, 1e-3 * (abs(a) + B2))
            fend[nf] = math.inf
            nf += 1
        else:
            Br = o[_O_B4]
            B = Bv + B2
            if L0 + o[_O_DELTA] - o[_O_B0] - B0 <= 0.0:
                fkind[nf], fB[nf] = _FN_PINCH, B
                fstart[nf] = t0
                fh[nf] = _grid_step(B, t_end, 1e-7)
                fend[nf] = math.inf
                nf += 1
            if o[_O_B2] >= a:
                fkind[nf], fB[nf] = _FN_RELEASE, Br
                fstart[nf] = t0
                fh[nf] = _grid_step(Br, t_end, 1e-3 * (abs(a) + o[_O_B2]))
                fend[nf] = math.inf
                nf += 1

        have = False
        te = 0.0
        name = -1
        for i in range(nf):
            lo = fstart[i]
            hi = min(te if have else t_end, fend[i])
            if lo >= hi:
                continue
            found, r = _search(fkind[i], cp, o, tab, ho, n, fB[i], lo, hi, fh[i], stack)
            if found:
                have, te, name = True, r, fkind[i]
        if not have:
            # the last segment runs to t_end: its share of the window integrals
            _window_integrals(tab, xs, n, t0, t_end, q, qd, t_from, t_end, stats, lam, G1, G2, cw)
            break
        if name == _FN_PINCH:
            status, t_status = STATUS_PINCHED, te
            break
        n_ev += 1
        if n_ev > max_events:
            status, t_status = STATUS_MAX_EVENTS, te
            break
        _window_integrals(tab, xs, n, t0, te, q, qd, t_from, t_end, stats, lam, G1, G2, cw)
        s = te - t0
        v, vd = _osc_pv(o, s)
        _modal_at(ho, tab, n, W, t0, te, q, qd)
        uh, uhd = _tip(te, cp, tab, ho, n, 0)
        if mode == FREE:
            w, wd = w0 + s * (wd0 + 0.5 * a * s), wd0 + a * s
        elif mode == ON_HORN:
            w, wd = uh, uhd
        else:
            w, wd = L0 + v, vd
        t = te
        if L0 + v <= 2.0 * B0:
            status, t_status = STATUS_PINCHED, te
            break
        if name == _FN_HREL:
            # the horn did the work that moved the riding mass (its reaction on the modes is neglected)
            work += (0.5 * m_free * wd * wd - m_free * a * w) - stick_E
            skip_h = te
            skip_t = te
            if record:
                if n_stk == stk.shape[0]:
                    stk = _grow2(stk, n_stk)
                stk[n_stk, 0], stk[n_stk, 1], stk[n_stk, 2] = stick_start, te, BODY_HORN
                n_stk += 1
            stats[S_T_ON_HORN] += max(0.0, min(te, t_end) - max(stick_start, t_from))
            mode = FREE
            continue
        if name == _FN_RELEASE:
            skip_h = te
            skip_t = te
            if record:
                if n_stk == stk.shape[0]:
                    stk = _grow2(stk, n_stk)
                stk[n_stk, 0], stk[n_stk, 1], stk[n_stk, 2] = stick_start, te, BODY_TOOL
                n_stk += 1
            d = max(0.0, min(te, t_end) - max(stick_start, t_from))
            stats[S_T_ON_TOOL] += d
            mode = FREE
            continue
        if name == _FN_HORN and hc[0] > 0.0:
            # compliant contact (Hunt-Crossley): integrated until the penetration is gone
            x = uh
            wb = wd
            t1, w1, wd1, J, diss, ok = _hc_contact(te, w, wd, q, qd, tab, xs, n, hc[0], hc[1], m_free, a,
                                                   uhd - wd, t_end, t_from, stats)
            if not ok:
                status, t_status = STATUS_CONTACT, te
                break
            work += (0.5 * m_free * wd1 * wd1 - m_free * a * w1) - (0.5 * m_free * wd * wd - m_free * a * w) + diss
            v, vd = _osc_pv(o, t1 - t0)
            t = t1
            w, wd = w1, wd1
            wa = wd1
            ub = uhd
            c_ = math.cos(W * t1)
            s_ = math.sin(W * t1)
            ua = W * (-Rc * s_ + Rs * c_)
            for i in range(n):
                ua += tab[i, H_TIP] * qd[i]
            skip_rel = 2.0 * max(wd1 - ua, 0.0)
            skip_t = t1
            vb = vd
            va = vd
            kind = KIND_HORN
        elif name == _FN_HORN:
            x = uh
            rel_in = wd - uhd
            J = -(1.0 + e2) * rel_in / (1.0 / m_free + Sg)
            wa = wd + J / m_free
            if series:
                for i in range(n):
                    q[i] += tab[i, H_JQ] * J
                    qd[i] += tab[i, H_JV] * J
            else:
                for i in range(n):
                    qd[i] -= tab[i, H_TIP] * J / tab[i, H_MASS]
            ua = uhd - J * Sg
            work += J * 0.5 * (uhd + ua)
            if te >= t_from and te <= t_end:
                # the residual is a driven displacement: the source does its work on the free mass
                stats[C_DRIVE] += J * W * (-Rc * math.sin(W * te) + Rs * math.cos(W * te))
            wb = wd
            uacc = _tip(te, cp, tab, ho, n, 2)[0]
            if _sticks(wa - ua, uacc - a, v_stick):
                wa = ua
                mode = ON_HORN
                stick_start = te
                stick_E = 0.5 * m_free * wa * wa - m_free * a * x
            else:
                skip_rel = 2.0 * (wa - ua)
            skip_t = te
            w, wd = x, wa
            vb = vd
            va = vd
            ub = uhd
            kind = KIND_HORN
        else:
            x = L0 + v
            vb, wb = vd, wd
            rel = wd - vd
            va = vd + m_free / M * (1.0 + e1) * rel
            wa = wd - m_tool / M * (1.0 + e1) * rel
            J = m_free * (wa - wd)
            acc_tool = -(c * va + k0 * v) / m_tool
            if _sticks(va - wa, a - acc_tool, v_stick):
                va = (m_tool * vd + m_free * wd) / M
                wa = va
                J = m_free * (wa - wd)
                mode = ON_TOOL
                stick_start = te
            else:
                _osc_make(o2, m_tool, k0, c, 0.0, v, va)
                skip_t = te + 2.0 * (va - wa) / (abs(a) + o2[_O_B2])
                skip_h = te
            w, wd, vd = x, wa, va
            ub = uhd
            ua = uhd
            kind = KIND_TOOL
        energy = 0.5 * m_free * wd * wd - m_free * a * w + 0.5 * m_tool * vd * vd + 0.5 * k0 * v * v
        if record:
            if n_rec == kinds.shape[0]:
                ev = _grow2(ev, n_rec)
                kinds = _grow1(kinds, n_rec)
            ev[n_rec, 0], ev[n_rec, 1], ev[n_rec, 2], ev[n_rec, 3] = te, x, wb, wa
            ev[n_rec, 4], ev[n_rec, 5], ev[n_rec, 6], ev[n_rec, 7] = vb, va, energy, work
            ev[n_rec, 8], ev[n_rec, 9], ev[n_rec, 10] = J, ub, ua
            kinds[n_rec] = kind
            n_rec += 1
        if te < t_from:
            w_from = work
        w_last = work
        if te >= t_from and te <= t_end:
            if kind == KIND_TOOL:
                stats[S_N_TOOL] += 1.0
                stats[S_KE_AFTER] += 0.5 * m_tool * va ** 2
                stats[S_KE_GAIN] += 0.5 * m_tool * (va ** 2 - vb ** 2)
            else:
                stats[S_N_HORN] += 1.0
    if status == STATUS_OK and mode != FREE:
        body = BODY_HORN if mode == ON_HORN else BODY_TOOL
        if record:
            if n_stk == stk.shape[0]:
                stk = _grow2(stk, n_stk)
            stk[n_stk, 0], stk[n_stk, 1], stk[n_stk, 2] = stick_start, t_end, body
            n_stk += 1
        d = max(0.0, t_end - max(stick_start, t_from))
        stats[S_T_ON_HORN if body == BODY_HORN else S_T_ON_TOOL] += d
    stats[S_HORN_WORK] = w_last - w_from
    stats[S_STATUS] = status
    stats[S_N_EVENTS] = n_ev
    return ev, kinds, n_rec, segs, n_seg, stk, n_stk, E0, status, t_status, n_ev


def _hc_array(contact) -> np.ndarray:
    """(k, chi) of a compliant contact, (0, 0) for Newton's law."""
    if contact is None:
        return np.zeros(2)
    return np.array([float(contact.stiffness), float(contact.chi)])


def _kernel_data(horn: ModalHorn, freq_hz: float):
    """``(tab, xs, lam, G1, G2)``: the packed horn and, with a series-resistance drive, the tables of
    its closed-form energy integrals (:meth:`impact.drive.SeriesModel.kernel_tables`; one-element
    placeholders with the voltage drive)."""
    if horn.series_resistance > 0:
        from .drive import pack_series, series_model

        model = series_model(horn, freq_hz)
        tab, xs = pack_series(horn, model)
        lam, G1, G2 = model.kernel_tables(horn)
        return np.ascontiguousarray(tab), xs, lam, G1, G2
    tab, xs = horn.pack(freq_hz)
    return np.ascontiguousarray(tab), xs, np.zeros(1, complex), np.zeros((4, 1, 1), complex), np.zeros((4, 1, 1), complex)


def run_events(params: ImpactParams, horn: ModalHorn, contact=None) -> tuple:
    """One coupled run (compiled): every event and segment.

    ``contact``: an :class:`impact.contact.HuntCrossley` for compliant horn contacts (integrated
    by an adaptive Dormand-Prince 5(4) scheme, rtol 1e-10, separation located by bisection of the
    step), or None (Newton's law). With a compliant contact the segments cover the free phases only.

    Returns
    -------
    tuple
        ``(ev, kinds, segs, stick, E0, status, t_status, n_events, window)``: ``ev`` (k, 11) columns
        t, x, w_before, w_after, v_before, v_after, energy, cumulative horn work, impulse on the free
        mass, tip velocity before / after (SI); ``kinds`` (k,) int8 ``KIND_*``; ``segs`` (s, 6 + 2n)
        segment starts: t, mode, w, w', v, v', then the n modal coordinates and n modal velocities;
        ``stick`` (p, 3): start, end, ``BODY_*``; initial energy (J); ``STATUS_*`` and its time (s);
        number of events; ``window`` the whole run's statistics row (``N_CSTATS``).
    """
    tab, xs, lam, G1, G2 = _kernel_data(horn, params.freq)
    stats = np.zeros(N_CSTATS)
    ev, kinds, nr, segs, ns, stk, nk, E0, status, t_status, n_ev = _core(
        pack(params), tab, xs, _hc_array(contact), float(params.t_end), int(params.max_events), True, 0.0, stats,
        lam, G1, G2)
    return (ev[:nr].copy(), kinds[:nr].copy(), segs[:ns].copy(), stk[:nk].copy(), float(E0), int(status),
            float(t_status), int(n_ev), stats)


@njit(cache=True, parallel=True)
def _ensemble(pmat, tab, xs, hc, t_from, t_end, max_events, out, lam, G1, G2):
    for i in prange(pmat.shape[0]):
        _core(pmat[i], tab, xs, hc, t_end, max_events, False, t_from, out[i], lam, G1, G2)


def ensemble_coupled(pmat: np.ndarray, horn: ModalHorn, freq_hz: float, t_from: float, t_end: float,
                     max_events: int, contact=None) -> np.ndarray:
    """Window statistics of many coupled runs (one horn, members differ in ``pmat`` rows).

    Parameters
    ----------
    pmat : ndarray (n_members, N_PARAMS)
        Packed impact parameters (:func:`impact.kernel.pack`); their ``freq`` must equal ``freq_hz``.
    horn : ModalHorn
    freq_hz : float
        Drive frequency, Hz.
    t_from, t_end : float
        Window, s.
    max_events : int
    contact : impact.contact.HuntCrossley, optional
        Compliant horn contact (see :func:`run_events`); None: Newton's law.

    Returns
    -------
    ndarray (n_members, N_CSTATS)
        The columns of :func:`impact.kernel.ensemble_stats` and ``C_DRIVE``, ``C_DAMP`` (J), ``C_FUND_RE``, ``C_FUND_IM`` (m s).
    """
    pmat = np.ascontiguousarray(np.atleast_2d(pmat), dtype=np.float64)
    if pmat.shape[1] != N_PARAMS:
        raise ValueError(f"pmat has {pmat.shape[1]} columns, expected {N_PARAMS}")
    tab, xs, lam, G1, G2 = _kernel_data(horn, freq_hz)
    out = np.zeros((pmat.shape[0], N_CSTATS))
    _ensemble(pmat, tab, xs, _hc_array(contact), float(t_from), float(t_end), int(max_events), out, lam, G1, G2)
    return out


def warmup() -> None:
    """Compile both entry points (or load them from numba's disk cache) on a tiny case;
    ``make install`` calls it beside :func:`impact.kernel.warmup`."""
    horn = ModalHorn([2 * math.pi * 20.5e3], [0.005], [1.0], [3.0], [0.5], [0.0], 1.0)
    p = ImpactParams(t_end=1e-3)
    run_events(p, horn)
    ensemble_coupled(pack(p)[None, :], horn, p.freq, 0.0, 1e-3, 1000)
