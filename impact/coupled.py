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

Approximation (the one place the coupling is not exact): the free mass *riding* the horn. When
the sticking rule fires at a horn impact (a chattering sequence ends, e.g. a spring-loaded free
mass on a horn still ringing up), the free mass moves with the tip, ``w = u``, until the contact
force per mass ``u'' - a`` falls to zero (found by the same guaranteed search, with the bound
``|u^(4)| <= W^4 |U^| + sum |s_i| b_4,i``), as on the kinematic horn. During the ride the
reaction ``m_w (u'' - a)`` on the modes is neglected (exactly it would add ``m_w s s^T`` to the
modal mass matrix, a non-proportionally damped system). Rides last less than half a drive
period (25 us at 20 kHz) and are rare (device scenario, 8 g: ~4e-7 of the time); the horn's work
on the riding mass is counted in ``horn_work`` as on the kinematic horn and reported apart in
:meth:`CoupledResult.energy_balance` (``riding_j``), so the balance of the modes stays exact. Only
``horn_law = "kinematic"`` is accepted (the modal horn has its own mass law).

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
from .model import (FREE, HORN, ON_HORN, ON_TOOL, TOOL, ImpactResult, SimulationError, _first_event, _Fn,
                    _grid_step, _Osc, _parabola_excursion, _parabola_leave, _parabola_reach, _pinch_message,
                    _sticks)
from .params import ImpactParams

__all__ = ["CoupledResult", "simulate_coupled", "check_coupled_params", "coupled_batch",
           "COUPLED_QUANTITIES"]

