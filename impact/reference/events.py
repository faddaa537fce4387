"""The readable reference engine of the impact model (kinematic horn; plain Python, numpy).

:class:`EventEngine` runs the model of :mod:`impact.model` as the compiled loop
:func:`impact.kernel._core` does, one method per step: :meth:`EventEngine.plan` (the contact
functions of a segment), :func:`impact.reference.search.first_event` (the earliest root),
:meth:`EventEngine.horn_impact` / :meth:`EventEngine.tool_impact` / :meth:`EventEngine.release`
(the laws), :meth:`EventEngine.record`. The same operations in the same order, so both engines
return the same events; the tests compare them (and both with :mod:`impact.reference.ivp`).
"""

from __future__ import annotations

import math

import numpy as np

from ..columns import FREE, ON_HORN, ON_TOOL
from ..event_rules import (free_mass_at, grid_step, next_cross, parabola_excursion, parabola_leave, parabola_reach,
                           sticks)
from ..oscillator import Oscillator
from ..params import ImpactParams
from ..result import HORN, TOOL, ImpactResult, SimulationError, max_events_message, pinch_message
from .search import ContactFn, first_event, tool_gap, tool_horn_gap, tool_release

__all__ = ["EventEngine", "count_event", "end_stick", "tool_oscillator", "tool_law", "tool_skip"]


def count_event(name: str, n_ev: int, max_events: int, te: float) -> int:
    """Count an event of kind ``name`` at te (s); raise SimulationError at a pinch or over the cap."""
    if name == "pinch":
        raise SimulationError(pinch_message(te))
    n_ev += 1
    if n_ev > max_events:
        raise SimulationError(max_events_message(max_events, te))
    return n_ev


def end_stick(stick: list, stick_start: float | None, mode: int, t_end: float) -> None:
    """At the end of a run: a sticking phase still on is closed at t_end (s) in ``stick``."""
    if stick_start is not None and mode != FREE:
        stick.append((stick_start, t_end, "horn" if mode == ON_HORN else "tool"))


def tool_oscillator(p: ImpactParams, mode: int, v: float, vd: float) -> Oscillator:
    """The tool over a segment from (v, vd): alone, or with the free mass riding it (mass
    ``m_tool + m_free`` about the static deflection ``m_free a / k0``)."""
    if mode == ON_TOOL:
        return Oscillator(p.m_tool + p.m_free, p.k0, p.c, p.m_free * p.a_free / p.k0, v, vd)
    return Oscillator(p.m_tool, p.k0, p.c, 0.0, v, vd)


def tool_law(p: ImpactParams, M: float, a: float, v: float, vd: float, wd: float) -> tuple[float, float, bool]:
    """Newton's law at the tool (restitution e1, momentum conserved; ``M = m_tool + m_free``) and
    the sticking rule: the tool's and free mass's velocities after the impact (m/s), stuck."""
    rel = wd - vd                            # > 0: approaching the tool
    va = vd + p.m_free / M * (1.0 + p.e1) * rel
    wa = wd - p.m_tool / M * (1.0 + p.e1) * rel
    acc_tool = -(p.c * va + p.k0 * v) / p.m_tool
    stuck = sticks(va - wa, a - acc_tool, p.v_stick)
    if stuck:
        va = wa = (p.m_tool * vd + p.m_free * wd) / M
    return va, wa, stuck


def tool_skip(p: ImpactParams, a: float, te: float, v: float, va: float, wa: float) -> float:
    """End of the interval after a tool impact at te on which the tool gap provably stays open (s)."""
    return te + 2.0 * (va - wa) / (abs(a) + Oscillator(p.m_tool, p.k0, p.c, 0.0, v, va).b2)


