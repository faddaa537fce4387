"""Compiled event loop of the compliant impact model (numba): the engine of :mod:`impact.compliant_loop`.

The model is :mod:`impact.compliant_loop`'s (read its docstring): free mass, modal horn under the
harmonic drive with the static residual ``g`` of the modes left out, damped tool, and a Hertz
contact with the restitution unloading of :class:`impact.hertz.HertzLaw` at the horn tip and at the
tool face. One loop, :func:`_core`, alternates two phases built from the shared blocks of
:mod:`impact.kernel_blocks`:

* **flight** (both contacts open): the closed-form motion of the coupled model's segments
  (:func:`impact.kernel_blocks.tip`, the tool's oscillator record), the next touch found by the
  guaranteed grid search of the Newton engines (:func:`impact.kernel_blocks.earliest`: no touch
  is missed, however grazing), the energy integrals in closed form
  (:func:`impact.kernel_energy.window_integrals`);
* **contact** (a contact is closed): free mass, tool and modes integrated together by the
  error-controlled Dormand-Prince 5(4) step of :func:`impact.kernel_blocks.dp_step`, the contact
  force the root of ``d + g K d^p = D`` (:func:`impact.compliant.approach_of`, compiled). The
  branch events of each contact (touch ``D = 0`` rising, peak ``D' = 0``, reload ``D = D_max``,
  separation ``D = 0`` falling) are located on the step length by the Illinois method, each
  trial one integration step from the step's start, and the law switches on the far side of the
  event. The phase ends when both contacts are open again.

Contacts that do not separate (a free mass pressed onto the tool or the horn) are integrated as
the contact they are: the law is rate-independent and continuous, so there is no Zeno chattering
to end and no sticking rule is needed; such a phase costs integration steps at the contact
frequency until the bodies part.

Energy: the drive's work (on the modes, and through the residual's driven displacement on the
contact), the modal and tool damping and the contacts' losses are accumulated from t = 0
(closed form over flights, integrated with the motion in contacts); at the window's start and end
the bodies' mechanical energy plus each closed contact's absorbed energy is taken, and the
balance (:data:`K_LEDGER`) is returned with the window statistics.

Window statistics (one row per member, :data:`N_KSTATS` columns): the Newton engines' ``S_*`` and
``C_*`` columns with a contact in place of an impact (counted at its separation; the tool's
kinetic energy after it and its gain over the contact; the horn's work on the free mass through
the contact; ``S_T_ON_*`` the time the contacts are closed), then :data:`K_TOOL_DAMP`,
:data:`K_LOSS`, :data:`K_STORED` (J over the window) and :data:`K_LEDGER` (J, the balance).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from . import kernel_cache  # noqa: F401  (drops stale caches first)
from . import compliant
from .columns import (C_DAMP, C_DRIVE, C_ELEC, C_FUND_IM, C_FUND_RE, N_CSTATS, S_HORN_WORK, S_KE_AFTER, S_KE_GAIN,
                      S_N_EVENTS, S_N_HORN, S_N_TOOL, S_STATUS, S_T_ON_HORN, S_T_ON_TOOL, STATUS_CONTACT,
                      STATUS_MAX_EVENTS, STATUS_OK)
from .horn import (H_A, H_B, H_FC, H_FS, H_GIM, H_GRE, H_MASS, H_OMEGA, H_TIP, H_ZETA, X_QBI, X_QBR, X_RC, X_RS,
                   X_STEADY, X_UC, X_US,
                   X_V0, X_W)
from .kernel import P_C, P_G, P_GAP, P_K0, P_M_FREE, P_M_TOOL, P_SPRING_FORCE, P_V0
from .kernel_blocks import (C_A, C_L0, C_N, C_T0, C_UC, C_US, C_W, C_W0, C_WD0, DP_C, FN_HORN, O_B0, O_B2, O_N, PL_ROWS,
                            dp_combine, dp_stage, earliest, grow2, horn_records, modal_at, osc_pv, plan_flight,
                            tool_osc)
from .kernel_energy import window_integrals

__all__ = ["N_KSTATS", "K_TOOL_DAMP", "K_LOSS", "K_STORED", "K_LEDGER", "LAW_N", "pack_laws", "run_contacts",
           "ensemble_rows", "LOG_N"]

approach_of = njit(cache=True)(compliant.approach_of)

#: extra window columns after ``N_CSTATS``: tool damping, contact losses (finished contacts),
#: change of the stored energy (bodies + closed contacts), the balance; J
K_TOOL_DAMP, K_LOSS, K_STORED, K_LEDGER = range(N_CSTATS, N_CSTATS + 4)
N_KSTATS = N_CSTATS + 4
#: packed laws: per contact (horn, tool) Hertz stiffness k (N/m^1.5), unloading exponent p,
#: restitution e; then the horn's residual compliance g (m/N) and the integration's rtol
L_K, L_P, L_E = 0, 1, 2
L_TOOL = 3
L_G, L_RTOL = 6, 7
LAW_N = 8
#: contact states and the columns of a contact's record (``cs`` row): state, branch K and p,
#: largest Hertz approach, largest total approach, start, approach speed, peak force, tool speed
#: at touch, horn work at touch
OPEN, LOADING, UNLOADING = 0, 1, 2
CS_STATE, CS_K, CS_P, CS_DMAX, CS_TMAX, CS_T0, CS_VIN, CS_PEAK, CS_XD0, CS_WORK0 = range(10)
CS_N = 10
#: contact log (``run_contacts``): body (0 horn, 1 tool), start, end, approach and separation
#: speeds, largest Hertz approach, peak force, loss, free-mass and tool speeds at separation
LOG_N = 10
#: integrals carried in a contact phase after the state: drive work, modal damping, tool
#: damping, horn work, fundamental re / im, electrical energy
N_INT = 7
#: trigger kinds of a contact's branch events
EV_TOUCH, EV_PEAK, EV_RELOAD, EV_SEPARATE = 0, 1, 2, 3
_MAX_STEPS = 20_000_000


def pack_laws(horn_law, tool_law, horn_residual: float, rtol: float) -> np.ndarray:
    """The two :class:`impact.hertz.HertzLaw` s, the residual and the rtol as the kernel's ``LAW_N`` vector."""
    lw = np.zeros(LAW_N)
    for j, law in ((0, horn_law), (L_TOOL, tool_law)):
        lw[j + L_K], lw[j + L_P], lw[j + L_E] = law.stiffness, law.exponent, law.restitution
    lw[L_G], lw[L_RTOL] = horn_residual, rtol
    return lw


