"""Compiled event kernel of the impact model (numba).

The same algorithm as the reference :class:`impact.model._Sim` (read its module docstring for
the model, the corrections to the article, the sticking rule and the event search), written
with scalars only so that numba compiles it to machine code: analytic motion between events,
grid bracketing with the same analytic |f''| bounds and grid steps, bisection down to 1e-12 s,
Brent's method to ~2e-16 s, the same sticking / release / pinch / skip rules. Every floating
point operation is written in the same order as in the reference and ``fastmath`` is off, so
both engines return the same events (to the last bit in practice).

Functions are compiled on first use (``cache=True`` keeps the machine code on disk in
``__pycache__``); :mod:`impact.model` imports this module lazily.

Packed parameters (``pack``): a float64 vector, indices ``P_*``; ``horn_law`` is 0 kinematic,
1 article. Ensemble statistics (``ensemble_stats``): columns ``S_*``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .params import ImpactParams

__all__ = ["pack", "run_events", "ensemble_stats", "N_PARAMS", "N_STATS"]

# ----------------------------------------------------------------------------- layouts

#: indices of the packed parameter vector (SI units, as in ImpactParams)
P_M_FREE, P_A0, P_FREQ, P_E1, P_E2, P_M_HORN, P_M_TOOL, P_K0, P_C, P_GAP, P_G, P_V0, P_T_END, \
    P_SPRING_FORCE, P_HORN_LAW, P_V_STICK, P_SAMPLE_DT, P_MAX_EVENTS = range(18)
N_PARAMS = 18
HORN_LAW_KINEMATIC, HORN_LAW_ARTICLE = 0, 1

#: columns of ensemble_stats (same as impact.model.window_stats)
S_N_TOOL, S_N_HORN, S_KE_AFTER, S_KE_GAIN, S_HORN_WORK, S_T_ON_HORN, S_T_ON_TOOL, S_STATUS, \
    S_N_EVENTS = range(9)
N_STATS = 9

#: status codes
STATUS_OK, STATUS_PINCHED, STATUS_MAX_EVENTS = 0, 1, 2
#: event kinds (int8) and sticking bodies
KIND_HORN, KIND_TOOL = 0, 1
BODY_HORN, BODY_TOOL = 0, 1
#: segment modes (as impact.model)
FREE, ON_HORN, ON_TOOL = 0, 1, 2

# same constants as impact.model (the tests check they agree)
CONTACT_TOL = 1e-15
_H_MIN = 1e-12
_XTOL = 2e-16
_RTOL = 8.9e-16
_APEX_MIN = 1e-13

# contact functions
_FN_HORN, _FN_TOOL, _FN_PINCH, _FN_RELEASE = 0, 1, 2, 3
# oscillator record: kind, delta, al, be, gm, l1, P[5], Q[5], b0, b2, b4
_O_KIND, _O_DELTA, _O_AL, _O_BE, _O_GM, _O_L1, _O_P, _O_Q, _O_B0, _O_B2, _O_B4 = \
    0, 1, 2, 3, 4, 5, 6, 11, 16, 17, 18
_O_N = 19
# contact-function record: t0, w0, wd0, a, A0, om, L0
_C_N = 7
# event record columns: t, x, wb, wa, vb, va, E, W
_E_N = 8


def pack(p: ImpactParams) -> np.ndarray:
    """Parameters as a float64 vector of length ``N_PARAMS`` (indices ``P_*``, SI units).

    Parameters
    ----------
    p : ImpactParams
        Validated parameters.

    Returns
    -------
    ndarray
        ``horn_law`` is ``HORN_LAW_KINEMATIC`` (0) or ``HORN_LAW_ARTICLE`` (1); ``max_events``
        is stored as a float (exact up to 2^53).
    """
    v = np.empty(N_PARAMS)
    v[P_M_FREE], v[P_A0], v[P_FREQ], v[P_E1], v[P_E2] = p.m_free, p.A0, p.freq, p.e1, p.e2
    v[P_M_HORN], v[P_M_TOOL], v[P_K0], v[P_C], v[P_GAP] = p.m_horn, p.m_tool, p.k0, p.c, p.gap
    v[P_G], v[P_V0], v[P_T_END], v[P_SPRING_FORCE] = p.g, p.v0, p.t_end, p.spring_force
    v[P_HORN_LAW] = HORN_LAW_ARTICLE if p.horn_law == "article" else HORN_LAW_KINEMATIC
    v[P_V_STICK], v[P_SAMPLE_DT], v[P_MAX_EVENTS] = p.v_stick, p.sample_dt, p.max_events
    return v


# ----------------------------------------------------------------------------- oscillator


@njit(cache=True)
def _osc_make(o, mass, k, c, delta, x0, xd0):
    """Fill ``o`` with the closed form of ``mass y'' + c y' + k y = 0`` (see model._Osc)."""
    wn2 = k / mass
    wn = math.sqrt(wn2)
    al = c / (2.0 * mass)
    # derivatives 0..5 at s = 0 from the equation of motion (no heap array: hot path)
    y0 = x0 - delta
    y1 = xd0
    y2 = -2.0 * al * y1 - wn2 * y0
    y3 = -2.0 * al * y2 - wn2 * y1
    y4 = -2.0 * al * y3 - wn2 * y2
    y5 = -2.0 * al * y4 - wn2 * y3
    y = (y0, y1, y2, y3, y4, y5)
    o[_O_DELTA] = delta
    o[_O_AL] = al
    if al < wn:
        o[_O_KIND] = 0.0
        be = math.sqrt((wn - al) * (wn + al))
        o[_O_BE] = be
        o[_O_GM] = 0.0
        o[_O_L1] = 0.0
        ks = min(1.0, be / (math.e * al)) if al > 0.0 else 1.0
        for n in range(5):
            P = y[n]
            Q = (y[n + 1] + al * y[n]) / be
            o[_O_P + n] = P
            o[_O_Q + n] = Q
            b = min(math.sqrt(P * P + Q * Q), abs(P) + abs(Q) * ks)
            if n == 0:
                o[_O_B0] = b
            elif n == 2:
                o[_O_B2] = b
            elif n == 4:
                o[_O_B4] = b
    else:
        o[_O_KIND] = 1.0
        gm = math.sqrt((al - wn) * (al + wn))
        l1 = -wn2 / (al + gm)
        o[_O_BE] = 0.0
        o[_O_GM] = gm
        o[_O_L1] = l1
        kp = 1.0 / (math.e * -l1)
        if gm > 0.0:
            kp = min(kp, 0.5 / gm)
        for n in range(5):
            P = y[n]
            Q = y[n + 1] - l1 * y[n]
            o[_O_P + n] = P
            o[_O_Q + n] = Q
            b = abs(P) + abs(Q) * kp
            if gm > 0.0:
                r = Q * (0.5 / gm)
                b = min(b, abs(P + r) + abs(r))
            if n == 0:
                o[_O_B0] = b
            elif n == 2:
                o[_O_B2] = b
            elif n == 4:
                o[_O_B4] = b


