"""Compiled drilling under load on the compliant model (numba): the FE horn and Hertz contacts of
:mod:`impact.kernel_compliant`, the tool pressed on rock by the weight on bit (:mod:`impact.drilling`).

Bodies (x along the drill, horn -> rock; SI units)::

    m_w w'' = m_w a + F_h - F_t                                  (a = g - F_s / m_w)
    m_i (q_i'' + 2 zeta_i omega_i q_i' + omega_i^2 q_i) = f_i(t) - s_i F_h
    m_t x'' = W - k0 (x - X) - c (x' - X') + F_t - F_r
    M_h X'' = F_s + k0 (x - X) + c (x' - X') - F_h               (X = 0 when M_h is infinite)
    F_h = law_h(d_h),  d_h + g F_h = X + u_m(t) - w,   F_t = law_t(w - (L0 - W / k0 + x))
    F_r = rock(d),     d = d_0 + x

* the housing (mass ``M_h``, displacement X) is pressed toward the rock by the weight on bit W and
  carries the horn and the tool's support spring k0 (damper c), pre-compressed by ``W / k0`` so
  that at rest the rock bears W; the free mass's restoring spring ``F_s`` pushes it back;
* the horn's modes (:meth:`impact.horn.ModalHorn.pack`) move with the housing: the tip is
  ``X + u_m``. Their inertial load from the housing's acceleration is left out: it is
  ``~ M_h X'' / (m_tip omega^2 A)`` of their drive, below 1e-2 even while the horn contact's
  reaction accelerates the housing (X'' ~ 2e3 m/s^2 against the tip's 2.7e5 m/s^2);
* the tool is rigid (mass ``m_t``, the no-load model's tool); the bit is its far end, at the
  penetration ``d`` below the original rock surface (``d_0`` the static penetration under W);
* the rock is the bilinear law with a crushing threshold of :mod:`impact.rock`, written as four
  linear branches of ``F_r(d)``: open (``e = d - p <= 0``), elastic loading ``k_load e`` below
  ``e_th = F_th / k_load``, the elastic curve ``F_th + k_unload (e - e_th)`` up to the largest force
  of the crater ``F_max``, and crushing ``F_c + k_load (d - d_c)`` (the crater floor ``p`` deepens
  by ``(1 - k_load / k_unload)`` of the bit's advance) until the bit stops. Every free-mass touch
  on the tool is a new blow: the crater's memory is cleared, ``F_max = max(F_th, F_r)``.

The whole run is integrated by the DOP853 steps of :mod:`impact.kernel_compliant` (the tool stays
on the rock, so there is no closed-form flight), each step cut at the earliest event of the
three contacts (horn and tool: touch, peak, reload, separation; rock: touch, threshold, the top
of the elastic curve, the bit's stop, release), located by the Illinois method on whole steps.
A step is at most 1/16 of the drive period, so a touch shorter than that (a graze of the free
mass on a body) can be missed; its energy is of the order of the grazing speed squared.

Energy: the drive's work, modal, tool and contact losses and the rock's dissipation (``F_r p'``:
the work of the crushing beyond the rock's elastic energy) are integrated with the motion; the
window's balance against the change of the stored energy (bodies, modes, closed contacts, the
rock's elastic energy, the potentials of W, F_s and gravity) is :data:`K_LEDGER`.

Window statistics: one row per member, the drilling kernel's ``S_*`` columns
(:mod:`impact.drill_kernel`; a blow is a free-mass touch on the tool, its peak force the largest
rock force until the next one, taken at the step ends and at the bit's stops; ``S_P_FROM`` and
``S_P_END`` are NaN: the modes carry momentum the row does not sum), then ``K_*``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from . import kernel_cache  # noqa: F401  (drops stale caches first)
from .drill_kernel import (N_DSTATS, S_BLOWS, S_EVENTS, S_FDT, S_FPEAK_SUM, S_HORN, S_HORN_WORK, S_KE_COLLAR,
                           S_P_END, S_P_FROM, S_PEN, S_ROCK_WORK, S_STATUS, S_STEPS, S_T, S_T_CONTACT)
from .horn import H_A, H_B, H_MASS, H_OMEGA, H_TIP, X_RC, X_RS, X_STEADY, X_V0, X_W
from .kernel import P_C, P_G, P_GAP, P_K0, P_M_FREE, P_M_TOOL, P_SPRING_FORCE, P_V0
from .kernel_compliant import (CS_STATE, CS_TMAX, CS_XD0, EV_PEAK, EV_RELOAD, L_E, L_G, L_K, L_RTOL, L_TOOL,
                               LOADING, OPEN, R8_A, R8_B, R8_C, R8_S, UNLOADING,
                               CS_K, CS_N, CS_P, CS_DMAX, absorbed, combine, contact_force, law_branch, loss,
                               modal_rates, rhs_table, step_error, tip_modal, tolerances, touch)

__all__ = ["DV_N", "pack_drill", "run_drill", "ensemble_drill", "N_KD", "K_DRIVE", "K_DAMP", "K_TOOL_DAMP", "K_LOSS",
           "K_ROCK_DISS", "K_STORED", "K_LEDGER", "K_ELEC", "STATUS_OK", "STATUS_STEPS", "warmup"]

#: the drilling parameters (beside :func:`impact.kernel.pack`'s): weight on bit, housing mass
#: (inf: fixed), rock law, the static rock state under the weight on bit, whether the rock is there
DV_WOB, DV_MH, DV_KL, DV_KU, DV_FTH, DV_E0, DV_P0, DV_FMAX0, DV_ROCK_ON = range(9)
DV_N = 9
#: window columns after the drilling kernel's: drive work, modal damping, tool damping, contact
#: losses, rock dissipation, change of the stored energy, the balance, electrical energy; J
K_DRIVE, K_DAMP, K_TOOL_DAMP, K_LOSS, K_ROCK_DISS, K_STORED, K_LEDGER, K_ELEC = range(N_DSTATS, N_DSTATS + 8)
N_KD = N_DSTATS + 8
STATUS_OK, STATUS_STEPS = 0, 2
#: rock state: branch, crater floor p, the crater's largest force, crushing start (d, p, F), the
#: largest force since the last blow
RK_BR, RK_P, RK_FMAX, RK_DC, RK_PC, RK_FC, RK_PEAK = range(7)
RK_N = 7
B_OPEN, B_LOW, B_UPPER, B_CRUSH = 0, 1, 2, 3
#: integrals after the state: drive, modal damping, tool damping, horn work, rock work, rock
#: dissipation, rock force x time, time on the rock, electrical energy
I_DRIVE, I_DAMP, I_TDAMP, I_HORN, I_RWORK, I_RDISS, I_FDT, I_TC, I_ELEC = range(9)
N_I = 9
N_EV = 6
_MAX_STEPS = 50_000_000


def pack_drill(wob: float, m_housing: float, rock, rock_on: bool = True) -> np.ndarray:
    """The drilling parameters as the kernel's ``DV_N`` vector (``rock`` a :class:`impact.rock.RockLaw`)."""
    v = np.zeros(DV_N)
    v[DV_WOB], v[DV_MH] = wob, m_housing
    v[DV_KL], v[DV_KU], v[DV_FTH] = rock.k_load, rock.k_unload, rock.f_threshold
    st = rock.static_state(wob) if rock_on else np.zeros(3)
    v[DV_E0], v[DV_P0], v[DV_FMAX0] = st[0], st[1], st[2] if rock_on else rock.f_threshold
    v[DV_ROCK_ON] = 1.0 if rock_on else 0.0
    return v