# ----------------------------------------------------------------------------- the contact law


@njit(cache=True)
def contact_force(D, state, K, p, g):
    """``(F, d)``: force (N) and Hertz approach (m) of a contact at total approach D (m)."""
    if state == OPEN or D <= 0.0:
        return 0.0, 0.0
    d = approach_of(D, g * K, p)
    return K * d ** p, d


@njit(cache=True)
def absorbed(D, cs, k, e, g):
    """Energy a closed contact holds or has lost, J: on loading the Hertz work ``0.4 k d^2.5``; on
    unloading what the curve returns plus the closed-form loss of the contact; and the residual
    spring ``g F^2 / 2``."""
    state = cs[CS_STATE]
    if state == OPEN:
        return 0.0
    F, d = contact_force(D, state, cs[CS_K], cs[CS_P], g)
    if state == LOADING:
        return 0.4 * k * d ** 2.5 + 0.5 * g * F * F
    return cs[CS_K] * d ** (cs[CS_P] + 1.0) / (cs[CS_P] + 1.0) + loss(k, e, cs[CS_DMAX]) + 0.5 * g * F * F


@njit(cache=True)
def loss(k, e, d_max):
    """Energy lost in a contact whose largest Hertz approach was d_max (J, :meth:`HertzLaw.dissipated`)."""
    return (1.0 - e * e) * 0.4 * k * max(d_max, 0.0) ** 2.5


# ----------------------------------------------------------------------------- the contact phase


