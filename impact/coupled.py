"""The impact model with the transducer in the loop: a modal horn instead of the kinematic tip.

Same free mass, drill tool, restitution laws, contact tolerance, event search and sticking
rules as :mod:`impact.model` (read its docstring), with the horn tip of a
:class:`impact.horn.ModalHorn`: ``u(t) = sum_i s_i q_i(t) + r(t)``, every modal coordinate a
closed-form damped oscillator under the harmonic drive between events (no time stepping).

Horn impact (Newton, restitution e2, the tip's effective mass from the modes): with the
approach speed ``rel = w' - u' < 0``, the impulse on the free mass is
``J = -(1 + e2) rel / (1/m_w + sum_i s_i^2/m_i)``; ``w'+ = w' + J/m_w``, ``q_i'+ = q_i' - s_i J/m_i``.
Then ``w'+ - u'+ = -e2 rel`` and momentum along the modal coordinates is conserved. The work of
the horn on the free mass is ``J (u'- + u'+)/2`` (kinetic energy it gains plus the restitution
loss). The kinematic horn (infinite mass) is the limit ``s_i^2/m_i -> 0``.

Bounds for the guaranteed event search: ``|u|, |u''| <= W^k |U^| + sum |s_i| b_k,i`` with
``b_k,i`` the bound of the i-th free oscillation's k-th derivative (``impact.model._Osc``); the
horn gap's ``|f''| <= |a| + W^2 |U^| + sum |s_i| b_2,i``.

Not modelled: the free mass *resting* on the horn. On the kinematic horn it rides the tip
until the tip's acceleration drops below its own; on a modal horn the riding mass would add to
the modal masses (a coupled, non-proportionally damped system). With the default parameters no
run of either scenario sticks on the horn (the tip accelerates at ~1e5 m/s^2); if the sticking
rule fires on a modal horn the run stops with status ``STATUS_HORN_STICK`` (the statistics then
report the case as failed, with the reason). Only ``horn_law = "kinematic"`` is accepted (the
modal horn has its own mass law).

Engines: :class:`_ModalSim` below is the readable reference; :mod:`impact.kernel_modal` is the
compiled kernel of the same algorithm, operation for operation (tests compare them).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np

from rpud_common import ParameterError

from .horn import ModalHorn, segment_integrals
from .model import (CONTACT_TOL, FREE, HORN, ON_TOOL, TOOL, ImpactResult, SimulationError, _first_event, _Fn,
                    _grid_step, _Osc, _parabola_excursion, _parabola_leave, _parabola_reach, _pinch_message,
                    _sticks)
from .params import ImpactParams

__all__ = ["CoupledResult", "simulate_coupled", "check_coupled_params", "HornStickError"]

log = logging.getLogger(__name__)


class HornStickError(SimulationError):
    """The free mass would rest on a modal horn (not modelled; see the module docstring)."""


def check_coupled_params(params: ImpactParams, horn: ModalHorn) -> None:
    """Refuse combinations the coupled model does not cover (ParameterError)."""
    if not isinstance(horn, ModalHorn):
        raise ParameterError("horn", type(horn).__name__, "must be an impact.horn.ModalHorn")
    if params.horn_law != "kinematic":
        raise ParameterError("horn_law", params.horn_law, "must be 'kinematic' with a modal horn "
                             "(the modes carry the horn's mass)")


@dataclass
class CoupledResult:
    """A coupled run: the impact events plus the horn's history.

    Attributes
    ----------
    impact : ImpactResult
        Events as in :func:`impact.model.simulate` (``horn_work``: cumulative work of the horn on
        the free mass, J; ``energy``: free mass + tool mechanical energy, J).
    horn : ModalHorn
    freq_hz : float
        Drive frequency, Hz.
    seg_t0 : ndarray (k,)
        Segment starts, s (segments end at the next start or ``t_end``).
    seg_q, seg_qd : ndarray (k, n)
        Modal coordinates and velocities at the segment starts.
    impulse : ndarray (n_events,)
        Impulse on the free mass at each impact (N s; tool impacts included).
    tip_v_before, tip_v_after : ndarray (n_events,)
        Horn-tip velocity just before / after each impact, m/s.
    t_grid, u, tip_velocity : ndarray
        Tip displacement (m) and velocity (m/s) on the uniform grid ``sample_dt`` (with ``series``).
    """

    impact: ImpactResult
    horn: ModalHorn
    freq_hz: float
    seg_t0: np.ndarray
    seg_q: np.ndarray
    seg_qd: np.ndarray
    impulse: np.ndarray
    tip_v_before: np.ndarray
    tip_v_after: np.ndarray
    t_grid: np.ndarray | None = None
    u: np.ndarray | None = None
    tip_velocity: np.ndarray | None = None
    extra: dict = field(default_factory=dict)

    # ------------------------------------------------------------------ energy
    def stored_energy(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Modal kinetic + strain energy of states (k, n), J."""
        h = self.horn
        return 0.5 * (h.modal_mass * qd ** 2 + h.modal_mass * h.omega ** 2 * q ** 2).sum(axis=-1)

    def state_at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Modal coordinates and velocities at time t (from the segment containing it)."""
        j = int(np.searchsorted(self.seg_t0, t, side="right") - 1)
        return _propagate(self.horn, self.freq_hz, self.seg_t0[j], self.seg_q[j], self.seg_qd[j], t - self.seg_t0[j])

    def energy_balance(self, edges) -> list[dict]:
        """Energy per interval between consecutive ``edges`` (s), every term in J.

        ``drive_j``: work of the drive on the modes plus on the quasi-static residual during
        impacts (the electrical input converted to mechanics); ``damping_j``: modal damping loss
        (mechanical and dielectric, as the LossModel's modal loss factors); ``stored_change_j``;
        ``to_free_mass_j``: work of the horn on the free mass at horn impacts; ``restitution_horn_j``
        and ``restitution_tool_j``: energy lost in the impacts; ``to_tool_j``: kinetic energy given
        to the drill tool at tool impacts. ``residual_j`` = drive - damping - stored change -
        to_free_mass (0 up to round-off).
        """
        edges = np.asarray(edges, float)
        p = self.impact.params
        t_end = p.t_end
        ends = np.append(self.seg_t0[1:], t_end)
        rows = []
        W = 2 * math.pi * self.freq_hz
        r = self.horn.residual_phasor()
        ev_t = self.impact.t
        horn_ev = ~self.impact.is_tool
        # work of the residual (a driven displacement) on the free mass at horn impacts
        res_vel = (1j * W * r * np.exp(1j * W * ev_t)).real
        for a, b in zip(edges[:-1], edges[1:]):
            lo = np.maximum(self.seg_t0, a)
            hi = np.minimum(ends, b)
            sel = hi > lo
            integ = segment_integrals(self.horn, self.freq_hz, self.seg_t0[sel], self.seg_q[sel], self.seg_qd[sel],
                                      lo[sel] - self.seg_t0[sel], hi[sel] - self.seg_t0[sel])
            inw = (ev_t >= a) & (ev_t < b)
            J = self.impulse
            hw = horn_ev & inw
            q_a, qd_a = self.state_at(a)
            q_b, qd_b = self.state_at(b)
            to_free = float(np.sum(J[hw] * 0.5 * (self.tip_v_before[hw] + self.tip_v_after[hw])))
            drive = float(integ["drive_j"].sum() + np.sum(J[hw] * res_vel[hw]))
            damp = float(integ["damping_j"].sum())
            stored = float(self.stored_energy(q_b, qd_b) - self.stored_energy(q_a, qd_a))
            imp = self.impact
            rel_h = imp.w_before[hw] - self.tip_v_before[hw]
            mu_h = 1.0 / (1.0 / p.m_free + 1.0 / self.horn.tip_mass)
            tw = imp.is_tool & inw
            rel_t = imp.w_before[tw] - imp.v_before[tw]
            mu_t = p.m_free * p.m_tool / (p.m_free + p.m_tool)
            rows.append({
                "t_from_s": float(a), "t_to_s": float(b), "drive_j": drive, "damping_j": damp,
                "stored_change_j": stored, "to_free_mass_j": to_free,
                "restitution_horn_j": float(np.sum(0.5 * mu_h * (1 - p.e2 ** 2) * rel_h ** 2)),
                "restitution_tool_j": float(np.sum(0.5 * mu_t * (1 - p.e1 ** 2) * rel_t ** 2)),
                "to_tool_j": float(np.sum(0.5 * p.m_tool * (imp.v_after[tw] ** 2 - imp.v_before[tw] ** 2))),
                "residual_j": drive - damp - stored - to_free,
            })
        return rows

    def envelope(self, cycles: int = 4) -> tuple[np.ndarray, np.ndarray]:
        """Running amplitude of the tip: the fundamental at the drive over consecutive windows of
        ``cycles`` drive periods, ``|2/T int u e^{-jWt} dt|`` (closed form). Returns window
        centres (s) and amplitudes (m)."""
        T = cycles / self.freq_hz
        n = int(math.floor(self.impact.params.t_end / T + 1e-9))
        edges = np.arange(n + 1) * T
        amp = np.array([abs(2.0 / T * self._fundamental(a, b)) for a, b in zip(edges[:-1], edges[1:])])
        return 0.5 * (edges[:-1] + edges[1:]), amp

    def _fundamental(self, a: float, b: float) -> complex:
        ends = np.append(self.seg_t0[1:], self.impact.params.t_end)
        lo = np.maximum(self.seg_t0, a)
        hi = np.minimum(ends, b)
        sel = hi > lo
        integ = segment_integrals(self.horn, self.freq_hz, self.seg_t0[sel], self.seg_q[sel], self.seg_qd[sel],
                                  lo[sel] - self.seg_t0[sel], hi[sel] - self.seg_t0[sel])
        return complex(integ["fundamental"].sum())

    def mean_amplitude(self, t_from: float, t_to: float) -> float:
        """Amplitude of the tip's fundamental over [t_from, t_to], m."""
        return abs(2.0 / (t_to - t_from) * self._fundamental(t_from, t_to))

    def drive_power(self, t_from: float, t_to: float, dt: float | None = None) -> tuple[float, float]:
        """Mean electrical power drawn (W) and RMS drive current (A) over [t_from, t_to], from
        the current ``I = dQ/dt`` sampled at ``dt`` (default: 64 points per drive period)."""
        dt = dt or 1.0 / (64 * self.freq_hz)
        t = np.arange(t_from, t_to, dt)
        q, qd, qdd = _states_on(self, t)
        h = self.horn
        W = 2 * math.pi * self.freq_hz
        I = h.drive_current(self.freq_hz, t, qd, qdd)
        V = h.voltage * np.sin(W * t)
        return float(np.mean(V * I)), float(np.sqrt(np.mean(I ** 2)))


def _propagate(horn: ModalHorn, freq_hz: float, t0: float, q0, qd0, s):
    """Modal state at t0 + s from (q0, qd0) at t0 (free evolution under the drive)."""
    W = 2 * math.pi * freq_hz
    qs = horn.steady_modal(freq_hz)
    e0 = np.exp(1j * W * t0)
    h0 = q0 - (qs * e0).real
    hd0 = qd0 - (1j * W * qs * e0).real
    mu = -horn.zeta * horn.omega + 1j * horn.omega * np.sqrt(1 - horn.zeta ** 2)
    C = h0 - 1j * (hd0 - h0 * mu.real) / mu.imag
    es = np.exp(mu * s)
    e1 = np.exp(1j * W * (t0 + s))
    return (qs * e1).real + (C * es).real, (1j * W * qs * e1).real + (C * mu * es).real


def _states_on(res: CoupledResult, t: np.ndarray):
    """Modal q, q', q'' at sorted times t (len(t), n)."""
    h = res.horn
    W = 2 * math.pi * res.freq_hz
    qs = h.steady_modal(res.freq_hz)
    mu = -h.zeta * h.omega + 1j * h.omega * np.sqrt(1 - h.zeta ** 2)
    idx = np.searchsorted(res.seg_t0, t, side="right") - 1
    t0 = res.seg_t0[idx][:, None]
    e0 = np.exp(1j * W * t0)
    h0 = res.seg_q[idx] - (qs * e0).real
    hd0 = res.seg_qd[idx] - (1j * W * qs * e0).real
    C = h0 - 1j * (hd0 - h0 * mu.real) / mu.imag
    es = np.exp(mu * (t[:, None] - t0))
    e1 = np.exp(1j * W * t[:, None])
    q = (qs * e1).real + (C * es).real
    qd = (1j * W * qs * e1).real + (C * mu * es).real
    qdd = (-W * W * qs * e1).real + (C * mu * mu * es).real
    return q, qd, qdd


# ----------------------------------------------------------------------------- reference engine


class _HornState:
    """The modal horn over one segment: steady part + one _Osc per mode (free oscillation)."""

    def __init__(self, sim: "_ModalSim", t0: float, q: list, qd: list):
        self.t0 = t0
        W = sim.W
        c, s = math.cos(W * t0), math.sin(W * t0)
        self.osc = []
        for i in range(sim.n):
            a, b = sim.ha[i], sim.hb[i]
            p = a * c + b * s
            pd = W * (-a * s + b * c)
            self.osc.append(_Osc(sim.hm[i], sim.hm[i] * sim.hw[i] * sim.hw[i], 2.0 * sim.hz[i] * sim.hw[i] * sim.hm[i],
                                 0.0, q[i] - p, qd[i] - pd))
        b0 = 0.0
        b2 = 0.0
        for i in range(sim.n):
            b0 += abs(sim.hs[i]) * self.osc[i].b0
            b2 += abs(sim.hs[i]) * self.osc[i].b2
        self.B0 = sim.Ua + b0                 # |u| <= B0
        self.B2 = sim.Ua * W * W + b2         # |u''| <= B2

    def tip(self, sim, tt: float) -> tuple[float, float]:
        W = sim.W
        c, s = math.cos(W * tt), math.sin(W * tt)
        u = sim.Uc * c + sim.Us * s
        ud = W * (-sim.Uc * s + sim.Us * c)
        for i in range(sim.n):
            y, yd = self.osc[i].pv(tt - self.t0)
            u += sim.hs[i] * y
            ud += sim.hs[i] * yd
        return u, ud

    def tip_vec(self, sim, tg: np.ndarray):
        W = sim.W
        c, s = np.cos(W * tg), np.sin(W * tg)
        u = sim.Uc * c + sim.Us * s
        ud = W * (-sim.Uc * s + sim.Us * c)
        for i in range(sim.n):
            y, yd = self.osc[i].pv_vec(tg - self.t0)
            u = u + sim.hs[i] * y
            ud = ud + sim.hs[i] * yd
        return u, ud

    def tip_acc(self, sim, tt: float) -> float:
        W = sim.W
        u2 = -W * W * (sim.Uc * math.cos(W * tt) + sim.Us * math.sin(W * tt))
        for i in range(sim.n):
            u2 += sim.hs[i] * self.osc[i].acc_jerk(tt - self.t0)[0]
        return u2

    def modal(self, sim, tt: float) -> tuple[list, list]:
        W = sim.W
        c, s = math.cos(W * tt), math.sin(W * tt)
        q, qd = [], []
        for i in range(sim.n):
            y, yd = self.osc[i].pv(tt - self.t0)
            q.append(sim.ha[i] * c + sim.hb[i] * s + y)
            qd.append(W * (-sim.ha[i] * s + sim.hb[i] * c) + yd)
        return q, qd


class _ModalSim:
    """Readable reference of the coupled model (see the module docstring)."""

    def __init__(self, p: ImpactParams, horn: ModalHorn):
        check_coupled_params(p, horn)
        self.p, self.horn = p, horn
        tab, x = horn.pack(p.freq)
        from .horn import H_A, H_B, H_MASS, H_OMEGA, H_TIP, H_ZETA, X_RC, X_RS, X_UC, X_US, X_W
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
        p = self.p
        return 0.5 * p.m_free * wd * wd - p.m_free * self.a * w + 0.5 * p.m_tool * vd * vd + 0.5 * p.k0 * v * v

    def run(self) -> CoupledResult:
        p, a, L0 = self.p, self.a, self.p.gap
        t_end = p.t_end
        q0, qd0 = self.horn.initial_state(p.freq)
        q, qd = [float(x) for x in q0], [float(x) for x in qd0]
        hs0 = _HornState(self, 0.0, q, qd)
        u0, ud0 = hs0.tip(self, 0.0)
        t = 0.0
        mode = FREE
        w, wd = u0, ud0 + p.v0
        v, vd = 0.0, 0.0
        skip_rel = 2.0 * p.v0          # skip_h = t0 + skip_rel / B_horn of the next segment
        skip_h = 0.0
        skip_t = 0.0
        E0 = self.energy(w, wd, v, vd)
        work = 0.0
        ev = {k: [] for k in ("t", "contact", "x", "wb", "wa", "vb", "va", "E", "W", "J", "ub", "ua")}
        segs, seg_q, seg_qd = [], [], []
        stick = []
        stick_start = None
        n_ev = 0
        while t < t_end:
            if mode == ON_TOOL:
                osc = _Osc(self.M, p.k0, p.c, p.m_free * a / p.k0, v, vd)
            else:
                osc = _Osc(p.m_tool, p.k0, p.c, 0.0, v, vd)
            hst = _HornState(self, t, q, qd)
            Bh = abs(a) + hst.B2
            if skip_rel > 0.0:
                skip_h = t + skip_rel / Bh
                skip_rel = 0.0
            segs.append((t, mode, w, wd, v, vd))
            seg_q.append(list(q))
            seg_qd.append(list(qd))
            t0, w0, wd0 = t, w, wd
            Bv = osc.b2
            fns = []
            if mode == FREE:
                def h_vec(tg, t0=t0, w0=w0, wd0=wd0, hst=hst):
                    s = tg - t0
                    u, ud = hst.tip_vec(self, tg)
                    return w0 + s * (wd0 + 0.5 * a * s) - u, wd0 + a * s - ud

                def h_sca(tt, t0=t0, w0=w0, wd0=wd0, hst=hst):
                    s = tt - t0
                    u, ud = hst.tip(self, tt)
                    return w0 + s * (wd0 + 0.5 * a * s) - u, wd0 + a * s - ud

                def t_vec(tg, t0=t0, w0=w0, wd0=wd0, osc=osc):
                    s = tg - t0
                    vv, vvd = osc.pv_vec(s)
                    return L0 + vv - (w0 + s * (wd0 + 0.5 * a * s)), vvd - (wd0 + a * s)

                def t_sca(tt, t0=t0, w0=w0, wd0=wd0, osc=osc):
                    s = tt - t0
                    vv, vvd = osc.pv(s)
                    return L0 + vv - (w0 + s * (wd0 + 0.5 * a * s)), vvd - (wd0 + a * s)

                Bt = Bv + abs(a)
                zone_h = t0 + _parabola_reach(w0 - hst.B0 - 1e-9, wd0, a)
                zone_t = t0 + _parabola_reach(L0 - osc.b0 - 1e-9 - w0, -wd0, -a)
                for name, vec, sca, B, zone, skip, lead, vel, acc in (
                        (HORN, h_vec, h_sca, Bh, zone_h, skip_h, w0 - hst.B0 - 1e-9, wd0, a),
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
            else:  # ON_TOOL
                def r_vec(tg, t0=t0, osc=osc):
                    acc, jerk = osc.acc_jerk_vec(tg - t0)
                    return a - acc, -jerk

                def r_sca(tt, t0=t0, osc=osc):
                    acc, jerk = osc.acc_jerk(tt - t0)
                    return a - acc, -jerk

                def g_vec(tg, t0=t0, osc=osc, hst=hst):
                    vv, vvd = osc.pv_vec(tg - t0)
                    u, ud = hst.tip_vec(self, tg)
                    return L0 + vv - u, vvd - ud

                def g_sca(tt, t0=t0, osc=osc, hst=hst):
                    vv, vvd = osc.pv(tt - t0)
                    u, ud = hst.tip(self, tt)
                    return L0 + vv - u, vvd - ud

                Br = osc.b4
                B = Bv + hst.B2
                if L0 + osc.delta - osc.b0 - hst.B0 <= 0.0:
                    fns.append(_Fn("pinch", g_vec, g_sca, B, t0, _grid_step(B, t_end)))
                if osc.b2 >= a:
                    fns.append(_Fn("release", r_vec, r_sca, Br, t0,
                                   _grid_step(Br, t_end, 1e-3 * (abs(a) + osc.b2))))

            te, name = _first_event(fns, t_end)
            if te is None:
                break
            te = float(te)
            if name == "pinch":
                raise SimulationError(_pinch_message(te))
            n_ev += 1
            if n_ev > p.max_events:
                raise SimulationError(f"more than max_events = {p.max_events} events by t = {te:.9g} s")
            s = te - t0
            v, vd = osc.pv(s)
            q, qd = hst.modal(self, te)
            uh, uhd = hst.tip(self, te)
            if mode == FREE:
                w, wd = w0 + s * (wd0 + 0.5 * a * s), wd0 + a * s
            else:
                w, wd = L0 + v, vd
            t = te
            if L0 + v <= 2.0 * hst.B0:
                raise SimulationError(_pinch_message(te))
            if name == "release":
                skip_h = te
                skip_t = te
                stick.append((stick_start, te, "tool"))
                mode = FREE
                continue
            if name == HORN:
                x = uh
                rel_in = wd - uhd
                J = -(1.0 + p.e2) * rel_in / (1.0 / p.m_free + self.S)
                wa = wd + J / p.m_free
                for i in range(self.n):
                    qd[i] -= self.hs[i] * J / self.hm[i]
                ua = uhd - J * self.S
                work += J * 0.5 * (uhd + ua)
                wb = wd
                if _sticks(wa - ua, hst.tip_acc(self, te) - a, p.v_stick):
                    raise HornStickError(f"the free mass would rest on the modal horn at t = {te:.9g} s "
                                         f"(relative speed {wa - ua:.3g} m/s): not modelled")
                skip_rel = 2.0 * (wa - ua)
                skip_t = te
                w, wd = x, wa
                vb = va = vd
                ub = uhd
            else:
                x = L0 + v
                M = self.M
                vb, wb = vd, wd
                rel = wd - vd
                va = vd + p.m_free / M * (1.0 + p.e1) * rel
                wa = wd - p.m_tool / M * (1.0 + p.e1) * rel
                J = p.m_free * (wa - wd)
                acc_tool = -(p.c * va + p.k0 * v) / p.m_tool
                if _sticks(va - wa, a - acc_tool, p.v_stick):
                    va = wa = (p.m_tool * vd + p.m_free * wd) / M
                    J = p.m_free * (wa - wd)
                    mode = ON_TOOL
                    stick_start = te
                else:
                    skip_t = te + 2.0 * (va - wa) / (abs(a) + _Osc(p.m_tool, p.k0, p.c, 0.0, v, va).b2)
                    skip_h = te
                w, wd, vd = x, wa, va
                ub = ua = uhd
            ev["t"].append(te)
            ev["contact"].append(name)
            ev["x"].append(x)
            ev["wb"].append(wb)
            ev["wa"].append(wa)
            ev["vb"].append(vb)
            ev["va"].append(va)
            ev["E"].append(self.energy(w, wd, v, vd))
            ev["W"].append(work)
            ev["J"].append(J)
            ev["ub"].append(ub)
            ev["ua"].append(ua)
        if stick_start is not None and mode != FREE:
            stick.append((stick_start, p.t_end, "tool"))
        arr = {k: np.array(val, dtype=float) for k, val in ev.items() if k != "contact"}
        res = ImpactResult(params=p, t=arr["t"], contact=np.array(ev["contact"], dtype="<U4"), x=arr["x"],
                           w_before=arr["wb"], w_after=arr["wa"], v_before=arr["vb"], v_after=arr["va"],
                           energy=arr["E"], horn_work=arr["W"], energy0=E0, stick=stick, n_events=n_ev)
        seg = tuple(np.array([sg[j] for sg in segs], dtype=np.int8 if j == 1 else float) for j in range(6))
        return CoupledResult(impact=res, horn=self.horn, freq_hz=p.freq, seg_t0=seg[0],
                             seg_q=np.array(seg_q, float).reshape(len(segs), self.n),
                             seg_qd=np.array(seg_qd, float).reshape(len(segs), self.n),
                             impulse=arr["J"], tip_v_before=arr["ub"], tip_v_after=arr["ua"],
                             extra={"segments": seg})


def _series(res: CoupledResult) -> None:
    """Sample tip, free mass and tool face on the grid ``sample_dt`` (analytic per segment)."""
    from .model import ON_HORN, _series as _kin_series

    p = res.impact.params
    seg = res.extra["segments"]
    # the free mass and tool face as in the kinematic model (no segment rides the horn here)
    assert not np.any(seg[1] == ON_HORN)
    _kin_series(res.impact, seg)
    tg = res.impact.t_grid
    q, qd, _ = _states_on(res, tg)
    h = res.horn
    W = 2 * math.pi * p.freq
    r = h.residual_phasor()
    e = np.exp(1j * W * tg)
    res.t_grid = tg
    res.u = q @ h.tip + (r * e).real
    res.tip_velocity = qd @ h.tip + (1j * W * r * e).real
    res.impact.u = res.u


def simulate_coupled(params: ImpactParams, horn: ModalHorn, *, series: bool = True,
                     engine: str = "kernel") -> CoupledResult:
    """Run the impact model with the modal horn (see the module docstring).

    Parameters
    ----------
    params : ImpactParams
        Free mass, tool, restitution, gap, ...; ``freq`` is the drive frequency (Hz) and ``A0``
        is not used (the tip motion comes from the horn).
    horn : ModalHorn
    series : bool
        Also sample the tip, free mass and tool face on the grid ``params.sample_dt``.
    engine : {"kernel", "python"}
        The compiled kernel (:mod:`impact.kernel_modal`) or the reference above.

    Returns
    -------
    CoupledResult

    Raises
    ------
    SimulationError
        Pinched free mass, too many events; :class:`HornStickError` if the free mass would rest on
        the horn.
    """
    check_coupled_params(params, horn)
    if engine == "python":
        res = _ModalSim(params, horn).run()
    elif engine == "kernel":
        from . import kernel_modal

        res = kernel_modal.run_coupled(params, horn)
    else:
        raise ParameterError("engine", engine, "must be 'kernel' or 'python'")
    if series:
        _series(res)
    log.info("coupled run %.4g s (%s, %d modes): %d tool impacts, %d horn impacts", params.t_end, engine,
             horn.n_modes, res.impact.tool_impacts, res.impact.horn_impacts)
    return res
