"""The readable reference engine of the coupled model (modal horn; plain Python, numpy).

:class:`ModalEngine` runs the model of :mod:`impact.coupled` as the compiled loop
:func:`impact.kernel_modal._core` does, one method per step: :meth:`ModalEngine.plan`,
:func:`impact.reference.search.first_event`, the laws (:meth:`ModalEngine.horn_impact`,
:meth:`ModalEngine.compliant_impact`, :meth:`ModalEngine.tool_impact`, :meth:`ModalEngine.release`)
and :meth:`ModalEngine.record`. :class:`HornState` is the modal horn over one segment.
"""

from __future__ import annotations

import math

import numpy as np

from ..columns import FREE, ON_HORN, ON_TOOL
from ..coupled_result import CoupledResult
from ..event_rules import free_mass_at, grid_step, parabola_excursion, parabola_leave, parabola_reach, sticks
from ..horn import H_A, H_B, H_MASS, H_OMEGA, H_TIP, H_ZETA, X_RC, X_RS, X_UC, X_US, X_W, ModalHorn
from ..oscillator import Oscillator
from ..params import ImpactParams
from ..result import HORN, TOOL, ImpactResult, SimulationError, pinch_message
from .events import count_event, end_stick, tool_law, tool_oscillator, tool_skip
from .search import ContactFn, first_event, tool_gap, tool_release

__all__ = ["ModalEngine", "HornState"]


class HornState:
    """The modal horn over one segment: steady part + one Oscillator per mode (free oscillation)."""

    def __init__(self, sim: "ModalEngine", t0: float, q: list, qd: list):
        self.t0 = t0
        W = sim.W
        c, s = math.cos(W * t0), math.sin(W * t0)
        self.osc = []
        for i in range(sim.n):
            a, b = sim.ha[i], sim.hb[i]
            p = a * c + b * s
            pd = W * (-a * s + b * c)
            self.osc.append(Oscillator(sim.hm[i], sim.hm[i] * sim.hw[i] * sim.hw[i],
                                       2.0 * sim.hz[i] * sim.hw[i] * sim.hm[i], 0.0, q[i] - p, qd[i] - pd))
        b0 = 0.0
        b2 = 0.0
        b4 = 0.0
        for i in range(sim.n):
            b0 += abs(sim.hs[i]) * self.osc[i].b0
            b2 += abs(sim.hs[i]) * self.osc[i].b2
            b4 += abs(sim.hs[i]) * self.osc[i].b4
        self.B0 = sim.Ua + b0                 # |u| <= B0
        self.B2 = sim.Ua * W * W + b2         # |u''| <= B2
        self.B4 = sim.Ua * W * W * W * W + b4  # |u| <= B4

    def _derivatives(self, sim, tt, order: int, vec: bool):
        """Tip derivatives ``order`` and ``order + 1`` (order 0 or 2) at time ``tt`` (an array if
        ``vec``): the steady part plus every mode's free oscillation, as ``kernel_blocks.tip``."""
        W = sim.W
        cos, sin = (np.cos, np.sin) if vec else (math.cos, math.sin)
        c, s = cos(W * tt), sin(W * tt)
        k = 1.0 if order == 0 else -W * W
        a = k * (sim.Uc * c + sim.Us * s)
        b = k * W * (-sim.Uc * s + sim.Us * c)
        for i in range(sim.n):
            osc = self.osc[i]
            f = (osc.pv_vec if vec else osc.pv) if order == 0 else (osc.acc_jerk_vec if vec else osc.acc_jerk)
            y, yd = f(tt - self.t0)
            a = a + sim.hs[i] * y
            b = b + sim.hs[i] * yd
        return a, b

    def tip(self, sim, tt: float) -> tuple[float, float]:
        return self._derivatives(sim, tt, 0, False)

    def tip_vec(self, sim, tg: np.ndarray):
        return self._derivatives(sim, tg, 0, True)

    def tip_acc(self, sim, tt: float) -> float:
        return self._derivatives(sim, tt, 2, False)[0]

    def tip_acc_jerk(self, sim, tt: float) -> tuple[float, float]:
        return self._derivatives(sim, tt, 2, False)

    def tip_acc_jerk_vec(self, sim, tg: np.ndarray):
        return self._derivatives(sim, tg, 2, True)

    def modal(self, sim, tt: float) -> tuple[list, list]:
        """Modal coordinates and velocities at tt (s)."""
        W = sim.W
        c, s = math.cos(W * tt), math.sin(W * tt)
        q, qd = [], []
        for i in range(sim.n):
            y, yd = self.osc[i].pv(tt - self.t0)
            q.append(sim.ha[i] * c + sim.hb[i] * s + y)
            qd.append(W * (-sim.ha[i] * s + sim.hb[i] * c) + yd)
        return q, qd