log = logging.getLogger(__name__)


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
        Modal coordinates and velocities at the segment starts (with a series-resistance drive the
        ``n + 1`` pseudo-modal ones of :mod:`impact.drive`).
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
        if self.horn.series_resistance > 0:
            from . import drive_result as drive

            x, xd, _ = drive.physical(self, [t])
            return x[0, :self.horn.n_modes], x[0, self.horn.n_modes:2 * self.horn.n_modes]
        j = int(np.searchsorted(self.seg_t0, t, side="right") - 1)
        return _propagate(self.horn, self.freq_hz, self.seg_t0[j], self.seg_q[j], self.seg_qd[j], t - self.seg_t0[j])

    def energy_balance(self, edges) -> list[dict]:
        """Energy per interval between consecutive ``edges`` (s), every term in J.

        ``electric_j``: electrical energy drawn from the source, ``int V I dt``;
        ``drive_j``: work of the drive on the modes plus on the quasi-static residual during
        impacts (the electrical input converted to mechanics); ``damping_j``: modal damping loss
        (mechanical and dielectric, as the LossModel's modal loss factors); ``stored_change_j``;
        ``to_free_mass_j``: work of the horn on the free mass at horn impacts; ``restitution_horn_j``
        and ``restitution_tool_j``: energy lost in the impacts; ``to_tool_j``: kinetic energy given
        to the drill tool at tool impacts; ``riding_j``: work of the tip on a free mass riding it
        (sticking phases ending in the interval; not drawn from the modes, see the module
        docstring). ``residual_j`` = drive - damping - stored change - to_free_mass (0 up to
        round-off). With a series-resistance drive the port adds ``source_loss_j``,
        ``electrode_change_j`` and ``electric_residual_j`` (:func:`impact.drive_result.port_terms`).
        """
        if self.extra.get("compliant"):
            raise ParameterError("energy_balance", "compliant contact",
                                 "needs closed-form segments; not available with the Hunt-Crossley option")
        edges = np.asarray(edges, float)
        rows = []
        for a, b in zip(edges[:-1], edges[1:]):
            if self.horn.series_resistance > 0:
                from . import drive_result

                row = drive_result.port_terms(self, a, b)
            else:
                row = self._voltage_terms(a, b)
            row.update(self._impact_terms(a, b))
            row["residual_j"] = row["drive_j"] - row["damping_j"] - row["stored_change_j"] - row["to_free_mass_j"]
            rows.append({"t_from_s": float(a), "t_to_s": float(b), **row})
        return rows

    def _integrals(self, a: float, b: float) -> dict:
        """:func:`impact.horn.segment_integrals` summed over the parts of the segments in [a, b]."""
        ends = np.append(self.seg_t0[1:], self.impact.params.t_end)
        lo = np.maximum(self.seg_t0, a)
        hi = np.minimum(ends, b)
        sel = hi > lo
        return segment_integrals(self.horn, self.freq_hz, self.seg_t0[sel], self.seg_q[sel], self.seg_qd[sel],
                                 lo[sel] - self.seg_t0[sel], hi[sel] - self.seg_t0[sel])

    def _voltage_terms(self, a: float, b: float) -> dict:
        """Electrical input, work on the modes, damping loss and stored change over [a, b] (voltage drive)."""
        integ = self._integrals(a, b)
        # the residual is a driven displacement: the source's work on the free mass at horn impacts
        W = 2 * math.pi * self.freq_hz
        imp = self.impact
        hw = ~imp.is_tool & (imp.t >= a) & (imp.t < b)
        res_vel = (1j * W * self.horn.residual_phasor() * np.exp(1j * W * imp.t[hw])).real
        q_a, qd_a = self.state_at(a)
        q_b, qd_b = self.state_at(b)
        return {"electric_j": float(integ["electric_j"].sum()),
                "drive_j": float(integ["drive_j"].sum() + np.sum(self.impulse[hw] * res_vel)),
                "damping_j": float(integ["damping_j"].sum()),
                "stored_change_j": float(self.stored_energy(q_b, qd_b) - self.stored_energy(q_a, qd_a))}

    def tip_at(self, t: float) -> tuple[float, float]:
        """Tip displacement (m) and velocity (m/s) at time t."""
        if self.horn.series_resistance > 0:
            from . import drive_result

            u, ud = drive_result.tip_series(self, [t])
            return float(u[0]), float(ud[0])
        return _tip_of(self, t, *self.state_at(t))

    def _impact_terms(self, a: float, b: float) -> dict:
        """Work on the free mass, restitution losses, energy to the tool and riding work over [a, b]."""
        p = self.impact.params
        imp = self.impact
        inw = (imp.t >= a) & (imp.t < b)
        hw = ~imp.is_tool & inw
        tw = imp.is_tool & inw
        J = self.impulse
        rel_h = imp.w_before[hw] - self.tip_v_before[hw]
        mu_h = 1.0 / (1.0 / p.m_free + 1.0 / self.horn.tip_mass)
        rel_t = imp.w_before[tw] - imp.v_before[tw]
        mu_t = p.m_free * p.m_tool / (p.m_free + p.m_tool)
        riding = 0.0
        for s0, s1, body in imp.stick:
            if body == "horn" and a <= s1 < b and s1 < p.t_end:
                (u0, ud0), (u1, ud1) = self.tip_at(s0), self.tip_at(s1)
                riding += (0.5 * p.m_free * ud1 ** 2 - p.m_free * p.a_free * u1) - \
                          (0.5 * p.m_free * ud0 ** 2 - p.m_free * p.a_free * u0)
        return {"to_free_mass_j": float(np.sum(J[hw] * 0.5 * (self.tip_v_before[hw] + self.tip_v_after[hw]))),
                "restitution_horn_j": float(np.sum(0.5 * mu_h * (1 - p.e2 ** 2) * rel_h ** 2)),
                "restitution_tool_j": float(np.sum(0.5 * mu_t * (1 - p.e1 ** 2) * rel_t ** 2)),
                "to_tool_j": float(np.sum(0.5 * p.m_tool * (imp.v_after[tw] ** 2 - imp.v_before[tw] ** 2))),
                "riding_j": float(riding)}

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
        if self.horn.series_resistance > 0:
            from . import drive_result as drive

            return drive.fundamental(self, a, b)
        integ = self._integrals(a, b)
        return complex(integ["fundamental"].sum())

    def mean_amplitude(self, t_from: float, t_to: float) -> float:
        """Amplitude of the tip's fundamental over [t_from, t_to], m."""
        return abs(2.0 / (t_to - t_from) * self._fundamental(t_from, t_to))

    def drive_power(self, t_from: float, t_to: float, dt: float | None = None) -> tuple[float, float]:
        """Mean electrical power drawn (W) and RMS drive current (A) over [t_from, t_to], from
        the current ``I = dQ/dt`` sampled at ``dt`` (default: 64 points per drive period); with a
        series resistance the source's power and current (:func:`impact.drive.drive_power`)."""
        if self.horn.series_resistance > 0:
            from . import drive_result as drive

            return drive.drive_power(self, t_from, t_to, dt)
        dt = dt or 1.0 / (64 * self.freq_hz)
        t = np.arange(t_from, t_to, dt)
        q, qd, qdd = _states_on(self, t)
        h = self.horn
        W = 2 * math.pi * self.freq_hz
        I = h.drive_current(self.freq_hz, t, qd, qdd)
        V = h.voltage * np.sin(W * t)
        return float(np.mean(V * I)), float(np.sqrt(np.mean(I ** 2)))