# ----------------------------------------------------------------------------- the rock's branches


@njit(cache=True, error_model="numpy")
def rock_force(d, rk, dv):
    """Rock force (N) at the bit penetration d (m) on the current branch (continued past its ends
    until the event is located)."""
    br = rk[RK_BR]
    if br == B_OPEN:
        return 0.0
    kl = dv[DV_KL]
    if br == B_CRUSH:
        return rk[RK_FC] + kl * (d - rk[RK_DC])
    e = d - rk[RK_P]
    if br == B_LOW:
        return kl * e
    return dv[DV_FTH] + dv[DV_KU] * (e - dv[DV_FTH] / kl)


@njit(cache=True, error_model="numpy")
def crater(d, rk, dv):
    """The crater floor p (m) at the bit penetration d."""
    if rk[RK_BR] == B_CRUSH:
        return rk[RK_PC] + (1.0 - dv[DV_KL] / dv[DV_KU]) * (d - rk[RK_DC])
    return rk[RK_P]


@njit(cache=True, error_model="numpy")
def rock_elastic(d, rk, dv):
    """Elastic energy the rock returns on unloading from d, J (0 open; the loading line below the
    threshold; the elastic curve above it)."""
    br = rk[RK_BR]
    if br == B_OPEN:
        return 0.0
    kl, fth = dv[DV_KL], dv[DV_FTH]
    e = d - crater(d, rk, dv)
    if br == B_LOW:
        return 0.5 * kl * e * e
    eth = fth / kl
    return 0.5 * fth * eth + fth * (e - eth) + 0.5 * dv[DV_KU] * (e - eth) ** 2


