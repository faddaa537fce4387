"""The rules of the event search that every engine applies, written once in plain Python.

The readable reference engines (:mod:`impact.reference`) call these functions as they are; the
compiled engines (:mod:`impact.kernel_blocks`) compile the same functions with numba, so both
take the same decisions on the same bits. Read :mod:`impact.model` for why each rule exists.

* :data:`CONTACT_TOL`, :data:`H_MIN`, :data:`XTOL`, :data:`RTOL`, :data:`APEX_MIN`: tolerances of
  the contact test, the bisection and Brent's method, and the smallest resolved flight apex;
* :func:`sticks`: the sticking rule after an impact;
* :func:`parabola_reach`, :func:`parabola_leave`, :func:`parabola_excursion`: where a free
  flight can first touch a contact's band, leaves it for good, or is out of it and back;
* :func:`grid_step`: the bracketing grid's step from the bound on ``|f''|``;
* :func:`next_cross`: when the kinematic horn's acceleration next crosses the free mass's;
* :func:`free_mass_at`: the free mass's position and velocity in each segment mode;
* :func:`brent_start`, :func:`brent_next`: Brent's method, one step at a time (each engine
  evaluates its contact function between the steps).
"""

from __future__ import annotations

import math

from .columns import FREE, ON_HORN

__all__ = ["free_mass_at", "CONTACT_TOL", "H_MIN", "XTOL", "RTOL", "APEX_MIN", "sticks", "parabola_reach", "parabola_leave",
           "parabola_excursion", "grid_step", "next_cross", "brent_start", "brent_next"]

#: interpenetration accepted as "touching" (m): far above round-off of mm positions (~1e-19 m)
CONTACT_TOL = 1e-15
#: shortest interval bisected in the event search (s)
H_MIN = 1e-12
#: Brent's method stops at ``XTOL + RTOL |t|`` (s)
XTOL = 2e-16
RTOL = 8.9e-16
#: smallest resolved flight apex after an impact (m): 100 CONTACT_TOL
APEX_MIN = 1e-13


def sticks(rel: float, push: float, v_stick: float) -> bool:
    """Sticking rule after an impact.

    Parameters
    ----------
    rel : float
        Relative separation speed just after the impact, m/s.
    push : float
        Relative acceleration that drives the bodies together, m/s^2 (> 0: compressive).
    v_stick : float
        Sticking threshold of the relative speed, m/s.

    Returns
    -------
    bool
        True if the bodies move on together.
    """
    if push <= 0.0:
        return False
    # A flight whose apex rel^2 / (2 push) stays below APEX_MIN cannot be resolved against
    # CONTACT_TOL: its re-impact is found late, with an approach speed ~sqrt(2 push tol) that
    # can exceed the departure speed, and the chattering never ends (a Zeno loop of
    # ~1e-10 s flights). It is the tail of a chattering sequence: stick now.
    return rel < v_stick or rel * rel < 2.0 * push * APEX_MIN


def parabola_reach(p0: float, p1: float, acc: float) -> float:
    """Smallest s >= 0 with ``p0 + p1 s + acc s^2/2 <= 0`` (inf if never); p0 > 0 expected.

    Units: p0 m, p1 m/s, acc m/s^2; returns s, a little early on purpose (the grid search
    starts before the zone is reached).
    """
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
            # numerically stable pair of roots of (acc/2) s^2 + p1 s + p0
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


def parabola_leave(p0: float, p1: float, acc: float) -> float:
    """The s after which ``p0 + p1 s + acc s^2/2`` stays > 0 for good (inf if it may not).

    For acc > 0 the parabola's larger root; for acc = 0 (no gravity, no spring: the free mass
    flies straight) the line's root when it moves away (p1 > 0), else inf. The line's case
    closes the horn's grid search once a weightless free mass has left the horn's band, rather
    than keeping it open over the whole flight (~10x the run time at g = 0). Returned a little
    late on purpose (the grid search ends after the zone is left).
    """
    if acc == 0.0 and p1 > 0.0:
        return max(0.0, -p0 / p1) * (1.0 + 1e-9) + 1e-12
    if acc <= 0.0:
        return math.inf
    disc = p1 * p1 - 2.0 * acc * p0
    if disc < 0.0:
        return 0.0
    r2 = (-p1 + math.sqrt(disc)) / acc
    return max(0.0, r2) * (1.0 + 1e-9) + 1e-12


