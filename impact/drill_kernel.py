"""Compiled time-stepped kernel of the drilling-under-load model (numba).

Bodies (x along the drill, horn -> rock; see :mod:`impact.drilling` for the model):

* housing (mass ``m_housing``, position X, velocity V) pressed toward the rock by the weight on
  bit; it carries the horn (tip at ``X + A0 cos(om t)``: the kinematic horn) and holds the
  collar through the support spring k0 and damper c; the free mass's restoring spring pushes
  the housing by ``spring_force`` while the free mass flies (its reaction);
* free mass (point, flight under ``g - spring_force / m_free``), Newton impacts on the horn
  (restitution e2 against the housing that carries the horn, the horn's vibration imposed on
  top) and on the collar (restitution e1), momentum conserved in both;
* collar: rigid, bonded to the top of the rod (or, for the Saint-Venant check, a unilateral
  striker); between impacts ``m_c x'' = -k0 q - c q' - N_top`` with ``q = x - X - gap`` and the
  rod's top force ``N_top = Z (x' - 2 b)`` (b: incoming wave), solved in closed form over a step
  with the spring force and the housing velocity frozen at the step start;
* rod: exact wave propagation (:mod:`impact.rod`), ring buffers;
* bit: :func:`impact.rock.rock_step`; every blow (free-mass impact on the collar) clears the
  crater's memory (:func:`impact.rock.rock_new_blow`).

Fixed step ``dt = L / (cells c)``. Impacts inside a step are located by bisection on the
closed-form gaps (free flight, the collar's exponential relaxation, the housing's parabola and
the horn's cosine) and the step is continued from the impact; at most ``_MAX_EV`` impacts per
step, the rest of a chattering step is closed plastically.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from . import kernel_cache  # noqa: F401  (drops stale caches first)
from .rock import R_E, R_FMAX, R_N, R_P, rock_new_blow, rock_step_fast

# packed parameters
(D_M_FREE, D_A0, D_OM, D_E1, D_E2, D_M_COLLAR, D_K0, D_C, D_GAP, D_G, D_V0, D_SPRING, D_Z, D_DT,
 D_CELLS, D_KL, D_KU, D_FTH, D_WOB, D_M_HOUSING, D_V_STICK, D_UNILATERAL, D_ROCK_ON, D_COLLAR_V0,
 D_E0, D_P0, D_FMAX0, D_COLD) = range(28)
N_DPARAMS = 28

# per-member window statistics
(S_BLOWS, S_HORN, S_PEN, S_ROCK_WORK, S_HORN_WORK, S_FDT, S_FPEAK_SUM, S_KE_COLLAR, S_STATUS,
 S_EVENTS, S_STEPS, S_T, S_P_FROM, S_P_END, S_T_CONTACT) = range(15)
N_DSTATS = 15

# recorded columns
(C_T, C_N_TOP, C_N_BIT, C_V_COLLAR, C_V_BIT, C_D, C_P, C_X_HOUSING, C_W, C_F_ROCK, C_ENERGY,
 C_ROCK_WORK, C_HORN_WORK) = range(13)
N_REC = 13

STATUS_OK, STATUS_PLASTIC = 0, 1
_MAX_EV = 16
_BISECT = 60


@njit(cache=True)
def _collar_x(x, v, fext, lam, mc, s):
    """Collar position and velocity after s under m x'' = fext - lam m x' (closed form)."""
    if lam > 0.0:
        vinf = fext / (lam * mc)
        em = -math.expm1(-lam * s)
        return x + vinf * s + (v - vinf) * em / lam, vinf + (v - vinf) * (1.0 - em)
    acc = fext / mc
    return x + v * s + 0.5 * acc * s * s, v + acc * s


@njit(cache=True)
def _gaps(s, t, xc, vc, fext, lam, mc, X, V, Ah, w, wd, aw, A0, om, free_on):
    xcs, _ = _collar_x(xc, vc, fext, lam, mc, s)
    if not free_on:
        return 1.0, 1.0
    ws = w + s * (wd + 0.5 * aw * s)
    hs = X + s * (V + 0.5 * Ah * s) + A0 * math.cos(om * (t + s))
    return ws - hs, xcs - ws


@njit(cache=True)
def _root(which, t, xc, vc, fext, lam, mc, X, V, Ah, w, wd, aw, A0, om, free_on, h):
    """First time in (0, h] where gap ``which`` (0 horn, 1 collar) is negative, by bisection."""
    lo = 0.0
    hi = h
    for _ in range(_BISECT):
        if hi - lo <= 1e-16 + 1e-13 * hi:
            break
        mid = 0.5 * (lo + hi)
        g = _gaps(mid, t, xc, vc, fext, lam, mc, X, V, Ah, w, wd, aw, A0, om, free_on)[which]
        if g < 0.0:
            hi = mid
        else:
            lo = mid
    return hi