@njit(cache=True, error_model="numpy")
def _crush(rk, d, F):
    rk[RK_BR], rk[RK_DC], rk[RK_PC], rk[RK_FC] = B_CRUSH, d, rk[RK_P], F


@njit(cache=True, error_model="numpy")
def rock_settle(rk, d, dd, dv):
    """Take the loading transitions the rock is at or past at penetration d, bit speed dd (after a
    touch, a threshold, the top of the elastic curve, or a blow's cleared memory); each keeps the
    force continuous."""
    eth = dv[DV_FTH] / dv[DV_KL]
    for _ in range(3):
        br = rk[RK_BR]
        e = d - rk[RK_P]
        F = rock_force(d, rk, dv)
        if br == B_OPEN and (e > 0.0 or (e == 0.0 and dd > 0.0)):
            rk[RK_BR] = B_LOW
        elif br == B_LOW and (e > eth or (e == eth and dd > 0.0)):
            if rk[RK_FMAX] <= dv[DV_FTH]:
                _crush(rk, d, F)
            else:
                rk[RK_BR] = B_UPPER
        elif br == B_UPPER and (F > rk[RK_FMAX] or (F == rk[RK_FMAX] and dd > 0.0)):
            _crush(rk, d, F)
        else:
            return


@njit(cache=True, error_model="numpy")
def rock_event(rk, which, d, dd, dv):
    """Apply the rock's event ``which`` (0 or 1, :func:`_events`) at penetration d, bit speed dd:
    the unloading ones here (release, below the threshold, the bit's stop), the loading ones by
    :func:`rock_settle`."""
    br = rk[RK_BR]
    if br == B_LOW and which == 0:
        rk[RK_BR] = B_OPEN
    elif br == B_UPPER and which == 0:
        rk[RK_BR] = B_LOW
    elif br == B_CRUSH:                     # the bit stops: the crater keeps its depth and force
        F = rock_force(d, rk, dv)
        rk[RK_P] = crater(d, rk, dv)
        rk[RK_FMAX] = F
        rk[RK_PEAK] = max(rk[RK_PEAK], F)
        rk[RK_BR] = B_UPPER
    rock_settle(rk, d, dd, dv)


@njit(cache=True, error_model="numpy")
def new_blow(rk, d, dd, dv):
    """A blow starts: the crater's memory is cleared (:func:`impact.rock.rock_new_blow`)."""
    if rk[RK_BR] == B_CRUSH:
        return
    rk[RK_FMAX] = max(dv[DV_FTH], rock_force(d, rk, dv))
    rock_settle(rk, d, dd, dv)


# ----------------------------------------------------------------------------- the motion