@njit(cache=True)
def _osc_eval(o, s, n):
    """Derivatives n and n+1 of y at s (n = 0: position minus delta and velocity)."""
    if o[_O_KIND] == 0.0:
        ex = math.exp(-o[_O_AL] * s)
        cs = math.cos(o[_O_BE] * s)
        sn = math.sin(o[_O_BE] * s)
    else:
        gm = o[_O_GM]
        sn = -math.expm1(-2.0 * gm * s) / (2.0 * gm) if gm > 0.0 else s
        ex = math.exp(o[_O_L1] * s)
        cs = 1.0
    return (ex * (o[_O_P + n] * cs + o[_O_Q + n] * sn),
            ex * (o[_O_P + n + 1] * cs + o[_O_Q + n + 1] * sn))


@njit(cache=True)
def _osc_pv(o, s):
    y, yd = _osc_eval(o, s, 0)
    return o[_O_DELTA] + y, yd


# ----------------------------------------------------------------------------- event search


@njit(cache=True)
def _fn(kind, tt, cp, o):
    """Contact function ``kind`` and its time derivative at absolute time tt."""
    t0, w0, wd0, a, A0, om, L0 = cp[0], cp[1], cp[2], cp[3], cp[4], cp[5], cp[6]
    if kind == _FN_HORN:
        s = tt - t0
        ph = om * tt
        return (w0 + s * (wd0 + 0.5 * a * s) - A0 * math.cos(ph),
                wd0 + a * s + A0 * om * math.sin(ph))
    if kind == _FN_TOOL:
        s = tt - t0
        vv, vvd = _osc_pv(o, s)
        return L0 + vv - (w0 + s * (wd0 + 0.5 * a * s)), vvd - (wd0 + a * s)
    if kind == _FN_PINCH:
        vv, vvd = _osc_pv(o, tt - t0)
        ph = om * tt
        return L0 + vv - A0 * math.cos(ph), vvd + A0 * om * math.sin(ph)
    acc, jerk = _osc_eval(o, tt - t0, 2)
    return a - acc, -jerk