def _tip_of(res: "CoupledResult", t: float, q, qd) -> tuple[float, float]:
    """Tip displacement and velocity from the modal state at time t."""
    W = 2 * math.pi * res.freq_hz
    r = res.horn.residual_phasor() * np.exp(1j * W * t)
    return float(q @ res.horn.tip + r.real), float(qd @ res.horn.tip + (1j * W * r).real)


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
        ``vec``): the steady part plus every mode's free oscillation, as ``kernel_modal._tip``."""
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

    def __init__(self, p: ImpactParams, horn: ModalHorn, contact=None):
        check_coupled_params(p, horn)
        self.p, self.horn = p, horn
        self.contact = contact
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
        stick_E = 0.0
        contacts = []
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
            elif mode == ON_HORN:
                # riding on the horn: the contact force per mass u'' - a falls to zero at the release
                def hr_vec(tg, hst=hst):
                    u2, u3 = hst.tip_acc_jerk_vec(self, tg)
                    return u2 - a, u3

                def hr_sca(tt, hst=hst):
                    u2, u3 = hst.tip_acc_jerk(self, tt)
                    return u2 - a, u3

                def gh_vec(tg, t0=t0, osc=osc, hst=hst):
                    vv, vvd = osc.pv_vec(tg - t0)
                    u, ud = hst.tip_vec(self, tg)
                    return L0 + vv - u, vvd - ud

                def gh_sca(tt, t0=t0, osc=osc, hst=hst):
                    vv, vvd = osc.pv(tt - t0)
                    u, ud = hst.tip(self, tt)
                    return L0 + vv - u, vvd - ud

                B = Bv + hst.B2
                if L0 - osc.b0 - hst.B0 <= 0.0:
                    fns.append(_Fn("pinch", gh_vec, gh_sca, B, max(t0, skip_t), _grid_step(B, t_end)))
                fns.append(_Fn("hrel", hr_vec, hr_sca, hst.B4, t0, _grid_step(hst.B4, t_end, 1e-3 * (abs(a) + hst.B2))))
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
            elif mode == ON_HORN:
                w, wd = uh, uhd
            else:
                w, wd = L0 + v, vd
            t = te
            if L0 + v <= 2.0 * hst.B0:
                raise SimulationError(_pinch_message(te))
            if name == "hrel":
                # the horn did the work that moved the riding mass (its reaction on the modes neglected)
                work += (0.5 * p.m_free * wd * wd - p.m_free * a * w) - stick_E
                skip_h = te
                skip_t = te
                stick.append((stick_start, te, "horn"))
                mode = FREE
                continue
            if name == "release":
                skip_h = te
                skip_t = te
                stick.append((stick_start, te, "tool"))
                mode = FREE
                continue
            if name == HORN and self.contact is not None:
                # compliant contact: integrate the contact phase (impact.contact)
                from .contact import contact_phase

                fc, fs = self.horn.forcing()
                tab = {"omega": np.array(self.hw), "zeta": np.array(self.hz), "mass": np.array(self.hm),
                       "tip": np.array(self.hs), "fc": fc, "fs": fs}
                t1, w1, wd1, q1, qd1, J, diss = contact_phase(self.contact, tab, te, wd=wd, w=w, q=np.array(q),
                                                              qd=np.array(qd), m_free=p.m_free, a=a, W=self.W,
                                                              rc=self.Rc, rs=self.Rs, t_max=t_end)
                v, vd = osc.pv(t1 - t0)
                work += (0.5 * p.m_free * wd1 * wd1 - p.m_free * a * w1) - (0.5 * p.m_free * wd * wd - p.m_free * a * w) + diss
                contacts.append((te, t1, J, diss))
                ev["t"].append(te)
                ev["contact"].append(HORN)
                ev["x"].append(uh)
                ev["wb"].append(wd)
                ev["wa"].append(wd1)
                ev["vb"].append(vd)
                ev["va"].append(vd)
                ev["J"].append(J)
                ev["ub"].append(uhd)
                q, qd = [float(x) for x in q1], [float(x) for x in qd1]
                t, w, wd = t1, w1, wd1
                hs1 = _HornState(self, t1, q, qd)
                u1, ud1 = hs1.tip(self, t1)
                ev["ua"].append(ud1)
                ev["E"].append(self.energy(w, wd, v, vd))
                ev["W"].append(work)
                if t1 >= t_end:
                    break
                skip_rel = 2.0 * max(wd1 - ud1, 0.0)
                skip_t = t1
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
                    wa = ua
                    mode = ON_HORN
                    stick_start = te
                    stick_E = 0.5 * p.m_free * wa * wa - p.m_free * a * x
                else:
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
            stick.append((stick_start, p.t_end, "horn" if mode == ON_HORN else "tool"))
        arr = {k: np.array(val, dtype=float) for k, val in ev.items() if k != "contact"}
        res = ImpactResult(params=p, t=arr["t"], contact=np.array(ev["contact"], dtype="<U4"), x=arr["x"],
                           w_before=arr["wb"], w_after=arr["wa"], v_before=arr["vb"], v_after=arr["va"],
                           energy=arr["E"], horn_work=arr["W"], energy0=E0, stick=stick, n_events=n_ev)
        seg = tuple(np.array([sg[j] for sg in segs], dtype=np.int8 if j == 1 else float) for j in range(6))
        return CoupledResult(impact=res, horn=self.horn, freq_hz=p.freq, seg_t0=seg[0],
                             seg_q=np.array(seg_q, float).reshape(len(segs), self.n),
                             seg_qd=np.array(seg_qd, float).reshape(len(segs), self.n),
                             impulse=arr["J"], tip_v_before=arr["ub"], tip_v_after=arr["ua"],
                             extra={"segments": seg, "contacts": contacts, "compliant": self.contact is not None})


