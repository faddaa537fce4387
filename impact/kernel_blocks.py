"""Compiled building blocks of the event-driven engines (numba), shared by every compiled loop.

Each engine's loop (:mod:`impact.kernel` for the kinematic horn, :mod:`impact.kernel_modal` for
the modal horn) reads as the model's steps, and every step is one function here:

============================  ===========================================================
step                          functions
============================  ===========================================================
motion between events         :func:`osc_make`, :func:`osc_eval`, :func:`osc_pv` (damped
                              oscillator in closed form), :func:`tip` (modal horn tip),
                              :func:`horn_records`, :func:`modal_at` (the modes' records)
integrated motion             :func:`dp_stage`, :func:`dp_combine` (a Dormand-Prince 5(4)
                              step, tableau ``DP_*``, for contact phases)
plan the contacts             :func:`plan_flight`, :func:`plan_pinch`, :func:`plan_on_tool`,
                              :func:`plan_add` (contact functions with their ``|f''|`` bound,
                              grid step and search interval)
earliest root                 :func:`earliest` -> :func:`search` (grid bracketing with the
                              chord / Taylor bounds, :func:`interval_safe`) -> :func:`refine`
                              (bisection) -> :func:`brent`; :func:`contact_fn` evaluates
                              the gaps, pinch and releases; on the modal horn the grid's
                              tip is turned from point to point (:func:`grid_value`,
                              ``rot_*``: one exp, cos and sin per mode every ``ROT_K``
                              points, the clearing allowing for the rotation's round-off)
apply the law                 :func:`tool_event`, :func:`tool_impact`, :func:`horn_impact_kinematic`,
                              :func:`horn_impact_modal`, :func:`tool_skip`, :func:`sticks`
record                        :func:`record_segment`, :func:`record_event`,
                              :func:`count_impact`, :func:`close_stick`,
                              :func:`close_run`, :func:`mech_energy`
============================  ===========================================================

The rules shared with the readable reference engines (tolerances, sticking rule, parabola
zones, grid step, the kinematic horn's acceleration crossings) are the plain-Python functions of
:mod:`impact.event_rules`, compiled here as they are. Every floating-point operation is written
in the reference engines' order and ``fastmath`` is off, so the engines return the same events.

A further contact law (e.g. a compliant contact phase) is one more function beside
:func:`tool_impact` / :func:`horn_impact_modal`, called from the loop's "apply the law" step;
a further contact function is one more ``FN_*`` kind in :func:`contact_fn`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import event_rules, kernel_cache  # noqa: F401  (kernel_cache: drops stale caches first)
from .columns import (BODY_HORN, BODY_TOOL, FREE, KIND_TOOL, ON_HORN, ON_TOOL, S_HORN_WORK, S_KE_AFTER, S_KE_GAIN,
                      S_N_EVENTS, S_N_HORN, S_N_TOOL, S_STATUS, S_T_ON_HORN, S_T_ON_TOOL, STATUS_MAX_EVENTS,
                      STATUS_OK, STATUS_PINCHED)
from .event_rules import CONTACT_TOL, H_MIN
from .horn import H_A, H_B, H_JQ, H_JV, H_MASS, H_OMEGA, H_TIP, H_ZETA

# the rules of impact.event_rules, compiled
sticks = njit(cache=True)(event_rules.sticks)
parabola_reach = njit(cache=True)(event_rules.parabola_reach)
parabola_leave = njit(cache=True)(event_rules.parabola_leave)
parabola_excursion = njit(cache=True)(event_rules.parabola_excursion)
grid_step = njit(cache=True)(event_rules.grid_step)
next_cross = njit(cache=True)(event_rules.next_cross)
brent_start = njit(cache=True)(event_rules.brent_start)
brent_next = njit(cache=True)(event_rules.brent_next)
free_mass_at = njit(cache=True)(event_rules.free_mass_at)

#: contact functions: free mass to horn tip, tool face to free mass, tool face to horn tip (the
#: free mass pinched), release from the tool (``a - v''``), release from the modal horn (``u'' - a``)
FN_HORN, FN_TOOL, FN_PINCH, FN_RELEASE, FN_HREL = 0, 1, 2, 3, 4

#: oscillator record: kind, delta, al, be, gm, l1, P[5], Q[5], b0, b2, b4
O_KIND, O_DELTA, O_AL, O_BE, O_GM, O_L1, O_P, O_Q, O_B0, O_B2, O_B4 = 0, 1, 2, 3, 4, 5, 6, 11, 16, 17, 18
O_N = 19
#: contact record: segment start t0, free mass w0, w0', its acceleration a, gap L0, horn
#: angular frequency W and tip amplitudes Uc, Us (``Uc cos Wt + Us sin Wt``; the kinematic horn:
#: Uc = A0, Us = 0)
C_T0, C_W0, C_WD0, C_A, C_L0, C_W, C_UC, C_US = range(8)
C_N = 8
#: plan of contact functions: one row per function (kind, |f''| bound, grid step, start, end)
PL_KIND, PL_B, PL_H, PL_START, PL_END = range(5)
PL_ROWS = 4
#: event record columns: t, x, w_before, w_after, v_before, v_after, energy, horn work
E_N = 8


# ----------------------------------------------------------------------------- motion


@njit(cache=True)
def osc_make(o, mass, k, c, delta, x0, xd0):
    """Fill ``o`` with the closed form of ``mass y'' + c y' + k y = 0`` about ``delta`` (m) from
    position x0 (m) and velocity xd0 (m/s) (see :class:`impact.oscillator.Oscillator`)."""
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
    o[O_DELTA] = delta
    o[O_AL] = al
    if al < wn:
        o[O_KIND] = 0.0
        be = math.sqrt((wn - al) * (wn + al))
        o[O_BE] = be
        o[O_GM] = 0.0
        o[O_L1] = 0.0
        ks = min(1.0, be / (math.e * al)) if al > 0.0 else 1.0
        for n in range(5):
            P = y[n]
            Q = (y[n + 1] + al * y[n]) / be
            o[O_P + n] = P
            o[O_Q + n] = Q
            _osc_bound(o, n, min(math.sqrt(P * P + Q * Q), abs(P) + abs(Q) * ks))
    else:
        o[O_KIND] = 1.0
        gm = math.sqrt((al - wn) * (al + wn))
        l1 = -wn2 / (al + gm)
        o[O_BE] = 0.0
        o[O_GM] = gm
        o[O_L1] = l1
        kp = 1.0 / (math.e * -l1)
        if gm > 0.0:
            kp = min(kp, 0.5 / gm)
        for n in range(5):
            P = y[n]
            Q = y[n + 1] - l1 * y[n]
            o[O_P + n] = P
            o[O_Q + n] = Q
            b = abs(P) + abs(Q) * kp
            if gm > 0.0:
                r = Q * (0.5 / gm)
                b = min(b, abs(P + r) + abs(r))
            _osc_bound(o, n, b)


@njit(cache=True)
def _osc_bound(o, n, b):
    """Store the bound of derivative n where the record keeps one (0, 2, 4)."""
    if n == 0:
        o[O_B0] = b
    elif n == 2:
        o[O_B2] = b
    elif n == 4:
        o[O_B4] = b


@njit(cache=True, inline="always")
def osc_eval(o, s, n):
    """Derivatives n and n+1 of y at s (n = 0: position minus delta and velocity)."""
    if o[O_KIND] == 0.0:
        ex = math.exp(-o[O_AL] * s)
        cs = math.cos(o[O_BE] * s)
        sn = math.sin(o[O_BE] * s)
    else:
        gm = o[O_GM]
        sn = -math.expm1(-2.0 * gm * s) / (2.0 * gm) if gm > 0.0 else s
        ex = math.exp(o[O_L1] * s)
        cs = 1.0
    return (ex * (o[O_P + n] * cs + o[O_Q + n] * sn),
            ex * (o[O_P + n + 1] * cs + o[O_Q + n + 1] * sn))


@njit(cache=True, inline="always")
def osc_pv(o, s):
    """Position (m) and velocity (m/s) at s."""
    y, yd = osc_eval(o, s, 0)
    return o[O_DELTA] + y, yd


@njit(cache=True)
def tool_osc(o, mode_on_tool, m_tool, m_free, k0, c, a, v, vd):
    """The tool's oscillator over a segment: alone, or with the free mass riding it (mass
    ``m_tool + m_free`` about the static deflection ``m_free a / k0``)."""
    if mode_on_tool:
        osc_make(o, m_tool + m_free, k0, c, m_free * a / k0, v, vd)
    else:
        osc_make(o, m_tool, k0, c, 0.0, v, vd)


@njit(cache=True, inline="always")
def steady_tip(cp, c, s, order):
    """The steady part ``Uc cos Wt + Us sin Wt`` of the tip, its derivatives ``order`` and
    ``order + 1`` (order 0 or 2), from c = cos Wt and s = sin Wt."""
    W, Uc, Us = cp[C_W], cp[C_UC], cp[C_US]
    if order == 0:
        return Uc * c + Us * s, W * (-Uc * s + Us * c)
    return -W * W * (Uc * c + Us * s), -W * W * W * (-Uc * s + Us * c)


@njit(cache=True, inline="always")
def tip(tt, cp, tab, ho, n, order):
    """Modal horn tip derivatives ``order`` and ``order + 1`` at absolute time tt (order 0 or 2):
    the steady part ``Uc cos Wt + Us sin Wt`` plus every mode's free oscillation ``ho[i]``
    weighted by its tip participation."""
    ph = cp[C_W] * tt
    u, ud = steady_tip(cp, math.cos(ph), math.sin(ph), order)
    sl = tt - cp[C_T0]
    for i in range(n):
        y, yd = osc_eval(ho[i], sl, order)
        u += tab[i, H_TIP] * y
        ud += tab[i, H_TIP] * yd
    return u, ud


@njit(cache=True)
def horn_records(ho, tab, n, W, t0, q, qd):
    """Free-oscillation records of every mode at t0; returns the bounds of the modes' part of the
    tip's |u|, |u''| and |u''''| (the steady part excluded)."""
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
        osc_make(ho[i], m, m * om * om, 2.0 * tab[i, H_ZETA] * om * m, 0.0, q[i] - p, qd[i] - pd)
        b0 += abs(tab[i, H_TIP]) * ho[i, O_B0]
        b2 += abs(tab[i, H_TIP]) * ho[i, O_B2]
        b4 += abs(tab[i, H_TIP]) * ho[i, O_B4]
    return b0, b2, b4


@njit(cache=True)
def modal_at(ho, tab, n, W, t0, tt, q, qd):
    """Modal coordinates and velocities at tt (s) from the segment's records (in place)."""
    c = math.cos(W * tt)
    s = math.sin(W * tt)
    for i in range(n):
        y, yd = osc_eval(ho[i], tt - t0, 0)
        q[i] = tab[i, H_A] * c + tab[i, H_B] * s + y
        qd[i] = W * (-tab[i, H_A] * s + tab[i, H_B] * c) + yd



#: Dormand-Prince 5(4) tableau (nodes, stages, fifth- and fourth-order weights) of the adaptive steps
DP_C = np.array([0.0, 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0, 1.0])
DP_A = np.array([
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [1.0 / 5.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [3.0 / 40.0, 9.0 / 40.0, 0.0, 0.0, 0.0, 0.0],
    [44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0, 0.0, 0.0, 0.0],
    [19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0, 0.0, 0.0],
    [9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0, 0.0],
    [35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0]])
DP_B5 = np.array([35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0, 0.0])
DP_B4 = np.array([5179.0 / 57600.0, 0.0, 7571.0 / 16695.0, 393.0 / 640.0, -92097.0 / 339200.0, 187.0 / 2100.0,
                   1.0 / 40.0])


@njit(cache=True)
def dp_stage(k, y, h, K, out):
    """Argument of Dormand-Prince stage k (1..6): ``y + h sum_{r<k} A[k, r] K[r]`` into ``out``."""
    for j in range(y.size):
        acc = y[j]
        for r in range(k):
            acc += h * DP_A[k, r] * K[r, j]
        out[j] = acc


@njit(cache=True)
def dp_combine(y, h, K, y5, y4):
    """The step's fifth-order (``y5``) and embedded fourth-order (``y4``) results from the stages K."""
    for j in range(y.size):
        s5 = 0.0
        s4 = 0.0
        for r in range(7):
            s5 += DP_B5[r] * K[r, j]
            s4 += DP_B4[r] * K[r, j]
        y5[j] = y[j] + h * s5
        y4[j] = y[j] + h * s4


# ----------------------------------------------------------------------------- contact functions


@njit(cache=True)
def contact_fn(kind, tt, cp, o, tab, ho, n):
    """Contact function ``kind`` (``FN_*``) and its time derivative at absolute time tt (s): gaps
    in m, releases in m/s^2 (force per mass).

    ``cp``: the segment's contact record (``C_*``); ``o``: the tool's oscillator; ``tab``, ``ho``,
    ``n``: the modal horn's table, mode oscillators and mode count (:func:`tip`), or ``tab`` None
    for the kinematic horn ``u = A0 cos(W t)`` (``A0 = cp[C_UC]``; numba compiles each horn's
    version apart, the other's branches pruned)."""
    t0, w0, wd0, a, L0 = cp[C_T0], cp[C_W0], cp[C_WD0], cp[C_A], cp[C_L0]
    if kind == FN_HORN:
        s = tt - t0
        if tab is None:
            A0, om = cp[C_UC], cp[C_W]
            ph = om * tt
            return (w0 + s * (wd0 + 0.5 * a * s) - A0 * math.cos(ph),
                    wd0 + a * s + A0 * om * math.sin(ph))
        else:
            u, ud = tip(tt, cp, tab, ho, n, 0)
            return tip_gap(kind, tt, cp, o, u, ud)
    if kind == FN_TOOL:
        s = tt - t0
        vv, vvd = osc_pv(o, s)
        return L0 + vv - (w0 + s * (wd0 + 0.5 * a * s)), vvd - (wd0 + a * s)
    if kind == FN_PINCH:
        if tab is None:
            vv, vvd = osc_pv(o, tt - t0)
            A0, om = cp[C_UC], cp[C_W]
            ph = om * tt
            return L0 + vv - A0 * math.cos(ph), vvd + A0 * om * math.sin(ph)
        else:
            u, ud = tip(tt, cp, tab, ho, n, 0)
            return tip_gap(kind, tt, cp, o, u, ud)
    if kind == FN_HREL:
        if tab is None:
            return 0.0, 0.0
        else:
            # riding on the modal horn: the contact force per mass (u'' - a) falls to zero at the release
            u2, u3 = tip(tt, cp, tab, ho, n, 2)
            return tip_gap(kind, tt, cp, o, u2, u3)
    acc, jerk = osc_eval(o, tt - t0, 2)
    return a - acc, -jerk


@njit(cache=True, inline="always")
def tip_gap(kind, tt, cp, o, u, ud):
    """Contact function ``kind`` (FN_HORN, FN_PINCH or FN_HREL) and its time derivative at tt (s)
    from the modal tip's displacement and velocity (m, m/s; FN_HORN, FN_PINCH) or its second and
    third derivatives (FN_HREL)."""
    t0 = cp[C_T0]
    if kind == FN_HORN:
        s = tt - t0
        return cp[C_W0] + s * (cp[C_WD0] + 0.5 * cp[C_A] * s) - u, cp[C_WD0] + cp[C_A] * s - ud
    if kind == FN_PINCH:
        vv, vvd = osc_pv(o, tt - t0)
        return cp[C_L0] + vv - u, vvd - ud
    return u - cp[C_A], ud


# ----------------------------------------------------------------------------- rotated grid

#: grid points of the search between two direct evaluations of the modes' exponentials, cosines
#: and sines; in between each is turned by its factor over one grid step (see :func:`grid_value`)
ROT_K = 32
#: rotation record, one row per mode and a last one for the drive: exp(-al s), cos(be s),
#: sin(be s) at the current grid point, and their factors over one grid step
R_EX, R_C, R_S, R_FE, R_FC, R_FS = range(6)
EPS = 2.220446049250313e-16


@njit(cache=True)
def rot_setup(kind, cp, tab, ho, n, t_max):
    """The rotation record for a search of ``kind`` on the modal horn (no rows, nothing rotated: the
    kinematic horn, the tool's functions or an overdamped mode), and the bounds e0, e1 (units of f
    and f') of the rotated values' difference from the direct ones up to time t_max (s).

    Why the bounds hold: between two anchors each of the ROT_K turns rounds cos, sin and exp by a
    few eps of their size (|cos|, |sin|, exp(-al s) <= 1), so a mode's value moves by less than
    8 ROT_K eps (|P| + |Q|) of it; and the rotated point stands for the anchor's rounded time plus
    whole steps while the direct one takes the rounded grid time, its phase and its time since
    the segment's start: less than 8 eps t_max apart, times the bound of the next derivative."""
    if tab is None:
        return np.empty((0, 6)), 0.0, 0.0
    else:
        rotating = kind == FN_HORN or kind == FN_PINCH or kind == FN_HREL
        for i in range(n):
            rotating = rotating and ho[i, O_KIND] == 0.0
        if not rotating:
            return np.empty((0, 6)), 0.0, 0.0
        order = 2 if kind == FN_HREL else 0
        W = cp[C_W]
        amp = abs(cp[C_UC]) + abs(cp[C_US])
        a0, a1, a2 = amp * W ** order, amp * W ** (order + 1), amp * W ** (order + 2)
        for i in range(n):
            w = abs(tab[i, H_TIP])
            a0 += w * (abs(ho[i, O_P + order]) + abs(ho[i, O_Q + order]))
            a1 += w * (abs(ho[i, O_P + order + 1]) + abs(ho[i, O_Q + order + 1]))
            a2 += w * (abs(ho[i, O_P + order + 2]) + abs(ho[i, O_Q + order + 2]))
        rot = np.empty((n + 1, 6))
        rot[n, R_EX] = 1.0
        rot[n, R_FE] = 1.0
        dt = 8.0 * EPS * abs(t_max)
        return rot, 8.0 * ROT_K * EPS * a0 + dt * a1, 8.0 * ROT_K * EPS * a1 + dt * a2


@njit(cache=True)
def rot_anchor(rot, tt, hh, first, cp, ho, n):
    """The rotation record at tt (s) from the library's exp, cos and sin (the same expressions as
    :func:`osc_eval` and :func:`tip`), and at a chunk's ``first`` point the factors of step hh."""
    W = cp[C_W]
    ph = W * tt
    rot[n, R_C] = math.cos(ph)
    rot[n, R_S] = math.sin(ph)
    sl = tt - cp[C_T0]
    for i in range(n):
        rot[i, R_EX] = math.exp(-ho[i, O_AL] * sl)
        rot[i, R_C] = math.cos(ho[i, O_BE] * sl)
        rot[i, R_S] = math.sin(ho[i, O_BE] * sl)
    if first:
        rot[n, R_FC] = math.cos(W * hh)
        rot[n, R_FS] = math.sin(W * hh)
        for i in range(n):
            rot[i, R_FE] = math.exp(-ho[i, O_AL] * hh)
            rot[i, R_FC] = math.cos(ho[i, O_BE] * hh)
            rot[i, R_FS] = math.sin(ho[i, O_BE] * hh)


@njit(cache=True)
def rot_advance(rot, n):
    """Every row of the rotation record one grid step on."""
    for i in range(n + 1):
        c, s = rot[i, R_C], rot[i, R_S]
        rot[i, R_C] = c * rot[i, R_FC] - s * rot[i, R_FS]
        rot[i, R_S] = s * rot[i, R_FC] + c * rot[i, R_FS]
        rot[i, R_EX] *= rot[i, R_FE]


@njit(cache=True)
def rot_tip(rot, cp, tab, ho, n, order):
    """The tip's derivatives ``order`` and ``order + 1`` from the rotation record: :func:`tip`'s
    sums in its order, so at an anchor the same numbers."""
    u, ud = steady_tip(cp, rot[n, R_C], rot[n, R_S], order)
    for i in range(n):
        ex, cs, sn = rot[i, R_EX], rot[i, R_C], rot[i, R_S]
        u += tab[i, H_TIP] * (ex * (ho[i, O_P + order] * cs + ho[i, O_Q + order] * sn))
        ud += tab[i, H_TIP] * (ex * (ho[i, O_P + order + 1] * cs + ho[i, O_Q + order + 1] * sn))
    return u, ud


@njit(cache=True)
def grid_value(kind, tt, j, hh, cp, o, tab, ho, n, rot):
    """Contact function and its derivative at the j-th point tt (s) of a chunk of step hh (s), and
    whether it is the direct value: every ROT_K-th point an anchor (:func:`rot_anchor`), between
    them the rotation record turned one step (:func:`rot_advance`); without rows
    :func:`contact_fn`."""
    if tab is None:
        f, fp = contact_fn(kind, tt, cp, o, tab, ho, n)
        return f, fp, True
    else:
        if rot.shape[0] == 0:
            f, fp = contact_fn(kind, tt, cp, o, tab, ho, n)
            return f, fp, True
        anchor = j % ROT_K == 0
        if anchor:
            rot_anchor(rot, tt, hh, j == 0, cp, ho, n)
        else:
            rot_advance(rot, n)
        u, ud = rot_tip(rot, cp, tab, ho, n, 2 if kind == FN_HREL else 0)
        f, fp = tip_gap(kind, tt, cp, o, u, ud)
        return f, fp, anchor


# ----------------------------------------------------------------------------- root search


@njit(cache=True, inline="always")
def interval_safe(fa, fpa, fb, fpb, B, h, tol):
    """True if [ta, ta + h] provably keeps f > -tol: chord bound ``min(fa, fb) - B h^2/8`` or one
    endpoint's Taylor bound ``f +- f' h - B h^2/2`` above -tol (B bounds |f''|)."""
    c2 = B * h * h
    return ((min(fa, fb) - 0.125 * c2 > -tol)
            or ((fa > -tol) and (fa + fpa * h - 0.5 * c2 > -tol))
            or ((fb > -tol) and (fb - fpb * h - 0.5 * c2 > -tol)))


@njit(cache=True)
def brent(kind, cp, o, tab, ho, n, xa, xb, fa, fb):
    """Root of contact function ``kind`` in [xa, xb] with f(xa) f(xb) < 0: Brent's method
    (:func:`impact.event_rules.brent_next`) to ``XTOL + RTOL |x|`` (s)."""
    st = brent_start(xa, xb, fa, fb)
    for _ in range(200):
        done, st = brent_next(st)
        if done:
            break
        xpre, xcur, xblk, fpre, fcur, fblk, spre, scur = st
        st = (xpre, xcur, xblk, fpre, contact_fn(kind, xcur, cp, o, tab, ho, n)[0], fblk, spre, scur)
    return st[1]


@njit(cache=True, inline="always")
def _push(stack, sp, a, b, fa, fpa, fb, fpb):
    stack[sp, 0], stack[sp, 1], stack[sp, 2], stack[sp, 3], stack[sp, 4], stack[sp, 5] = a, b, fa, fpa, fb, fpb
    return sp + 1


@njit(cache=True)
def refine(kind, cp, o, tab, ho, n, a, b, fa, fpa, fb, fpb, B, tol, stack):
    """First time in (a, b] where f reaches -tol (f(a) > -tol assumed): bisection, depth first,
    left half first (an explicit stack of intervals); a provably monotone sign change goes to
    :func:`brent`. Returns (found, t)."""
    sp = _push(stack, 0, a, b, fa, fpa, fb, fpb)
    while sp > 0:
        sp -= 1
        a, b, fa, fpa, fb, fpb = (stack[sp, 0], stack[sp, 1], stack[sp, 2], stack[sp, 3],
                                  stack[sp, 4], stack[sp, 5])
        h = b - a
        if fb <= -tol:
            # f' <= (fpa + fpb + B h)/2 on the interval: monotone => one root
            if fpa + fpb + B * h < 0.0 or h < H_MIN:
                if fa <= 0.0:
                    return True, a
                # the root of f itself (not f + tol): no systematic shift of the contact position
                return True, brent(kind, cp, o, tab, ho, n, a, b, fa, fb)
        else:
            c2 = B * h * h
            if (min(fa, fb) - 0.125 * c2 > -tol or fa + fpa * h - 0.5 * c2 > -tol
                    or fb - fpb * h - 0.5 * c2 > -tol or h < H_MIN):
                continue
        m = 0.5 * (a + b)
        fm, fpm = contact_fn(kind, m, cp, o, tab, ho, n)
        # right half below the left one: the left is searched first
        sp = _push(stack, sp, m, b, fm, fpm, fb, fpb)
        sp = _push(stack, sp, a, m, fa, fpa, fm, fpm)
    return False, 0.0


@njit(cache=True)
def search(kind, cp, o, tab, ho, n, B, lo, hi, h, stack):
    """First root of one contact function on [lo, hi]: a grid of step about h in chunks that
    grow geometrically (short right after an event, long in mid-flight), each interval cleared
    by :func:`interval_safe` or handed to :func:`refine`. Returns (found, t)."""
    nn = 32
    a = lo
    rot, e0, e1 = rot_setup(kind, cp, tab, ho, n, hi)
    while a < hi:
        b = min(a + nn * h, hi)
        k = max(1, int(math.ceil((b - a) / h)))
        hh = (b - a) / k
        fa, fpa, _ = grid_value(kind, a, 0, hh, cp, o, tab, ho, n, rot)
        if fa <= -CONTACT_TOL and fpa < 0.0:
            return True, a
        ta, ea = a, True
        for i in range(k):
            tb = b if i == k - 1 else a + (i + 1) * hh
            fb, fpb, eb = grid_value(kind, tb, i + 1, hh, cp, o, tab, ho, n, rot)
            # a rotated value is cleared with its bound off (rot_setup); refine gets direct ones
            da, db = (0.0 if ea else e0), (0.0 if eb else e0)
            ga, gb = (0.0 if ea else e1), (0.0 if eb else e1)
            if not interval_safe(fa - da, fpa - ga, fb - db, fpb + gb, B, hh, CONTACT_TOL):
                if not ea:
                    fa, fpa = contact_fn(kind, ta, cp, o, tab, ho, n)
                if not eb:
                    fb, fpb = contact_fn(kind, tb, cp, o, tab, ho, n)
                    eb = True
                found, r = refine(kind, cp, o, tab, ho, n, ta, tb, fa, fpa, fb, fpb, B, CONTACT_TOL, stack)
                if found:
                    return True, r
            ta, fa, fpa, ea = tb, fb, fpb, eb
        a = b
        nn = min(nn * 2, 4096)
    return False, 0.0


@njit(cache=True)
def earliest(plan, nf, t_hi, cp, o, tab, ho, n, stack):
    """Earliest root over the ``nf`` planned contact functions, each searched on its
    [start, min(end, t_hi, the earliest root so far)]. Returns (found, t, kind)."""
    have = False
    te = 0.0
    name = -1
    for i in range(nf):
        lo = plan[i, PL_START]
        hi = min(te if have else t_hi, plan[i, PL_END])
        if lo >= hi:
            continue
        kind = int(plan[i, PL_KIND])
        found, r = search(kind, cp, o, tab, ho, n, plan[i, PL_B], lo, hi, plan[i, PL_H], stack)
        if found:
            have, te, name = True, r, kind
    return have, te, name


@njit(cache=True)
def event_status(name, n_ev, max_events):
    """Does the run end at an event of kind ``name``: a pinch, or one event over the cap?
    Returns (``STATUS_*``, the event count with this event unless pinched)."""
    if name == FN_PINCH:
        return STATUS_PINCHED, n_ev
    n_ev += 1
    return (STATUS_MAX_EVENTS if n_ev > max_events else STATUS_OK), n_ev


# ----------------------------------------------------------------------------- planning


@njit(cache=True)
def plan_add(plan, nf, kind, B, start, h, end):
    """Append contact function ``kind`` (``|f''| <= B``, grid step h, searched on [start, end])."""
    plan[nf, PL_KIND] = kind
    plan[nf, PL_B] = B
    plan[nf, PL_H] = h
    plan[nf, PL_START] = start
    plan[nf, PL_END] = end
    return nf + 1


@njit(cache=True)
def plan_flight(plan, nf, t0, w0, wd0, a, L0, b_horn, b_tool, skip_h, skip_t, Bh, Bt, t_end):
    """The contact functions to search during a free flight from (t0, w0, wd0) under the constant
    acceleration ``a``: horn and tool, each from where the parabola can first reach its band
    (``b_horn``, ``b_tool``: the bodies' displacement bounds, m) to where it leaves it for good,
    with the excursion out of the band and back skipped. Returns the new count."""
    zone_h = t0 + parabola_reach(w0 - b_horn - 1e-9, wd0, a)
    zone_t = t0 + parabola_reach(L0 - b_tool - 1e-9 - w0, -wd0, -a)
    # a flight that leaves a contact's band and comes back cannot touch in between
    xh1, xh2 = parabola_excursion(w0 - b_horn - 1e-9, wd0, a)
    xt1, xt2 = parabola_excursion(L0 - b_tool - 1e-9 - w0, -wd0, -a)
    for kind, zone, skip, B, lead, vel, acc, x1, x2 in (
            (FN_HORN, zone_h, skip_h, Bh, w0 - b_horn - 1e-9, wd0, a, xh1, xh2),
            (FN_TOOL, zone_t, skip_t, Bt, L0 - b_tool - 1e-9 - w0, -wd0, -a, xt1, xt2)):
        if zone < math.inf:
            start = max(t0, skip, zone)
            end = t0 + parabola_leave(lead, vel, acc)
            h = grid_step(B, t_end, 1e-7)
            if x2 < math.inf:
                nf = plan_add(plan, nf, kind, B, start, h, min(end, t0 + x1))
                nf = plan_add(plan, nf, kind, B, max(start, t0 + x2), h, end)
            else:
                nf = plan_add(plan, nf, kind, B, start, h, end)
    return nf


@njit(cache=True)
def plan_pinch(plan, nf, o, L0, horn_b0, horn_b2, start, t_end):
    """While the free mass rides the horn: search the tool face reaching the horn tip (a pinch)
    unless the bounds ``|v| <= b0``, ``|u| <= horn_b0`` (m) rule it out."""
    B = o[O_B2] + horn_b2
    if L0 - o[O_B0] - horn_b0 <= 0.0:
        nf = plan_add(plan, nf, FN_PINCH, B, start, grid_step(B, t_end, 1e-7), math.inf)
    return nf


@njit(cache=True)
def plan_on_tool(plan, nf, o, L0, a, horn_b0, horn_b2, t0, t_end):
    """While the free mass rides the tool: the pinch (tool face to horn tip) and the release
    (contact force per mass ``a - v''`` falls to zero), each unless its bound rules it out. The
    release function is an acceleration: its grid scale is a fraction of its own size."""
    B = o[O_B2] + horn_b2
    if L0 + o[O_DELTA] - o[O_B0] - horn_b0 <= 0.0:
        nf = plan_add(plan, nf, FN_PINCH, B, t0, grid_step(B, t_end, 1e-7), math.inf)
    if o[O_B2] >= a:
        Br = o[O_B4]
        nf = plan_add(plan, nf, FN_RELEASE, Br, t0, grid_step(Br, t_end, 1e-3 * (abs(a) + o[O_B2])), math.inf)
    return nf


# ----------------------------------------------------------------------------- contact laws


@njit(cache=True)
def tool_impact(m_free, m_tool, e1, c, k0, a, v_stick, v, vd, wd):
    """Newton's law at the tool (restitution e1, momentum conserved) and the sticking rule.

    Returns (v+, w+, stuck): the tool's and free mass's velocities after the impact (m/s); if
    ``stuck`` both move on with the common velocity."""
    M = m_tool + m_free
    rel = wd - vd                            # > 0: approaching the tool
    va = vd + m_free / M * (1.0 + e1) * rel
    wa = wd - m_tool / M * (1.0 + e1) * rel
    acc_tool = -(c * va + k0 * v) / m_tool
    stuck = sticks(va - wa, a - acc_tool, v_stick)
    if stuck:
        va = (m_tool * vd + m_free * wd) / M
        wa = va
    return va, wa, stuck


@njit(cache=True)
def tool_skip(o2, te, m_tool, k0, c, a, v, va, wa):
    """End of the interval after a tool impact on which the tool gap provably stays open: the
    separation speed over the bound of the relative acceleration (s)."""
    osc_make(o2, m_tool, k0, c, 0.0, v, va)
    return te + 2.0 * (va - wa) / (abs(a) + o2[O_B2])


@njit(cache=True)
def tool_event(o2, te, m_free, m_tool, e1, c, k0, a, v_stick, v, vd, wd, mode, stick_start, skip_h, skip_t):
    """A tool impact at te: :func:`tool_impact`, then either the stick on the tool or the
    interval on which the tool gap provably stays open. Returns (v+, w+, mode, stick_start,
    skip_h, skip_t)."""
    va, wa, stuck = tool_impact(m_free, m_tool, e1, c, k0, a, v_stick, v, vd, wd)
    if stuck:
        return va, wa, ON_TOOL, te, skip_h, skip_t
    return va, wa, mode, stick_start, te, tool_skip(o2, te, m_tool, k0, c, a, v, va, wa)


@njit(cache=True)
def horn_impact_kinematic(article, e2, m_horn, m_free, wd, uhd):
    """Newton's law at the kinematic horn: the infinite-mass driver ``w+ = u' - e2 (w- - u')``, or
    eq. 21 as printed (``article``), whose remaining approach is closed plastically. Returns w+."""
    rel_in = wd - uhd                        # < 0: approaching
    if not article:
        return uhd - e2 * rel_in
    mu = m_horn / (m_horn + m_free)
    wa = wd - mu * (1.0 + e2) * rel_in
    if wa < uhd:
        wa = uhd
    return wa


@njit(cache=True)
def horn_impact_modal(e2, m_free, Sg, series, tab, n, q, qd, wd, uhd):
    """Newton's law at the modal horn: the impulse ``J = -(1 + e2) rel / (1/m_w + Sg)`` on the
    free mass (``Sg = sum s_i^2 / m_i``, the tip's inverse effective mass), its reaction on the
    modes (``q`` and ``qd`` updated in place; a series drive's pseudo-modes jump by columns
    ``H_JQ``, ``H_JV``). Returns (J, w+, u'+)."""
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
    return J, wa, uhd - J * Sg


# ----------------------------------------------------------------------------- recording


@njit(cache=True)
def mech_energy(m_free, m_tool, k0, a, w, wd, v, vd):
    """Mechanical energy of free mass and tool (J): kinetic, tool spring, ``- m_w a w``."""
    return 0.5 * m_free * wd * wd - m_free * a * w + 0.5 * m_tool * vd * vd + 0.5 * k0 * v * v


@njit(cache=True)
def grow2(arr, n):
    """``arr`` (rows, cols) with twice the rows, the first n kept."""
    out = np.empty((2 * arr.shape[0], arr.shape[1]), arr.dtype)
    out[:n] = arr[:n]
    return out


@njit(cache=True)
def grow1(arr, n):
    """``arr`` with twice the length, the first n kept."""
    out = np.empty(2 * arr.shape[0], arr.dtype)
    out[:n] = arr[:n]
    return out


@njit(cache=True)
def record_segment(segs, n_seg, t, mode, w, wd, v, vd):
    """Store a segment start (t, mode, free mass w, w', tool v, v') in row n_seg; returns segs."""
    if n_seg == segs.shape[0]:
        segs = grow2(segs, n_seg)
    segs[n_seg, 0], segs[n_seg, 1], segs[n_seg, 2] = t, mode, w
    segs[n_seg, 3], segs[n_seg, 4], segs[n_seg, 5] = wd, v, vd
    return segs


@njit(cache=True)
def record_event(ev, kinds, n_rec, kind, te, x, wb, wa, vb, va, energy, work):
    """Store an impact in row n_rec (the first ``E_N`` columns); returns (ev, kinds)."""
    if n_rec == kinds.shape[0]:
        ev = grow2(ev, n_rec)
        kinds = grow1(kinds, n_rec)
    ev[n_rec, 0], ev[n_rec, 1], ev[n_rec, 2], ev[n_rec, 3] = te, x, wb, wa
    ev[n_rec, 4], ev[n_rec, 5], ev[n_rec, 6], ev[n_rec, 7] = vb, va, energy, work
    kinds[n_rec] = kind
    return ev, kinds


@njit(cache=True)
def record_stick(stk, n_stk, s0, s1, body):
    """Store a sticking phase [s0, s1] on ``body`` in row n_stk; returns stk."""
    if n_stk == stk.shape[0]:
        stk = grow2(stk, n_stk)
    stk[n_stk, 0], stk[n_stk, 1], stk[n_stk, 2] = s0, s1, body
    return stk


@njit(cache=True)
def count_impact(stats, te, t_from, t_end, kind, m_tool, vb, va, work, w_from):
    """Window statistics of one impact at te inside [t_from, t_end]: counts and, at the tool,
    its kinetic energy after the impact and its gain (J). Returns the horn work at the window's
    start (J): ``work`` while te is before it, else ``w_from``."""
    if te >= t_from and te <= t_end:
        if kind == KIND_TOOL:
            stats[S_N_TOOL] += 1.0
            stats[S_KE_AFTER] += 0.5 * m_tool * va ** 2
            stats[S_KE_GAIN] += 0.5 * m_tool * (va ** 2 - vb ** 2)
        else:
            stats[S_N_HORN] += 1.0
    return work if te < t_from else w_from


@njit(cache=True)
def close_stick(stk, n_stk, record, stats, body, s0, s1, t_from, t_end):
    """A sticking phase [s0, s1] on ``body`` ends: stored (with ``record``) and its time inside
    the window [t_from, t_end] counted (s). Returns (stk, n_stk)."""
    if record:
        stk = record_stick(stk, n_stk, s0, s1, body)
        n_stk += 1
    stats[S_T_ON_HORN if body == BODY_HORN else S_T_ON_TOOL] += max(0.0, min(s1, t_end) - max(s0, t_from))
    return stk, n_stk


@njit(cache=True)
def close_run(stk, n_stk, record, stats, status, mode, stick_start, t_from, t_end, horn_work, n_ev):
    """The run ends (``STATUS_*``): a stick still on at t_end is closed there; the window's horn
    work (J), status and event count go into ``stats``. Returns (stk, n_stk)."""
    if status == STATUS_OK and mode != FREE:
        stk, n_stk = close_stick(stk, n_stk, record, stats, BODY_HORN if mode == ON_HORN else BODY_TOOL,
                                 stick_start, t_end, t_from, t_end)
    stats[S_HORN_WORK] = horn_work
    stats[S_STATUS] = status
    stats[S_N_EVENTS] = n_ev
    return stk, n_stk