@njit(cache=True)
def _safe(fa, fpa, fb, fpb, B, h, tol):
    c2 = B * h * h
    return ((min(fa, fb) - 0.125 * c2 > -tol)
            or ((fa > -tol) and (fa + fpa * h - 0.5 * c2 > -tol))
            or ((fb > -tol) and (fb - fpb * h - 0.5 * c2 > -tol)))


@njit(cache=True)
def _brent(kind, cp, o, xa, xb, fa, fb):
    """Brent's method, operation for operation as model._brent."""
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
        fcur = _fn(kind, xcur, cp, o)[0]
    return xcur


@njit(cache=True)
def _refine(kind, cp, o, a, b, fa, fpa, fb, fpb, B, tol, stack):
    """model._refine without recursion: depth first, left half first. Returns (found, t)."""
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
                return True, _brent(kind, cp, o, a, b, fa, fb)
        else:
            c2 = B * h * h
            if (min(fa, fb) - 0.125 * c2 > -tol or fa + fpa * h - 0.5 * c2 > -tol
                    or fb - fpb * h - 0.5 * c2 > -tol or h < _H_MIN):
                continue
        m = 0.5 * (a + b)
        fm, fpm = _fn(kind, m, cp, o)
        # right half below the left one: the left is searched first
        stack[sp, 0], stack[sp, 1], stack[sp, 2], stack[sp, 3], stack[sp, 4], stack[sp, 5] = \
            m, b, fm, fpm, fb, fpb
        sp += 1
        stack[sp, 0], stack[sp, 1], stack[sp, 2], stack[sp, 3], stack[sp, 4], stack[sp, 5] = \
            a, m, fa, fpa, fm, fpm
        sp += 1
    return False, 0.0


@njit(cache=True)
def _search(kind, cp, o, B, lo, hi, h, stack):
    """First root of one contact function on [lo, hi] (model._first_event, one function)."""
    n = 32
    a = lo
    while a < hi:
        b = min(a + n * h, hi)
        k = max(1, int(math.ceil((b - a) / h)))
        hh = (b - a) / k
        fa, fpa = _fn(kind, a, cp, o)
        if fa <= -CONTACT_TOL and fpa < 0.0:
            return True, a
        ta = a
        for i in range(k):
            tb = b if i == k - 1 else a + (i + 1) * hh
            fb, fpb = _fn(kind, tb, cp, o)
            if not _safe(fa, fpa, fb, fpb, B, hh, CONTACT_TOL):
                found, r = _refine(kind, cp, o, ta, tb, fa, fpa, fb, fpb, B, CONTACT_TOL, stack)
                if found:
                    return True, r
            ta, fa, fpa = tb, fb, fpb
        a = b
        n = min(n * 2, 4096)
    return False, 0.0


# ----------------------------------------------------------------------------- helpers


@njit(cache=True)
def _sticks(rel, push, v_stick):
    if push <= 0.0:
        return False
    return rel < v_stick or rel * rel < 2.0 * push * _APEX_MIN


@njit(cache=True)
def _parabola_reach(p0, p1, acc):
    if p0 <= 0.0:
        return 0.0
    r = math.inf
    if acc == 0.0:
        if p1 < 0.0:
            r = -p0 / p1
    else:
        disc = p1 * p1 - 2.0 * acc * p0
        if disc >= 0.0:
            sq = math.sqrt(disc)
            q = -(p1 + math.copysign(sq, p1))
            if q != 0.0:
                r1 = q / acc
                r2 = 2.0 * p0 / q
                if r1 >= 0.0:
                    r = r1
                if r2 >= 0.0 and r2 < r:
                    r = r2
    if r == math.inf:
        return r
    return max(0.0, r * (1.0 - 1e-9) - 1e-12)