def _series(res: CoupledResult) -> None:
    """Sample tip, free mass and tool face on the grid ``sample_dt`` (analytic per segment)."""
    from .model import _series as _kin_series

    p = res.impact.params
    seg = res.extra["segments"]
    # the free mass and tool face as in the kinematic model; riding the horn: below
    _kin_series(res.impact, seg)
    tg = res.impact.t_grid
    res.t_grid = tg
    h = res.horn
    if h.series_resistance > 0:
        from . import drive_result as drive

        res.u, res.tip_velocity = drive.tip_series(res, tg)
    else:
        q, qd, _ = _states_on(res, tg)
        W = 2 * math.pi * p.freq
        r = h.residual_phasor()
        e = np.exp(1j * W * tg)
        res.u = q @ h.tip + (r * e).real
        res.tip_velocity = qd @ h.tip + (1j * W * r * e).real
    res.impact.u = res.u
    idx = np.searchsorted(seg[0], tg, side="right") - 1
    riding = seg[1][idx] == ON_HORN
    res.impact.w[riding] = res.u[riding]


def _run_kernel(params: ImpactParams, horn: ModalHorn, contact=None) -> CoupledResult:
    from . import kernel as K
    from . import kernel_modal

    ev, kinds, segs, stk, E0, status, t_status, n_ev, window = kernel_modal.run_events(params, horn, contact)
    if status == K.STATUS_PINCHED:
        raise SimulationError(_pinch_message(t_status))
    if status == K.STATUS_MAX_EVENTS:
        raise SimulationError(f"more than max_events = {params.max_events} events by t = {t_status:.9g} s")
    if status == kernel_modal.STATUS_CONTACT:
        raise SimulationError(f"the compliant contact starting at t = {t_status:.9g} s was not resolved in 1e6 "
                              "integration steps (contact stiffness or damping out of range)")
    n = (segs.shape[1] - 6) // 2
    contact = np.where(kinds == K.KIND_TOOL, TOOL, HORN).astype("<U4")
    stick = [(float(a), float(b), "tool" if body == K.BODY_TOOL else "horn") for a, b, body in stk]
    res = ImpactResult(params=params, t=ev[:, 0].copy(), contact=contact, x=ev[:, 1].copy(),
                       w_before=ev[:, 2].copy(), w_after=ev[:, 3].copy(), v_before=ev[:, 4].copy(),
                       v_after=ev[:, 5].copy(), energy=ev[:, 6].copy(), horn_work=ev[:, 7].copy(),
                       energy0=E0, stick=stick, n_events=n_ev)
    seg = (segs[:, 0].copy(), segs[:, 1].astype(np.int8), segs[:, 2].copy(), segs[:, 3].copy(),
           segs[:, 4].copy(), segs[:, 5].copy())
    return CoupledResult(impact=res, horn=horn, freq_hz=params.freq, seg_t0=segs[:, 0].copy(),
                         seg_q=segs[:, 6:6 + n].copy(), seg_qd=segs[:, 6 + n:6 + 2 * n].copy(),
                         impulse=ev[:, 8].copy(), tip_v_before=ev[:, 9].copy(), tip_v_after=ev[:, 10].copy(),
                         extra={"segments": seg, "window": window})


