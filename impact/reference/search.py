"""The event search of the readable reference engines (plain Python, numpy).

A contact function is a :class:`ContactFn`: its values and time derivative, vectorised (to screen
a grid) and scalar (to decide), a bound B on ``|f''|`` and the interval to search.
:func:`first_event` finds the earliest root over several of them: grid bracketing with the chord
and Taylor bounds (:func:`interval_safe`), bisection (:func:`refine`) and Brent's method
(:func:`brent`, on :func:`impact.event_rules.brent_next`). The compiled engines run the same
search (:mod:`impact.kernel_blocks`) with scalars.
"""

from __future__ import annotations

import math

import numpy as np

from ..event_rules import CONTACT_TOL, H_MIN, brent_next, brent_start

__all__ = ["ContactFn", "first_event", "interval_safe", "brent", "refine", "tool_horn_gap", "tool_gap",
           "tool_release"]


def interval_safe(fa, fpa, fb, fpb, B, h, tol):
    """True where an interval provably keeps f > -tol (works on arrays and scalars)."""
    c2 = B * h * h
    return ((np.minimum(fa, fb) - 0.125 * c2 > -tol)
            | ((fa > -tol) & (fa + fpa * h - 0.5 * c2 > -tol))
            | ((fb > -tol) & (fb - fpb * h - 0.5 * c2 > -tol)))


def brent(f, xa: float, xb: float, fa: float, fb: float) -> float:
    """Root of f in [xa, xb] with f(xa) f(xb) < 0: Brent's method
    (:func:`impact.event_rules.brent_next`) to ``XTOL + RTOL |x|`` (s)."""
    st = brent_start(xa, xb, fa, fb)
    for _ in range(200):
        done, st = brent_next(st)
        if done:
            return st[1]
        st = st[:4] + (f(st[1])[0],) + st[5:]
    return st[1]


def refine(sca, a, b, fa, fpa, fb, fpb, B, tol):
    """First time in (a, b] where f reaches -tol, or None; f(a) > -tol is assumed."""
    h = b - a
    if fb <= -tol:
        # f' <= min(fpa + B s, fpb + B (h - s)) <= (fpa + fpb + B h)/2: monotone => one root.
        if fpa + fpb + B * h < 0.0 or h < H_MIN:
            # the root of f itself (not f + tol): no systematic shift of the contact position
            if fa <= 0.0:
                return a
            return brent(sca, a, b, fa, fb)
    else:
        c2 = B * h * h
        if (min(fa, fb) - 0.125 * c2 > -tol or fa + fpa * h - 0.5 * c2 > -tol
                or fb - fpb * h - 0.5 * c2 > -tol or h < H_MIN):
            return None
    m = 0.5 * (a + b)
    fm, fpm = sca(m)
    r = refine(sca, a, m, fa, fpa, fm, fpm, B, tol)
    if r is not None:
        return r
    return refine(sca, m, b, fm, fpm, fb, fpb, B, tol)


class ContactFn:
    """A contact function: vectorised and scalar (value, derivative), |f''| bound, search start."""

    __slots__ = ("name", "vec", "sca", "B", "start", "h", "end")

    def __init__(self, name, vec, sca, B, start, h, end=math.inf):
        self.name, self.vec, self.sca, self.B, self.start, self.h = name, vec, sca, B, start, h
        self.end = end


def tool_horn_gap(osc, t0: float, L0: float, A0: float, om: float):
    """Gap between the tool face and the horn tip while the free mass rides on one of them,
    and its time derivative: vectorised (for bracketing grids) and scalar (for root finding)."""

    def g_vec(tg):
        vv, vvd = osc.pv_vec(tg - t0)
        ph = om * tg
        return L0 + vv - A0 * np.cos(ph), vvd + A0 * om * np.sin(ph)

    def g_sca(tt):
        vv, vvd = osc.pv(tt - t0)
        ph = om * tt
        return L0 + vv - A0 * math.cos(ph), vvd + A0 * om * math.sin(ph)

    return g_vec, g_sca


def tool_gap(osc, t0: float, w0: float, wd0: float, a: float, L0: float):
    """Gap from the free mass in flight (from w0, wd0 at t0 under ``a``) to the tool face and its
    time derivative: vectorised and scalar."""

    def t_vec(tg):
        s = tg - t0
        vv, vvd = osc.pv_vec(s)
        return L0 + vv - (w0 + s * (wd0 + 0.5 * a * s)), vvd - (wd0 + a * s)

    def t_sca(tt):
        s = tt - t0
        vv, vvd = osc.pv(s)
        return L0 + vv - (w0 + s * (wd0 + 0.5 * a * s)), vvd - (wd0 + a * s)

    return t_vec, t_sca


def tool_release(osc, t0: float, a: float):
    """Contact force per mass ``a - v''`` of a free mass riding the tool (its release where it
    falls to zero) and its time derivative: vectorised and scalar."""

    def r_vec(tg):
        acc, jerk = osc.acc_jerk_vec(tg - t0)
        return a - acc, -jerk

    def r_sca(tt):
        acc, jerk = osc.acc_jerk(tt - t0)
        return a - acc, -jerk

    return r_vec, r_sca


def first_event(fns: list[ContactFn], t_hi: float) -> tuple[float | None, str | None]:
    """Earliest root over several contact functions in their [start, t_hi].

    The vectorised values only screen the grid; every interval that is not cleared is
    re-evaluated with the scalar function (the compiled kernel uses scalars throughout, and
    numpy's vector exp/cos may differ from libm in the last bit).
    """
    best_t, best_name = None, None
    for fn in fns:
        lo = fn.start
        hi = min(t_hi if best_t is None else best_t, fn.end)
        if lo >= hi:
            continue
        h = fn.h
        sca = fn.sca
        # chunks grow geometrically: short right after an event, long in mid-flight
        n = 32
        a = lo
        found = None
        while a < hi:
            b = min(a + n * h, hi)
            k = max(1, int(math.ceil((b - a) / h)))
            hh = (b - a) / k
            tg = a + np.arange(k + 1) * hh
            tg[k] = b
            f, fp = fn.vec(tg)
            f0, fp0 = sca(a)
            if f0 <= -CONTACT_TOL and fp0 < 0.0:
                found = a
                break
            ok = interval_safe(f[:-1], fp[:-1], f[1:], fp[1:], fn.B, hh, CONTACT_TOL)
            if not ok.all():
                for i in np.flatnonzero(~ok):
                    fa, fpa = sca(tg[i])
                    fb, fpb = sca(tg[i + 1])
                    if interval_safe(fa, fpa, fb, fpb, fn.B, hh, CONTACT_TOL):
                        continue
                    r = refine(sca, tg[i], tg[i + 1], fa, fpa, fb, fpb, fn.B, CONTACT_TOL)
                    if r is not None:
                        found = r
                        break
            if found is not None:
                break
            a = b
            n = min(n * 2, 4096)
        if found is not None:
            best_t, best_name = found, fn.name
    return best_t, best_name