@njit(cache=True, error_model="numpy")
def _approaches(t, y, n, mt, xs, pv, dv):
    """Total approaches at horn and tool and their rates (m, m/s)."""
    u, ud = tip_modal(t, y, n, mt, xs)
    j = 4 + 2 * n
    face = pv[P_GAP] - dv[DV_WOB] / pv[P_K0] + y[2]
    return y[j] + u - y[0], y[j + 1] + ud - y[1], y[0] - face, y[1] - y[3]


@njit(cache=True, error_model="numpy")
def rhs(t, y, out, n, mt, xs, pv, lw, cs, dv, rk):
    """Right-hand side: ``y = [w, w', x, x', q (n), q' (n), X, X', integrals (N_I)]``."""
    m_w, m_t, k0, c = pv[P_M_FREE], pv[P_M_TOOL], pv[P_K0], pv[P_C]
    Fs, wob, Mh = pv[P_SPRING_FORCE], dv[DV_WOB], dv[DV_MH]
    j = 4 + 2 * n
    W = xs[X_W]
    co, si = math.cos(W * t), math.sin(W * t)
    rd = W * (-xs[X_RC] * si + xs[X_RS] * co)
    Dh, _, Dt, _ = _approaches(t, y, n, mt, xs, pv, dv)
    Fh = contact_force(Dh, cs[0, CS_STATE], cs[0, CS_K], cs[0, CS_P], lw[L_G])[0]
    Ft = contact_force(Dt, cs[1, CS_STATE], cs[1, CS_K], cs[1, CS_P], 0.0)[0]
    Fr = rock_force(dv[DV_E0] + dv[DV_P0] + y[2], rk, dv)
    s, sd = y[2] - y[j], y[3] - y[j + 1]
    Fk = k0 * s + c * sd                    # the support's pull back on the tool beyond W
    out[0], out[1] = y[1], pv[P_G] - Fs / m_w + (Fh - Ft) / m_w
    out[2], out[3] = y[3], (wob - Fk + Ft - Fr) / m_t
    out[j] = y[j + 1]
    out[j + 1] = (Fs + Fk - Fh) / Mh if math.isfinite(Mh) else 0.0
    V = xs[X_V0] * si
    drive, damp, cur = modal_rates(y, out, n, mt, xs, co, si, Fh)
    umd = 0.0
    for i in range(n):
        umd += mt[i, H_TIP] * y[4 + n + i]
    k = j + 2
    crushing = rk[RK_BR] == B_CRUSH
    out[k + I_DRIVE], out[k + I_DAMP], out[k + I_TDAMP] = drive + Fh * rd, damp, c * sd * sd
    out[k + I_HORN], out[k + I_RWORK] = Fh * (y[j + 1] + umd + rd), Fr * y[3]
    out[k + I_RDISS] = Fr * (1.0 - dv[DV_KL] / dv[DV_KU]) * y[3] if crushing else 0.0
    out[k + I_FDT], out[k + I_TC], out[k + I_ELEC] = Fr, 0.0 if rk[RK_BR] == B_OPEN else 1.0, V * cur


@njit(cache=True, error_model="numpy")
def _step(t, y, h, n, mt, xs, pv, lw, cs, dv, rk, st, y8, tmp, fresh):
    """One DOP853 step of length h from (t, y) into y8 (:data:`impact.kernel_compliant.R8_A`)."""
    if fresh:
        rhs(t, y, st[0], n, mt, xs, pv, lw, cs, dv, rk)
    for q in range(1, R8_S):
        combine(y, h, st, R8_A[q], q, tmp)
        rhs(t + R8_C[q] * h, tmp, st[q], n, mt, xs, pv, lw, cs, dv, rk)
    combine(y, h, st, R8_B, R8_S, y8)