def parabola_excursion(p0: float, p1: float, acc: float) -> tuple[float, float]:
    """For p0 <= 0 < p1 and acc < 0: (r1, r2), a little narrow, on which ``p0 + p1 s + acc s^2/2``
    stays > 0 (the flight is out of a contact's band and back); (inf, inf) otherwise."""
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


def grid_step(B: float, t_end: float, fscale: float = 1e-7) -> float:
    """Grid step (s) whose chord bound ``B h^2/8`` is ``fscale`` (unit of f): far from a root
    every interval is cleared at once. Gaps use 0.1 µm; the release function (an acceleration)
    uses a fraction of its own size, else the bound |v''''| of a stiff tool forces ns steps."""
    if B <= 0.0:
        return t_end
    return min(math.sqrt(8.0 * fscale / B), 1e-3)


def next_cross(t0: float, up: bool, A0: float, om: float, om2: float, a: float) -> float:
    """Next t > t0 (s) where the kinematic horn's acceleration ``-A0 om^2 cos(om t)`` crosses the
    free mass's ``a`` upward (``up``) or downward; inf if it never does (``om2 = om^2``)."""
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


def brent_start(xa: float, xb: float, fa: float, fb: float) -> tuple:
    """State of Brent's method on [xa, xb] with f(xa) f(xb) < 0, for :func:`brent_next`:
    ``(xpre, xcur, xblk, fpre, fcur, fblk, spre, scur)`` (s and the unit of f)."""
    return xa, xb, 0.0, fa, fb, 0.0, 0.0, 0.0


def brent_next(st: tuple) -> tuple:
    """One step of Brent's method (inverse quadratic / secant steps safeguarded by bisection).

    Parameters
    ----------
    st : tuple
        The state (:func:`brent_start`), its ``fcur`` the value of f at its ``xcur``.

    Returns
    -------
    done : bool
        True if ``xcur`` is the root to ``XTOL + RTOL |x|`` (s).
    st : tuple
        The next state; unless ``done``, the caller evaluates f at its ``xcur`` (``st[1]``) and
        puts the value in its ``fcur`` (``st[4]``).
    """
    xpre, xcur, xblk, fpre, fcur, fblk, spre, scur = st
    if fpre != 0.0 and fcur != 0.0 and (fpre < 0.0) != (fcur < 0.0):
        xblk, fblk = xpre, fpre
        spre = xcur - xpre
        scur = spre
    if abs(fblk) < abs(fcur):
        xpre, xcur, xblk = xcur, xblk, xcur
        fpre, fcur, fblk = fcur, fblk, fcur
    delta = 0.5 * (XTOL + RTOL * abs(xcur))
    sbis = 0.5 * (xblk - xcur)
    if fcur == 0.0 or abs(sbis) < delta:
        return True, (xpre, xcur, xblk, fpre, fcur, fblk, spre, scur)
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
    return False, (xpre, xcur, xblk, fpre, fcur, fblk, spre, scur)


def free_mass_at(mode: int, s: float, w0: float, wd0: float, a: float, L0: float, uh: float, uhd: float,
                 v: float, vd: float) -> tuple[float, float]:
    """The free mass's position (m) and velocity (m/s) a time s (s) into a segment of ``mode``:
    its flight from (w0, wd0) under the acceleration ``a``, or riding the horn tip (uh, uhd) or
    the tool face (``L0 + v``, vd)."""
    if mode == FREE:
        return w0 + s * (wd0 + 0.5 * a * s), wd0 + a * s
    if mode == ON_HORN:
        return uh, uhd
    return L0 + v, vd
