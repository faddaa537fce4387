"""Event-driven simulation of the RPUD percussive system: horn -> free mass -> drill tool.

Model (article section 3, assumptions 1-5)
------------------------------------------
Axis x along the drill, from the horn tip toward the drill tool; ``g`` acts along +x (drill
pointing down pulls the free mass toward the tool; set ``g = 0`` for space, negative for a
drill pointing up).

* Horn tip: kinematic driver ``u(t) = A0 cos(2 pi f t)``, unaffected by impacts (eq. 1-2).
* Free mass (point mass m_w; its length is subtracted into the gap): free flight
  ``w'' = a = g - F_spring / m_w`` (``F_spring`` = optional restoring spring toward the horn,
  0 by default, taken constant over the stroke: the device's soft preloaded spring).
* Drill tool: damped oscillator ``m_v v'' + c v' + k0 v = 0`` about its rest position; its face
  is at ``x = L0 + v(t)``. Gravity on the tool is balanced by k0 in the rest position. Under-,
  critically and over-damped tools are all solved in closed form (:class:`_Osc`).
* Contacts: gap to horn ``g_h = w - u >= 0``, gap to tool ``g_t = L0 + v - w >= 0``.
* Tool impact (eq. 11-13, restitution e1, momentum conserved).
* Horn impact (eq. 19-21, restitution e2). With the default ``horn_law="kinematic"`` the horn
  is an infinite-mass driver (assumption 1): ``w+ = u' - e2 (w- - u')``. ``horn_law="article"``
  keeps eq. 21 as printed: ``w+ = w- - m_u/(m_u+m_w) (1+e2)(w- - u')`` with the horn's velocity
  unchanged (an effective-mass reading of the horn tip during the microsecond impact).
* Initial state (t = 0): horn at u(0) = A0 with zero velocity, the free mass just leaving it,
  ``w(0) = A0``, ``w'(0) = v0`` toward the tool (the article starts just after a horn impact;
  starting at rest on the horn with gravity toward the tool never reaches the horn again);
  tool at rest, ``v = v' = 0``.

Corrections to the article's equations
--------------------------------------
1. Eq. 4 repeats the term ``w'_{k-1}(t - t_{k-1})`` and drops the initial position: the
   flight is ``w(t) = u(t_{k-1}) + w'_{k-1}(t - t_{k-1}) + (a/2)(t - t_{k-1})^2``.
2. Eq. 3-5/14-15 write gravity as ``-g`` with an axis whose direction is not fixed; here the
   axis is fixed (horn -> tool) and gravity is ``+g`` along it, a single sign used everywhere.
3. Eq. 7 uses absolute time t in ``exp(-zeta wn t) sin(wd t + phi)`` with initial values taken
   at t_{i-1}: the time origin must be the last impact, ``s = t - t_{i-1}``; with
   ``tan phi = wd v / (v' + zeta wn v)`` the amplitude is ``sqrt(v^2 + ((v' + zeta wn v)/wd)^2)``
   (consistent); we use the equivalent complex form ``v = Re(C exp(lambda s))``.
4. Eq. 8-9: the contact condition is tool face = free mass, ``L0 + v(t_i) = w(t_i)``: the gap
   L0 is missing, and eq. 9's right side repeats eq. 4's typo (``w'_{k-1}`` in place of the
   start position).
5. Eq. 10: the free-mass velocity is ``w' - g(t - t_k)`` (article: ``+g/2``); the tool velocity
   uses the amplitude of the current flight (article: ``v_0``, ``v'_0``) and the time since the
   last impact.
6. Eq. 12 and 20 are written with the sign convention "separation speed over approach speed";
   we use ``(w+ - v+) = -e1 (w- - v-)``, identical in content.
7. Eq. 15: ``w(t_i) = L0 + v(t_i)`` (the gap again).
8. Eq. 17: the right side must be the free-mass flight of eq. 15
   ``L0 + v(t_i) + w'_i (t - t_i) + (a/2)(t - t_i)^2``; the article substitutes the tool's
   *velocity* expression of eq. 10 for the position.
9. Eq. 21: the horn's velocity is unchanged, ``u'+ = u'`` (article: ``= v_k``, the tool).
   Under assumption 1 the horn is an infinite-mass driver, so the factor
   ``m_u / (m_u + m_w)`` becomes 1 (our default); eq. 21 as printed is available as
   ``horn_law="article"``.
10. Eq. 21 as printed, with ``e2 < m_w / m_u``, leaves the free mass still approaching the
    horn (``w+ - u' < 0``: the factor ``m_u/(m_u+m_w)(1+e2)`` is below 1) and it would end up
    inside the horn. We keep the law but close the remaining approach plastically,
    ``w+ = u'`` (zero relative velocity); the sticking rule then decides (stick while
    ``u'' > a``, else separate). The horn work counts the whole impulse,
    ``m_w (w+ - w-) u'``.
11. Eq. 7 is an underdamped sinusoid; critically and over-damped tools (``c >= 2 sqrt(k0 m_v)``)
    use ``(c1 + c2 s) exp(-wn s)`` and two real exponentials (written as
    ``exp(l1 s)(P + Q (1 - exp(-2 gm s))/(2 gm))`` to avoid cancellation near critical).

Chattering and sticking
-----------------------
When an impact leaves a relative speed below ``v_stick`` (default 1e-6 m/s) and the contact
force needed to keep the bodies together is compressive, the free mass sticks:
* on the horn it moves with the horn, ``w = u``, while the horn accelerates toward the tool
  faster than the free mass would fall, ``u'' > a``; it separates (zero relative speed) at the
  analytic time where ``u''`` drops below ``a``;
* on the tool the pair moves as one damped oscillator of mass ``m_v + m_w`` loaded by
  ``m_w a``; it separates where the tool's acceleration exceeds ``a``.
Each chattering sequence therefore ends after finitely many impacts (relative speeds fall by
the factor e each time until below ``v_stick``). With e = 1 there is no chattering. A free mass
pinched between horn and tool raises :class:`SimulationError` ("increase gap or k0").

Bounded time (rule of the sub-tolerance flight): an impact also ends in sticking when the
flight it starts could not be resolved, i.e. its apex ``rel^2 / (2 push)`` (``push`` = the
relative acceleration driving the bodies together, e.g. ``u'' - a`` on the horn) is below
``_APEX_MIN = 1e-13 m`` = 100 ``CONTACT_TOL``. Without it, a free mass pressed onto the horn
by a strong spring or negative g (|a| ~ 1e3 m/s^2, horn acceleration ~3e5 m/s^2) made
flights of ~1e-10 s whose apex (~2e-17 m) stayed inside the contact tolerance: the re-impact
was detected only once the gap reached -1e-15 m, with an approach speed sqrt(2 push tol)
~1e-5 m/s larger than the departure speed (1.4e-6 m/s, just above ``v_stick``), so the
relative speed never decayed and the events piled up at one instant (a Zeno
loop: before the rule, 29 of 400 random parameter sets over broad ranges took > 4 s in the
Python engine). With the rule, every resolved flight
has its approach speed right to ~10 % (the detection lag is at most sqrt(2 push tol)) and a
chattering sequence shrinks geometrically into a stick. The release function of a stick on
the tool, an acceleration, gets a grid step scaled to its own size (not the 0.1 µm of the
gaps), else a stiff tool's |v''''| bound forced nanosecond steps through long sticks.

Event finding (no missed impacts)
---------------------------------
Each contact function f(t) (gap, or contact force for a release) has an analytic bound B on
|f''| over the current flight (horn: A0 w^2; tool: |C| wn^2 from the complex amplitude;
free mass: |a|). On a grid of step h, an interval [ta, tb] is proven contact-free if
``min(fa, fb) - B h^2/8 > -tol`` (chord bound) or one endpoint's Taylor bound
``f + f' h - B h^2/2`` stays above ``-tol``. Other intervals are bisected (down to 1e-12 s),
a sign change with a provably monotone f goes to Brent's method (xtol ~2e-16 s). This finds
grazing contacts as well (a local minimum below zero forces bisection). ``tol = 1e-15 m``:
the largest interpenetration that can go unnoticed is ~1e-15 m. After a horn impact, the horn
gap is convex while ``u'' < a``: it cannot close before ``u''`` rises above ``a`` again,
which is found analytically.

Engines
-------
:func:`simulate` runs the compiled kernel (:mod:`impact.kernel`, numba) by default and this
module's :class:`_Sim` with ``engine="python"``: the same algorithm, operation for operation,
so both return the same events. :func:`window_stats` computes the statistics columns of
:func:`impact.kernel.ensemble_stats` from one :class:`ImpactResult`.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np

from rpud_common.result import Result

from .columns import (FREE, N_STATS, ON_HORN, ON_TOOL, S_HORN_WORK, S_KE_AFTER, S_KE_GAIN, S_N_EVENTS, S_N_HORN,
                      S_N_TOOL, S_STATUS, S_T_ON_HORN, S_T_ON_TOOL)
from .event_rules import (APEX_MIN as _APEX_MIN, CONTACT_TOL, H_MIN as _H_MIN, RTOL as _RTOL, XTOL as _XTOL,
                          brent_next, brent_start, grid_step as _grid_step, next_cross,
                          parabola_excursion as _parabola_excursion, parabola_leave as _parabola_leave,
                          parabola_reach as _parabola_reach, sticks as _sticks)
from .params import ImpactParams

__all__ = ["simulate", "window_stats", "ImpactResult", "SimulationError", "CONTACT_TOL",
           "amplitude_spectrum", "N_STATS"]

log = logging.getLogger(__name__)

HORN, TOOL = "horn", "tool"


class SimulationError(RuntimeError):
    """The simulation cannot continue (pinched free mass, event cap reached)."""


# ----------------------------------------------------------------------------- primitives


class _Osc:
    """Free motion of a damped oscillator ``m y'' + c y' + k y = 0``, position ``delta + y(s)``.

    Every derivative ``z = y^(n)`` solves the same equation, with initial values
    ``y^(n)(0), y^(n+1)(0)`` from the recursion ``y'' = -2 al y' - wn^2 y``
    (``al = c / 2m``, ``wn^2 = k / m``). Closed forms, with ``P = z(0)``:

    * underdamped (al < wn, ``be = sqrt(wn^2 - al^2)``):
      ``z = exp(-al s) (P cos(be s) + Q sin(be s))``, ``Q = (z'(0) + al P) / be``;
    * critically (al = wn) and over-damped (``gm = sqrt(al^2 - wn^2)``, slow root
      ``l1 = -al + gm``): ``z = exp(l1 s) (P + Q phi(s))``, ``Q = z'(0) - l1 P``,
      ``phi = (1 - exp(-2 gm s)) / (2 gm)`` (``= s`` at critical damping): the sum of the two
      real exponentials written without their cancellation near critical damping.

    ``b0``, ``b2``, ``b4`` bound ``|y|``, ``|y''|``, ``|y''''|`` over all s >= 0 (m, m/s^2,
    m/s^4); the event search relies on them.
    """

    __slots__ = ("delta", "kind", "al", "be", "gm", "l1", "P", "Q", "b0", "b2", "b4")

    def __init__(self, mass: float, k: float, c: float, delta: float, x0: float, xd0: float):
        wn2 = k / mass
        wn = math.sqrt(wn2)
        al = c / (2.0 * mass)
        y = [x0 - delta, xd0]
        for _ in range(4):
            y.append(-2.0 * al * y[-1] - wn2 * y[-2])
        self.delta, self.al = delta, al
        P, Q, bnd = [0.0] * 5, [0.0] * 5, [0.0] * 5
        if al < wn:
            self.kind = 0
            be = math.sqrt((wn - al) * (wn + al))
            self.be, self.gm, self.l1 = be, 0.0, 0.0
            # exp(-al s)|sin(be s)| <= min(1, be s exp(-al s)) <= min(1, be / (e al)): finite
            # near critical damping, where |Q| alone grows like 1 / be
            ks = min(1.0, be / (math.e * al)) if al > 0.0 else 1.0
            for n in range(5):
                P[n] = y[n]
                Q[n] = (y[n + 1] + al * y[n]) / be
                bnd[n] = min(math.sqrt(P[n] * P[n] + Q[n] * Q[n]), abs(P[n]) + abs(Q[n]) * ks)
        else:
            self.kind = 1
            gm = math.sqrt((al - wn) * (al + wn))
            l1 = -wn2 / (al + gm)          # = -al + gm, without the cancellation
            self.be, self.gm, self.l1 = 0.0, gm, l1
            # exp(l1 s) phi(s) <= min(s exp(l1 s), 1 / (2 gm)) <= min(1 / (e |l1|), 1 / (2 gm))
            kp = 1.0 / (math.e * -l1)
            if gm > 0.0:
                kp = min(kp, 0.5 / gm)
            for n in range(5):
                P[n] = y[n]
                Q[n] = y[n + 1] - l1 * y[n]
                b = abs(P[n]) + abs(Q[n]) * kp
                if gm > 0.0:
                    # two-exponential form (P + Q/2gm) e^{l1 s} - (Q/2gm) e^{(l1 - 2gm) s}
                    r = Q[n] * (0.5 / gm)
                    b = min(b, abs(P[n] + r) + abs(r))
                bnd[n] = b
        self.P, self.Q = P, Q
        self.b0, self.b2, self.b4 = bnd[0], bnd[2], bnd[4]

    # scalar ---------------------------------------------------------------
    def _basis(self, s: float) -> tuple[float, float, float]:
        if self.kind == 0:
            return math.exp(-self.al * s), math.cos(self.be * s), math.sin(self.be * s)
        ph = -math.expm1(-2.0 * self.gm * s) / (2.0 * self.gm) if self.gm > 0.0 else s
        return math.exp(self.l1 * s), 1.0, ph

    def pos(self, s: float) -> float:
        ex, cs, sn = self._basis(s)
        return self.delta + ex * (self.P[0] * cs + self.Q[0] * sn)

    def pv(self, s: float) -> tuple[float, float]:
        ex, cs, sn = self._basis(s)
        P, Q = self.P, self.Q
        return self.delta + ex * (P[0] * cs + Q[0] * sn), ex * (P[1] * cs + Q[1] * sn)

    def acc_jerk(self, s: float) -> tuple[float, float]:
        ex, cs, sn = self._basis(s)
        P, Q = self.P, self.Q
        return ex * (P[2] * cs + Q[2] * sn), ex * (P[3] * cs + Q[3] * sn)

    # vector ---------------------------------------------------------------
    def _basis_vec(self, s: np.ndarray):
        if self.kind == 0:
            return np.exp(-self.al * s), np.cos(self.be * s), np.sin(self.be * s)
        ph = -np.expm1(-2.0 * self.gm * s) / (2.0 * self.gm) if self.gm > 0.0 else s
        return np.exp(self.l1 * s), 1.0, ph

    def pv_vec(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ex, cs, sn = self._basis_vec(s)
        P, Q = self.P, self.Q
        return self.delta + ex * (P[0] * cs + Q[0] * sn), ex * (P[1] * cs + Q[1] * sn)

    def acc_jerk_vec(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ex, cs, sn = self._basis_vec(s)
        P, Q = self.P, self.Q
        return ex * (P[2] * cs + Q[2] * sn), ex * (P[3] * cs + Q[3] * sn)


def _safe(fa, fpa, fb, fpb, B, h, tol):
    """True where an interval provably keeps f > -tol (works on arrays and scalars)."""
    c2 = B * h * h
    return ((np.minimum(fa, fb) - 0.125 * c2 > -tol)
            | ((fa > -tol) & (fa + fpa * h - 0.5 * c2 > -tol))
            | ((fb > -tol) & (fb - fpb * h - 0.5 * c2 > -tol)))


def _brent(f, xa: float, xb: float, fa: float, fb: float) -> float:
    """Root of f in [xa, xb] with f(xa) f(xb) < 0: Brent's method
    (:func:`impact.event_rules.brent_next`) to ``XTOL + RTOL |x|`` (s)."""
    st = brent_start(xa, xb, fa, fb)
    for _ in range(200):
        done, st = brent_next(st)
        if done:
            break
        st = st[:4] + (f(st[1])[0],) + st[5:]
    return st[1]


def _refine(sca, a, b, fa, fpa, fb, fpb, B, tol):
    """First time in (a, b] where f reaches -tol, or None; f(a) > -tol is assumed."""
    h = b - a
    if fb <= -tol:
        # f' <= min(fpa + B s, fpb + B (h - s)) <= (fpa + fpb + B h)/2: monotone => one root.
        if fpa + fpb + B * h < 0.0 or h < _H_MIN:
            # the root of f itself (not f + tol): no systematic shift of the contact position
            if fa <= 0.0:
                return a
            return _brent(sca, a, b, fa, fb)
    else:
        c2 = B * h * h
        if (min(fa, fb) - 0.125 * c2 > -tol or fa + fpa * h - 0.5 * c2 > -tol
                or fb - fpb * h - 0.5 * c2 > -tol or h < _H_MIN):
            return None
    m = 0.5 * (a + b)
    fm, fpm = sca(m)
    r = _refine(sca, a, m, fa, fpa, fm, fpm, B, tol)
    if r is not None:
        return r
    return _refine(sca, m, b, fm, fpm, fb, fpb, B, tol)


class _Fn:
    """A contact function: vectorised and scalar (value, derivative), |f''| bound, search start."""

    __slots__ = ("name", "vec", "sca", "B", "start", "h", "end")

    def __init__(self, name, vec, sca, B, start, h, end=math.inf):
        self.name, self.vec, self.sca, self.B, self.start, self.h = name, vec, sca, B, start, h
        self.end = end


def _tool_horn_gap(osc, t0: float, L0: float, A0: float, om: float):
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


def _first_event(fns: list[_Fn], t_hi: float) -> tuple[float | None, str | None]:
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
            ok = _safe(f[:-1], fp[:-1], f[1:], fp[1:], fn.B, hh, CONTACT_TOL)
            if not ok.all():
                for i in np.flatnonzero(~ok):
                    fa, fpa = sca(tg[i])
                    fb, fpb = sca(tg[i + 1])
                    if _safe(fa, fpa, fb, fpb, fn.B, hh, CONTACT_TOL):
                        continue
                    r = _refine(sca, tg[i], tg[i + 1], fa, fpa, fb, fpb, fn.B, CONTACT_TOL)
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


# ----------------------------------------------------------------------------- results


def amplitude_spectrum(x: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Single-sided amplitude spectrum of a uniformly sampled signal (mean removed).

    Parameters
    ----------
    x : ndarray
        Samples (any unit).
    dt : float
        Sample spacing, s.

    Returns
    -------
    freq : ndarray
        Frequencies, Hz.
    amp : ndarray
        Amplitude of each sinusoidal component, same unit as ``x`` (2|X|/N, DC as |X|/N).
    """
    x = np.asarray(x, dtype=float)
    n = x.size
    X = np.fft.rfft(x - x.mean())
    amp = np.abs(X) / n
    amp[1:] *= 2.0
    if n % 2 == 0:
        amp[-1] /= 2.0
    return np.fft.rfftfreq(n, dt), amp


@dataclass(repr=False)
class ImpactResult(Result):
    """Outcome of :func:`simulate`: one trajectory, i.e. one sample of a chaotic motion (for
    numbers to read, use the ensemble statistics of :func:`impact.ensemble_statistics`).

    Event arrays (one entry per impact, time-ordered):

    ``t`` (s), ``contact`` ("horn"/"tool"), ``x`` (contact position, m), ``w_before``/``w_after``
    (free-mass velocity, m/s), ``v_before``/``v_after`` (tool velocity, m/s; at a horn impact
    the tool is not involved and both equal its velocity at that time), ``energy`` (mechanical
    energy of free mass + tool after the event, J: kinetic + tool spring - m_w a w),
    ``horn_work`` (cumulative work done by the horn up to and including the event, J).

    ``stick`` lists (t_start, t_end, body) of sticking phases. ``n_events`` counts impacts and
    releases (the solver's events). ``t_grid`` (s), ``u``, ``w``
    and ``tool_face`` (m) are the horn tip, free mass and tool face positions on a uniform grid.
    """

    params: ImpactParams
    t: np.ndarray
    contact: np.ndarray
    x: np.ndarray
    w_before: np.ndarray
    w_after: np.ndarray
    v_before: np.ndarray
    v_after: np.ndarray
    energy: np.ndarray
    horn_work: np.ndarray
    energy0: float
    stick: list = field(default_factory=list)
    n_events: int = 0
    t_grid: np.ndarray | None = None
    u: np.ndarray | None = None
    w: np.ndarray | None = None
    tool_face: np.ndarray | None = None

    @property
    def is_tool(self) -> np.ndarray:
        return self.contact == TOOL

    @property
    def tool_impacts(self) -> int:
        return int(np.count_nonzero(self.is_tool))

    @property
    def horn_impacts(self) -> int:
        return int(self.t.size - self.tool_impacts)

    @property
    def tool_impact_rate_hz(self) -> float:
        """Mean free-mass/tool collision rate over the simulated time, Hz."""
        return self.tool_impacts / self.params.t_end

    @property
    def horn_impact_rate_hz(self) -> float:
        return self.horn_impacts / self.params.t_end

    @property
    def tool_ke_after(self) -> np.ndarray:
        """Drill-tool kinetic energy just after each tool impact, J."""
        return 0.5 * self.params.m_tool * self.v_after[self.is_tool] ** 2

    @property
    def mean_tool_ke_after_impact_j(self) -> float:
        ke = self.tool_ke_after
        return float(ke.mean()) if ke.size else 0.0

    def spectrum(self) -> tuple[np.ndarray, np.ndarray]:
        """Amplitude spectrum of the free-mass displacement (Hz, m): the Fig. 12 analogue."""
        if self.w is None:
            raise ValueError("simulate(..., series=False) recorded no time series")
        return amplitude_spectrum(self.w, self.params.sample_dt)

    def events(self) -> list[dict]:
        return [
            {"t": float(self.t[i]), "contact": str(self.contact[i]),
             "w_before": float(self.w_before[i]), "w_after": float(self.w_after[i]),
             "v_before": float(self.v_before[i]), "v_after": float(self.v_after[i])}
            for i in range(self.t.size)
        ]

    def summary(self) -> dict:
        return {
            "tool_impacts": self.tool_impacts,
            "horn_impacts": self.horn_impacts,
            "tool_impact_rate_hz": self.tool_impact_rate_hz,
            "horn_impact_rate_hz": self.horn_impact_rate_hz,
            "mean_tool_ke_after_impact_j": self.mean_tool_ke_after_impact_j,
            "sticking_phases": len(self.stick),
        }

    def _headline(self) -> str:
        p = self.params
        return (f"one sample, {p.m_free * 1e3:g} g free mass, A0 {p.A0 * 1e6:.3g} um, {p.t_end * 1e3:g} ms: "
                f"{self.tool_impacts} tool and {self.horn_impacts} horn impacts, "
                f"mean tool KE after impact {self.mean_tool_ke_after_impact_j * 1e3:.3g} mJ")

    def _arrays(self) -> dict:
        out = {k: getattr(self, k) for k in ("t", "x", "w_before", "w_after", "v_before", "v_after", "energy",
                                             "horn_work")}
        out["is_tool"] = self.is_tool
        if self.t_grid is not None:
            out.update(t_grid=self.t_grid, u=self.u, w=self.w, tool_face=self.tool_face)
        return out

    def _record(self) -> dict:
        """The CLI's JSON document: params, counts, rates, mean tool KE, events."""
        out = {"params": self.params.to_dict()}
        out.update(self.summary())
        out["events"] = self.events()
        return out


# ----------------------------------------------------------------------------- simulation


class _Sim:
    """The readable reference implementation; :mod:`impact.kernel` compiles the same steps."""

    def __init__(self, p: ImpactParams):
        self.p = p
        self.om = p.omega
        self.om2 = self.om * self.om
        self.A0 = p.A0
        self.a = p.a_free
        self.L0 = p.gap
        self.Bh = abs(self.a) + p.A0 * self.om2
        self.M = p.m_tool + p.m_free

    # horn ------------------------------------------------------------------
    def horn(self, t):
        ph = self.om * t
        return self.A0 * math.cos(ph), -self.A0 * self.om * math.sin(ph)

    def horn_acc(self, t):
        return -self.A0 * self.om2 * math.cos(self.om * t)

    def _next_cross(self, t0: float, up: bool) -> float:
        """Next t > t0 where f = u'' - a crosses zero upward (up) or downward."""
        return next_cross(t0, up, self.A0, self.om, self.om2, self.a)

    def energy(self, w, wd, v, vd):
        p = self.p
        return 0.5 * p.m_free * wd * wd - p.m_free * self.a * w + 0.5 * p.m_tool * vd * vd + 0.5 * p.k0 * v * v

    # main loop -------------------------------------------------------------
    def run(self) -> tuple[ImpactResult, tuple]:
        """Simulate; return the result (no time series) and the segment starts
        ``(t0, mode, w0, wd0, v0, vd0)`` that :func:`_series` samples."""
        p = self.p
        A0, om, a, L0 = self.A0, self.om, self.a, self.L0
        t = 0.0
        mode = FREE
        w, wd = A0, p.v0          # leaving the horn tip at its outermost point
        v, vd = 0.0, 0.0
        # the horn gap is convex while u'' < a: no horn contact before that ends
        skip_h = max(self._next_cross(0.0, up=True) if self.horn_acc(0.0) < a else 0.0,
                     2.0 * p.v0 / self.Bh)
        skip_t = 0.0
        E0 = self.energy(w, wd, v, vd)
        work = 0.0
        ev = {k: [] for k in ("t", "contact", "x", "wb", "wa", "vb", "va", "E", "W")}
        segs = []  # (t0, mode, w0, wd0, v0, vd0)
        stick = []
        stick_start = None
        stick_E = 0.0
        n_ev = 0
        t_end = p.t_end
        while t < t_end:
            if mode == ON_TOOL:
                osc = _Osc(self.M, p.k0, p.c, p.m_free * a / p.k0, v, vd)
            else:
                osc = _Osc(p.m_tool, p.k0, p.c, 0.0, v, vd)
            segs.append((t, mode, w, wd, v, vd))
            t0, w0, wd0 = t, w, wd
            Bv = osc.b2   # bound on |v''|
            fns = []
            if mode == FREE:
                def h_vec(tg, t0=t0, w0=w0, wd0=wd0):
                    s = tg - t0
                    ph = om * tg
                    return (w0 + s * (wd0 + 0.5 * a * s) - A0 * np.cos(ph),
                            wd0 + a * s + A0 * om * np.sin(ph))

                def h_sca(tt, t0=t0, w0=w0, wd0=wd0):
                    s = tt - t0
                    ph = om * tt
                    return (w0 + s * (wd0 + 0.5 * a * s) - A0 * math.cos(ph),
                            wd0 + a * s + A0 * om * math.sin(ph))

                def t_vec(tg, t0=t0, w0=w0, wd0=wd0, osc=osc):
                    s = tg - t0
                    vv, vvd = osc.pv_vec(s)
                    return L0 + vv - (w0 + s * (wd0 + 0.5 * a * s)), vvd - (wd0 + a * s)

                def t_sca(tt, t0=t0, w0=w0, wd0=wd0, osc=osc):
                    s = tt - t0
                    vv, vvd = osc.pv(s)
                    return L0 + vv - (w0 + s * (wd0 + 0.5 * a * s)), vvd - (wd0 + a * s)

                Bt = Bv + abs(a)
                # g_h >= w - A0 and g_t >= L0 - |v| - w: no contact before the parabola w(s)
                # comes within 1 nm of these bounds (found analytically)
                zone_h = t0 + _parabola_reach(w0 - A0 - 1e-9, wd0, a)
                zone_t = t0 + _parabola_reach(L0 - osc.b0 - 1e-9 - w0, -wd0, -a)
                # a flight that leaves a contact's band and comes back cannot touch in between
                for name, vec, sca, B, zone, skip, lead, vel, acc in (
                        (HORN, h_vec, h_sca, self.Bh, zone_h, skip_h, w0 - A0 - 1e-9, wd0, a),
                        (TOOL, t_vec, t_sca, Bt, zone_t, skip_t, L0 - osc.b0 - 1e-9 - w0, -wd0, -a)):
                    if zone == math.inf:
                        continue
                    start, end = max(t0, skip, zone), t0 + _parabola_leave(lead, vel, acc)
                    x1, x2 = _parabola_excursion(lead, vel, acc)
                    if x2 < math.inf:
                        fns.append(_Fn(name, vec, sca, B, start, _grid_step(B, t_end), min(end, t0 + x1)))
                        fns.append(_Fn(name, vec, sca, B, max(start, t0 + x2), _grid_step(B, t_end), end))
                    else:
                        fns.append(_Fn(name, vec, sca, B, start, _grid_step(B, t_end), end))
                t_rel = math.inf
            elif mode == ON_HORN:
                g_vec, g_sca = _tool_horn_gap(osc, t0, L0, A0, om)

                B = Bv + A0 * self.om2
                # |v| <= b0 and |u| <= A0: a tool face this far away cannot reach the horn
                if L0 - osc.b0 - A0 <= 0.0:
                    fns.append(_Fn("pinch", g_vec, g_sca, B, max(t0, skip_t), _grid_step(B, t_end)))
                t_rel = self._next_cross(t0, up=False)
            else:  # ON_TOOL: contact force a - v'' >= 0 ends the stick; horn gap pinches
                def r_vec(tg, t0=t0, osc=osc):
                    acc, jerk = osc.acc_jerk_vec(tg - t0)
                    return a - acc, -jerk

                def r_sca(tt, t0=t0, osc=osc):
                    acc, jerk = osc.acc_jerk(tt - t0)
                    return a - acc, -jerk

                g_vec, g_sca = _tool_horn_gap(osc, t0, L0, A0, om)

                Br = osc.b4
                B = Bv + A0 * self.om2
                # bounds |v - delta| <= b0, |v''| <= b2 rule out pinch / release at once
                if L0 + osc.delta - osc.b0 - A0 <= 0.0:
                    fns.append(_Fn("pinch", g_vec, g_sca, B, t0, _grid_step(B, t_end)))
                if osc.b2 >= a:
                    # the release function is a force per mass: its grid and tolerance are
                    # accelerations
                    fns.append(_Fn("release", r_vec, r_sca, Br, t0,
                                   _grid_step(Br, t_end, 1e-3 * (abs(a) + osc.b2))))
                t_rel = math.inf

            te, name = _first_event(fns, min(t_end, t_rel))
            if te is None and t_rel <= t_end:
                te, name = t_rel, "release"
            if te is None:
                break
            te = float(te)
            if name == "pinch":
                raise SimulationError(_pinch_message(te))
            n_ev += 1
            if n_ev > p.max_events:
                raise SimulationError(f"more than max_events = {p.max_events} events by t = {te:.9g} s")
            # state at te
            s = te - t0
            v, vd = osc.pv(s)
            uh, uhd = self.horn(te)
            if mode == FREE:
                w, wd = w0 + s * (wd0 + 0.5 * a * s), wd0 + a * s
            elif mode == ON_HORN:
                w, wd = uh, uhd
            else:
                w, wd = L0 + v, vd
            t = te
            if L0 + v <= 2.0 * A0:
                raise SimulationError(_pinch_message(te))
            if name == "release":
                if mode == ON_HORN:
                    # the horn did the work that moved the stuck mass
                    work += (0.5 * p.m_free * wd * wd - p.m_free * a * w) - stick_E
                    skip_h = self._next_cross(te, up=True)
                    skip_t = te
                else:
                    skip_h = te
                    skip_t = te
                stick.append((stick_start, te, "horn" if mode == ON_HORN else "tool"))
                mode = FREE
                continue
            if name == HORN:
                x = uh
                rel_in = wd - uhd                       # < 0: approaching
                if p.horn_law == "kinematic":
                    wa = uhd - p.e2 * rel_in
                else:
                    mu = p.m_horn / (p.m_horn + p.m_free)
                    wa = wd - mu * (1.0 + p.e2) * rel_in
                    if wa < uhd:
                        # eq. 21 leaves the mass still approaching the horn: close the rest of
                        # the approach plastically instead of interpenetrating
                        wa = uhd
                work += p.m_free * (wa - wd) * uhd
                wb = wd
                if _sticks(wa - uhd, self.horn_acc(te) - a, p.v_stick):
                    wa = uhd
                    mode = ON_HORN
                    stick_start = te
                    stick_E = 0.5 * p.m_free * wa * wa - p.m_free * a * x
                    skip_t = te
                else:
                    fu = self.horn_acc(te) - a       # > 0: horn pushes into contact
                    skip_h = te + 2.0 * (wa - uhd) / self.Bh
                    if fu < 0.0:
                        skip_h = max(skip_h, self._next_cross(te, up=True))
                    skip_t = te
                w, wd = x, wa
                vb = va = vd
            else:  # TOOL
                x = L0 + v
                M = self.M
                vb, wb = vd, wd
                rel = wd - vd                            # > 0: approaching the tool
                va = vd + p.m_free / M * (1.0 + p.e1) * rel
                wa = wd - p.m_tool / M * (1.0 + p.e1) * rel
                acc_tool = -(p.c * va + p.k0 * v) / p.m_tool
                if _sticks(va - wa, a - acc_tool, p.v_stick):
                    va = wa = (p.m_tool * vd + p.m_free * wd) / M
                    mode = ON_TOOL
                    stick_start = te
                else:
                    skip_t = te + 2.0 * (va - wa) / (abs(a) + _Osc(p.m_tool, p.k0, p.c, 0.0, v, va).b2)
                    skip_h = te
                w, wd, vd = x, wa, va
            ev["t"].append(te)
            ev["contact"].append(name)
            ev["x"].append(x)
            ev["wb"].append(wb)
            ev["wa"].append(wa)
            ev["vb"].append(vb)
            ev["va"].append(va)
            ev["E"].append(self.energy(w, wd, v, vd))
            ev["W"].append(work)
        if stick_start is not None and mode != FREE:
            stick.append((stick_start, p.t_end, "horn" if mode == ON_HORN else "tool"))
        res = ImpactResult(
            params=p, t=np.array(ev["t"], dtype=float), contact=np.array(ev["contact"], dtype="<U4"),
            x=np.array(ev["x"], dtype=float), w_before=np.array(ev["wb"], dtype=float),
            w_after=np.array(ev["wa"], dtype=float), v_before=np.array(ev["vb"], dtype=float),
            v_after=np.array(ev["va"], dtype=float), energy=np.array(ev["E"], dtype=float),
            horn_work=np.array(ev["W"], dtype=float), energy0=E0, stick=stick, n_events=n_ev)
        seg = tuple(np.array([sg[j] for sg in segs], dtype=np.int8 if j == 1 else float) for j in range(6))
        return res, seg


def _pinch_message(te: float) -> str:
    return (f"free mass pinched between horn and tool at t = {te:.9g} s: the tool face swings "
            f"back into the horn's stroke; increase gap or k0")


def _series(res: ImpactResult, seg) -> None:
    """Sample horn, free mass and tool face on the uniform grid ``sample_dt`` from the
    segment starts ``(t0, mode, w0, wd0, v0, vd0)`` (analytic motion within each segment)."""
    p = res.params
    a, L0, A0, om = p.a_free, p.gap, p.A0, p.omega
    M = p.m_tool + p.m_free
    n = int(math.floor(p.t_end / p.sample_dt + 1e-9)) + 1
    tg = np.arange(n) * p.sample_dt
    u = A0 * np.cos(om * tg)
    w = np.empty(n)
    face = np.empty(n)
    seg_t0, seg_mode, seg_w0, seg_wd0, seg_v0, seg_vd0 = seg
    idx = np.searchsorted(tg, seg_t0, side="left")
    idx = np.append(idx, n)
    for j in range(seg_t0.size):
        i0, i1 = idx[j], idx[j + 1]
        if i1 <= i0:
            continue
        t0, mode = float(seg_t0[j]), int(seg_mode[j])
        if mode == ON_TOOL:
            osc = _Osc(M, p.k0, p.c, p.m_free * a / p.k0, float(seg_v0[j]), float(seg_vd0[j]))
        else:
            osc = _Osc(p.m_tool, p.k0, p.c, 0.0, float(seg_v0[j]), float(seg_vd0[j]))
        s = tg[i0:i1] - t0
        vv, _ = osc.pv_vec(s)
        face[i0:i1] = L0 + vv
        if mode == FREE:
            w[i0:i1] = seg_w0[j] + s * (seg_wd0[j] + 0.5 * a * s)
        elif mode == ON_HORN:
            w[i0:i1] = u[i0:i1]
        else:
            w[i0:i1] = L0 + vv
    res.t_grid, res.u, res.w, res.tool_face = tg, u, w, face


def _run_kernel(p: ImpactParams) -> tuple[ImpactResult, tuple]:
    from . import kernel   # numba is imported (and the kernel compiled) on first use only

    out = kernel.run_events(kernel.pack(p), p.t_end, p.max_events)
    (t, kind, x, wb, wa, vb, va, en, work, st0, st1, sbody,
     s_t0, s_mode, s_w0, s_wd0, s_v0, s_vd0, E0, status, t_status, n_ev) = out
    if status == kernel.STATUS_PINCHED:
        raise SimulationError(_pinch_message(t_status))
    if status == kernel.STATUS_MAX_EVENTS:
        raise SimulationError(f"more than max_events = {p.max_events} events by t = {t_status:.9g} s")
    contact = np.where(kind == kernel.KIND_TOOL, TOOL, HORN).astype("<U4")
    stick = [(float(a), float(b), "tool" if body == kernel.BODY_TOOL else "horn")
             for a, b, body in zip(st0, st1, sbody)]
    res = ImpactResult(params=p, t=t, contact=contact, x=x, w_before=wb, w_after=wa,
                       v_before=vb, v_after=va, energy=en, horn_work=work, energy0=float(E0),
                       stick=stick, n_events=int(n_ev))
    return res, (s_t0, s_mode, s_w0, s_wd0, s_v0, s_vd0)




def window_stats(result: ImpactResult, t_from: float, t_end: float) -> np.ndarray:
    """Statistics of one run over the window ``[t_from, t_end]`` (pure Python).

    Parameters
    ----------
    result : ImpactResult
        A finished simulation.
    t_from, t_end : float
        Window, s.

    Returns
    -------
    ndarray, shape (N_STATS,)
        Columns ``S_N_TOOL``, ``S_N_HORN`` (impacts with t_from <= t <= t_end), ``S_KE_AFTER``
        (sum of 0.5 m_tool v_after^2 over those tool impacts, J), ``S_KE_GAIN`` (sum of
        0.5 m_tool (v_after^2 - v_before^2), J), ``S_HORN_WORK`` (cumulative horn work at the
        last impact <= t_end minus that at the last impact < t_from, J), ``S_T_ON_HORN``,
        ``S_T_ON_TOOL`` (sticking time clipped to the window, s), ``S_STATUS`` (0: a finished
        run) and ``S_N_EVENTS`` (impacts and releases of the whole run).
    """
    r = result
    m_tool = r.params.m_tool
    out = np.zeros(N_STATS)
    inw = (r.t >= t_from) & (r.t <= t_end)
    tool = inw & r.is_tool
    out[S_N_TOOL] = np.count_nonzero(tool)
    out[S_N_HORN] = np.count_nonzero(inw & ~r.is_tool)
    out[S_KE_AFTER] = float(np.sum(0.5 * m_tool * r.v_after[tool] ** 2))
    out[S_KE_GAIN] = float(np.sum(0.5 * m_tool * (r.v_after[tool] ** 2 - r.v_before[tool] ** 2)))
    i_end = np.searchsorted(r.t, t_end, side="right") - 1
    i_from = np.searchsorted(r.t, t_from, side="left") - 1
    w_end = r.horn_work[i_end] if i_end >= 0 else 0.0
    w_from = r.horn_work[i_from] if i_from >= 0 else 0.0
    out[S_HORN_WORK] = w_end - w_from
    for s0, s1, body in r.stick:
        d = max(0.0, min(s1, t_end) - max(s0, t_from))
        out[S_T_ON_HORN if body == "horn" else S_T_ON_TOOL] += d
    out[S_STATUS] = 0.0
    out[S_N_EVENTS] = r.n_events
    return out


def simulate(params: ImpactParams | None = None, *, series: bool = True,
             engine: str = "kernel") -> ImpactResult:
    """Run the event-driven impact model.

    Parameters
    ----------
    params : ImpactParams, optional
        All inputs (SI); Table 1 and the calibrated defaults if omitted. The pipeline feeds
        ``A0`` (m) and ``freq`` (Hz) from the FE model via ``params.with_(A0=..., freq=...)``.
    series : bool
        Also sample horn, free mass and tool face positions on the uniform grid ``sample_dt``.
    engine : {"kernel", "python"}
        "kernel": the compiled :mod:`impact.kernel` (numba; compiled on first use and cached
        on disk). "python": the reference implementation in this module. Both run the same
        algorithm and return the same events.

    Returns
    -------
    ImpactResult

    Raises
    ------
    SimulationError
        Pinched free mass (the message names the parameters to change) or more than
        ``params.max_events`` events.
    """
    p = params if params is not None else ImpactParams()
    if engine == "kernel":
        res, seg = _run_kernel(p)
    elif engine == "python":
        res, seg = _Sim(p).run()
    else:
        raise ValueError(f"engine = {engine!r}: must be 'kernel' or 'python'")
    if series:
        _series(res, seg)
    log.info("simulated %.4g s (%s): %d tool impacts (%.1f Hz), %d horn impacts, mean tool KE %.3g J",
             p.t_end, engine, res.tool_impacts, res.tool_impact_rate_hz, res.horn_impacts,
             res.mean_tool_ke_after_impact_j)
    return res