@njit(cache=True)
def _tip_modal(t, y, n, tab, xs):
    """Tip of the modes and the driven residual (the contact's far end) and its velocity, m, m/s."""
    W = xs[X_W]
    c, s = math.cos(W * t), math.sin(W * t)
    u = xs[X_RC] * c + xs[X_RS] * s
    ud = W * (-xs[X_RC] * s + xs[X_RS] * c)
    for i in range(n):
        u += tab[i, H_TIP] * y[4 + i]
        ud += tab[i, H_TIP] * y[4 + n + i]
    return u, ud


@njit(cache=True)
def approaches(t, y, n, tab, xs, L0):
    """``(D_h, D_h', D_t, D_t')``: total approaches at horn and tool (m) and their rates (m/s)."""
    u, ud = _tip_modal(t, y, n, tab, xs)
    return u - y[0], ud - y[1], y[0] - (L0 + y[2]), y[1] - y[3]


@njit(cache=True)
def contact_rhs(t, y, out, n, tab, xs, pv, lw, cs):
    """Right-hand side of a contact phase: ``y = [w, w', x, x', q, q', integrals (N_INT)]``."""
    m_free, m_tool, k0, c = pv[P_M_FREE], pv[P_M_TOOL], pv[P_K0], pv[P_C]
    a = pv[P_G] - pv[P_SPRING_FORCE] / m_free
    g = lw[L_G]
    Dh, _, Dt, _ = approaches(t, y, n, tab, xs, pv[P_GAP])
    Fh = contact_force(Dh, cs[0, CS_STATE], cs[0, CS_K], cs[0, CS_P], g)[0]
    Ft = contact_force(Dt, cs[1, CS_STATE], cs[1, CS_K], cs[1, CS_P], 0.0)[0]
    W = xs[X_W]
    co, si = math.cos(W * t), math.sin(W * t)
    rd = W * (-xs[X_RC] * si + xs[X_RS] * co)
    out[0], out[1] = y[1], a + (Fh - Ft) / m_free
    out[2], out[3] = y[3], (Ft - c * y[3] - k0 * y[2]) / m_tool
    V = xs[X_V0] * si
    Vd = xs[X_V0] * W * co
    cur = xs[X_QBR] * Vd - xs[X_QBI] * W * V
    drive = damp = um = umd = 0.0
    for i in range(n):
        om, ze, m, s = tab[i, H_OMEGA], tab[i, H_ZETA], tab[i, H_MASS], tab[i, H_TIP]
        qv = y[4 + n + i]
        f = tab[i, H_FC] * co + tab[i, H_FS] * si
        acc = (f - s * Fh) / m - 2.0 * ze * om * qv - om * om * y[4 + i]
        out[4 + i], out[4 + n + i] = qv, acc
        drive += f * qv
        damp += 2.0 * ze * om * m * qv * qv
        cur += tab[i, H_GRE] * qv + tab[i, H_GIM] / W * acc
        um += s * y[4 + i]
        umd += s * qv
    j = 4 + 2 * n
    u = um + xs[X_RC] * co + xs[X_RS] * si - g * Fh       # the tip recedes by g F_h
    out[j], out[j + 1], out[j + 2], out[j + 3] = drive + Fh * rd, damp, c * y[3] * y[3], Fh * (umd + rd)
    out[j + 4], out[j + 5], out[j + 6] = u * co, -u * si, V * cur


@njit(cache=True)
def _step(t, y, h, n, tab, xs, pv, lw, cs, st, y5, y4, tmp):
    """One Dormand-Prince step of length h from (t, y) (the integrals restart from zero)."""
    contact_rhs(t, y, st[0], n, tab, xs, pv, lw, cs)
    for k in range(1, 7):
        dp_stage(k, y, h, st, tmp)
        contact_rhs(t + DP_C[k] * h, tmp, st[k], n, tab, xs, pv, lw, cs)
    dp_combine(y, h, st, y5, y4)


@njit(cache=True)
def _error(y, y5, y4, atol, rtol):
    """Largest error estimate of the state over its tolerance ``atol + rtol |y|`` (the integrals
    follow the state and are not controlled apart)."""
    err = 0.0
    for j in range(atol.size):
        err = max(err, abs(y5[j] - y4[j]) / (atol[j] + rtol * max(abs(y[j]), abs(y5[j]))))
    return err