@njit(cache=True)
def _parabola_leave(p0, p1, acc):
    # model._parabola_leave, with its straight flight (acc = 0) case
    if acc == 0.0 and p1 > 0.0:
        return max(0.0, -p0 / p1) * (1.0 + 1e-9) + 1e-12
    if acc <= 0.0:
        return math.inf
    disc = p1 * p1 - 2.0 * acc * p0
    if disc < 0.0:
        return 0.0
    r2 = (-p1 + math.sqrt(disc)) / acc
    return max(0.0, r2) * (1.0 + 1e-9) + 1e-12


@njit(cache=True)
def _parabola_excursion(p0, p1, acc):
    # p0 <= 0 < p1, acc < 0: p > 0 (no contact possible) on (r1, r2), returned a little narrow
    if p0 > 0.0 or p1 <= 0.0 or acc >= 0.0:
        return math.inf, math.inf
    disc = p1 * p1 - 2.0 * acc * p0
    if disc <= 0.0:
        return math.inf, math.inf
    q = p1 + math.sqrt(disc)
    r1 = (-2.0 * p0 / q) * (1.0 + 1e-9) + 1e-12
    r2 = (q / -acc) * (1.0 - 1e-9) - 1e-12
    if r2 <= r1:
        return math.inf, math.inf
    return r1, r2


@njit(cache=True)
def _grid_step(B, t_end, fscale):
    if B <= 0.0:
        return t_end
    return min(math.sqrt(8.0 * fscale / B), 1e-3)


@njit(cache=True)
def _plan_flight(t0, w0, wd0, a, L0, b_horn, b_tool, skip_h, skip_t, Bh, Bt, t_end,
                 fkind, fB, fh, fstart, fend, nf):
    """The contact functions to search during a free flight from (t0, w0, wd0) under the constant
    acceleration ``a``: horn and tool, each from where the parabola can first reach its band
    (``b_horn``, ``b_tool``: the bodies' displacement bounds, m) to where it leaves it for good,
    with the excursion out of the band and back skipped. Appended from row ``nf`` of the
    ``f*`` arrays; returns the new count. Shared by both compiled engines."""
    zone_h = t0 + _parabola_reach(w0 - b_horn - 1e-9, wd0, a)
    zone_t = t0 + _parabola_reach(L0 - b_tool - 1e-9 - w0, -wd0, -a)
    # a flight that leaves a contact's band and comes back cannot touch in between
    xh1, xh2 = _parabola_excursion(w0 - b_horn - 1e-9, wd0, a)
    xt1, xt2 = _parabola_excursion(L0 - b_tool - 1e-9 - w0, -wd0, -a)
    for kind, zone, skip, B, lead, vel, acc, x1, x2 in (
            (_FN_HORN, zone_h, skip_h, Bh, w0 - b_horn - 1e-9, wd0, a, xh1, xh2),
            (_FN_TOOL, zone_t, skip_t, Bt, L0 - b_tool - 1e-9 - w0, -wd0, -a, xt1, xt2)):
        if zone < math.inf:
            start = max(t0, skip, zone)
            end = t0 + _parabola_leave(lead, vel, acc)
            for part in range(2 if x2 < math.inf else 1):
                fkind[nf], fB[nf] = kind, B
                fh[nf] = _grid_step(B, t_end, 1e-7)
                if x2 < math.inf:
                    fstart[nf] = start if part == 0 else max(start, t0 + x2)
                    fend[nf] = min(end, t0 + x1) if part == 0 else end
                else:
                    fstart[nf], fend[nf] = start, end
                nf += 1
    return nf


@njit(cache=True)
def _next_cross(t0, up, A0, om, om2, a):
    if A0 == 0.0:
        return math.inf
    cstar = -a / (A0 * om2)
    if abs(cstar) >= 1.0:
        return math.inf
    th = math.acos(cstar) if up else 2.0 * math.pi - math.acos(cstar)
    ph0 = om * t0
    k = math.ceil((ph0 - th) / (2.0 * math.pi))
    t = (th + 2.0 * math.pi * k) / om
    while t <= t0:
        k += 1
        t = (th + 2.0 * math.pi * k) / om
    return t


@njit(cache=True)
def _grow2(arr, n):
    out = np.empty((2 * arr.shape[0], arr.shape[1]), arr.dtype)
    out[:n] = arr[:n]
    return out


@njit(cache=True)
def _grow1(arr, n):
    out = np.empty(2 * arr.shape[0], arr.dtype)
    out[:n] = arr[:n]
    return out


