"""The impact model with compliant contacts at the horn and the tool (Python reference engine).

Same bodies as :mod:`impact.coupled` (free mass, modal horn under the harmonic drive, damped tool
oscillator; read its docstring and :mod:`impact.model`'s for the axis and the tool), with both
impacts replaced by contacts of finite duration (:class:`impact.hertz.HertzLaw`: Hertz loading,
the restitution unloading that returns ``e`` of the approach speed on a rigid flat). The horn seen
by the contact is its modes kept plus the static compliance ``g`` of the modes left out
(:func:`results.coupled.tip_body` builds both from the FE drill)::

    m_w w'' = m_w a + F_h - F_t
    m_i (q_i'' + 2 zeta_i omega_i q_i' + omega_i^2 q_i) = f_i(t) - s_i F_h
    m_v x'' + c x' + k0 x = F_t
    F_h = law_h(d_h),   d_h + g F_h = u_m(t) - w,   u_m = sum s_i q_i + r(t)   (tip recedes by g F_h)
    F_t = law_t(d_t),   d_t = w - (L0 + x)

Between contacts the motion is closed form (free fall, the tool's and the modes' damped
oscillations, the modes' steady drive response); the next touch is found on a grid of 1/12 of the
shortest period (of the modes, the tool and the drive) and refined by Brent's method. Each contact
is integrated (``scipy.integrate.solve_ivp``, DOP853, error-controlled) in phases between its
events: it reaches its largest approach (loading -> unloading), reloads past it, or separates (the
approach returns to zero). ``flights="integrated"`` integrates the flights too, with the
integrator's event detection (the reference the fast path is tested against). The energy ledger
(drive work on the modes, the drive residual's work through the contact, modal and tool damping)
is integrated with the contacts and taken in closed form over the flights
(:func:`impact.horn.segment_integrals`), and closed against the bodies' energies and the contacts'
absorbed energy (:meth:`HertzLaw.stored` plus the loss of a contact that has unloaded).

Engines: :mod:`impact.kernel_compliant` (compiled, the default; :mod:`impact.compliant_engine`)
and this module's Python reference (about 1 s per 20 ms of an 8 g run with 16 modes to 70 kHz,
bench_compliant). Neither has a sticking rule: a free mass resting on a body is a long contact
phase, integrated as such.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rpud_common import ParameterError, check_choice, check_nonnegative

from .compliant_result import CompliantRun, Contact
from .hertz import HertzLaw
from .horn import ModalHorn
from .params import ImpactParams

__all__ = ["CompliantRun", "Contact", "simulate_compliant"]

# contact states
_OPEN, _LOADING, _UNLOADING = 0, 1, 2


@dataclass
class _Contact:
    law: HertzLaw
    residual: float = 0.0          # series static compliance, m/N
    state: int = _OPEN
    d_max: float = 0.0             # largest Hertz approach of the current contact
    total_max: float = 0.0         # total approach D at d_max
    t_start: float = 0.0
    v_in: float = 0.0
    peak: float = 0.0
    log: list = field(default_factory=list)

    def force_of(self, total: float) -> tuple[float, float]:
        """``(F, d)`` at the total approach ``total``."""
        from .compliant import approach_of

        if self.state == _OPEN:
            return 0.0, 0.0
        K, p = self.law.branch(self.d_max if self.state == _UNLOADING else None)
        d = approach_of(total, self.residual * K, p)
        return K * d ** p, d

    def absorbed(self, total: float) -> float:
        """Energy the contact holds or has lost, J: stored + residual spring + the loss of an unloading contact."""
        if self.state == _OPEN:
            return 0.0
        F, d = self.force_of(total)
        if self.state == _LOADING:          # Hertz's work, its loss not yet split off
            return 0.4 * self.law.stiffness * d ** 2.5 + 0.5 * self.residual * F * F
        return self.law.stored(d, self.d_max) + self.law.dissipated(self.d_max) + 0.5 * self.residual * F * F


class _System:
    """The right-hand side, the events and the energies of one run."""

    def __init__(self, p: ImpactParams, horn: ModalHorn, horn_residual: float, law_h: HertzLaw, law_t: HertzLaw):
        self.p, self.h = p, horn
        self.n = horn.n_modes
        self.W = 2 * math.pi * p.freq
        self.fc, self.fs = horn.forcing()
        r = horn.residual_phasor()
        self.rc, self.rs = r.real, -r.imag              # r(t) = rc cos Wt + rs sin Wt
        self.c2, self.w2 = 2.0 * horn.zeta * horn.omega, horn.omega ** 2
        self.horn_c = _Contact(law_h, horn_residual)
        self.tool_c = _Contact(law_t)
        self.a = p.a_free

    def split(self, y):
        n = self.n
        return y[0], y[1], y[2], y[3], y[4:4 + n], y[4 + n:4 + 2 * n]

    def tip(self, t, q, qd):
        c, s = math.cos(self.W * t), math.sin(self.W * t)
        u = float(self.h.tip @ q) + self.rc * c + self.rs * s
        ud = float(self.h.tip @ qd) + self.W * (self.rs * c - self.rc * s)
        return u, ud

    def approaches(self, t, y):
        """``(D_h, D_h', D_t, D_t')``: total approaches at horn and tool and their rates."""
        w, wd, x, xd, q, qd = self.split(y)
        u, ud = self.tip(t, q, qd)
        return u - w, ud - wd, w - (self.p.gap + x), wd - xd

    def rhs(self, t, y):
        p, n = self.p, self.n
        w, wd, x, xd, q, qd = self.split(y)
        Dh, _, Dt, _ = self.approaches(t, y)
        Fh, _ = self.horn_c.force_of(Dh)
        Ft, _ = self.tool_c.force_of(Dt)
        c, s = math.cos(self.W * t), math.sin(self.W * t)
        f = self.fc * c + self.fs * s
        m = self.h.modal_mass
        qdd = (f - self.h.tip * Fh) / m - self.c2 * qd - self.w2 * q
        rd = self.W * (self.rs * c - self.rc * s)
        out = np.empty_like(y)
        out[0], out[1] = wd, self.a + (Fh - Ft) / p.m_free
        out[2], out[3] = xd, (Ft - p.c * xd - p.k0 * x) / p.m_tool
        out[4:4 + n], out[4 + n:4 + 2 * n] = qd, qdd
        # ledger: drive work on the modes and through the residual (the tip's driven part r pushes
        # the free mass by F_h), modal damping, tool damping
        out[4 + 2 * n] = float(f @ qd) + Fh * rd
        out[5 + 2 * n] = float(np.sum(m * self.c2 * qd * qd))
        out[6 + 2 * n] = p.c * xd * xd
        return out

    def energy(self, t, y) -> float:
        """Bodies' mechanical energy + the contacts' absorbed energy - the constant force's potential, J."""
        p = self.p
        w, wd, x, xd, q, qd = self.split(y)
        Dh, _, Dt, _ = self.approaches(t, y)
        m = self.h.modal_mass
        return (0.5 * p.m_free * wd * wd + 0.5 * p.m_tool * xd * xd + 0.5 * p.k0 * x * x
                + 0.5 * float(np.sum(m * qd * qd + m * self.w2 * q * q))
                + self.horn_c.absorbed(Dh) + self.tool_c.absorbed(Dt))

    def events(self):
        """Terminal events of the current phase, each ``(function, contact, kind)``."""
        out = []
        for k, con in ((0, self.horn_c), (2, self.tool_c)):
            if con.state == _OPEN:
                out.append((lambda t, y, k=k: self.approaches(t, y)[k], con, "touch", 1))
            elif con.state == _LOADING:
                out.append((lambda t, y, k=k: self.approaches(t, y)[k + 1], con, "peak", -1))
                # a touch that starts receding (re-touch right after a separation) leaves elastically
                out.append((lambda t, y, k=k: self.approaches(t, y)[k], con, "separate", -1))
            else:
                out.append((lambda t, y, k=k, con=con: self.approaches(t, y)[k] - con.total_max, con, "reload", 1))
                out.append((lambda t, y, k=k: self.approaches(t, y)[k], con, "separate", -1))
        return out