@njit(cache=True)
def _triggers(state):
    """The two branch events a contact in ``state`` waits for (-1: none)."""
    if state == OPEN:
        return EV_TOUCH, -1
    if state == LOADING:
        return EV_PEAK, EV_SEPARATE
    return EV_RELOAD, EV_SEPARATE


@njit(cache=True)
def _phi(kind, D, Dd, tmax):
    """The event function of ``kind``, positive past the event (D, D' the contact's total approach
    and its rate, ``tmax`` the largest total approach of the contact)."""
    if kind == EV_TOUCH:
        return D
    if kind == EV_PEAK:
        return -Dd
    if kind == EV_RELOAD:
        return D - tmax
    return -D


@njit(cache=True)
def _phi_at(t, y, n, tab, xs, L0, cs, j, kind):
    Dh, Dhd, Dt, Dtd = approaches(t, y, n, tab, xs, L0)
    if j == 0:
        return _phi(kind, Dh, Dhd, cs[0, CS_TMAX])
    return _phi(kind, Dt, Dtd, cs[1, CS_TMAX])


@njit(cache=True)
def _locate(t, y, hh, f_lo, f_hi, j, kind, n, tab, xs, pv, lw, cs, st, y5, y4, tmp):
    """Step length in (0, hh] just past the event ``kind`` of contact j (its function rises
    through zero): the Illinois method, every trial one step from (t, y). Returns the far end of
    the final bracket (the event function positive there)."""
    lo, hi, side = 0.0, hh, 0
    for _ in range(100):
        if hi - lo <= 4e-16 * (abs(t) + hi):
            break
        x = hi - f_hi * (hi - lo) / (f_hi - f_lo)
        if not (lo < x < hi):
            x = 0.5 * (lo + hi)
        _step(t, y, x, n, tab, xs, pv, lw, cs, st, y5, y4, tmp)
        fx = _phi_at(t + x, y5, n, tab, xs, pv[P_GAP], cs, j, kind)
        if fx > 0.0:
            hi, f_hi = x, fx
            if side == 1:
                f_lo *= 0.5
            side = 1
        else:
            lo, f_lo = x, fx
            if side == -1:
                f_hi *= 0.5
            side = -1
    return hi


@njit(cache=True)
def _earliest_event(t, y, hh, n, tab, xs, pv, lw, cs, st, y5, y4, tmp):
    """The earliest branch event in the step (t, t + hh] whose end is in y5: ``(found, h, j,
    kind)``, h the step length to take (the event just behind it)."""
    L0 = pv[P_GAP]
    best, bj, bk = hh, -1, -1
    f_end = np.empty(4)
    for j in range(2):
        k1, k2 = _triggers(cs[j, CS_STATE])
        for i, kind in enumerate((k1, k2)):
            f_end[2 * j + i] = _phi_at(t + hh, y5, n, tab, xs, L0, cs, j, kind) if kind >= 0 else -1.0
    for j in range(2):
        k1, k2 = _triggers(cs[j, CS_STATE])
        for i, kind in enumerate((k1, k2)):
            if kind < 0 or not f_end[2 * j + i] > 0.0:
                continue
            f0 = _phi_at(t, y, n, tab, xs, L0, cs, j, kind)
            if f0 > 0.0:
                continue                      # already past it at the step's start: no crossing
            h = _locate(t, y, hh, f0, f_end[2 * j + i], j, kind, n, tab, xs, pv, lw, cs, st, y5, y4, tmp)
            if bj < 0 or h < best:
                best, bj, bk = h, j, kind
    return bj >= 0, best, bj, bk


# ----------------------------------------------------------------------------- branch switches


@njit(cache=True)
def touch(cs, j, lw, t, Dd, xd, horn_work):
    """Contact j closes at t: Hertz loading from its approach speed Dd (m/s)."""
    cs[j, CS_STATE], cs[j, CS_T0], cs[j, CS_VIN] = LOADING, t, Dd
    cs[j, CS_K], cs[j, CS_P] = lw[L_TOOL * j + L_K], 1.5
    cs[j, CS_DMAX] = cs[j, CS_TMAX] = cs[j, CS_PEAK] = 0.0
    cs[j, CS_XD0], cs[j, CS_WORK0] = xd, horn_work


