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
* **contact** (the horn's contact closed): free mass, tool and modes integrated together by the
  error-controlled explicit Runge-Kutta scheme of order 8 of Dormand and Prince (DOP853, its
  5th- and 3rd-order error estimates), the contact force the root of ``d + g K d^p = D``
  (:func:`impact.compliant.approach_of`, compiled). The branch events of each contact (touch ``D = 0`` rising, peak
  ``D' = 0``, reload ``D = D_max``, separation ``D = 0`` falling) are located on the step's
  7th-order interpolant by the Illinois method; the step to the event is then taken, checked to
  end on its far side (else moved on by a Newton step on the interpolant's slope, or the
  Illinois method on whole steps), and the law switches there. The phase ends when both
  contacts are open again;
* **tool-only contact** (the tool's contact closed, the horn's open): no force acts on the
  modes, so they move in closed form as in a flight (:func:`tool_only`) and only the free mass
  and the tool are integrated, by the same steps and branch events on 4 states instead of
  4 + 2n; the horn's touch is watched at each step's end on the modes' closed form. Same model,
  same tolerance: about a third of the contact time costs a fraction of its steps' work.

Why order 8: a Hertz contact lasts ~15-40 us and its force is not smooth at touch (``d^1.5``);
at rtol 1e-10 the 5(4) pair needs ~110-150 steps per contact, DOP853 ~25-35 (each of 12 slopes),
with an error well inside the tolerance (the window's energy balance ~4e-11 of the drive work
against ~1.5e-10), and the interpolant spares the ~8 whole trial steps per event of a search on
the step length. The steps are set by the contact force, not by the modes: the count hardly
changes between 7 modes (40 kHz) and 26 (100 kHz).

A step takes one library cosine and sine of the drive's phase, at its start; its stages and the
interpolant's extra slopes turn that phase by their nodes' angles (:func:`turn`, exact to
round-off), so a slope costs no trigonometric call.

Compiled with numba's ``numpy`` error model (here and in :mod:`impact.kernel_drill_compliant`): a
float division by zero gives inf or nan instead of raising, so no division carries a test and an
exception path. The numbers are the same (no division here has a zero divisor); a contact slope
costs about half as much, and a member ~1.5x less.

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
from numba import njit, parallel_chunksize, prange
from scipy.integrate._ivp import dop853_coefficients as _dop853

from . import kernel_cache  # noqa: F401  (drops stale caches first)
from . import compliant
from .columns import (C_DAMP, C_DRIVE, C_ELEC, C_FUND_IM, C_FUND_RE, N_CSTATS, S_HORN_WORK, S_KE_AFTER, S_KE_GAIN,
                      S_N_EVENTS, S_N_HORN, S_N_TOOL, S_STATUS, S_T_ON_HORN, S_T_ON_TOOL, STATUS_CONTACT,
                      STATUS_MAX_EVENTS, STATUS_OK)
from .horn import (H_A, H_B, H_FC, H_FS, H_GIM, H_GRE, H_MASS, H_OMEGA, H_TIP, H_ZETA, X_QBI, X_QBR, X_RC, X_RS,
                   X_STEADY, X_UC, X_US,
                   X_V0, X_W)
from .kernel import P_C, P_G, P_GAP, P_K0, P_M_FREE, P_M_TOOL, P_SPRING_FORCE, P_V0
from .kernel_blocks import (C_A, C_L0, C_N, C_T0, C_UC, C_US, C_W, C_W0, C_WD0, FN_HORN, O_B0, O_B2, O_N, PL_ROWS,
                            earliest, grow2, horn_records, modal_at, osc_pv, plan_flight, tip, tool_osc)
from .kernel_energy import window_integrals

__all__ = ["N_KSTATS", "K_TOOL_DAMP", "K_LOSS", "K_STORED", "K_LEDGER", "LAW_N", "pack_laws", "run_contacts",
           "ensemble_rows", "LOG_N"]



@njit(cache=True, error_model="numpy", inline="always")
def _pw(x, p):
    """x^p (x >= 0), through the square root for the Hertz loading's p = 1.5 (a slope of a
    contact phase is mostly this power)."""
    if p == 1.5:
        return x * math.sqrt(x)
    return x ** p


approach_of = njit(cache=True, error_model="numpy")(compliant.approach_of)

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
#: the horn contact while a tool-only contact is integrated without the modes (:func:`tool_only`):
#: open, its touch watched on the modes' closed form by that phase instead of the branch events
AWAY = -1
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

#: the explicit Runge-Kutta scheme of order 8 of Dormand and Prince with its embedded 5th- and
#: 3rd-order error estimates (Hairer, Norsett & Wanner, Solving ODEs I, sec. II.10: DOP853), the
#: published tableau as scipy carries it. On a Hertz contact at rtol 1e-10 it takes ~4x fewer
#: steps than the 5(4) pair for the same tolerance, and its error is well inside it
R8_S = 12
R8_C = np.ascontiguousarray(_dop853.C[:R8_S])
R8_A = np.ascontiguousarray(_dop853.A[:R8_S, :R8_S])
R8_B = np.ascontiguousarray(_dop853.B[:R8_S])
R8_E5 = np.ascontiguousarray(_dop853.E5[:R8_S])
R8_E3 = np.ascontiguousarray(_dop853.E3[:R8_S])
#: its 7th-order interpolant: nodes and stages of the three extra slopes, and the weights of the
#: interpolant's four upper coefficients over the 16 slopes (the 12 stages, the end, the extra 3)
R8_CX = np.ascontiguousarray(_dop853.C[R8_S + 1:R8_S + 4])
R8_AX = np.ascontiguousarray(_dop853.A[R8_S + 1:R8_S + 4, :R8_S + 3])
R8_D = np.ascontiguousarray(_dop853.D[:, :R8_S + 4])


def pack_laws(horn_law, tool_law, horn_residual: float, rtol: float) -> np.ndarray:
    """The two :class:`impact.hertz.HertzLaw` s, the residual and the rtol as the kernel's ``LAW_N`` vector."""
    lw = np.zeros(LAW_N)
    for j, law in ((0, horn_law), (L_TOOL, tool_law)):
        lw[j + L_K], lw[j + L_P], lw[j + L_E] = law.stiffness, law.exponent, law.restitution
    lw[L_G], lw[L_RTOL] = horn_residual, rtol
    return lw


# ----------------------------------------------------------------------------- the contact law


@njit(cache=True, error_model="numpy")
def contact_force(D, state, K, p, g):
    """``(F, d)``: force (N) and Hertz approach (m) of a contact at total approach D (m)."""
    if state <= OPEN or D <= 0.0:
        return 0.0, 0.0
    d = approach_of(D, g * K, p)
    return K * _pw(d, p), d


@njit(cache=True, error_model="numpy")
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


@njit(cache=True, error_model="numpy")
def loss(k, e, d_max):
    """Energy lost in a contact whose largest Hertz approach was d_max (J, :meth:`HertzLaw.dissipated`)."""
    return (1.0 - e * e) * 0.4 * k * max(d_max, 0.0) ** 2.5


# ----------------------------------------------------------------------------- the contact phase


@njit(cache=True, error_model="numpy")
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


@njit(cache=True, error_model="numpy")
def approaches(t, y, n, tab, xs, L0):
    """``(D_h, D_h', D_t, D_t')``: total approaches at horn and tool (m) and their rates (m/s)."""
    u, ud = _tip_modal(t, y, n, tab, xs)
    return u - y[0], ud - y[1], y[0] - (L0 + y[2]), y[1] - y[3]


#: the contact phases' table of the modes: the horn's (:meth:`impact.horn.ModalHorn.pack`, 12
#: columns) and the right-hand side's products of them: 1 / m, 2 zeta omega, omega^2, the
#: current's G_im / W, the damping 2 zeta omega m
M_INVM, M_2ZO, M_OM2, M_GIMW, M_DAMP = range(12, 17)
M_N = 17


@njit(cache=True, error_model="numpy")
def rhs_table(tab, xs):
    """The modes' table of the contact phases (:data:`M_N` columns, the horn's first)."""
    n = tab.shape[0]
    mt = np.empty((n, M_N))
    mt[:, :12] = tab[:, :12]
    for i in range(n):
        om, ze, m = tab[i, H_OMEGA], tab[i, H_ZETA], tab[i, H_MASS]
        mt[i, M_INVM], mt[i, M_2ZO], mt[i, M_OM2] = 1.0 / m, 2.0 * ze * om, om * om
        mt[i, M_GIMW], mt[i, M_DAMP] = tab[i, H_GIM] / xs[X_W], 2.0 * ze * om * m
    return mt


@njit(cache=True, error_model="numpy", inline="always")
def modal_rates(y, out, n, mt, xs, co, si, Fh):
    """The modes' rates into ``out[4:4 + 2n]`` (``y = [.., .., .., .., q (n), q' (n), ..]``, the tip
    force ``Fh`` on them, ``co, si`` the drive's phase) and the power integrands they give:
    ``(drive power, modal damping power, the electrode current)``. Shared by every model with the
    FE horn's modes in its state."""
    W = xs[X_W]
    V, Vd = xs[X_V0] * si, xs[X_V0] * W * co
    cur = xs[X_QBR] * Vd - xs[X_QBI] * W * V
    drive = damp = 0.0
    for i in range(n):
        qv = y[4 + n + i]
        f = mt[i, H_FC] * co + mt[i, H_FS] * si
        acc = (f - mt[i, H_TIP] * Fh) * mt[i, M_INVM] - mt[i, M_2ZO] * qv - mt[i, M_OM2] * y[4 + i]
        out[4 + i], out[4 + n + i] = qv, acc
        drive += f * qv
        damp += mt[i, M_DAMP] * qv * qv
        cur += mt[i, H_GRE] * qv + mt[i, M_GIMW] * acc
    return drive, damp, cur


@njit(cache=True, error_model="numpy")
def contact_rhs(t, y, out, n, mt, xs, pv, lw, cs):
    """Right-hand side of a contact phase at t: :func:`slope` at the drive's phase ``W t``."""
    W = xs[X_W]
    slope(math.cos(W * t), math.sin(W * t), y, out, n, mt, xs, pv, lw, cs)


@njit(cache=True, error_model="numpy", inline="always")
def turn(co, si, x):
    """``(cos, sin)`` of the angle ``phi + x`` from ``co, si`` = cos, sin of ``phi``: the drive's
    phase at a step's stages from the phase at its start (one library cosine and sine a step
    instead of one a slope). x's own by their Taylor series through x^13 when ``|x| <= 0.3`` (the
    first term left out is below 6e-19, under round-off), else by the library."""
    if abs(x) <= 0.3:
        x2 = x * x
        c = 1.0 + x2 * (-1.0 / 2 + x2 * (1.0 / 24 + x2 * (-1.0 / 720 + x2 * (1.0 / 40320 + x2 * (
            -1.0 / 3628800 + x2 / 479001600)))))
        s = x * (1.0 + x2 * (-1.0 / 6 + x2 * (1.0 / 120 + x2 * (-1.0 / 5040 + x2 * (1.0 / 362880 + x2 * (
            -1.0 / 39916800 + x2 / 6227020800))))))
    else:
        c, s = math.cos(x), math.sin(x)
    return co * c - si * s, si * c + co * s


@njit(cache=True, error_model="numpy")
def slope(co, si, y, out, n, mt, xs, pv, lw, cs):
    """Right-hand side of a contact phase: ``y = [w, w', x, x', q, q', integrals (N_INT)]``
    (``mt`` the modes' table, :func:`rhs_table`; ``co, si`` the cosine and sine of the drive's
    phase)."""
    m_free, m_tool, k0, c = pv[P_M_FREE], pv[P_M_TOOL], pv[P_K0], pv[P_C]
    a = pv[P_G] - pv[P_SPRING_FORCE] / m_free
    g = lw[L_G]
    W = xs[X_W]
    r = xs[X_RC] * co + xs[X_RS] * si
    rd = W * (-xs[X_RC] * si + xs[X_RS] * co)
    um = umd = 0.0
    for i in range(n):
        um += mt[i, H_TIP] * y[4 + i]
        umd += mt[i, H_TIP] * y[4 + n + i]
    Fh = contact_force(um + r - y[0], cs[0, CS_STATE], cs[0, CS_K], cs[0, CS_P], g)[0]
    Ft = contact_force(y[0] - (pv[P_GAP] + y[2]), cs[1, CS_STATE], cs[1, CS_K], cs[1, CS_P], 0.0)[0]
    out[0], out[1] = y[1], a + (Fh - Ft) / m_free
    out[2], out[3] = y[3], (Ft - c * y[3] - k0 * y[2]) / m_tool
    V = xs[X_V0] * si
    drive, damp, cur = modal_rates(y, out, n, mt, xs, co, si, Fh)
    j = 4 + 2 * n
    u = um + r - g * Fh       # the tip recedes by g F_h
    out[j], out[j + 1], out[j + 2], out[j + 3] = drive + Fh * rd, damp, c * y[3] * y[3], Fh * (umd + rd)
    out[j + 4], out[j + 5], out[j + 6] = u * co, -u * si, V * cur


@njit(cache=True, error_model="numpy")
def _combine(y, h, st, row, k, out):
    """``out = y + h sum_q row[q] st[q]`` over the first k stages (zero weights skipped; the copy
    as a loop: a slice assignment costs about as much as the sums of a stage here)."""
    for j in range(y.size):
        out[j] = y[j]
    for q in range(k):
        cq = h * row[q]
        if cq != 0.0:
            for j in range(y.size):
                out[j] += cq * st[q, j]


@njit(cache=True, error_model="numpy")
def _step(t, y, h, n, tab, xs, pv, lw, cs, st, y8, tmp, fresh):
    """One step of the 8th-order Dormand-Prince scheme (:data:`R8_A`) of length h from (t, y) into
    y8 (the integrals restart from zero); ``st`` keeps the stages for the error estimate. The
    first stage, the slope at (t, y), is reused unless ``fresh``."""
    W = xs[X_W]
    co, si = math.cos(W * t), math.sin(W * t)
    if fresh:
        slope(co, si, y, st[0], n, tab, xs, pv, lw, cs)
    for k in range(1, R8_S):
        _combine(y, h, st, R8_A[k], k, tmp)
        ck, sk = turn(co, si, W * R8_C[k] * h)
        slope(ck, sk, tmp, st[k], n, tab, xs, pv, lw, cs)
    _combine(y, h, st, R8_B, R8_S, y8)


@njit(cache=True, error_model="numpy")
def _error(y, y8, st, h, atol, rtol):
    """The step's error over its tolerance ``atol + rtol |y|`` (Hairer's combination of the 5th-
    and 3rd-order estimates, in the largest component; the integrals follow the state and are not
    controlled apart)."""
    e5 = e3 = 0.0
    for j in range(atol.size):
        s5 = s3 = 0.0
        for q in range(R8_S):
            s5 += R8_E5[q] * st[q, j]
            s3 += R8_E3[q] * st[q, j]
        sc = atol[j] + rtol * max(abs(y[j]), abs(y8[j]))
        e5 = max(e5, abs(s5) / sc)
        e3 = max(e3, abs(s3) / sc)
    if e5 == 0.0:
        return 0.0
    return abs(h) * e5 * e5 / math.sqrt(e5 * e5 + 0.01 * e3 * e3)


@njit(cache=True, error_model="numpy")
def _triggers(state):
    """The two branch events a contact in ``state`` waits for (-1: none)."""
    if state == AWAY:
        return -1, -1
    if state == OPEN:
        return EV_TOUCH, -1
    if state == LOADING:
        return EV_PEAK, EV_SEPARATE
    return EV_RELOAD, EV_SEPARATE


@njit(cache=True, error_model="numpy")
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


@njit(cache=True, error_model="numpy")
def _phi_at(t, y, n, tab, xs, L0, cs, j, kind):
    Dh, Dhd, Dt, Dtd = approaches(t, y, n, tab, xs, L0)
    if j == 0:
        return _phi(kind, Dh, Dhd, cs[0, CS_TMAX])
    return _phi(kind, Dt, Dtd, cs[1, CS_TMAX])


@njit(cache=True, error_model="numpy")
def _dense(t, y, y8, h, n, tab, xs, pv, lw, cs, st, tmp, F):
    """The coefficients ``F`` (7, state) of the scheme's 7th-order interpolant over the step of
    length h from (t, y) that ended in y8 (its stages in ``st``): four more slopes, at the end and
    at the three extra nodes :data:`R8_CX`."""
    W = xs[X_W]
    co, si = math.cos(W * t), math.sin(W * t)
    ck, sk = turn(co, si, W * h)
    slope(ck, sk, y8, st[R8_S], n, tab, xs, pv, lw, cs)
    for s in range(R8_S + 1, R8_S + 4):
        _combine(y, h, st, R8_AX[s - R8_S - 1], s, tmp)
        ck, sk = turn(co, si, W * R8_CX[s - R8_S - 1] * h)
        slope(ck, sk, tmp, st[s], n, tab, xs, pv, lw, cs)
    for j in range(F.shape[1]):
        dy = y8[j] - y[j]
        F[0, j], F[1, j], F[2, j] = dy, h * st[0, j] - dy, 2.0 * dy - h * (st[R8_S, j] + st[0, j])
        for r in range(4):
            acc = 0.0
            for q in range(R8_S + 4):
                acc += R8_D[r, q] * st[q, j]
            F[3 + r, j] = h * acc


@njit(cache=True, error_model="numpy")
def _interpolate(y, F, x, out):
    """The state at the fraction x of the step from the interpolant's coefficients ``F``."""
    for j in range(F.shape[1]):
        v = F[6, j] * x
        for r in range(5, -1, -1):
            v = (v + F[r, j]) * (x if r % 2 == 0 else 1.0 - x)
        out[j] = y[j] + v


@njit(cache=True, error_model="numpy")
def _trial(t, y, x, dense, hh, j, kind, n, tab, xs, pv, lw, cs, st, y8, tmp, F):
    """The event function of ``kind`` (contact j) at the step length x: on the interpolant
    (``dense``, step length hh) or after one step of length x from (t, y) (left in y8)."""
    if dense:
        _interpolate(y, F, x / hh, tmp)
        return _phi_at(t + x, tmp, n, tab, xs, pv[P_GAP], cs, j, kind)
    _step(t, y, x, n, tab, xs, pv, lw, cs, st, y8, tmp, False)
    return _phi_at(t + x, y8, n, tab, xs, pv[P_GAP], cs, j, kind)


@njit(cache=True, error_model="numpy", inline="always")
def _illinois_point(lo, hi, f_lo, f_hi):
    """The Illinois method's next trial in (lo, hi): the secant, or the midpoint when it leaves the bracket."""
    x = hi - f_hi * (hi - lo) / (f_hi - f_lo)
    return x if lo < x < hi else 0.5 * (lo + hi)


@njit(cache=True, error_model="numpy", inline="always")
def _illinois_update(lo, hi, f_lo, f_hi, side, x, fx):
    """The bracket after the trial ``fx`` at x: ``(lo, hi, f_lo, f_hi, side, at)``, ``at`` whether x
    is its new far end; the kept end's value is halved when the same end moves twice running."""
    if fx > 0.0:
        return lo, x, (0.5 * f_lo if side == 1 else f_lo), fx, 1, True
    return x, hi, fx, (0.5 * f_hi if side == -1 else f_hi), -1, False


@njit(cache=True, error_model="numpy")
def _locate(t, y, lo, hi, f_lo, f_hi, dense, hh, j, kind, n, tab, xs, pv, lw, cs, st, y8, tmp, F):
    """Step length in (lo, hi] just past the event ``kind`` of contact j (its function rises
    through zero between f_lo <= 0 and f_hi > 0): the Illinois method, each trial on the
    interpolant (``dense``) or one step from (t, y). Returns ``(h, at)``: the far end of the final
    bracket (the event function positive there) and whether y8 holds the step to it."""
    side, at = 0, False
    for _ in range(100):
        if hi - lo <= 4e-16 * (abs(t) + hi):
            break
        x = _illinois_point(lo, hi, f_lo, f_hi)
        fx = _trial(t, y, x, dense, hh, j, kind, n, tab, xs, pv, lw, cs, st, y8, tmp, F)
        lo, hi, f_lo, f_hi, side, at = _illinois_update(lo, hi, f_lo, f_hi, side, x, fx)
    return hi, at and not dense


@njit(cache=True, error_model="numpy")
def _earliest_event(t, y, hh, n, tab, xs, pv, lw, cs, st, y8, tmp, F):
    """The earliest branch event in the step (t, t + hh] whose end is in y8: ``(found, h, j,
    kind)``, h the step length to take (the event just behind it); when found, y8 holds the step
    to it. Each crossing is found on the step's interpolant, then the step to it is checked
    (and, should the event still lie ahead, the bracket closed by steps from (t, y))."""
    L0 = pv[P_GAP]
    best, bj, bk, f_best = hh, -1, -1, 0.0
    f_end = np.empty(4)
    for j in range(2):
        k1, k2 = _triggers(cs[j, CS_STATE])
        for i, kind in enumerate((k1, k2)):
            f_end[2 * j + i] = _phi_at(t + hh, y8, n, tab, xs, L0, cs, j, kind) if kind >= 0 else -1.0
    have_dense = False
    for j in range(2):
        k1, k2 = _triggers(cs[j, CS_STATE])
        for i, kind in enumerate((k1, k2)):
            if kind < 0 or not f_end[2 * j + i] > 0.0:
                continue
            f0 = _phi_at(t, y, n, tab, xs, L0, cs, j, kind)
            if f0 > 0.0:
                continue                      # already past it at the step's start: no crossing
            if not have_dense:
                _dense(t, y, y8, hh, n, tab, xs, pv, lw, cs, st, tmp, F)
                have_dense = True
            h = _locate(t, y, 0.0, hh, f0, f_end[2 * j + i], True, hh, j, kind, n, tab, xs, pv, lw, cs, st, y8,
                        tmp, F)[0]
            if bj < 0 or h < best:
                best, bj, bk, f_best = h, j, kind, f_end[2 * j + i]
    if bj < 0:
        return False, hh, -1, -1
    f = _trial(t, y, best, False, hh, bj, bk, n, tab, xs, pv, lw, cs, st, y8, tmp, F)
    lo, f_lo = best, f
    for _ in range(4):
        if f > 0.0:
            return True, best, bj, bk
        # the interpolant's error left the event a little ahead: a Newton step on its slope
        # there, overshooting twice
        a, b = max(best - 1e-3 * hh, 0.0), min(best + 1e-3 * hh, hh)
        s = (_trial(t, y, b, True, hh, bj, bk, n, tab, xs, pv, lw, cs, st, y8, tmp, F)
             - _trial(t, y, a, True, hh, bj, bk, n, tab, xs, pv, lw, cs, st, y8, tmp, F)) / (b - a)
        if not s > 0.0:
            break
        lo, f_lo = best, f
        best = min(best - 2.0 * f / s, hh)
        f = _trial(t, y, best, False, hh, bj, bk, n, tab, xs, pv, lw, cs, st, y8, tmp, F)
    if f > 0.0:
        return True, best, bj, bk
    best, at = _locate(t, y, best, hh, f, f_best, False, hh, bj, bk, n, tab, xs, pv, lw, cs, st, y8, tmp, F)
    if not at:
        _step(t, y, best, n, tab, xs, pv, lw, cs, st, y8, tmp, False)
    return True, best, bj, bk


# ----------------------------------------------------------------------------- branch switches


@njit(cache=True, error_model="numpy")
def touch(cs, j, lw, t, Dd, xd, horn_work):
    """Contact j closes at t: Hertz loading from its approach speed Dd (m/s)."""
    cs[j, CS_STATE], cs[j, CS_T0], cs[j, CS_VIN] = LOADING, t, Dd
    cs[j, CS_K], cs[j, CS_P] = lw[L_TOOL * j + L_K], 1.5
    cs[j, CS_DMAX] = cs[j, CS_TMAX] = cs[j, CS_PEAK] = 0.0
    cs[j, CS_XD0], cs[j, CS_WORK0] = xd, horn_work


@njit(cache=True, error_model="numpy")
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


@njit(cache=True, error_model="numpy")
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


@njit(cache=True, error_model="numpy")
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


@njit(cache=True, error_model="numpy")
def _accept(y, y8, n, acc):
    """Take the step: the state moves on, the integrals' increments go into ``acc`` (from t = 0)."""
    j = 4 + 2 * n
    acc[C_DRIVE] += y8[j]
    acc[C_DAMP] += y8[j + 1]
    acc[K_TOOL_DAMP] += y8[j + 2]
    acc[S_HORN_WORK] += y8[j + 3]
    acc[C_FUND_RE] += y8[j + 4]
    acc[C_FUND_IM] += y8[j + 5]
    acc[C_ELEC] += y8[j + 6]
    for i in range(j):
        y[i] = y8[i]


# ----------------------------------------------------------------------------- the two phases


@njit(cache=True, error_model="numpy", inline="always")
def _control(err, hh, h, rejected):
    """The step controller after a trial step of length hh whose error over its tolerance is err:
    ``(accept, h, grow, rejected)``: on rejection the next trial length h, else the growth factor
    for the next step (none right after a rejection: no cycling)."""
    grow = min(6.0, max(0.2, 0.9 * max(err, 1e-30) ** -0.125))
    if err > 1.0 and hh > 1e-18:
        return False, hh * grow, grow, True
    if rejected:
        grow = min(grow, 1.0)
    return True, h, grow, False


@njit(cache=True, error_model="numpy")
def _horn_gap(tt, w, cp, tab, ho, n):
    """The horn contact's total approach at tt from the modes' closed form (the tool-only phase)."""
    return tip(tt, cp, tab, ho, n, 0)[0] - w


@njit(cache=True, error_model="numpy")
def _horn_touch(t, y, hh, f_hi, n, tab, xs, pv, lw, cs, st, y8, tmp, cp, ho):
    """Step length in (0, hh] just past the horn's touch in a tool-only step (its approach ``f_hi``
    > 0 at hh, <= 0 at t): the Illinois method on whole steps of the few integrated states (cheap
    there), the modes' tip in closed form. y8 holds the step to the returned length."""
    empty = tab[:0]
    lo, hi, f_lo = 0.0, hh, _horn_gap(t, y[0], cp, tab, ho, n)
    side, at = 0, True
    for _ in range(100):
        if hi - lo <= 4e-16 * (abs(t) + hi):
            break
        x = _illinois_point(lo, hi, f_lo, f_hi)
        _step(t, y, x, 0, empty, xs, pv, lw, cs, st, y8, tmp, False)
        fx = _horn_gap(t + x, y8[0], cp, tab, ho, n)
        lo, hi, f_lo, f_hi, side, at = _illinois_update(lo, hi, f_lo, f_hi, side, x, fx)
    if not at:
        _step(t, y, hi, 0, empty, xs, pv, lw, cs, st, y8, tmp, False)
    return hi


@njit(cache=True, error_model="numpy")
def tool_only(t, t_stop, y, h, n, tab, xs, pv, lw, cs, atol, acc, out, t_from, t_end, log, n_log, record, n_ev, tw):
    """The tool's contact closed, the horn's open: the horn's modes are then free damped oscillators
    under the drive (no force on them), so only the free mass and the tool are integrated (the
    same steps, error control and branch events as :func:`contact_phase`, on 4 states instead of
    4 + 2n) and the modes, the drive's work, the modal damping and the fundamental and electrical
    integrals follow in closed form (:func:`impact.kernel_blocks.modal_at`,
    :func:`impact.kernel_energy.window_integrals`, as in a flight). The horn's touch is watched at
    every step's end on the modes' closed form and located by :func:`_horn_touch`. Runs to the
    tool's separation, the horn's touch (which it applies) or ``t_stop``; ``y`` holds the whole
    state at the end. Returns as :func:`contact_phase`."""
    yr, wr, ho, cp, cw, lam, G = tw
    st, y8, tmp, F = wr[:R8_S + 4], wr[R8_S + 4], wr[R8_S + 5], wr[R8_S + 6:, :4]
    empty = tab[:0]
    rtol = lw[L_RTOL]
    W = xs[X_W]
    q, qd = y[4:4 + n], y[4 + n:4 + 2 * n]
    t_s = t
    horn_records(ho, tab, n, W, t, q, qd)
    cp[C_T0] = t
    yr[:4] = y[:4]
    yr[4:] = 0.0
    cs[0, CS_STATE] = AWAY
    steps, ok, horn = 0, True, False
    fresh, rejected = True, False
    while t < t_stop and cs[1, CS_STATE] != OPEN:
        steps += 1
        if steps > _MAX_STEPS:
            ok = False
            break
        hh = min(h, t_stop - t)
        _step(t, yr, hh, 0, empty, xs, pv, lw, cs, st, y8, tmp, fresh)
        fresh = False
        accept, h, grow, rejected = _control(_error(yr, y8, st, hh, atol[:4], rtol), hh, h, rejected)
        if not accept:
            continue
        found, he, j, kind = _earliest_event(t, yr, hh, 0, empty, xs, pv, lw, cs, st, y8, tmp, F)
        if found:
            hh = he
        f_h = _horn_gap(t + hh, y8[0], cp, tab, ho, n)
        if f_h > 0.0:
            hh = _horn_touch(t, yr, hh, f_h, n, tab, xs, pv, lw, cs, st, y8, tmp, cp, ho)
            found, horn = True, True
        acc[K_TOOL_DAMP] += y8[6]
        for i in range(4):
            yr[i] = y8[i]
        t += hh
        fresh = True
        if not found:
            h = hh * grow if hh >= h else max(h, hh * grow)
        elif horn:
            break
        else:
            Dt, Dtd = yr[0] - (pv[P_GAP] + yr[2]), yr[1] - yr[3]
            if kind == EV_SEPARATE:
                log, n_log = _separate(cs, 1, lw, t, Dtd, yr, pv[P_M_TOOL], acc, out, t_from, t_end, log, n_log,
                                       record)
                n_ev += 1
            else:
                _law_branch(cs, 1, lw, kind, Dt)
    window_integrals(tab, xs, n, t_s, t, q, qd, 0.0, math.inf, acc, lam, G, G, cw)
    modal_at(ho, tab, n, W, t_s, t, q, qd)
    y[:4] = yr[:4]
    cs[0, CS_STATE] = OPEN
    if horn:
        Dh, Dhd, _, _ = approaches(t, y, n, tab, xs, pv[P_GAP])
        touch(cs, 0, lw, t, Dhd, y[3], acc[S_HORN_WORK])
    return t, h, log, n_log, n_ev, ok


@njit(cache=True, error_model="numpy")
def contact_phase(t, t_stop, y, h, n, tab, xs, pv, lw, cs, atol, wk, acc, out, t_from, t_end, log, n_log, record,
                  n_ev, tw):
    """Integrate while a contact is closed, to the phase's end (both open) or ``t_stop``: error-
    controlled steps, each cut at its earliest branch event; the stretches where only the tool's
    contact is closed by :func:`tool_only` (``tw`` its work arrays). Returns (t, h, log, n_log,
    n_ev, ok); ok False if the phase took more than ``_MAX_STEPS`` steps."""
    st, y8, tmp, F = wk[:R8_S + 4], wk[R8_S + 4], wk[R8_S + 5], wk[R8_S + 6:, :4 + 2 * n]
    rtol = lw[L_RTOL]
    steps = 0
    fresh, rejected = True, False
    while t < t_stop and (cs[0, CS_STATE] != OPEN or cs[1, CS_STATE] != OPEN):
        if cs[0, CS_STATE] == OPEN:
            t, h, log, n_log, n_ev, ok = tool_only(t, t_stop, y, h, n, tab, xs, pv, lw, cs, atol, acc, out, t_from,
                                                   t_end, log, n_log, record, n_ev, tw)
            if not ok:
                return t, h, log, n_log, n_ev, False
            fresh = True
            continue
        steps += 1
        if steps > _MAX_STEPS:
            return t, h, log, n_log, n_ev, False
        hh = min(h, t_stop - t)
        _step(t, y, hh, n, tab, xs, pv, lw, cs, st, y8, tmp, fresh)
        fresh = False
        accept, h, grow, rejected = _control(_error(y, y8, st, hh, atol, rtol), hh, h, rejected)
        if not accept:
            continue
        found, he, j, kind = _earliest_event(t, y, hh, n, tab, xs, pv, lw, cs, st, y8, tmp, F)
        if found:
            hh = he
        _accept(y, y8, n, acc)
        t += hh
        fresh = True
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


@njit(cache=True, error_model="numpy")
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


@njit(cache=True, error_model="numpy")
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


@njit(cache=True, error_model="numpy")
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


@njit(cache=True, error_model="numpy")
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


@njit(cache=True, error_model="numpy")
def _core(pv, lw, tab, xs, t_from, t_end, max_events, record, out):
    """One run: flights and contact phases in turn, the window [t_from, t_end] marked. Returns
    (log, n_log, y, t, status, E0, acc) with ``acc`` the integrals from t = 0."""
    n = tab.shape[0]
    m = 4 + 2 * n + N_INT
    y, wk = np.zeros(m), np.empty((R8_S + 13, m))
    cs, acc, acc0 = np.zeros((2, CS_N)), np.zeros(N_KSTATS), np.zeros(N_KSTATS)
    fw = (np.empty(O_N), np.empty((n, O_N)), np.empty((PL_ROWS, 5)), np.empty((128, 6)), np.zeros(C_N))
    cp = fw[4]
    a = pv[P_G] - pv[P_SPRING_FORCE] / pv[P_M_FREE]
    cp[C_A], cp[C_L0], cp[C_W], cp[C_UC], cp[C_US] = a, pv[P_GAP], xs[X_W], xs[X_UC], xs[X_US]
    cw, lam = np.empty(n + 1, np.complex128), np.zeros(1, np.complex128)
    G = np.zeros((4, 1, 1), np.complex128)
    log = np.empty((64 if record else 1, LOG_N))
    atol = _tolerances(tab, n, lw[L_RTOL])
    mt = rhs_table(tab, xs)
    tw = (np.zeros(4 + N_INT), np.empty((R8_S + 13, 4 + N_INT)), fw[1], cp, cw, lam, G)
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
            t, h, log, n_log, n_ev, ok = contact_phase(t, t_stop, y, h, n, mt, xs, pv, lw, cs, atol, wk, acc, out,
                                                       t_from, t_end, log, n_log, record, n_ev, tw)
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


@njit(cache=True, error_model="numpy")
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


# nogil: the pipeline runs the compliant ensembles in a worker thread beside its other stages;
# holding the GIL here would stall them for the whole call (the omp threading layer is thread-safe)
@njit(cache=True, error_model="numpy", parallel=True, nogil=True)
def _ensemble(pmat, lmat, tab, xs, t_from, t_end, max_events, out):
    for i in prange(pmat.shape[0]):
        _core(pmat[i], lmat[i], tab, xs, t_from, t_end, max_events, False, out[i])


def ensemble_rows(pmat: np.ndarray, laws: np.ndarray, tab: np.ndarray, xs: np.ndarray, t_from: float, t_end: float,
                  max_events: int) -> np.ndarray:
    """Window statistics (n_members, ``N_KSTATS``) of many runs in parallel (members differ in the
    packed parameter rows ``pmat``, :func:`impact.kernel.pack`, and in their laws when ``laws`` has
    one :func:`pack_laws` row per member). The members go to the threads one at a time (a member
    costs from ~10 to ~100 ms: equal shares of the rows would leave a core idle); each row is
    computed alone, so the rows do not depend on the threads."""
    pmat = np.ascontiguousarray(np.atleast_2d(pmat), dtype=np.float64)
    lmat = np.ascontiguousarray(np.broadcast_to(np.asarray(laws, dtype=np.float64), (pmat.shape[0], LAW_N)))
    out = np.zeros((pmat.shape[0], N_KSTATS))
    with parallel_chunksize(1):
        _ensemble(pmat, lmat, np.ascontiguousarray(tab), xs, float(t_from), float(t_end), int(max_events), out)
    return out


#: the DOP853 pieces :mod:`impact.kernel_drill_compliant` builds its steps and events from
combine, step_error, law_branch, tip_modal, tolerances = _combine, _error, _law_branch, _tip_modal, _tolerances