@njit(cache=True, error_model="numpy")
def _events(t, y, n, mt, xs, pv, dv, cs, rk, out):
    """The event functions, positive past their event: horn and tool (touch, or peak / reload and
    separation), rock (touch or release, threshold / top of the elastic curve / the bit's stop);
    -1 where a contact waits for one event only."""
    Dh, Dhd, Dt, Dtd = _approaches(t, y, n, mt, xs, pv, dv)
    for c in range(2):
        D, Dd = (Dh, Dhd) if c == 0 else (Dt, Dtd)
        state = cs[c, CS_STATE]
        if state == OPEN:
            out[2 * c], out[2 * c + 1] = D, -1.0
        elif state == LOADING:
            out[2 * c], out[2 * c + 1] = -Dd, -D
        else:
            out[2 * c], out[2 * c + 1] = D - cs[c, CS_TMAX], -D
    d = dv[DV_E0] + dv[DV_P0] + y[2]
    br = rk[RK_BR]
    e = d - rk[RK_P]
    eth = dv[DV_FTH] / dv[DV_KL]
    if dv[DV_ROCK_ON] == 0.0:
        out[4], out[5] = -1.0, -1.0
    elif br == B_OPEN:
        out[4], out[5] = e, -1.0
    elif br == B_LOW:
        out[4], out[5] = -e, e - eth
    elif br == B_UPPER:
        out[4], out[5] = eth - e, rock_force(d, rk, dv) - rk[RK_FMAX]
    else:
        out[4], out[5] = -y[3], -1.0


@njit(cache=True, error_model="numpy")
def _locate(t, y, hh, k, f_lo, f_hi, n, mt, xs, pv, lw, cs, dv, rk, st, y8, tmp, ev):
    """Step length just past event k (its function rises through zero in (0, hh]): the Illinois
    method on whole steps from (t, y); y8 holds the step to the returned length."""
    lo, hi, side = 0.0, hh, 0
    for _ in range(100):
        if hi - lo <= 4e-16 * (abs(t) + hi):
            break
        x = hi - f_hi * (hi - lo) / (f_hi - f_lo)
        if not (lo < x < hi):
            x = 0.5 * (lo + hi)
        _step(t, y, x, n, mt, xs, pv, lw, cs, dv, rk, st, tmp, y8, False)
        _events(t + x, tmp, n, mt, xs, pv, dv, cs, rk, ev)
        if ev[k] > 0.0:
            hi, f_hi = x, ev[k]
            if side == 1:
                f_lo *= 0.5
            side = 1
        else:
            lo, f_lo = x, ev[k]
            if side == -1:
                f_hi *= 0.5
            side = -1
    _step(t, y, hi, n, mt, xs, pv, lw, cs, dv, rk, st, y8, tmp, False)
    return hi


# ----------------------------------------------------------------------------- events and energy


@njit(cache=True, error_model="numpy")
def energy(t, y, n, mt, xs, pv, lw, cs, dv, rk):
    """Stored energy, J: bodies, modes, the support spring's and the constant forces' potentials,
    the closed contacts' absorbed energy and the rock's elastic energy."""
    m_w, m_t, k0 = pv[P_M_FREE], pv[P_M_TOOL], pv[P_K0]
    Fs, wob, Mh = pv[P_SPRING_FORCE], dv[DV_WOB], dv[DV_MH]
    j = 4 + 2 * n
    a = pv[P_G] - Fs / m_w
    s = y[2] - y[j]
    E = 0.5 * m_w * y[1] * y[1] - m_w * a * y[0] + 0.5 * m_t * y[3] * y[3] + 0.5 * k0 * s * s - wob * s
    if math.isfinite(Mh):
        E += 0.5 * Mh * y[j + 1] * y[j + 1] - (wob + Fs) * y[j]
    for i in range(n):
        E += 0.5 * mt[i, H_MASS] * (y[4 + n + i] ** 2 + mt[i, H_OMEGA] ** 2 * y[4 + i] ** 2)
    Dh, _, Dt, _ = _approaches(t, y, n, mt, xs, pv, dv)
    E += absorbed(Dh, cs[0], lw[L_K], lw[L_E], lw[L_G])
    E += absorbed(Dt, cs[1], lw[L_TOOL + L_K], lw[L_TOOL + L_E], 0.0)
    return E + rock_elastic(dv[DV_E0] + dv[DV_P0] + y[2], rk, dv)


