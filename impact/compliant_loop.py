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

The whole run is integrated (``scipy.integrate.solve_ivp``, DOP853, error-controlled) in phases
between events: a contact starts (its approach crosses zero upward), reaches its largest approach
(loading -> unloading), reloads past it, or separates (the approach returns to the permanent set).
The energy ledger is integrated with the motion (drive work on the modes, the drive residual's
work through the contact, modal and tool damping) and closed against the bodies' energies and the
contacts' absorbed energy (:meth:`HertzLaw.stored` plus the loss of a contact that has unloaded).

It is the readable, slow reference (about 1e4 steps per ms with modes to 70 kHz); it has no
sticking rule: a free mass resting on a body is a long contact phase.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rpud_common import ParameterError, check_nonnegative

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
        lost = self.law.dissipated(self.d_max) if self.state == _UNLOADING else 0.0
        return self.law.stored(d, self.d_max) + lost + 0.5 * self.residual * F * F


@dataclass(frozen=True)
class Contact:
    """One finished contact: ``body`` ("horn" or "tool"), start and end (s), approach and separation
    speeds (relative, m/s, both > 0), largest Hertz approach (m), peak force (N), energy lost (J),
    free-mass and tool velocities at separation (m/s)."""

    body: str
    t_start: float
    t_end: float
    v_in: float
    v_out: float
    d_max: float
    peak_force: float
    loss: float
    free_mass_after: float
    tool_after: float


@dataclass
class CompliantRun:
    """One run of :func:`simulate_compliant`.

    Attributes
    ----------
    contacts : list of Contact
        The finished contacts in order of their start.
    t_end : float
        End of the run, s.
    state : ndarray
        ``[w, w', x, x', q..., q'...]`` at ``t_end``.
    ledger : dict
        Energies over the run, J: ``drive_j`` (modes + residual through the contact),
        ``gravity_j`` (the constant force on the free mass), ``modal_damping_j``,
        ``tool_damping_j``, ``contact_loss_j`` (finished contacts), ``stored_change_j`` (bodies +
        open contacts' absorbed energy), ``residual_j`` (the balance; 0 up to the integration error).
    """

    contacts: list
    t_end: float
    state: np.ndarray
    ledger: dict

    def tool_contacts(self) -> list:
        return [c for c in self.contacts if c.body == "tool"]


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
            else:
                out.append((lambda t, y, k=k, con=con: self.approaches(t, y)[k] - con.total_max, con, "reload", 1))
                out.append((lambda t, y, k=k: self.approaches(t, y)[k], con, "separate", -1))
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
                       horn_residual: float = 0.0, rtol: float = 1e-10, max_phases: int = 100_000) -> CompliantRun:
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
    rtol : float
        Relative tolerance of the integration.
    max_phases : int
        Safety cap on the number of phases.

    Returns
    -------
    CompliantRun
    """
    from scipy.integrate import solve_ivp

    if not isinstance(horn, ModalHorn):
        raise ParameterError("horn", type(horn).__name__, "must be an impact.horn.ModalHorn")
    check_nonnegative("horn_residual", horn_residual, "m/N")
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
    while t < params.t_end:
        phases += 1
        if phases > max_phases:
            raise ParameterError("max_phases", max_phases, f"is too small: the run stopped at t = {t:g} s")
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