@njit(cache=True)
def _law_branch(cs, j, lw, kind, D):
    """Apply a peak (unloading from the largest approach) or a reload (Hertz again) to contact j."""
    k, p_u = lw[L_TOOL * j + L_K], lw[L_TOOL * j + L_P]
    if kind == EV_PEAK:
        d_m = approach_of(D, lw[L_G] * k if j == 0 else 0.0, 1.5)
        cs[j, CS_TMAX], cs[j, CS_DMAX] = D, d_m
        cs[j, CS_PEAK] = max(cs[j, CS_PEAK], k * d_m ** 1.5)
        cs[j, CS_STATE], cs[j, CS_K], cs[j, CS_P] = UNLOADING, k * d_m ** (1.5 - p_u), p_u
    else:
        cs[j, CS_STATE], cs[j, CS_K], cs[j, CS_P] = LOADING, k, 1.5


@njit(cache=True)
def _separate(cs, j, lw, t, Dd, y, m_tool, acc, out, t_from, t_end, log, n_log, record):
    """Contact j opens at t: its loss, its window statistics (tool: kinetic energy after and gain)
    and its log row. Returns (log, n_log)."""
    k, e = lw[L_TOOL * j + L_K], lw[L_TOOL * j + L_E]
    lost = loss(k, e, cs[j, CS_DMAX]) if cs[j, CS_STATE] == UNLOADING else 0.0
    acc[K_LOSS] += lost
    t0 = cs[j, CS_T0]
    out[S_T_ON_HORN if j == 0 else S_T_ON_TOOL] += max(0.0, min(t, t_end) - max(t0, t_from))
    if t >= t_from and t <= t_end:
        if j == 1:
            out[S_N_TOOL] += 1.0
            out[S_KE_AFTER] += 0.5 * m_tool * y[3] * y[3]
            out[S_KE_GAIN] += 0.5 * m_tool * (y[3] * y[3] - cs[j, CS_XD0] * cs[j, CS_XD0])
        else:
            out[S_N_HORN] += 1.0
    if record:
        if n_log == log.shape[0]:
            log = grow2(log, n_log)
        row = log[n_log]
        row[0], row[1], row[2], row[3], row[4] = j, t0, t, cs[j, CS_VIN], -Dd
        row[5], row[6], row[7], row[8], row[9] = cs[j, CS_DMAX], cs[j, CS_PEAK], lost, y[1], y[3]
        n_log += 1
    cs[j, CS_STATE] = OPEN
    return log, n_log


@njit(cache=True)
def energy(t, y, n, tab, xs, pv, lw, cs):
    """Bodies' mechanical energy (the constant force's potential ``-m_w a w`` included) plus the
    closed contacts' absorbed energy (:func:`absorbed`), J."""
    m_free, m_tool, k0 = pv[P_M_FREE], pv[P_M_TOOL], pv[P_K0]
    a = pv[P_G] - pv[P_SPRING_FORCE] / m_free
    E = 0.5 * m_free * y[1] * y[1] - m_free * a * y[0] + 0.5 * m_tool * y[3] * y[3] + 0.5 * k0 * y[2] * y[2]
    for i in range(n):
        m, om = tab[i, H_MASS], tab[i, H_OMEGA]
        E += 0.5 * m * (y[4 + n + i] * y[4 + n + i] + om * om * y[4 + i] * y[4 + i])
    Dh, _, Dt, _ = approaches(t, y, n, tab, xs, pv[P_GAP])
    E += absorbed(Dh, cs[0], lw[L_K], lw[L_E], lw[L_G])
    E += absorbed(Dt, cs[1], lw[L_TOOL + L_K], lw[L_TOOL + L_E], 0.0)
    return E


@njit(cache=True)
def _accept(y, y5, n, acc):
    """Take the step: the state moves on, the integrals' increments go into ``acc`` (from t = 0)."""
    j = 4 + 2 * n
    acc[C_DRIVE] += y5[j]
    acc[C_DAMP] += y5[j + 1]
    acc[K_TOOL_DAMP] += y5[j + 2]
    acc[S_HORN_WORK] += y5[j + 3]
    acc[C_FUND_RE] += y5[j + 4]
    acc[C_FUND_IM] += y5[j + 5]
    acc[C_ELEC] += y5[j + 6]
    y[:j] = y5[:j]