@njit(cache=True, error_model="numpy")
def _apply(k, t, y, n, mt, xs, pv, lw, cs, dv, rk, acc, stats, inside):
    """Apply event k at t (the step to it taken): the contact laws' branches, the blows, the rock's."""
    Dh, Dhd, Dt, Dtd = _approaches(t, y, n, mt, xs, pv, dv)
    d, dd = dv[DV_E0] + dv[DV_P0] + y[2], y[3]
    if k >= 4:
        rock_event(rk, k - 4, d, dd, dv)
        return
    c = k // 2
    D, Dd = (Dh, Dhd) if c == 0 else (Dt, Dtd)
    state = cs[c, CS_STATE]
    if state == OPEN:
        touch(cs, c, lw, t, Dd, y[3], 0.0)
        if c == 1:                                          # a blow
            if inside:
                stats[S_BLOWS] += 1.0
                stats[S_FPEAK_SUM] += rk[RK_PEAK]
            rk[RK_PEAK] = 0.0
            if dv[DV_ROCK_ON] != 0.0:
                new_blow(rk, d, dd, dv)
    elif k % 2 == 0:
        law_branch(cs, c, lw, EV_PEAK if state == LOADING else EV_RELOAD, D)
    else:                                                   # separation
        if state == UNLOADING:
            acc[K_LOSS] += loss(lw[L_TOOL * c + L_K], lw[L_TOOL * c + L_E], cs[c, CS_DMAX])
        if inside:
            if c == 1:
                stats[S_KE_COLLAR] += 0.5 * pv[P_M_TOOL] * (y[3] * y[3] - cs[c, CS_XD0] ** 2)
            else:
                stats[S_HORN] += 1.0
        cs[c, CS_STATE] = OPEN


@njit(cache=True, error_model="numpy")
def _start(y, n, mt, xs, pv, lw, cs, dv, rk):
    """The state at t = 0: the modes steady (or at rest), the tool and the rock static under the
    weight on bit, the free mass on the tip leaving at v0."""
    steady = xs[X_STEADY] == 1.0
    for i in range(n):
        y[4 + i] = mt[i, H_A] if steady else 0.0
        y[4 + n + i] = xs[X_W] * mt[i, H_B] if steady else 0.0
    u0, ud0 = tip_modal(0.0, y, n, mt, xs)
    y[0], y[1] = u0, ud0 + pv[P_V0]
    rk[:] = 0.0
    rk[RK_P], rk[RK_FMAX] = dv[DV_P0], dv[DV_FMAX0]
    if dv[DV_ROCK_ON] != 0.0 and dv[DV_E0] > 0.0:
        rk[RK_BR] = B_LOW if dv[DV_E0] < dv[DV_FTH] / dv[DV_KL] else B_UPPER


@njit(cache=True, error_model="numpy")
def _tolerances(mt, n, rtol):
    """Absolute tolerances: the compliant engine's (mm positions, m/s speeds, the modes through
    their tip participation), the housing's as the tool's."""
    atol = np.empty(6 + 2 * n)
    atol[:4 + 2 * n] = tolerances(mt, n, rtol)
    atol[4 + 2 * n], atol[5 + 2 * n] = 1e-3 * rtol, rtol
    return atol


@njit(cache=True, error_model="numpy")
def _mark(y, n, mt, xs, pv, lw, cs, dv, rk, t, snap):
    """The window's start or end: stored energy, crater depth, integrals (``snap``)."""
    k = 6 + 2 * n
    snap[0] = energy(t, y, n, mt, xs, pv, lw, cs, dv, rk)
    snap[1] = crater(dv[DV_E0] + dv[DV_P0] + y[2], rk, dv)
    snap[2:2 + N_I] = y[k:k + N_I]