# ----------------------------------------------------------------------------- main loop


@njit(cache=True)
def _core(pv, t_end, max_events, record, t_from, stats):
    """One run. With ``record`` the events, sticking phases and segments are stored (growable
    arrays); ``stats`` (length N_STATS) is filled with the window statistics either way."""
    m_free, A0, e1, e2 = pv[P_M_FREE], pv[P_A0], pv[P_E1], pv[P_E2]
    m_horn, m_tool, k0, c, L0 = pv[P_M_HORN], pv[P_M_TOOL], pv[P_K0], pv[P_C], pv[P_GAP]
    v_stick = pv[P_V_STICK]
    article = pv[P_HORN_LAW] == HORN_LAW_ARTICLE
    om = 2.0 * math.pi * pv[P_FREQ]
    om2 = om * om
    a = pv[P_G] - pv[P_SPRING_FORCE] / m_free
    Bh = abs(a) + A0 * om2
    M = m_tool + m_free

    cap = 1024 if record else 1
    ev = np.empty((cap, _E_N))
    kinds = np.empty(cap, np.int8)
    segs = np.empty((cap, 6))
    stk = np.empty((cap, 3))
    n_rec = 0
    n_seg = 0
    n_stk = 0

    o = np.empty(_O_N)
    o2 = np.empty(_O_N)
    cp = np.empty(_C_N)
    stack = np.empty((128, 6))
    fkind = np.empty(4, np.int64)
    fB = np.empty(4)
    fstart = np.empty(4)
    fh = np.empty(4)
    fend = np.empty(4)

    for j in range(stats.shape[0]):
        stats[j] = 0.0
    w_from = 0.0
    w_last = 0.0

    t = 0.0
    mode = FREE
    w = A0
    wd = pv[P_V0]
    v = 0.0
    vd = 0.0
    skip_h = max(_next_cross(0.0, True, A0, om, om2, a) if -A0 * om2 * math.cos(om * 0.0) < a else 0.0,
                 2.0 * pv[P_V0] / Bh)
    skip_t = 0.0
    E0 = 0.5 * m_free * wd * wd - m_free * a * w + 0.5 * m_tool * vd * vd + 0.5 * k0 * v * v
    work = 0.0
    stick_start = 0.0
    stick_E = 0.0
    n_ev = 0
    status = STATUS_OK
    t_status = 0.0
    while t < t_end:
        if mode == ON_TOOL:
            _osc_make(o, M, k0, c, m_free * a / k0, v, vd)
        else:
            _osc_make(o, m_tool, k0, c, 0.0, v, vd)
        if record:
            if n_seg == segs.shape[0]:
                segs = _grow2(segs, n_seg)
            segs[n_seg, 0], segs[n_seg, 1], segs[n_seg, 2] = t, mode, w
            segs[n_seg, 3], segs[n_seg, 4], segs[n_seg, 5] = wd, v, vd
            n_seg += 1
        t0, w0, wd0 = t, w, wd
        cp[0], cp[1], cp[2], cp[3], cp[4], cp[5], cp[6] = t0, w0, wd0, a, A0, om, L0
        Bv = o[_O_B2]
        nf = 0
        t_rel = math.inf
        if mode == FREE:
            Bt = Bv + abs(a)
            nf = _plan_flight(t0, w0, wd0, a, L0, A0, o[_O_B0], skip_h, skip_t, Bh, Bt, t_end,
                              fkind, fB, fh, fstart, fend, nf)
        elif mode == ON_HORN:
            B = Bv + A0 * om2
            if L0 - o[_O_B0] - A0 <= 0.0:
                fkind[nf], fB[nf] = _FN_PINCH, B
                fstart[nf] = max(t0, skip_t)
                fh[nf] = _grid_step(B, t_end, 1e-7)
                fend[nf] = math.inf
                nf += 1
            t_rel = _next_cross(t0, False, A0, om, om2, a)
        else:
            Br = o[_O_B4]
            B = Bv + A0 * om2
            if L0 + o[_O_DELTA] - o[_O_B0] - A0 <= 0.0:
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

        # earliest root over the contact functions
        t_hi = min(t_end, t_rel)
        have = False
        te = 0.0
        name = -1
        for i in range(nf):
            lo = fstart[i]
            hi = min(te if have else t_hi, fend[i])
            if lo >= hi:
                continue
            found, r = _search(fkind[i], cp, o, fB[i], lo, hi, fh[i], stack)
            if found:
                have, te, name = True, r, fkind[i]
        if not have and t_rel <= t_end:
            have, te, name = True, t_rel, _FN_RELEASE
        if not have:
            break
        if name == _FN_PINCH:
            status, t_status = STATUS_PINCHED, te
            break
        n_ev += 1
        if n_ev > max_events:
            status, t_status = STATUS_MAX_EVENTS, te
            break
        s = te - t0
        v, vd = _osc_pv(o, s)
        ph = om * te
        uh = A0 * math.cos(ph)
        uhd = -A0 * om * math.sin(ph)
        if mode == FREE:
            w, wd = w0 + s * (wd0 + 0.5 * a * s), wd0 + a * s
        elif mode == ON_HORN:
            w, wd = uh, uhd
        else:
            w, wd = L0 + v, vd
        t = te
        if L0 + v <= 2.0 * A0:
            status, t_status = STATUS_PINCHED, te
            break
        if name == _FN_RELEASE:
            if mode == ON_HORN:
                work += (0.5 * m_free * wd * wd - m_free * a * w) - stick_E
                skip_h = _next_cross(te, True, A0, om, om2, a)
                skip_t = te
            else:
                skip_h = te
                skip_t = te
            body = BODY_HORN if mode == ON_HORN else BODY_TOOL
            if record:
                if n_stk == stk.shape[0]:
                    stk = _grow2(stk, n_stk)
                stk[n_stk, 0], stk[n_stk, 1], stk[n_stk, 2] = stick_start, te, body
                n_stk += 1
            d = max(0.0, min(te, t_end) - max(stick_start, t_from))
            stats[S_T_ON_HORN if body == BODY_HORN else S_T_ON_TOOL] += d
            mode = FREE
            continue
        if name == _FN_HORN:
            x = uh
            rel_in = wd - uhd
            if not article:
                wa = uhd - e2 * rel_in
            else:
                mu = m_horn / (m_horn + m_free)
                wa = wd - mu * (1.0 + e2) * rel_in
                if wa < uhd:
                    wa = uhd
            work += m_free * (wa - wd) * uhd
            wb = wd
            uacc = -A0 * om2 * math.cos(om * te)
            if _sticks(wa - uhd, uacc - a, v_stick):
                wa = uhd
                mode = ON_HORN
                stick_start = te
                stick_E = 0.5 * m_free * wa * wa - m_free * a * x
                skip_t = te
            else:
                fu = uacc - a
                skip_h = te + 2.0 * (wa - uhd) / Bh
                if fu < 0.0:
                    skip_h = max(skip_h, _next_cross(te, True, A0, om, om2, a))
                skip_t = te
            w, wd = x, wa
            vb = vd
            va = vd
            kind = KIND_HORN
        else:
            x = L0 + v
            vb, wb = vd, wd
            rel = wd - vd
            va = vd + m_free / M * (1.0 + e1) * rel
            wa = wd - m_tool / M * (1.0 + e1) * rel
            acc_tool = -(c * va + k0 * v) / m_tool
            if _sticks(va - wa, a - acc_tool, v_stick):
                va = (m_tool * vd + m_free * wd) / M
                wa = va
                mode = ON_TOOL
                stick_start = te
            else:
                _osc_make(o2, m_tool, k0, c, 0.0, v, va)
                skip_t = te + 2.0 * (va - wa) / (abs(a) + o2[_O_B2])
                skip_h = te
            w, wd, vd = x, wa, va
            kind = KIND_TOOL
        energy = 0.5 * m_free * wd * wd - m_free * a * w + 0.5 * m_tool * vd * vd + 0.5 * k0 * v * v
        if record:
            if n_rec == kinds.shape[0]:
                ev = _grow2(ev, n_rec)
                kinds = _grow1(kinds, n_rec)
            ev[n_rec, 0], ev[n_rec, 1], ev[n_rec, 2], ev[n_rec, 3] = te, x, wb, wa
            ev[n_rec, 4], ev[n_rec, 5], ev[n_rec, 6], ev[n_rec, 7] = vb, va, energy, work
            kinds[n_rec] = kind
            n_rec += 1
        # window statistics
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