class _Flight:
    """Closed-form motion while both contacts are open: free fall of the free mass, the tool's and
    every mode's damped oscillation (``A e^{mu1 s} + B e^{mu2 s}``, the two roots of each
    oscillator; a critically damped one is nudged by 1e-9 in zeta), the modes' steady drive
    response, and the ledger's drive work and modal damping in closed form
    (:func:`impact.horn.segment_integrals`); the tool's damping takes what its energy loses."""

    def __init__(self, sys_: "_System"):
        self.sys = sys_
        h, p = sys_.h, sys_.p
        self.qs = h.steady_modal(p.freq)
        self.mu_q = self._roots(h.omega, h.zeta)
        wn = math.sqrt(p.k0 / p.m_tool)
        self.mu_x = self._roots(np.array([wn]), np.array([p.c / (2.0 * math.sqrt(p.k0 * p.m_tool))]))
        f_max = max(float(np.max(h.omega)), wn, sys_.W) / (2 * math.pi)
        self.step = 1.0 / (12.0 * f_max)

    @staticmethod
    def _roots(omega, zeta):
        z = np.where(np.abs(zeta - 1.0) < 1e-9, zeta + 1e-9, zeta).astype(complex)
        root = omega * np.sqrt(z * z - 1.0)
        return -z * omega + root, -z * omega - root

    @staticmethod
    def _free(mu, h0, hd0, s):
        """Displacement and velocity ``(k, n)`` of oscillators started at ``h0, hd0`` after times ``s (k,)``."""
        m1, m2 = mu
        A = (hd0 - m2 * h0) / (m1 - m2)
        B = (m1 * h0 - hd0) / (m1 - m2)
        e1, e2 = np.exp(np.outer(s, m1)), np.exp(np.outer(s, m2))
        return (A * e1 + B * e2).real, (A * m1 * e1 + B * m2 * e2).real

    def states(self, t0, y, ts):
        """``(w, wd, x, xd, q, qd)`` at the absolute times ``ts`` of a flight starting at ``(t0, y)``."""
        sys_ = self.sys
        W, n = sys_.W, sys_.n
        w, wd, x, xd, q, qd = sys_.split(y)
        s = np.asarray(ts, float) - t0
        e0 = np.exp(1j * W * t0)
        hq, hqd = self._free(self.mu_q, q - (self.qs * e0).real, qd - (1j * W * self.qs * e0).real, s)
        et = np.exp(1j * W * np.asarray(ts, float))[:, None]
        qq = (self.qs[None, :] * et).real + hq
        qqd = (1j * W * self.qs[None, :] * et).real + hqd
        xx, xxd = self._free(self.mu_x, np.array([x]), np.array([xd]), s)
        return w + wd * s + 0.5 * sys_.a * s * s, wd + sys_.a * s, xx[:, 0], xxd[:, 0], qq, qqd

    def gaps(self, t0, y, ts):
        """Total approaches ``(D_h, D_t)`` at ``ts``."""
        sys_ = self.sys
        w, _, x, _, q, _ = self.states(t0, y, ts)
        ts = np.asarray(ts, float)
        r = sys_.rc * np.cos(sys_.W * ts) + sys_.rs * np.sin(sys_.W * ts)
        return q @ sys_.h.tip + r - w, w - (sys_.p.gap + x)

    def fly(self, t0, y, t_end):
        """Advance to the first touch (or ``t_end``): ``(t, y, which)`` with ``which`` 0 (horn),
        2 (tool) or None."""
        from scipy.optimize import brentq

        t_a, hit = t0, None
        while hit is None and t_a < t_end:
            ts = np.minimum(t_a + self.step * np.arange(1, 257), t_end)
            Dh, Dt = self.gaps(t0, y, ts)
            inside = np.flatnonzero((Dh > 0.0) | (Dt > 0.0))
            if inside.size:
                i = int(inside[0])
                k = 0 if Dh[i] > 0.0 else 2
                lo = t_a if i == 0 else float(ts[i - 1])
                fn = (lambda t: self.gaps(t0, y, [t])[k // 2][0])
                hit = (self._touch(fn, lo, float(ts[i])), k)
            t_a = float(ts[-1])
        t1 = hit[0] if hit else t_end
        return t1, self._advance(t0, y, t1), (hit[1] if hit else None)

    @staticmethod
    def _touch(fn, lo: float, hi: float) -> float:
        """The first zero of the approach ``fn`` in ``[lo, hi]`` (``fn(hi) > 0``). Only at a flight's
        start can ``fn(lo)`` be above zero (a separation leaves the approach at zero to round-off):
        the bodies then part if the approach dips below zero in between (the touch is after the
        dip), else they touch again at ``lo``."""
        from scipy.optimize import brentq, minimize_scalar

        if fn(lo) > 0.0:
            dip = minimize_scalar(fn, bounds=(lo, hi), method="bounded", options={"xatol": 1e-15})
            if not dip.fun < 0.0:
                return lo
            lo = float(dip.x)
        return brentq(fn, lo, hi, xtol=1e-15, rtol=8.9e-16)

    def _advance(self, t0, y, t1):
        from .horn import segment_integrals

        sys_, n = self.sys, self.sys.n
        w, wd, x, xd, q, qd = (a[0] for a in self.states(t0, y, [t1]))
        seg = segment_integrals(sys_.h, sys_.p.freq, np.array([t0]), y[None, 4:4 + n], y[None, 4 + n:4 + 2 * n],
                                np.zeros(1), np.array([t1 - t0]))
        p = sys_.p
        e_tool = 0.5 * p.m_tool * y[3] ** 2 + 0.5 * p.k0 * y[2] ** 2 - 0.5 * p.m_tool * xd ** 2 - 0.5 * p.k0 * x ** 2
        out = np.concatenate(([w, wd, x, xd], q, qd, y[4 + 2 * n:]))
        out[4 + 2 * n] += float(seg["drive_j"][0])
        out[5 + 2 * n] += float(seg["damping_j"][0])
        out[6 + 2 * n] += e_tool
        return out


def _switch(sys_: _System, con: _Contact, kind: str, t: float, y, k: int) -> None:
    """Apply one event to its contact."""
    D, Dd = sys_.approaches(t, y)[k], sys_.approaches(t, y)[k + 1]
    if kind == "touch":
        con.state, con.t_start, con.v_in, con.d_max = _LOADING, t, Dd, 0.0
        con.peak = 0.0
    elif kind == "peak":
        con.total_max = D
        con.d_max = con.force_of(D)[1]
        con.peak = max(con.peak, con.force_of(D)[0])
        con.state = _UNLOADING
    elif kind == "reload":
        con.state = _LOADING
    else:
        con.log.append((con.t_start, t, con.v_in, -Dd, con.d_max, con.peak, float(y[1]), float(y[3])))
        con.state = _OPEN


def simulate_compliant(params: ImpactParams, horn: ModalHorn, *, horn_law: HertzLaw, tool_law: HertzLaw,
                       horn_residual: float = 0.0, rtol: float | None = None, max_phases: int = 100_000,
                       flights: str = "closed-form", engine: str = "kernel") -> CompliantRun:
    """Run the compliant model (module docstring) from t = 0 to ``params.t_end``.

    Parameters
    ----------
    params : ImpactParams
        Free mass, tool, gap, acceleration, start speed ``v0`` and ``t_end`` (``A0``, ``e1``, ``e2``,
        ``horn_law`` are not used: the horn is ``horn``, the restitutions the laws').
    horn : ModalHorn
        The modes kept and the drive (drive frequency ``params.freq``); the free mass starts on its
        tip at ``u(0)`` leaving at ``v0``.
    horn_law, tool_law : HertzLaw
        Contact laws at the horn tip and at the tool face.
    horn_residual : float
        Static compliance of the horn's modes left out, at the tip, m/N.
    rtol : float, optional
        Relative tolerance of the contacts' integration (default 1e-10 in the kernel, 1e-11 in the
        Python engine).
    max_phases : int
        Safety cap on the number of phases.
    flights : {"closed-form", "integrated"}
        Between contacts: the closed-form motion, the touch found on a grid of 1/12 of the
        shortest period and refined by Brent's method (fast), or the same integration as the
        contacts with its event detection (the reference). Python engine only.
    engine : {"kernel", "python"}
        The compiled engine (:func:`impact.compliant_engine.run_compliant`: closed-form flights
        with the guaranteed touch search, DOP853 contacts) or this module's Python
        reference (DOP853 contacts).

    Returns
    -------
    CompliantRun
    """
    from scipy.integrate import solve_ivp

    check_choice("engine", engine, ("kernel", "python"))
    if engine == "kernel":
        from .compliant_engine import run_compliant

        if flights != "closed-form":
            raise ParameterError("flights", flights, "must be 'closed-form' with engine='kernel'")
        return run_compliant(params, horn, horn_law=horn_law, tool_law=tool_law, horn_residual=horn_residual,
                             rtol=1e-10 if rtol is None else rtol)
    rtol = 1e-11 if rtol is None else rtol
    if not isinstance(horn, ModalHorn):
        raise ParameterError("horn", type(horn).__name__, "must be an impact.horn.ModalHorn")
    check_nonnegative("horn_residual", horn_residual, "m/N")
    check_choice("flights", flights, ("closed-form", "integrated"))
    sys_ = _System(params, horn, float(horn_residual), horn_law, tool_law)
    n = sys_.n
    q0, qd0 = horn.initial_state(params.freq)
    u0, ud0 = sys_.tip(0.0, q0, qd0)
    y = np.concatenate(([u0, ud0 + params.v0, 0.0, 0.0], q0, qd0, [0.0, 0.0, 0.0]))
    e_start = sys_.energy(0.0, y)
    t, phases = 0.0, 0
    # absolute tolerances: rtol of mm positions, m/s speeds, mJ energies (the modes through the tip)
    s_tip = np.maximum(np.abs(horn.tip), 1e-12 * np.abs(horn.tip).max())
    atol = rtol * np.concatenate(([1e-3, 1.0, 1e-3, 1.0], 1e-5 / s_tip, 1.0 / s_tip, [1e-3, 1e-3, 1e-3]))
    Dh, Dhd, _, _ = sys_.approaches(0.0, y)
    if Dhd > 0.0:                 # the tip overtakes the free mass it starts on: a contact from t = 0
        sys_.horn_c.state, sys_.horn_c.v_in = _LOADING, Dhd
    flight = _Flight(sys_) if flights == "closed-form" else None
    while t < params.t_end:
        phases += 1
        if phases > max_phases:
            raise ParameterError("max_phases", max_phases, f"is too small: the run stopped at t = {t:g} s")
        if flight is not None and sys_.horn_c.state == _OPEN and sys_.tool_c.state == _OPEN:
            t, y, k = flight.fly(t, y, params.t_end)
            if k is not None:
                _switch(sys_, sys_.horn_c if k == 0 else sys_.tool_c, "touch", t, y, k)
            continue
        evs = sys_.events()
        funcs = []
        for fn, _, _, direction in evs:
            fn.terminal, fn.direction = True, direction
            funcs.append(fn)
        sol = solve_ivp(sys_.rhs, (t, params.t_end), y, method="DOP853", rtol=rtol, atol=atol, events=funcs)
        if sol.status < 0:
            raise ParameterError("rtol", rtol, f"integration failed at t = {sol.t[-1]:g} s: {sol.message}")
        y, t = sol.y[:, -1].copy(), float(sol.t[-1])
        hit = [i for i, te in enumerate(sol.t_events) if te.size]
        if not hit:
            break
        i = hit[0]
        _, con, kind, _ = evs[i]
        _switch(sys_, con, kind, t, y, 0 if con is sys_.horn_c else 2)
    return _result(sys_, params, y, t, e_start, float(u0))


def _result(sys_: _System, params: ImpactParams, y, t: float, e_start: float, w_start: float) -> CompliantRun:
    n = sys_.n
    contacts, loss = [], 0.0
    for name, con in (("horn", sys_.horn_c), ("tool", sys_.tool_c)):
        for t0, t1, v_in, v_out, d_max, peak, w_after, x_after in con.log:
            loss += con.law.dissipated(d_max)
            contacts.append(Contact(name, t0, t1, v_in, v_out, d_max, peak, con.law.dissipated(d_max), w_after,
                                    x_after))
    contacts.sort(key=lambda c: c.t_start)
    ledger = {"drive_j": float(y[4 + 2 * n]), "gravity_j": params.m_free * sys_.a * float(y[0] - w_start),
              "modal_damping_j": float(y[5 + 2 * n]), "tool_damping_j": float(y[6 + 2 * n]),
              "contact_loss_j": loss, "stored_change_j": sys_.energy(t, y) - e_start}
    ledger["residual_j"] = (ledger["drive_j"] + ledger["gravity_j"] - ledger["modal_damping_j"]
                            - ledger["tool_damping_j"] - ledger["contact_loss_j"] - ledger["stored_change_j"])
    return CompliantRun(contacts=contacts, t_end=t, state=y[:4 + 2 * n].copy(), ledger=ledger)