@njit(cache=True, error_model="numpy")
def _close(out, s0, s1, acc, loss0):
    """The window's row from its start and end marks."""
    a, b = s0[2:], s1[2:]
    out[S_PEN] = s1[1] - s0[1]
    out[S_ROCK_WORK], out[S_HORN_WORK] = b[I_RWORK] - a[I_RWORK], b[I_HORN] - a[I_HORN]
    out[S_FDT], out[S_T_CONTACT] = b[I_FDT] - a[I_FDT], b[I_TC] - a[I_TC]
    out[K_DRIVE], out[K_DAMP], out[K_TOOL_DAMP] = b[I_DRIVE] - a[I_DRIVE], b[I_DAMP] - a[I_DAMP], b[I_TDAMP] - a[I_TDAMP]
    out[K_ROCK_DISS], out[K_ELEC] = b[I_RDISS] - a[I_RDISS], b[I_ELEC] - a[I_ELEC]
    out[K_LOSS] = acc[K_LOSS] - loss0
    out[K_STORED] = s1[0] - s0[0]
    out[K_LEDGER] = out[K_DRIVE] - out[K_DAMP] - out[K_TOOL_DAMP] - out[K_LOSS] - out[K_ROCK_DISS] - out[K_STORED]
    out[S_P_FROM], out[S_P_END] = math.nan, math.nan


@njit(cache=True, error_model="numpy")
def _core(pv, lw, dv, tab, xs, t_from, t_end, out, y):
    """One run; the window's row into ``out``, the final state into ``y``. Returns the status."""
    n = tab.shape[0]
    m = 6 + 2 * n + N_I
    mt = rhs_table(tab, xs)
    st, y8, tmp = np.empty((R8_S, m)), np.empty(m), np.empty(m)
    cs, rk, acc = np.zeros((2, CS_N)), np.empty(RK_N), np.zeros(N_KD)
    ev0, ev1, ev = np.empty(N_EV), np.empty(N_EV), np.empty(N_EV)
    s0, s1 = np.zeros(2 + N_I), np.zeros(2 + N_I)
    atol = _tolerances(mt, n, lw[L_RTOL])
    rtol = lw[L_RTOL]
    out[:] = 0.0
    y[:] = 0.0
    _start(y, n, mt, xs, pv, lw, cs, dv, rk)
    h_max = 2.0 * math.pi / xs[X_W] / 16.0
    t, h, steps, n_ev, loss0 = 0.0, 1e-7, 0, 0, 0.0
    marked, fresh, rejected = t_from <= 0.0, True, False
    if marked:
        _mark(y, n, mt, xs, pv, lw, cs, dv, rk, t, s0)
    _events(t, y, n, mt, xs, pv, dv, cs, rk, ev0)
    while t < t_end:
        steps += 1
        if steps > _MAX_STEPS:
            out[S_STATUS] = STATUS_STEPS
            break
        t_stop = t_end if marked else t_from
        hh = min(h, h_max, t_stop - t)
        _step(t, y, hh, n, mt, xs, pv, lw, cs, dv, rk, st, y8, tmp, fresh)
        fresh = False
        err = step_error(y, y8, st, hh, atol, rtol)
        grow = min(6.0, max(0.2, 0.9 * max(err, 1e-30) ** -0.125))
        if err > 1.0 and hh > 1e-18:
            h, rejected = hh * grow, True
            continue
        if rejected:
            grow, rejected = min(grow, 1.0), False
        _events(t + hh, y8, n, mt, xs, pv, dv, cs, rk, ev1)
        k_best, h_best = -1, hh
        for k in range(N_EV):
            if ev0[k] <= 0.0 and ev1[k] > 0.0:
                hk = _locate(t, y, hh, k, ev0[k], ev1[k], n, mt, xs, pv, lw, cs, dv, rk, st, y8, tmp, ev)
                if k_best < 0 or hk < h_best:
                    k_best, h_best = k, hk
        if k_best >= 0:
            hh = h_best
            _step(t, y, hh, n, mt, xs, pv, lw, cs, dv, rk, st, y8, tmp, False)
        else:
            h = hh * grow if hh >= min(h, h_max) else max(h, hh * grow)
        for j in range(y.size):
            y[j] = y8[j]
        t = t_stop if t_stop - t - hh <= 1e-15 * t_stop else t + hh
        fresh = True
        if k_best >= 0:
            inside = marked and t <= t_end
            _apply(k_best, t, y, n, mt, xs, pv, lw, cs, dv, rk, acc, out, inside)
            n_ev += 1
        F = rock_force(dv[DV_E0] + dv[DV_P0] + y[2], rk, dv)
        rk[RK_PEAK] = max(rk[RK_PEAK], F)
        if not marked and t >= t_from:
            marked = True
            loss0 = acc[K_LOSS]
            _mark(y, n, mt, xs, pv, lw, cs, dv, rk, t, s0)
        _events(t, y, n, mt, xs, pv, dv, cs, rk, ev0)
    _mark(y, n, mt, xs, pv, lw, cs, dv, rk, t, s1)
    _close(out, s0, s1, acc, loss0)
    out[S_T], out[S_STEPS], out[S_EVENTS] = t_end - t_from, steps, n_ev
    return int(out[S_STATUS])