def run_events(pvec: np.ndarray, t_end: float, max_events: int) -> tuple:
    """Simulate one parameter set and return every event (compiled; see module docstring).

    Parameters
    ----------
    pvec : ndarray
        Packed parameters (:func:`pack`).
    t_end : float
        Simulated time, s.
    max_events : int
        Event cap (impacts and releases); exceeding it ends the run with status 2.

    Returns
    -------
    tuple
        ``(t, kind, x, w_before, w_after, v_before, v_after, energy, horn_work,
        stick_start, stick_end, stick_body, seg_t0, seg_mode, seg_w0, seg_wd0, seg_v0,
        seg_vd0, energy0, status, t_status, n_events)``: event arrays (s, int8 ``KIND_*``, m,
        m/s, m/s, m/s, m/s, J, cumulative J), sticking phases (s, s, int8 ``BODY_*``), segment
        starts (s, int8 mode ``FREE``/``ON_HORN``/``ON_TOOL``, free-mass position m and velocity
        m/s, tool position m and velocity m/s: enough to rebuild each segment's oscillator),
        initial energy (J), ``STATUS_*`` and the time it was reached (s; 0 when ok) and the
        number of events (impacts and releases).
    """
    stats = np.zeros(N_STATS)
    ev, kinds, n, segs, ns, stk, nk, E0, status, t_status, n_ev = _core(
        np.ascontiguousarray(pvec, dtype=np.float64), float(t_end), int(max_events), True, 0.0, stats)
    ev = ev[:n]
    segs = segs[:ns]
    stk = stk[:nk]
    return (ev[:, 0].copy(), kinds[:n].copy(), ev[:, 1].copy(), ev[:, 2].copy(), ev[:, 3].copy(),
            ev[:, 4].copy(), ev[:, 5].copy(), ev[:, 6].copy(), ev[:, 7].copy(),
            stk[:, 0].copy(), stk[:, 1].copy(), stk[:, 2].astype(np.int8),
            segs[:, 0].copy(), segs[:, 1].astype(np.int8), segs[:, 2].copy(), segs[:, 3].copy(),
            segs[:, 4].copy(), segs[:, 5].copy(), float(E0), int(status), float(t_status), int(n_ev))