class EventEngine:
    """One run of the impact model with the kinematic horn (see :mod:`impact.model`).

    Parameters
    ----------
    p : ImpactParams
        The run's parameters (SI).
    """

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
        """Tip position (m) and velocity (m/s) at t (s)."""
        ph = self.om * t
        return self.A0 * math.cos(ph), -self.A0 * self.om * math.sin(ph)

    def horn_acc(self, t):
        """Tip acceleration (m/s^2) at t (s)."""
        return -self.A0 * self.om2 * math.cos(self.om * t)

    def _next_cross(self, t0: float, up: bool) -> float:
        """Next t > t0 where f = u'' - a crosses zero upward (up) or downward."""
        return next_cross(t0, up, self.A0, self.om, self.om2, self.a)

    def energy(self, w, wd, v, vd):
        """Mechanical energy of free mass and tool (J)."""
        p = self.p
        return 0.5 * p.m_free * wd * wd - p.m_free * self.a * w + 0.5 * p.m_tool * vd * vd + 0.5 * p.k0 * v * v

    # the loop --------------------------------------------------------------
    def run(self) -> tuple[ImpactResult, tuple]:
        """Simulate; return the result (no time series) and the segment starts
        ``(t0, mode, w0, wd0, v0, vd0)`` that :func:`impact.result.sample_series` samples."""
        p = self.p
        self._start()
        while self.t < p.t_end:
            # plan the contacts of this segment
            osc = tool_oscillator(p, self.mode, self.v, self.vd)
            self.segs.append((self.t, self.mode, self.w, self.wd, self.v, self.vd))
            self.t0, self.w0, self.wd0 = self.t, self.w, self.wd
            fns, t_rel = self.plan(osc)
            # earliest root (a release from the horn is found analytically)
            te, name = first_event(fns, min(p.t_end, t_rel))
            if te is None and t_rel <= p.t_end:
                te, name = t_rel, "release"
            if te is None:
                break
            te = float(te)
            self.n_ev = count_event(name, self.n_ev, p.max_events, te)
            # the state at the event, then the law
            uh, uhd = self._move_to(te, osc)
            if name == "release":
                self.release(te)
                continue
            row = self.horn_impact(te, uh, uhd) if name == HORN else self.tool_impact(te)
            self.record(te, name, *row)
        end_stick(self.stick, self.stick_start, self.mode, p.t_end)
        return self._result()

    def _start(self) -> None:
        """Initial state: the free mass leaves the horn tip at its outermost point."""
        p = self.p
        self.t, self.mode = 0.0, FREE
        self.w, self.wd = self.A0, p.v0
        self.v, self.vd = 0.0, 0.0
        # the horn gap is convex while u'' < a: no horn contact before that ends
        self.skip_h = max(self._next_cross(0.0, up=True) if self.horn_acc(0.0) < self.a else 0.0,
                          2.0 * p.v0 / self.Bh)
        self.skip_t = 0.0
        self.E0 = self.energy(self.w, self.wd, self.v, self.vd)
        self.work = 0.0
        self.ev = {k: [] for k in ("t", "contact", "x", "wb", "wa", "vb", "va", "E", "W")}
        self.segs = []
        self.stick = []
        self.stick_start = None
        self.stick_E = 0.0
        self.n_ev = 0

    # plan the contacts -----------------------------------------------------
    def plan(self, osc: Oscillator) -> tuple[list[ContactFn], float]:
        """The contact functions of the segment starting now, and the analytic release time
        from the horn (inf unless riding it)."""
        p, t0, L0, a, t_end = self.p, self.t0, self.L0, self.a, self.p.t_end
        A0, om = self.A0, self.om
        Bv = osc.b2   # bound on |v''|
        fns = []
        if self.mode == FREE:
            return self._plan_flight(osc), math.inf
        if self.mode == ON_HORN:
            g_vec, g_sca = tool_horn_gap(osc, t0, L0, A0, om)
            B = Bv + A0 * self.om2
            # |v| <= b0 and |u| <= A0: a tool face this far away cannot reach the horn
            if L0 - osc.b0 - A0 <= 0.0:
                fns.append(ContactFn("pinch", g_vec, g_sca, B, max(t0, self.skip_t), grid_step(B, t_end)))
            return fns, self._next_cross(t0, up=False)

        # riding the tool: contact force a - v'' >= 0 ends the stick; horn gap pinches
        r_vec, r_sca = tool_release(osc, t0, a)
        g_vec, g_sca = tool_horn_gap(osc, t0, L0, A0, om)
        Br = osc.b4
        B = Bv + A0 * self.om2
        # bounds |v - delta| <= b0, |v''| <= b2 rule out pinch / release at once
        if L0 + osc.delta - osc.b0 - A0 <= 0.0:
            fns.append(ContactFn("pinch", g_vec, g_sca, B, t0, grid_step(B, t_end)))
        if osc.b2 >= a:
            # the release function is a force per mass: its grid and tolerance are accelerations
            fns.append(ContactFn("release", r_vec, r_sca, Br, t0, grid_step(Br, t_end, 1e-3 * (abs(a) + osc.b2))))
        return fns, math.inf

    def _plan_flight(self, osc: Oscillator) -> list[ContactFn]:
        """A free flight's horn and tool gaps, each searched from where the parabola can reach
        its band to where it leaves it for good, the excursion out of the band and back skipped."""
        t0, w0, wd0, a, L0, A0, om = self.t0, self.w0, self.wd0, self.a, self.L0, self.A0, self.om
        t_end = self.p.t_end

        def h_vec(tg):
            s = tg - t0
            ph = om * tg
            return (w0 + s * (wd0 + 0.5 * a * s) - A0 * np.cos(ph),
                    wd0 + a * s + A0 * om * np.sin(ph))

        def h_sca(tt):
            s = tt - t0
            ph = om * tt
            return (w0 + s * (wd0 + 0.5 * a * s) - A0 * math.cos(ph),
                    wd0 + a * s + A0 * om * math.sin(ph))

        t_vec, t_sca = tool_gap(osc, t0, w0, wd0, a, L0)
        Bt = osc.b2 + abs(a)
        # g_h >= w - A0 and g_t >= L0 - |v| - w: no contact before the parabola w(s)
        # comes within 1 nm of these bounds (found analytically)
        zone_h = t0 + parabola_reach(w0 - A0 - 1e-9, wd0, a)
        zone_t = t0 + parabola_reach(L0 - osc.b0 - 1e-9 - w0, -wd0, -a)
        fns = []
        for name, vec, sca, B, zone, skip, lead, vel, acc in (
                (HORN, h_vec, h_sca, self.Bh, zone_h, self.skip_h, w0 - A0 - 1e-9, wd0, a),
                (TOOL, t_vec, t_sca, Bt, zone_t, self.skip_t, L0 - osc.b0 - 1e-9 - w0, -wd0, -a)):
            if zone == math.inf:
                continue
            start, end = max(t0, skip, zone), t0 + parabola_leave(lead, vel, acc)
            x1, x2 = parabola_excursion(lead, vel, acc)
            if x2 < math.inf:
                fns.append(ContactFn(name, vec, sca, B, start, grid_step(B, t_end), min(end, t0 + x1)))
                fns.append(ContactFn(name, vec, sca, B, max(start, t0 + x2), grid_step(B, t_end), end))
            else:
                fns.append(ContactFn(name, vec, sca, B, start, grid_step(B, t_end), end))
        return fns

    # the state at an event and the laws -------------------------------------
    def _move_to(self, te: float, osc: Oscillator) -> tuple[float, float]:
        """Advance the bodies to the event time te; returns the tip position and velocity there."""
        s = te - self.t0
        self.v, self.vd = osc.pv(s)
        uh, uhd = self.horn(te)
        self.w, self.wd = free_mass_at(self.mode, s, self.w0, self.wd0, self.a, self.L0, uh, uhd, self.v, self.vd)
        self.t = te
        if self.L0 + self.v <= 2.0 * self.A0:
            raise SimulationError(pinch_message(te))
        return uh, uhd

    def release(self, te: float) -> None:
        """A sticking phase ends at te: the free mass flies again."""
        p = self.p
        if self.mode == ON_HORN:
            # the horn did the work that moved the stuck mass
            self.work += (0.5 * p.m_free * self.wd * self.wd - p.m_free * self.a * self.w) - self.stick_E
            self.skip_h = self._next_cross(te, up=True)
            self.skip_t = te
        else:
            self.skip_h = te
            self.skip_t = te
        self.stick.append((self.stick_start, te, "horn" if self.mode == ON_HORN else "tool"))
        self.mode = FREE

    def horn_impact(self, te: float, uh: float, uhd: float) -> tuple:
        """Newton's law at the horn and the sticking rule; returns (x, wb, wa, vb, va)."""
        p, a, wd = self.p, self.a, self.wd
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
        self.work += p.m_free * (wa - wd) * uhd
        wb = wd
        if sticks(wa - uhd, self.horn_acc(te) - a, p.v_stick):
            wa = uhd
            self.mode = ON_HORN
            self.stick_start = te
            self.stick_E = 0.5 * p.m_free * wa * wa - p.m_free * a * x
            self.skip_t = te
        else:
            fu = self.horn_acc(te) - a       # > 0: horn pushes into contact
            self.skip_h = te + 2.0 * (wa - uhd) / self.Bh
            if fu < 0.0:
                self.skip_h = max(self.skip_h, self._next_cross(te, up=True))
            self.skip_t = te
        self.w, self.wd = x, wa
        return x, wb, wa, self.vd, self.vd

    def tool_impact(self, te: float) -> tuple:
        """Newton's law at the tool and the sticking rule; returns (x, wb, wa, vb, va)."""
        x, vb, wb = self.L0 + self.v, self.vd, self.wd
        va, wa, stuck = tool_law(self.p, self.M, self.a, self.v, self.vd, self.wd)
        if stuck:
            self.mode = ON_TOOL
            self.stick_start = te
        else:
            self.skip_t = tool_skip(self.p, self.a, te, self.v, va, wa)
            self.skip_h = te
        self.w, self.wd, self.vd = x, wa, va
        return x, wb, wa, vb, va

    # record ------------------------------------------------------------------
    def record(self, te: float, name: str, x: float, wb: float, wa: float, vb: float, va: float) -> None:
        """Store an impact with the energy after it and the cumulative horn work."""
        ev = self.ev
        for key, val in (("t", te), ("contact", name), ("x", x), ("wb", wb), ("wa", wa), ("vb", vb), ("va", va),
                         ("E", self.energy(self.w, self.wd, self.v, self.vd)), ("W", self.work)):
            ev[key].append(val)

    def _result(self) -> tuple[ImpactResult, tuple]:
        ev = self.ev
        arr = {k: np.array(val, dtype=float) for k, val in ev.items() if k != "contact"}
        res = ImpactResult(
            params=self.p, t=arr["t"], contact=np.array(ev["contact"], dtype="<U4"), x=arr["x"],
            w_before=arr["wb"], w_after=arr["wa"], v_before=arr["vb"], v_after=arr["va"], energy=arr["E"],
            horn_work=arr["W"], energy0=self.E0, stick=self.stick, n_events=self.n_ev)
        seg = tuple(np.array([sg[j] for sg in self.segs], dtype=np.int8 if j == 1 else float) for j in range(6))
        return res, seg