def run_drill(pvec: np.ndarray, laws: np.ndarray, dvec: np.ndarray, tab: np.ndarray, xs: np.ndarray,
              t_from: float, t_end: float) -> tuple[np.ndarray, np.ndarray]:
    """One run: the window's row (``N_KD`` columns) and the final state."""
    row = np.zeros(N_KD)
    y = np.zeros(6 + 2 * tab.shape[0] + N_I)
    _core(np.asarray(pvec, float), laws, np.asarray(dvec, float), np.ascontiguousarray(tab), xs, float(t_from),
          float(t_end), row, y)
    return row, y


@njit(cache=True, error_model="numpy", parallel=True)
def _ensemble(pmat, lmat, dmat, tab, xs, t_from, t_end, out):
    for i in prange(pmat.shape[0]):
        y = np.zeros(6 + 2 * tab.shape[0] + N_I)
        _core(pmat[i], lmat[i], dmat[i], tab, xs, t_from, t_end, out[i], y)


def ensemble_drill(pmat: np.ndarray, lmat: np.ndarray, dmat: np.ndarray, tab: np.ndarray, xs: np.ndarray,
                   t_from: float, t_end: float) -> np.ndarray:
    """Window rows (n_members, ``N_KD``) of many runs in parallel: one row of each matrix per
    member (:func:`impact.kernel.pack`, :func:`impact.kernel_compliant.pack_laws`, :func:`pack_drill`)."""
    pmat = np.ascontiguousarray(np.atleast_2d(pmat), dtype=np.float64)
    out = np.zeros((pmat.shape[0], N_KD))
    _ensemble(pmat, np.ascontiguousarray(np.atleast_2d(lmat)), np.ascontiguousarray(np.atleast_2d(dmat)),
              np.ascontiguousarray(tab), xs, float(t_from), float(t_end), out)
    return out


def warmup() -> None:
    """Compile both entry points (or load them from numba's disk cache) on a tiny case; ``make
    install`` calls it, so the first compliant drilling run does not spend ~20 s compiling."""
    from .hertz import HertzLaw
    from .horn import ModalHorn
    from .kernel import pack
    from .kernel_compliant import pack_laws
    from .params import ImpactParams
    from .rock import RockLaw

    horn = ModalHorn([2 * math.pi * 20.5e3], [0.005], [1.0], [3.0], [0.5], [0.0], 1.0)
    p = ImpactParams(t_end=1e-3)
    tab, xs = horn.pack(p.freq)
    lw = pack_laws(HertzLaw(1e9, p.e2), HertzLaw(1e9, p.e1), 0.0, 1e-9)
    dv = pack_drill(7.0, 0.5, RockLaw())
    run_drill(pack(p), lw, dv, tab, xs, 0.0, 1e-3)
    ensemble_drill(pack(p)[None, :], lw[None, :], dv[None, :], tab, xs, 0.0, 1e-3)