@njit(cache=True)
def _momentum(Mh, V, mc, vc, m_w, wd, Z, dt, ringA, ringB):
    # total momentum along x: housing, collar, free mass, rod (each cell rho A dx = Z dt)
    p = mc * vc + m_w * wd + Z * dt * (ringA.sum() + ringB.sum())
    if math.isfinite(Mh):
        p += Mh * V
    return p


@njit(cache=True)
def _horn_blow(te, X, V, wd, A0, om, e2, v_stick, mu_h, Mh, m_w, housing_free, work_horn, started, stats):
    """The free mass meets the horn at te: Newton's law between it and the housing that carries
    the horn (effective mass mu; the horn's vibration is imposed): momentum and, for e2 = 1 and a
    still horn, energy are exact. Returns (w, w', V, horn work)."""
    hx = X + A0 * math.cos(om * te)
    hv = V - A0 * om * math.sin(om * te)
    ap = hv - wd
    w = hx
    if ap > 0.0:
        ee = e2 if e2 * ap >= v_stick else 0.0
        J = mu_h * (1.0 + ee) * ap
        work_horn += J * hv
        if housing_free:
            V -= J / Mh
        wd = wd + J / m_w
        if started:
            stats[S_HORN] += 1.0
    return w, wd, V, work_horn


@njit(cache=True)
def _collar_blow(xc, vc, wd, m_w, mc, e1, v_stick, fpeak, started, stats, rock_on, rs, kl, ku, fth):
    """The free mass strikes the collar: Newton's law (restitution e1, plastic below v_stick), the
    blow's statistics, and the rock's memory cleared (each blow meets fresh rock). Returns (w, w',
    the collar's velocity, the peak rock force since the blow)."""
    ap = wd - vc
    w = xc
    if ap > 0.0:
        M = m_w + mc
        if e1 * ap < v_stick:
            vn = (m_w * wd + mc * vc) / M
            wn = vn
        else:
            vn = vc + m_w / M * (1.0 + e1) * ap
            wn = wd - mc / M * (1.0 + e1) * ap
        if started:
            stats[S_BLOWS] += 1.0
            stats[S_KE_COLLAR] += 0.5 * mc * (vn * vn - vc * vc)
            stats[S_FPEAK_SUM] += fpeak
        fpeak = 0.0
        vc, wd = vn, wn
        if rock_on:
            rock_new_blow(rs, kl, ku, fth)
    return w, wd, vc, fpeak


@njit(cache=True)
def _record_row(row, t_rec, Z, dt, a0, b0, n_bit, vc, dd, rs, X, V, w, wd, xc, f_rock_end, racc, work_horn, mc, k0, L0,
                kl, ku, fth, wob, Mh, housing_free, free_on, m_w, g, Fs, ringA, ringB):
    """One recorded row (columns ``C_*``) at the end of a step, t_rec (s)."""
    row[C_T] = t_rec
    row[C_N_TOP] = Z * (a0 - b0)
    row[C_N_BIT] = n_bit
    row[C_V_COLLAR] = vc
    row[C_V_BIT] = dd / dt
    row[C_D] = rs[R_E] + rs[R_P]
    row[C_P] = rs[R_P]
    row[C_X_HOUSING] = X
    row[C_W] = w
    row[C_F_ROCK] = f_rock_end
    # mechanical energy (J): kinetic, spring k0, rod waves, rock's elastic energy (the
    # elastic curve), potentials of the WOB, gravity on the free mass, restoring spring
    q = xc - X - L0
    e = rs[R_E]
    if e <= 0.0:
        er = 0.0
    elif e <= fth / kl:
        er = 0.5 * kl * e * e
    else:
        eth = fth / kl
        er = 0.5 * fth * eth + fth * (e - eth) + 0.5 * ku * (e - eth) ** 2
    en = (0.5 * mc * vc * vc + 0.5 * k0 * q * q + Z * dt * ((ringA * ringA).sum() + (ringB * ringB).sum())
          + er - wob * X)
    if housing_free:
        en += 0.5 * Mh * V * V
    if free_on:
        en += 0.5 * m_w * wd * wd - m_w * g * w + Fs * (w - X)
    row[C_ENERGY] = en
    row[C_ROCK_WORK] = racc[0]
    row[C_HORN_WORK] = work_horn


@njit(cache=True)
def _close_plastic(X, V, w, wd, xc, vc, A0, om, t1):
    """A chattering step closed plastically at its end t1 (s): no interpenetration left with the
    horn (on the housing X, V) or the collar (xc, vc). Returns the free mass's (w, w')."""
    hp = X + A0 * math.cos(om * t1)
    if w < hp:
        w = hp
        wd = V - A0 * om * math.sin(om * t1)
    if w > xc:
        w = xc
        wd = vc
    return w, wd


