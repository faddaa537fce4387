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
  critically and over-damped tools are all solved in closed form (:class:`impact.oscillator.Oscillator`).
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
:func:`simulate` runs the compiled kernel (:mod:`impact.kernel`, numba) by default and the
readable reference :class:`impact.reference.events.EventEngine` with ``engine="python"``: the
same algorithm, operation for operation, so both return the same events. The steps of the
model are written once as the compiled building blocks of :mod:`impact.kernel_blocks` and the
plain rules of :mod:`impact.event_rules`. :func:`impact.result.window_stats` computes the
statistics columns of :func:`impact.kernel.ensemble_stats` from one :class:`ImpactResult`.
"""

from __future__ import annotations

import logging

import numpy as np

from .columns import (FREE, N_STATS, ON_HORN, ON_TOOL, S_HORN_WORK, S_KE_AFTER, S_KE_GAIN, S_N_EVENTS, S_N_HORN,
                      S_N_TOOL, S_STATUS, S_T_ON_HORN, S_T_ON_TOOL)
from .event_rules import CONTACT_TOL
from .params import ImpactParams
from .result import (HORN, TOOL, ImpactResult, SimulationError, amplitude_spectrum, max_events_message,
                     pinch_message, sample_series, window_stats)

__all__ = ["simulate", "window_stats", "ImpactResult", "SimulationError", "CONTACT_TOL",
           "amplitude_spectrum", "N_STATS", "FREE", "ON_HORN", "ON_TOOL", "S_N_TOOL", "S_N_HORN", "S_KE_AFTER",
           "S_KE_GAIN", "S_HORN_WORK", "S_T_ON_HORN", "S_T_ON_TOOL", "S_STATUS", "S_N_EVENTS"]

log = logging.getLogger(__name__)


def _run_kernel(p: ImpactParams) -> tuple[ImpactResult, tuple]:
    """One run of the compiled kernel as an ImpactResult and its segment starts."""
    from . import kernel   # numba is imported (and the kernel compiled) on first use only

    out = kernel.run_events(kernel.pack(p), p.t_end, p.max_events)
    (t, kind, x, wb, wa, vb, va, en, work, st0, st1, sbody,
     s_t0, s_mode, s_w0, s_wd0, s_v0, s_vd0, E0, status, t_status, n_ev) = out
    if status == kernel.STATUS_PINCHED:
        raise SimulationError(pinch_message(t_status))
    if status == kernel.STATUS_MAX_EVENTS:
        raise SimulationError(max_events_message(p.max_events, t_status))
    contact = np.where(kind == kernel.KIND_TOOL, TOOL, HORN).astype("<U4")
    stick = [(float(a), float(b), "tool" if body == kernel.BODY_TOOL else "horn")
             for a, b, body in zip(st0, st1, sbody)]
    res = ImpactResult(params=p, t=t, contact=contact, x=x, w_before=wb, w_after=wa,
                       v_before=vb, v_after=va, energy=en, horn_work=work, energy0=float(E0),
                       stick=stick, n_events=int(n_ev))
    return res, (s_t0, s_mode, s_w0, s_wd0, s_v0, s_vd0)


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

    Examples
    --------
    Ten milliseconds of the article's case (8 g free mass, horn tip 15 um at 20 kHz), one
    launch speed: one sample of a chaotic motion (statistics: :func:`ensemble_statistics`):

    >>> from impact import ImpactParams, simulate
    >>> simulate(ImpactParams(t_end=0.01))
    ImpactResult(one sample, 8 g free mass, A0 15 um, 10 ms: 3 tool and 3 horn impacts, mean tool KE after impact 13.2 mJ)
    """
    p = params if params is not None else ImpactParams()
    if engine == "kernel":
        res, seg = _run_kernel(p)
    elif engine == "python":
        from .reference.events import EventEngine

        res, seg = EventEngine(p).run()
    else:
        raise ValueError(f"engine = {engine!r}: must be 'kernel' or 'python'")
    if series:
        sample_series(res, seg)
    log.info("simulated %.4g s (%s): %d tool impacts (%.1f Hz), %d horn impacts, mean tool KE %.3g J",
             p.t_end, engine, res.tool_impacts, res.tool_impact_rate_hz, res.horn_impacts,
             res.mean_tool_ke_after_impact_j)
    return res