class ModalEngine:
    """One run of the coupled model (see :mod:`impact.coupled`); ``contact``: an
    :class:`impact.contact.HuntCrossley` for compliant horn contacts, None for Newton's law.
    The caller checks the parameters (:func:`impact.coupled.check_coupled_params`)."""

    def __init__(self, p: ImpactParams, horn: ModalHorn, contact=None):
        self.p, self.horn = p, horn
        self.contact = contact
        tab, x = horn.pack(p.freq)
        self.n = tab.shape[0]
        self.hw, self.hz, self.hm = list(tab[:, H_OMEGA]), list(tab[:, H_ZETA]), list(tab[:, H_MASS])
        self.hs, self.ha, self.hb = list(tab[:, H_TIP]), list(tab[:, H_A]), list(tab[:, H_B])
        self.W, self.Uc, self.Us = x[X_W], x[X_UC], x[X_US]
        self.Rc, self.Rs = x[X_RC], x[X_RS]
        self.Ua = math.hypot(self.Uc, self.Us)
        S = 0.0
        for i in range(self.n):
            S += self.hs[i] * self.hs[i] / self.hm[i]
        self.S = S
        self.a = p.a_free
        self.M = p.m_tool + p.m_free

    def energy(self, w, wd, v, vd):
        """Mechanical energy of free mass and tool (J)."""
        p = self.p
        return 0.5 * p.m_free * wd * wd - p.m_free * self.a * w + 0.5 * p.m_tool * vd * vd + 0.5 * p.k0 * v * v

    # the loop --------------------------------------------------------------
    def run(self) -> CoupledResult:
        """Simulate; the result without time series."""
        p = self.p
        self._start()
        while self.t < p.t_end:
            # plan the contacts of this segment
            osc = tool_oscillator(p, self.mode, self.v, self.vd)
            hst = HornState(self, self.t, self.q, self.qd)
            self.Bh = abs(self.a) + hst.B2
            if self.skip_rel > 0.0:
                self.skip_h = self.t + self.skip_rel / self.Bh
                self.skip_rel = 0.0
            self.segs.append((self.t, self.mode, self.w, self.wd, self.v, self.vd))
            self.seg_q.append(list(self.q))
            self.seg_qd.append(list(self.qd))
            self.t0, self.w0, self.wd0 = self.t, self.w, self.wd
            # earliest root
            te, name = first_event(self.plan(osc, hst), p.t_end)
            if te is None:
                break
            te = float(te)
            self.n_ev = count_event(name, self.n_ev, p.max_events, te)
            # the state at the event, then the law
            uh, uhd = self._move_to(te, osc, hst)
            if name in ("hrel", "release"):
                self.release(te, name)
                continue
            if name == HORN and self.contact is not None:
                if self.compliant_impact(te, osc, uh, uhd):
                    break
                continue
            row = self.horn_impact(te, hst, uh, uhd) if name == HORN else self.tool_impact(te, uhd)
            self.record(te, name, *row)
        end_stick(self.stick, self.stick_start, self.mode, p.t_end)
        return self._result()

    def _start(self) -> None:
        """Initial state: the modes as the horn starts, the free mass leaving the tip at v0."""
        p = self.p
        q0, qd0 = self.horn.initial_state(p.freq)
        self.q, self.qd = [float(x) for x in q0], [float(x) for x in qd0]
        hs0 = HornState(self, 0.0, self.q, self.qd)
        u0, ud0 = hs0.tip(self, 0.0)
        self.t, self.mode = 0.0, FREE
        self.w, self.wd = u0, ud0 + p.v0
        self.v, self.vd = 0.0, 0.0
        self.skip_rel = 2.0 * p.v0          # skip_h = t0 + skip_rel / B_horn of the next segment
        self.skip_h = 0.0
        self.skip_t = 0.0
        self.E0 = self.energy(self.w, self.wd, self.v, self.vd)
        self.work = 0.0
        self.ev = {k: [] for k in ("t", "contact", "x", "wb", "wa", "vb", "va", "E", "W", "J", "ub", "ua")}
        self.segs, self.seg_q, self.seg_qd = [], [], []
        self.stick = []
        self.stick_start = None
        self.stick_E = 0.0
        self.contacts = []
        self.n_ev = 0

    # plan the contacts -----------------------------------------------------
    def plan(self, osc: Oscillator, hst: HornState) -> list[ContactFn]:
        """The contact functions of the segment starting now."""
        t0, L0, a, t_end = self.t0, self.p.gap, self.a, self.p.t_end
        Bv = osc.b2

        def g_vec(tg):
            vv, vvd = osc.pv_vec(tg - t0)
            u, ud = hst.tip_vec(self, tg)
            return L0 + vv - u, vvd - ud

        def g_sca(tt):
            vv, vvd = osc.pv(tt - t0)
            u, ud = hst.tip(self, tt)
            return L0 + vv - u, vvd - ud

        fns = []
        if self.mode == FREE:
            return self._plan_flight(osc, hst)
        if self.mode == ON_HORN:
            # riding on the horn: the contact force per mass u'' - a falls to zero at the release
            def hr_vec(tg):
                u2, u3 = hst.tip_acc_jerk_vec(self, tg)
                return u2 - a, u3

            def hr_sca(tt):
                u2, u3 = hst.tip_acc_jerk(self, tt)
                return u2 - a, u3

            B = Bv + hst.B2
            if L0 - osc.b0 - hst.B0 <= 0.0:
                fns.append(ContactFn("pinch", g_vec, g_sca, B, max(t0, self.skip_t), grid_step(B, t_end)))
            fns.append(ContactFn("hrel", hr_vec, hr_sca, hst.B4, t0, grid_step(hst.B4, t_end, 1e-3 * (abs(a) + hst.B2))))
            return fns
        r_vec, r_sca = tool_release(osc, t0, a)
        Br = osc.b4
        B = Bv + hst.B2
        if L0 + osc.delta - osc.b0 - hst.B0 <= 0.0:
            fns.append(ContactFn("pinch", g_vec, g_sca, B, t0, grid_step(B, t_end)))
        if osc.b2 >= a:
            fns.append(ContactFn("release", r_vec, r_sca, Br, t0, grid_step(Br, t_end, 1e-3 * (abs(a) + osc.b2))))
        return fns

    def _plan_flight(self, osc: Oscillator, hst: HornState) -> list[ContactFn]:
        """A free flight's horn and tool gaps, each searched where the parabola can touch its band."""
        t0, w0, wd0, a, L0, t_end = self.t0, self.w0, self.wd0, self.a, self.p.gap, self.p.t_end

        def h_vec(tg):
            s = tg - t0
            u, ud = hst.tip_vec(self, tg)
            return w0 + s * (wd0 + 0.5 * a * s) - u, wd0 + a * s - ud

        def h_sca(tt):
            s = tt - t0
            u, ud = hst.tip(self, tt)
            return w0 + s * (wd0 + 0.5 * a * s) - u, wd0 + a * s - ud

        t_vec, t_sca = tool_gap(osc, t0, w0, wd0, a, L0)
        Bt = osc.b2 + abs(a)
        zone_h = t0 + parabola_reach(w0 - hst.B0 - 1e-9, wd0, a)
        zone_t = t0 + parabola_reach(L0 - osc.b0 - 1e-9 - w0, -wd0, -a)
        fns = []
        for name, vec, sca, B, zone, skip, lead, vel, acc in (
                (HORN, h_vec, h_sca, self.Bh, zone_h, self.skip_h, w0 - hst.B0 - 1e-9, wd0, a),
                (TOOL, t_vec, t_sca, Bt, zone_t, self.skip_t, L0 - osc.b0 - 1e-9 - w0, -wd0, -a)):
            if zone == math.inf:
                continue
            start, end = max(t0, skip, zone), t0 + parabola_leave(lead, vel, acc)
            x1, x2 = parabola_excursion(lead, vel, acc)
            h = grid_step(B, t_end)
            if x2 < math.inf:
                fns.append(ContactFn(name, vec, sca, B, start, h, min(end, t0 + x1)))
                fns.append(ContactFn(name, vec, sca, B, max(start, t0 + x2), h, end))
            else:
                fns.append(ContactFn(name, vec, sca, B, start, h, end))
        return fns

    # the state at an event and the laws -------------------------------------
    def _move_to(self, te: float, osc: Oscillator, hst: HornState) -> tuple[float, float]:
        """Advance the bodies and modes to te; returns the tip position and velocity there."""
        s = te - self.t0
        self.v, self.vd = osc.pv(s)
        self.q, self.qd = hst.modal(self, te)
        uh, uhd = hst.tip(self, te)
        self.w, self.wd = free_mass_at(self.mode, s, self.w0, self.wd0, self.a, self.p.gap, uh, uhd, self.v,
                                       self.vd)
        self.t = te
        if self.p.gap + self.v <= 2.0 * hst.B0:
            raise SimulationError(pinch_message(te))
        return uh, uhd

    def release(self, te: float, name: str) -> None:
        """A ride on the horn ("hrel") or the tool ("release") ends at te."""
        p = self.p
        if name == "hrel":
            # the horn did the work that moved the riding mass (its reaction on the modes neglected)
            self.work += (0.5 * p.m_free * self.wd * self.wd - p.m_free * self.a * self.w) - self.stick_E
        self.skip_h = te
        self.skip_t = te
        self.stick.append((self.stick_start, te, "horn" if name == "hrel" else "tool"))
        self.mode = FREE

    def compliant_impact(self, te: float, osc: Oscillator, uh: float, uhd: float) -> bool:
        """Integrate a compliant horn contact from te (:func:`impact.contact.contact_phase`) and
        record it; True if it lasts to the end of the run."""
        from ..contact import contact_phase

        p, a, w, wd = self.p, self.a, self.w, self.wd
        fc, fs = self.horn.forcing()
        tab = {"omega": np.array(self.hw), "zeta": np.array(self.hz), "mass": np.array(self.hm),
               "tip": np.array(self.hs), "fc": fc, "fs": fs}
        t1, w1, wd1, q1, qd1, J, diss = contact_phase(self.contact, tab, te, wd=wd, w=w, q=np.array(self.q),
                                                      qd=np.array(self.qd), m_free=p.m_free, a=a, W=self.W,
                                                      rc=self.Rc, rs=self.Rs, t_max=p.t_end)
        self.v, self.vd = osc.pv(t1 - self.t0)
        self.work += (0.5 * p.m_free * wd1 * wd1 - p.m_free * a * w1) - (0.5 * p.m_free * wd * wd - p.m_free * a * w) + diss
        self.contacts.append((te, t1, J, diss))
        self.q, self.qd = [float(x) for x in q1], [float(x) for x in qd1]
        self.t, self.w, self.wd = t1, w1, wd1
        u1, ud1 = HornState(self, t1, self.q, self.qd).tip(self, t1)
        self.record(te, HORN, uh, wd, wd1, self.vd, self.vd, J, uhd, ud1)
        if t1 >= p.t_end:
            return True
        self.skip_rel = 2.0 * max(wd1 - ud1, 0.0)
        self.skip_t = t1
        return False

    def horn_impact(self, te: float, hst: HornState, uh: float, uhd: float) -> tuple:
        """Newton's law at the modal horn and the sticking rule; returns the event's row."""
        p, a, wd = self.p, self.a, self.wd
        x = uh
        rel_in = wd - uhd
        J = -(1.0 + p.e2) * rel_in / (1.0 / p.m_free + self.S)
        wa = wd + J / p.m_free
        for i in range(self.n):
            self.qd[i] -= self.hs[i] * J / self.hm[i]
        ua = uhd - J * self.S
        self.work += J * 0.5 * (uhd + ua)
        wb = wd
        if sticks(wa - ua, hst.tip_acc(self, te) - a, p.v_stick):
            wa = ua
            self.mode = ON_HORN
            self.stick_start = te
            self.stick_E = 0.5 * p.m_free * wa * wa - p.m_free * a * x
        else:
            self.skip_rel = 2.0 * (wa - ua)
        self.skip_t = te
        self.w, self.wd = x, wa
        return x, wb, wa, self.vd, self.vd, J, uhd, ua

    def tool_impact(self, te: float, uhd: float) -> tuple:
        """Newton's law at the tool and the sticking rule; returns the event's row."""
        p = self.p
        x, vb, wb = p.gap + self.v, self.vd, self.wd
        va, wa, stuck = tool_law(p, self.M, self.a, self.v, self.vd, self.wd)
        J = p.m_free * (wa - self.wd)
        if stuck:
            self.mode = ON_TOOL
            self.stick_start = te
        else:
            self.skip_t = tool_skip(p, self.a, te, self.v, va, wa)
            self.skip_h = te
        self.w, self.wd, self.vd = x, wa, va
        return x, wb, wa, vb, va, J, uhd, uhd

    # record ------------------------------------------------------------------
    def record(self, te, name, x, wb, wa, vb, va, J, ub, ua) -> None:
        """Store an impact with the energy after it, the cumulative horn work, the impulse on the
        free mass and the tip velocity before and after."""
        ev = self.ev
        for key, val in (("t", te), ("contact", name), ("x", x), ("wb", wb), ("wa", wa), ("vb", vb), ("va", va),
                         ("E", self.energy(self.w, self.wd, self.v, self.vd)), ("W", self.work), ("J", J),
                         ("ub", ub), ("ua", ua)):
            ev[key].append(val)

    def _result(self) -> CoupledResult:
        p, ev = self.p, self.ev
        arr = {k: np.array(val, dtype=float) for k, val in ev.items() if k != "contact"}
        res = ImpactResult(params=p, t=arr["t"], contact=np.array(ev["contact"], dtype="<U4"), x=arr["x"],
                           w_before=arr["wb"], w_after=arr["wa"], v_before=arr["vb"], v_after=arr["va"],
                           energy=arr["E"], horn_work=arr["W"], energy0=self.E0, stick=self.stick, n_events=self.n_ev)
        segs = self.segs
        seg = tuple(np.array([sg[j] for sg in segs], dtype=np.int8 if j == 1 else float) for j in range(6))
        return CoupledResult(impact=res, horn=self.horn, freq_hz=p.freq, seg_t0=seg[0],
                             seg_q=np.array(self.seg_q, float).reshape(len(segs), self.n),
                             seg_qd=np.array(self.seg_qd, float).reshape(len(segs), self.n),
                             impulse=arr["J"], tip_v_before=arr["ub"], tip_v_after=arr["ua"],
                             extra={"segments": seg, "contacts": self.contacts,
                                    "compliant": self.contact is not None})