@njit(cache=True)
def _core(pv, t_from, t_end, stats, rec_every, rec):
    m_w, A0, om, e1, e2 = pv[D_M_FREE], pv[D_A0], pv[D_OM], pv[D_E1], pv[D_E2]
    mc, k0, c, L0, g = pv[D_M_COLLAR], pv[D_K0], pv[D_C], pv[D_GAP], pv[D_G]
    Fs, Z, dt, N = pv[D_SPRING], pv[D_Z], pv[D_DT], int(pv[D_CELLS])
    kl, ku, fth, wob, Mh = pv[D_KL], pv[D_KU], pv[D_FTH], pv[D_WOB], pv[D_M_HOUSING]
    v_stick = pv[D_V_STICK]
    unilateral = pv[D_UNILATERAL] != 0.0
    rock_on = pv[D_ROCK_ON] != 0.0
    free_on = m_w > 0.0
    housing_free = math.isfinite(Mh)
    aw = g - Fs / m_w if free_on else 0.0
    mu_h = m_w * Mh / (m_w + Mh) if housing_free else m_w
    Fs_h = Fs if free_on else 0.0

    for j in range(stats.shape[0]):
        stats[j] = 0.0
    # static equilibrium under the weight on bit: uniform compression, spring deflected, rock
    # pressed (the free mass leaves the horn at t = 0 as in the no-load model)
    # (``cold``: everything unstressed, the bit just touching the rock: the settling check)
    cold = pv[D_COLD] != 0.0
    f0 = 0.0 if cold else wob
    ringA = np.full(N, f0 / (2.0 * Z))
    ringB = np.full(N, -f0 / (2.0 * Z))
    rs = np.empty(R_N)
    rs[R_E], rs[R_P], rs[R_FMAX] = pv[D_E0], pv[D_P0], pv[D_FMAX0]
    racc = np.zeros(2)
    X = 0.0
    V = 0.0
    q_static = -f0 / k0 if k0 > 0.0 else 0.0
    if cold:
        rs[R_E], rs[R_P], rs[R_FMAX] = 0.0, 0.0, fth
    xc = L0 + q_static
    vc = pv[D_COLLAR_V0]
    in_contact = True                      # collar on the rod (always, unless unilateral)
    w = A0
    wd = pv[D_V0]
    n_steps = int(math.ceil(t_end / dt - 1e-9))
    em_l = -math.expm1(-kl / Z * dt)
    em_u = -math.expm1(-ku / Z * dt)
    lam_on = (Z + c) / mc
    em_on = -math.expm1(-lam_on * dt)
    work_rock_from = 0.0
    work_horn = 0.0
    work_horn_from = 0.0
    p_from = rs[R_P]
    fpeak = 0.0
    started = t_from <= 0.0
    status = STATUS_OK
    n_ev_total = 0
    n_rec = 0
    f_rock_end = wob
    for n in range(n_steps):
        t = n * dt
        if not started and t >= t_from:
            started = True
            work_rock_from = racc[0]
            work_horn_from = work_horn
            p_from = rs[R_P]
            stats[S_T] = 0.0
            stats[S_P_FROM] = _momentum(Mh, V, mc, vc, m_w, wd, Z, dt, ringA, ringB)
        slot = n % N
        aN = ringA[slot]
        b0 = ringB[slot]
        # ---- bit end
        if rock_on:
            dd = rock_step_fast(aN, Z, kl, ku, fth, rs, dt, racc, em_l, em_u, False)
        else:
            dd = 2.0 * aN * dt
            rs[R_E] += dd
        bN = dd / dt - aN
        # ---- top: collar, free mass, housing
        q0 = xc - X - L0
        fspring = -k0 * q0 - c * (vc - V)          # on the collar
        if in_contact:
            fext = -k0 * q0 + c * V + 2.0 * Z * b0
            lam = (Z + c) / mc
        else:
            fext = -k0 * q0 + c * V
            lam = c / mc
        Ah = (wob + Fs_h - fspring) / Mh if housing_free else 0.0
        xc_start = xc
        s = 0.0
        n_ev = 0
        while True:
            h = dt - s
            if h <= 0.0:
                break
            tt = t + s
            # the bodies at the step end, no impact (one closed form each; the gaps from them)
            if h == dt and lam == lam_on:
                # a whole step in contact with the rod (the common case): precomputed exponential
                vinf = fext / (lam * mc)
                xce, vce = xc + vinf * h + (vc - vinf) * em_on / lam, vinf + (vc - vinf) * (1.0 - em_on)
            else:
                xce, vce = _collar_x(xc, vc, fext, lam, mc, h)
            Xe = X + h * (V + 0.5 * Ah * h)
            we = w + h * (wd + 0.5 * aw * h)
            if free_on:
                gh = we - Xe - A0 * math.cos(om * (tt + h))
                gc = xce - we
            else:
                gh, gc = 1.0, 1.0
            if (gh >= 0.0 and gc >= 0.0) or n_ev >= _MAX_EV:
                xc, vc = xce, vce
                X, V = Xe, V + Ah * h
                if free_on:
                    w, wd = we, wd + aw * h
                    if n_ev >= _MAX_EV:
                        status = STATUS_PLASTIC
                        w, wd = _close_plastic(X, V, w, wd, xc, vc, A0, om, t + dt)
                break
            sh = _root(0, tt, xc, vc, fext, lam, mc, X, V, Ah, w, wd, aw, A0, om, free_on, h) if gh < 0.0 else math.inf
            sc = _root(1, tt, xc, vc, fext, lam, mc, X, V, Ah, w, wd, aw, A0, om, free_on, h) if gc < 0.0 else math.inf
            se = min(sh, sc)
            xc, vc = _collar_x(xc, vc, fext, lam, mc, se)
            X, V = X + se * (V + 0.5 * Ah * se), V + Ah * se
            w, wd = w + se * (wd + 0.5 * aw * se), wd + aw * se
            s += se
            te = t + s
            n_ev += 1
            if sh <= sc:
                w, wd, V, work_horn = _horn_blow(te, X, V, wd, A0, om, e2, v_stick, mu_h, Mh, m_w, housing_free,
                                                 work_horn, started, stats)
            else:
                w, wd, vc, fpeak = _collar_blow(xc, vc, wd, m_w, mc, e1, v_stick, fpeak, started, stats, rock_on, rs,
                                                kl, ku, fth)
        n_ev_total += n_ev
        vbar = (xc - xc_start) / dt
        if unilateral and in_contact and vbar - 2.0 * b0 < 0.0:
            # the striker would pull on the rod: it separates (Saint-Venant check only)
            in_contact = False
        a0 = vbar - b0 if in_contact else b0
        ringA[slot] = a0
        ringB[slot] = bN
        e = rs[R_E]
        if not rock_on or e <= 0.0:
            f_rock_end = 0.0
        else:
            eth = fth / kl
            f_rock_end = kl * e if e <= eth else fth + ku * (e - eth)
        if f_rock_end > fpeak:
            fpeak = f_rock_end
        n_bit = Z * (aN - bN)
        if started:
            stats[S_FDT] += n_bit * dt
            stats[S_T] += dt
            if f_rock_end > 0.0:
                stats[S_T_CONTACT] += dt
        if rec_every > 0 and (n + 1) % rec_every == 0 and n_rec < rec.shape[0]:
            _record_row(rec[n_rec], t + dt, Z, dt, a0, b0, n_bit, vc, dd, rs, X, V, w, wd, xc, f_rock_end, racc,
                        work_horn, mc, k0, L0, kl, ku, fth, wob, Mh, housing_free, free_on, m_w, g, Fs, ringA, ringB)
            n_rec += 1
    if t_from <= 0.0:
        stats[S_P_FROM] = m_w * pv[D_V0] + mc * pv[D_COLLAR_V0]
    stats[S_P_END] = _momentum(Mh, V, mc, vc, m_w, wd, Z, dt, ringA, ringB)
    stats[S_PEN] = rs[R_P] - p_from
    stats[S_ROCK_WORK] = racc[0] - work_rock_from
    stats[S_HORN_WORK] = work_horn - work_horn_from
    stats[S_STATUS] = status
    stats[S_EVENTS] = n_ev_total
    stats[S_STEPS] = n_steps
    return n_rec


def run_record(pv: np.ndarray, t_end: float, rec_every: int = 1):
    """One run with a record every ``rec_every`` steps: (stats, rec (n, N_REC))."""
    pv = np.ascontiguousarray(pv, dtype=np.float64)
    n_steps = int(math.ceil(t_end / pv[D_DT] - 1e-9))
    rec = np.zeros((n_steps // max(rec_every, 1) + 1, N_REC))
    stats = np.zeros(N_DSTATS)
    n = _core(pv, 0.0, float(t_end), stats, int(rec_every), rec)
    return stats, rec[:n]


@njit(cache=True, parallel=True)
def _ensemble(pmat, t_from, t_end, out):
    dummy = np.zeros((1, N_REC))
    for i in prange(pmat.shape[0]):
        _core(pmat[i], t_from, t_end, out[i], 0, dummy)


def ensemble(pmat: np.ndarray, t_from: float, t_end: float) -> np.ndarray:
    """Window statistics of many members in parallel, shape (n, N_DSTATS)."""
    pmat = np.ascontiguousarray(np.atleast_2d(pmat), dtype=np.float64)
    out = np.zeros((pmat.shape[0], N_DSTATS))
    _ensemble(pmat, float(t_from), float(t_end), out)
    return out