def simulate_coupled(params: ImpactParams, horn: ModalHorn, *, series: bool = True,
                     engine: str = "kernel", contact=None) -> CoupledResult:
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
    contact : impact.contact.HuntCrossley, optional
        Compliant horn contact (Hertz + Hunt-Crossley, integrated numerically during each contact:
        DOP853 in the Python engine, an adaptive Dormand-Prince 5(4) scheme in the kernel) instead of
        Newton's law; without series or energy balance (the contact phases are not closed-form
        segments; the kernel's window statistics integrate them).

    Returns
    -------
    CoupledResult

    Raises
    ------
    SimulationError
        Pinched free mass, too many events.
    """
    check_coupled_params(params, horn)
    if horn.series_resistance > 0:
        if contact is not None:
            raise ParameterError("contact", "hunt-crossley", "is not available with a series-resistance drive "
                                 "(its contact phases integrate the voltage-driven modes); use Newton's law")
        if engine == "python":
            raise ParameterError("engine", engine, "must be 'kernel' with a series-resistance drive")
    if contact is not None:
        from .contact import HuntCrossley

        if not isinstance(contact, HuntCrossley):
            raise ParameterError("contact", type(contact).__name__, "must be an impact.contact.HuntCrossley")
        if series:
            raise ParameterError("series", series, "must be False with a compliant contact (its contact phases "
                                 "are not closed-form segments)")
        if engine == "python":
            return _ModalSim(params, horn, contact).run()
        if engine != "kernel":
            raise ParameterError("engine", engine, "must be 'kernel' or 'python'")
        res = _run_kernel(params, horn, contact)
        res.extra["compliant"] = True
        return res
    if engine == "python":
        res = _ModalSim(params, horn).run()
    elif engine == "kernel":
        res = _run_kernel(params, horn)
    else:
        raise ParameterError("engine", engine, "must be 'kernel' or 'python'")
    if series:
        _series(res)
    log.info("coupled run %.4g s (%s, %d modes): %d tool impacts, %d horn impacts", params.t_end, engine,
             horn.n_modes, res.impact.tool_impacts, res.impact.horn_impacts)
    return res


# ----------------------------------------------------------------------------- statistics

#: quantities added to impact.stats.QUANTITIES by the coupled model
COUPLED_QUANTITIES = (
    ("tip_amplitude_m", "m", "horn-tip amplitude (fundamental at the drive over the window)"),
    ("drive_power_w", "W", "electrical power drawn from the source (mean V I)"),
    ("mech_drive_power_w", "W", "power of the drive on the modes (to mechanics)"),
    ("damping_power_w", "W", "modal damping loss per second"),
)


def coupled_batch(cases: list[ImpactParams], horn: ModalHorn, scenario="device", settings=None,
                  progress=None, contact=None) -> list:
    """Converged ensemble statistics of coupled runs (one horn, several cases, e.g. free masses).

    The members, scenarios, confidence intervals and the convergence rule are those of
    :func:`impact.stats.ensemble_batch` (every case's ``freq`` must be the drive frequency); the
    statistics add :data:`COUPLED_QUANTITIES` (per-member window means, Student t intervals). A
    case with a failed member (pinched, too many events) has no statistics, with the reason.
    ``contact``: an :class:`impact.contact.HuntCrossley` for compliant horn contacts (compiled
    kernel, contact phases integrated numerically), None for Newton's law.

    Returns
    -------
    list of impact.stats.EnsembleStats
    """
    from . import kernel
    from . import kernel_modal as KM
    from .stats import (DRIVING, QUANTITIES, EnsembleStats, Estimate, StatsSettings, _estimates, ensemble_members,
                        get_scenario, mean_ci)

    sc = get_scenario(scenario)
    st = settings or StatsSettings()
    for p in cases:
        check_coupled_params(p, horn)
    bases = [sc.apply(p) for p in cases]
    freqs = {p.freq for p in bases}
    if len(freqs) != 1:
        raise ParameterError("freq", sorted(freqs), "every case of a coupled batch must share the drive frequency")
    freq = freqs.pop()
    T = sc.window_s
    raws = [np.empty((0, KM.N_CSTATS)) for _ in bases]
    target = [st.n_start] * len(bases)
    done = [False] * len(bases)
    out = [None] * len(bases)
    names = [q for q, _, _ in QUANTITIES] + [q for q, _, _ in COUPLED_QUANTITIES]
    while not all(done):
        todo = [i for i in range(len(bases)) if not done[i]]
        members, owner = [], []
        for i in todo:
            new = ensemble_members(bases[i], target[i] - raws[i].shape[0], st, start=raws[i].shape[0])
            members += new
            owner += [i] * len(new)
        pmat = np.array([kernel.pack(p) for p in members], dtype=float).reshape(len(members), -1)
        raw = KM.ensemble_coupled(pmat, horn, freq, sc.t_from, sc.t_end, max(p.max_events for p in members),
                                  contact=contact)
        owner = np.array(owner)
        for i in todo:
            r = np.vstack([raws[i], raw[owner == i]])
            raws[i] = r
            status = r[:, kernel.S_STATUS]
            n = r.shape[0]
            if np.any(status != 0):
                why = (f"{int(np.sum(status != 0))} of {n} members failed (free mass pinched between horn and "
                       f"tool: increase gap or k0; too many events; or an unresolved compliant contact)")
                est = {q: Estimate(math.nan, math.nan, n, st.level, why) for q in names}
                out[i] = EnsembleStats(params=bases[i], scenario=sc, estimates=est, members=n,
                                       failed=int(np.sum(status != 0)), converged=False, settings=st, note=why,
                                       events=int(r[:, kernel.S_N_EVENTS].sum()), raw=r)
                done[i] = True
                continue
            est = _estimates(r[:, :kernel.N_STATS], T, st.level)
            amp = np.abs(2.0 / T * (r[:, KM.C_FUND_RE] + 1j * r[:, KM.C_FUND_IM]))
            est["tip_amplitude_m"] = mean_ci(amp, st.level)
            est["drive_power_w"] = mean_ci(r[:, KM.C_ELEC] / T, st.level)
            est["mech_drive_power_w"] = mean_ci(r[:, KM.C_DRIVE] / T, st.level)
            est["damping_power_w"] = mean_ci(r[:, KM.C_DAMP] / T, st.level)
            rel = [est[q].rel_half_width for q in DRIVING]
            conv = bool(n >= 2 and all(math.isfinite(x) and x <= st.rel_tol for x in rel))
            note = "" if conv or n < st.n_max else f"member cap n_max = {st.n_max} reached before the {st.rel_tol:.0%} target"
            out[i] = EnsembleStats(params=bases[i], scenario=sc, estimates=est, members=n, failed=0, converged=conv,
                                   settings=st, note=note, events=int(r[:, kernel.S_N_EVENTS].sum()), raw=r)
            if conv or n >= st.n_max:
                done[i] = True
            else:
                target[i] = min(2 * n, st.n_max)
        msg = (f"{sc.name} (coupled, {horn.n_modes} modes): round of {len(members)} members done, "
               f"{sum(done)}/{len(done)} case(s) finished")
        log.info("%s", msg)
        if progress is not None:
            progress(msg)
    return out