@njit(cache=True, parallel=True)
def _ensemble(pmat, t_from, t_end, max_events, out):
    for i in prange(pmat.shape[0]):
        _core(pmat[i], t_end, max_events, False, t_from, out[i])


def ensemble_stats(pmat: np.ndarray, t_from: float, t_end: float, max_events: int) -> np.ndarray:
    """Window statistics of many runs, in parallel over the members (no per-event storage).

    Parameters
    ----------
    pmat : ndarray, shape (n_members, N_PARAMS)
        Packed parameters (:func:`pack`), one row per member.
    t_from, t_end : float
        Window [t_from, t_end], s; every member runs from 0 to t_end.
    max_events : int
        Event cap per member.

    Returns
    -------
    ndarray, shape (n_members, N_STATS)
        Columns ``S_N_TOOL``, ``S_N_HORN``, ``S_KE_AFTER`` (J), ``S_KE_GAIN`` (J),
        ``S_HORN_WORK`` (J), ``S_T_ON_HORN``, ``S_T_ON_TOOL`` (s), ``S_STATUS``,
        ``S_N_EVENTS`` (see :func:`impact.model.window_stats`). A member with status != 0
        (pinched, too many events) does not stop the others; its other columns hold the values
        up to the failure and should be discarded.
    """
    pmat = np.ascontiguousarray(np.atleast_2d(pmat), dtype=np.float64)
    if pmat.shape[1] != N_PARAMS:
        raise ValueError(f"pmat has {pmat.shape[1]} columns, expected N_PARAMS = {N_PARAMS}")
    out = np.zeros((pmat.shape[0], N_STATS))
    _ensemble(pmat, float(t_from), float(t_end), int(max_events), out)
    return out


def warmup() -> None:
    """Compile both entry points (or load them from numba's on-disk cache) on a tiny case.

    ``make install`` calls it, so the first real run does not pay
    the compile time (about 20 s from a cold cache, 0.3 s from the cache).
    """
    from .params import ImpactParams

    pv = pack(ImpactParams(t_end=1e-3))
    run_events(pv, 1e-3, 1000)
    ensemble_stats(pv[None, :], 0.0, 1e-3, 1000)