# ----------------------------------------------------------------------------- the two phases


@njit(cache=True)
def contact_phase(t, t_stop, y, h, n, tab, xs, pv, lw, cs, atol, wk, acc, out, t_from, t_end, log, n_log, record,
                  n_ev):
    """Integrate while a contact is closed, to the phase's end (both open) or ``t_stop``: error-
    controlled steps, each cut at its earliest branch event. Returns (t, h, log, n_log, n_ev, ok);
    ok False if the phase took more than ``_MAX_STEPS`` steps."""
    st, y5, y4, tmp = wk[:7], wk[7], wk[8], wk[9]
    rtol = lw[L_RTOL]
    steps = 0
    while t < t_stop and (cs[0, CS_STATE] != OPEN or cs[1, CS_STATE] != OPEN):
        steps += 1
        if steps > _MAX_STEPS:
            return t, h, log, n_log, n_ev, False
        hh = min(h, t_stop - t)
        _step(t, y, hh, n, tab, xs, pv, lw, cs, st, y5, y4, tmp)
        err = _error(y, y5, y4, atol, rtol)
        grow = min(5.0, max(0.2, 0.9 * max(err, 1e-30) ** -0.2))
        if err > 1.0 and hh > 1e-18:
            h = hh * grow
            continue
        found, he, j, kind = _earliest_event(t, y, hh, n, tab, xs, pv, lw, cs, st, y5, y4, tmp)
        if found:
            _step(t, y, he, n, tab, xs, pv, lw, cs, st, y5, y4, tmp)
            hh = he
        _accept(y, y5, n, acc)
        t += hh
        if not found:
            h = hh * grow if hh >= h else max(h, hh * grow)
        if found:
            Dh, Dhd, Dt, Dtd = approaches(t, y, n, tab, xs, pv[P_GAP])
            D, Dd = (Dh, Dhd) if j == 0 else (Dt, Dtd)
            if kind == EV_TOUCH:
                touch(cs, j, lw, t, Dd, y[3], acc[S_HORN_WORK])
            elif kind == EV_SEPARATE:
                log, n_log = _separate(cs, j, lw, t, Dd, y, pv[P_M_TOOL], acc, out, t_from, t_end, log, n_log,
                                       record)
                n_ev += 1
            else:
                _law_branch(cs, j, lw, kind, D)
    return t, h, log, n_log, n_ev, True


@njit(cache=True)
def flight(t, t_stop, y, n, tab, xs, pv, fw, acc, cw, lam, G1, G2):
    """Both contacts open: the closed-form motion from t to the first touch or ``t_stop``, found
    by the guaranteed search; the energy integrals in closed form. Returns (t, contact j or -1)."""
    o, ho, plan, stack, cp = fw
    m_free, m_tool, k0, c, L0 = pv[P_M_FREE], pv[P_M_TOOL], pv[P_K0], pv[P_C], pv[P_GAP]
    a = pv[P_G] - pv[P_SPRING_FORCE] / m_free
    W = xs[X_W]
    q, qd = y[4:4 + n], y[4 + n:4 + 2 * n]
    Ua = math.hypot(xs[X_UC], xs[X_US])
    tool_osc(o, False, m_tool, m_free, k0, c, a, y[2], y[3])
    hb0, hb2, _ = horn_records(ho, tab, n, W, t, q, qd)
    Bh = abs(a) + Ua * W * W + hb2
    cp[C_T0], cp[C_W0], cp[C_WD0] = t, y[0], y[1]
    nf = plan_flight(plan, 0, t, y[0], y[1], a, L0, Ua + hb0, o[O_B0], t, t, Bh, o[O_B2] + abs(a), t_stop)
    have, te, name = earliest(plan, nf, t_stop, cp, o, tab, ho, n, stack)
    t1 = te if have else t_stop
    window_integrals(tab, xs, n, t, t1, q, qd, 0.0, math.inf, acc, lam, G1, G2, cw)
    e_tool = 0.5 * m_tool * y[3] * y[3] + 0.5 * k0 * y[2] * y[2]
    s = t1 - t
    y[2], y[3] = osc_pv(o, s)
    acc[K_TOOL_DAMP] += e_tool - 0.5 * m_tool * y[3] * y[3] - 0.5 * k0 * y[2] * y[2]
    modal_at(ho, tab, n, W, t, t1, q, qd)
    y[0], y[1] = y[0] + s * (y[1] + 0.5 * a * s), y[1] + a * s
    if not have:
        return t1, -1
    return t1, 0 if name == FN_HORN else 1


# ----------------------------------------------------------------------------- the event loop


@njit(cache=True)
def _start(pv, lw, tab, xs, n, y, cs):
    """The state at t = 0: the modes steady (or at rest), the free mass on the tip leaving at v0
    (a contact from t = 0 if the tip overtakes it)."""
    steady = xs[X_STEADY] == 1.0
    for i in range(n):
        y[4 + i] = tab[i, H_A] if steady else 0.0
        y[4 + n + i] = xs[X_W] * tab[i, H_B] if steady else 0.0
    u0, ud0 = _tip_modal(0.0, y, n, tab, xs)
    y[0], y[1] = u0, ud0 + pv[P_V0]
    if ud0 - y[1] > 0.0:
        touch(cs, 0, lw, 0.0, ud0 - y[1], 0.0, 0.0)


@njit(cache=True)
def _tolerances(tab, n, rtol):
    """Absolute tolerances of the state: rtol of mm positions and m/s speeds (the modes through
    their tip participation)."""
    smax = 0.0
    for i in range(n):
        smax = max(smax, abs(tab[i, H_TIP]))
    atol = np.empty(4 + 2 * n)
    atol[0], atol[1], atol[2], atol[3] = 1e-3 * rtol, rtol, 1e-3 * rtol, rtol
    for i in range(n):
        s = max(abs(tab[i, H_TIP]), 1e-12 * smax)
        atol[4 + i], atol[4 + n + i] = 1e-5 * rtol / s, rtol / s
    return atol


@njit(cache=True)
def _close(t, y, n, tab, xs, pv, lw, cs, acc, acc0, E_from, out, t_from, t_end, status, n_ev):
    """The window's statistics: integrals from its start, contacts still closed counted to its
    end, the stored energy's change and the balance."""
    for j in range(2):
        if cs[j, CS_STATE] != OPEN:
            out[S_T_ON_HORN if j == 0 else S_T_ON_TOOL] += max(0.0, min(t, t_end) - max(cs[j, CS_T0], t_from))
    for col in (C_DRIVE, C_DAMP, C_FUND_RE, C_FUND_IM, C_ELEC, S_HORN_WORK, K_TOOL_DAMP, K_LOSS):
        out[col] = acc[col] - acc0[col]
    out[K_STORED] = energy(t, y, n, tab, xs, pv, lw, cs) - E_from
    out[K_LEDGER] = out[C_DRIVE] - out[C_DAMP] - out[K_TOOL_DAMP] - out[K_LOSS] - out[K_STORED]
    out[S_STATUS], out[S_N_EVENTS] = status, n_ev


@njit(cache=True)
def _core(pv, lw, tab, xs, t_from, t_end, max_events, record, out):
    """One run: flights and contact phases in turn, the window [t_from, t_end] marked. Returns
    (log, n_log, y, t, status, E0, acc) with ``acc`` the integrals from t = 0."""
    n = tab.shape[0]
    m = 4 + 2 * n + N_INT
    y, wk = np.zeros(m), np.empty((10, m))
    cs, acc, acc0 = np.zeros((2, CS_N)), np.zeros(N_KSTATS), np.zeros(N_KSTATS)
    fw = (np.empty(O_N), np.empty((n, O_N)), np.empty((PL_ROWS, 5)), np.empty((128, 6)), np.zeros(C_N))
    cp = fw[4]
    a = pv[P_G] - pv[P_SPRING_FORCE] / pv[P_M_FREE]
    cp[C_A], cp[C_L0], cp[C_W], cp[C_UC], cp[C_US] = a, pv[P_GAP], xs[X_W], xs[X_UC], xs[X_US]
    cw, lam = np.empty(n + 1, np.complex128), np.zeros(1, np.complex128)
    G = np.zeros((4, 1, 1), np.complex128)
    log = np.empty((64 if record else 1, LOG_N))
    atol = _tolerances(tab, n, lw[L_RTOL])
    out[:] = 0.0
    _start(pv, lw, tab, xs, n, y, cs)
    E0 = energy(0.0, y, n, tab, xs, pv, lw, cs)
    E_from, marked = E0, t_from <= 0.0
    t, h, n_log, n_ev, status = 0.0, 1e-9, 0, 0, STATUS_OK
    while t < t_end:
        t_stop = t_from if not marked else t_end
        if cs[0, CS_STATE] == OPEN and cs[1, CS_STATE] == OPEN:
            t, j = flight(t, t_stop, y, n, tab, xs, pv, fw, acc, cw, lam, G, G)
            if j >= 0:
                Dh, Dhd, Dt, Dtd = approaches(t, y, n, tab, xs, pv[P_GAP])
                touch(cs, j, lw, t, Dhd if j == 0 else Dtd, y[3], acc[S_HORN_WORK])
                h = 1e-3 * _contact_time(pv, lw, j, Dhd if j == 0 else Dtd)
        else:
            t, h, log, n_log, n_ev, ok = contact_phase(t, t_stop, y, h, n, tab, xs, pv, lw, cs, atol, wk, acc, out,
                                                       t_from, t_end, log, n_log, record, n_ev)
            if not ok:
                status = STATUS_CONTACT
                break
        if n_ev > max_events:
            status = STATUS_MAX_EVENTS
            break
        if not marked and t >= t_from:
            marked = True
            acc0[:] = acc
            E_from = energy(t, y, n, tab, xs, pv, lw, cs)
    _close(t, y, n, tab, xs, pv, lw, cs, acc, acc0, E_from, out, t_from, t_end, status, n_ev)
    return log, n_log, y, t, status, E0, acc


@njit(cache=True)
def _contact_time(pv, lw, j, v):
    """Elastic Hertz contact time of the free mass at approach speed v on a rigid flat (s): the
    scale of the first integration step."""
    k = lw[L_TOOL * j + L_K]
    v = max(abs(v), 1e-6)
    return 3.218 * (pv[P_M_FREE] ** 2 / (k * k * v)) ** 0.2


def run_contacts(pvec: np.ndarray, laws: np.ndarray, tab: np.ndarray, xs: np.ndarray, t_from: float, t_end: float,
                 max_events: int) -> tuple:
    """One run with its contact log: ``(log (k, LOG_N), state y, t, status, E0 (J), acc, row)``,
    ``acc`` the integrals from t = 0 (``C_*``, ``S_HORN_WORK``, ``K_TOOL_DAMP``, ``K_LOSS``, J) and
    ``row`` the window statistics (``N_KSTATS``)."""
    row = np.zeros(N_KSTATS)
    log, n_log, y, t, status, E0, acc = _core(np.asarray(pvec, float), laws, np.ascontiguousarray(tab), xs,
                                              float(t_from), float(t_end), int(max_events), True, row)
    return log[:n_log].copy(), y, float(t), int(status), float(E0), acc, row


@njit(cache=True, parallel=True)
def _ensemble(pmat, laws, tab, xs, t_from, t_end, max_events, out):
    for i in prange(pmat.shape[0]):
        _core(pmat[i], laws, tab, xs, t_from, t_end, max_events, False, out[i])


def ensemble_rows(pmat: np.ndarray, laws: np.ndarray, tab: np.ndarray, xs: np.ndarray, t_from: float, t_end: float,
                  max_events: int) -> np.ndarray:
    """Window statistics (n_members, ``N_KSTATS``) of many runs in parallel (members differ in the
    packed parameter rows ``pmat``, :func:`impact.kernel.pack`)."""
    pmat = np.ascontiguousarray(np.atleast_2d(pmat), dtype=np.float64)
    out = np.zeros((pmat.shape[0], N_KSTATS))
    _ensemble(pmat, laws, np.ascontiguousarray(tab), xs, float(t_from), float(t_end), int(max_events), out)
    return out
