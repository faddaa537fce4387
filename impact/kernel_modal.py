"""Compiled event kernel of the coupled model (modal horn; numba).

The algorithm of :class:`impact.reference.modal.ModalEngine` (read :mod:`impact.coupled` for the
model) as one loop, :func:`_core`, on the building blocks of :mod:`impact.kernel_blocks` shared
with the kinematic kernel: plan the contact functions of the segment, find the earliest root,
apply the law (Newton's at the modal horn or at the tool, a release, or the compliant contact of
:mod:`impact.kernel_contact`), record. The horn tip is ``u = Uc cos Wt + Us sin Wt + sum_i s_i
h_i(t - t0)``, each ``h_i`` the free oscillation of mode i over the current segment (an oscillator
record of :mod:`impact.kernel_blocks`).

Entry points: :func:`run_events` (one run, every event and segment) and
:func:`ensemble_coupled` (window statistics of many members in parallel, the columns of
:func:`impact.kernel.ensemble_stats` followed by ``C_DRIVE`` (work of the drive on the modes and
the residual, J), ``C_DAMP`` (modal damping loss, J), ``C_FUND_RE``/``C_FUND_IM``
(``int u e^{-jWt} dt`` over the window, m s), ``C_ELEC`` (electrical energy drawn ``int V I dt``,
J): closed-form integrals per segment, :mod:`impact.kernel_energy`) and ``C_SOURCE_LOSS``
(resistor and dielectric loss of a series-resistance drive, J; 0 with the voltage drive).

With a series-resistance drive (``X_SERIES``, :mod:`impact.drive`) the rows of the table are
pseudo-modes: an impulse jumps both a row's coordinate and its velocity (columns ``H_JQ``,
``H_JV``), and the energy integrals are quadratic forms over every pair of rows
(:func:`impact.kernel_energy.segment_energy_series`): ``C_ELEC`` the source's work, ``C_DRIVE``
the conversion to mechanics, ``C_DAMP`` the modal damping, ``C_SOURCE_LOSS`` the resistor and
dielectric loss.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .columns import (BODY_HORN, BODY_TOOL, C_DAMP, C_DRIVE, C_ELEC, C_FUND_IM, C_FUND_RE, C_SOURCE_LOSS,
                      FREE, KIND_HORN, KIND_TOOL, N_CSTATS, ON_HORN, ON_TOOL, STATUS_CONTACT, STATUS_OK, STATUS_PINCHED)
from .horn import H_A, H_B, H_JV, H_MASS, H_TIP, X_RC, X_RS, X_SERIES, X_STEADY, X_UC, X_US, X_W, ModalHorn
from .kernel import (N_PARAMS, P_C, P_E1, P_E2, P_G, P_GAP, P_K0, P_M_FREE, P_M_TOOL, P_SPRING_FORCE, P_V0,
                     P_V_STICK, pack)
from .kernel_blocks import (event_status, free_mass_at, horn_records, modal_at, C_A, C_L0, C_N, C_T0, C_UC, C_US, C_W,
                            C_W0, C_WD0, E_N, FN_HORN, FN_HREL, FN_RELEASE, O_B0, O_B2, O_N, PL_ROWS, count_impact,
                            close_run, close_stick, earliest, grid_step, horn_impact_modal, mech_energy, osc_pv,
                            plan_add, plan_flight, plan_on_tool, plan_pinch, record_event, record_segment, sticks, tip,
                            tool_event, tool_osc)
from .kernel_contact import hc_contact
from .kernel_energy import window_integrals
from .params import ImpactParams

__all__ = ["run_events", "ensemble_coupled", "warmup", "N_CSTATS", "STATUS_CONTACT", "C_DRIVE", "C_DAMP",
           "C_FUND_RE", "C_FUND_IM", "C_ELEC", "C_SOURCE_LOSS"]


# ----------------------------------------------------------------------------- the modal horn


@njit(cache=True)
def _tip_velocity(tt, xs, tab, n, qd):
    """Tip velocity (m/s) from the modal velocities and the residual's driven motion at tt."""
    W, Rc, Rs = xs[X_W], xs[X_RC], xs[X_RS]
    c_ = math.cos(W * tt)
    s_ = math.sin(W * tt)
    ua = W * (-Rc * s_ + Rs * c_)
    for i in range(n):
        ua += tab[i, H_TIP] * qd[i]
    return ua


@njit(cache=True)
def _inverse_tip_mass(tab, n, series):
    """``Sg``: the tip's inverse effective mass (1/kg), the sum of ``s_i^2 / m_i`` (with a series
    drive, of the pseudo-modes' velocity jumps per impulse)."""
    Sg = 0.0
    for i in range(n):
        if series:
            Sg -= tab[i, H_TIP] * tab[i, H_JV]
        else:
            Sg += tab[i, H_TIP] * tab[i, H_TIP] / tab[i, H_MASS]
    return Sg


@njit(cache=True)
def _initial_modes(tab, xs, n, q, qd):
    """Modal state at t = 0: the steady state, or at rest."""
    steady = xs[X_STEADY] == 1.0
    for i in range(n):
        if steady:
            q[i] = tab[i, H_A]
            qd[i] = xs[X_W] * tab[i, H_B]
        else:
            q[i] = 0.0
            qd[i] = 0.0


@njit(cache=True)
def _plan_modal(plan, mode, o, t0, w0, wd0, a, L0, B0, B2, B4, Bh, skip_h, skip_t, t_end):
    """The contact functions of one segment with the modal horn (tip bounds B0, B2, B4 on |u|,
    |u''|, |u''''|): the flight's horn and tool contacts, or, riding the horn, the pinch and the
    release ``u'' - a``, or, riding the tool, its pinch and release."""
    if mode == FREE:
        return plan_flight(plan, 0, t0, w0, wd0, a, L0, B0, o[O_B0], skip_h, skip_t, Bh, o[O_B2] + abs(a), t_end)
    if mode == ON_HORN:
        nf = plan_pinch(plan, 0, o, L0, B0, B2, max(t0, skip_t), t_end)
        return plan_add(plan, nf, FN_HREL, B4, t0, grid_step(B4, t_end, 1e-3 * (abs(a) + B2)), math.inf)
    return plan_on_tool(plan, 0, o, L0, a, B0, B2, t0, t_end)


@njit(cache=True)
def _riding_work(m_free, a, wd, w, stick_E):
    """Work of the tip on a free mass riding it, from the stick's start (its energy stick_E) (J)."""
    return (0.5 * m_free * wd * wd - m_free * a * w) - stick_E


@njit(cache=True)
def _horn_event(te, x, wd, uhd, cp, tab, ho, n, xs, e2, m_free, a, v_stick, Sg, series, q, qd, t_from, t_end, stats,
                mode, stick_start, stick_E, skip_rel):
    """A Newton impact on the modal horn at te (:func:`impact.kernel_blocks.horn_impact_modal`, the
    modes updated in place), the source's work through the residual, then the sticking rule.
    Returns (J, w+, u'+, mode, stick_start, stick_E, skip_rel)."""
    J, wa, ua = horn_impact_modal(e2, m_free, Sg, series, tab, n, q, qd, wd, uhd)
    if te >= t_from and te <= t_end:
        # the residual is a driven displacement: the source does its work on the free mass
        W = xs[X_W]
        stats[C_DRIVE] += J * W * (-xs[X_RC] * math.sin(W * te) + xs[X_RS] * math.cos(W * te))
    if sticks(wa - ua, tip(te, cp, tab, ho, n, 2)[0] - a, v_stick):
        wa = ua
        return J, wa, ua, ON_HORN, te, 0.5 * m_free * wa * wa - m_free * a * x, skip_rel
    return J, wa, ua, mode, stick_start, stick_E, 2.0 * (wa - ua)


# ----------------------------------------------------------------------------- the event loop


@njit(cache=True)
def _core(pv, tab, xs, hc, t_end, max_events, record, t_from, stats, lam, G1, G2):
    """One run: plan the contacts of the segment -> earliest root -> apply the law -> record, with
    the segment's window integrals. ``hc``: (stiffness, chi) of a compliant horn contact, (0, 0)
    for Newton's law."""
    m_free, e1, e2 = pv[P_M_FREE], pv[P_E1], pv[P_E2]
    m_tool, k0, c, L0 = pv[P_M_TOOL], pv[P_K0], pv[P_C], pv[P_GAP]
    v_stick = pv[P_V_STICK]
    a = pv[P_G] - pv[P_SPRING_FORCE] / m_free
    n = tab.shape[0]
    W = xs[X_W]
    Ua = math.hypot(xs[X_UC], xs[X_US])
    series = xs[X_SERIES] == 1.0
    Sg = _inverse_tip_mass(tab, n, series)
    cw = np.empty(n + 1, np.complex128)
    cap = 1024 if record else 1
    ev, kinds = np.empty((cap, E_N + 3)), np.empty(cap, np.int8)
    segs, stk = np.empty((cap, 6 + 2 * n)), np.empty((cap, 3))
    n_rec = n_seg = n_stk = 0
    o, o2, ho = np.empty(O_N), np.empty(O_N), np.empty((n, O_N))
    plan, stack = np.empty((PL_ROWS, 5)), np.empty((128, 6))
    cp = np.zeros(C_N)
    cp[C_A], cp[C_L0], cp[C_W], cp[C_UC], cp[C_US] = a, L0, W, xs[X_UC], xs[X_US]
    q, qd = np.empty(n), np.empty(n)
    stats[:] = 0.0
    w_from = w_last = 0.0
    _initial_modes(tab, xs, n, q, qd)
    horn_records(ho, tab, n, W, 0.0, q, qd)
    u0, ud0 = tip(0.0, cp, tab, ho, n, 0)
    t, mode, w, wd, v, vd = 0.0, FREE, u0, ud0 + pv[P_V0], 0.0, 0.0
    skip_rel = 2.0 * pv[P_V0]     # skip_h = t0 + skip_rel / Bh of the next segment
    skip_h = skip_t = 0.0
    E0 = mech_energy(m_free, m_tool, k0, a, w, wd, v, vd)
    work = stick_start = stick_E = 0.0
    n_ev = 0
    status, t_status = STATUS_OK, 0.0
    while t < t_end:
        # plan the contacts of this segment
        tool_osc(o, mode == ON_TOOL, m_tool, m_free, k0, c, a, v, vd)
        hb0, hb2, hb4 = horn_records(ho, tab, n, W, t, q, qd)
        B0, B2 = Ua + hb0, Ua * W * W + hb2
        Bh = abs(a) + B2
        if skip_rel > 0.0:
            skip_h = t + skip_rel / Bh
            skip_rel = 0.0
        if record:
            segs = record_segment(segs, n_seg, t, mode, w, wd, v, vd)
            segs[n_seg, 6:6 + n] = q
            segs[n_seg, 6 + n:6 + 2 * n] = qd
            n_seg += 1
        t0, w0, wd0 = t, w, wd
        cp[C_T0], cp[C_W0], cp[C_WD0] = t0, w0, wd0
        nf = _plan_modal(plan, mode, o, t0, w0, wd0, a, L0, B0, B2, Ua * W * W * W * W + hb4, Bh, skip_h, skip_t,
                         t_end)
        # earliest root
        have, te, name = earliest(plan, nf, t_end, cp, o, tab, ho, n, stack)
        if not have:
            # the last segment runs to t_end: its share of the window integrals
            window_integrals(tab, xs, n, t0, t_end, q, qd, t_from, t_end, stats, lam, G1, G2, cw)
            break
        status, n_ev = event_status(name, n_ev, max_events)
        if status != STATUS_OK:
            t_status = te
            break
        # the state at the event
        window_integrals(tab, xs, n, t0, te, q, qd, t_from, t_end, stats, lam, G1, G2, cw)
        s = te - t0
        v, vd = osc_pv(o, s)
        modal_at(ho, tab, n, W, t0, te, q, qd)
        uh, uhd = tip(te, cp, tab, ho, n, 0)
        w, wd = free_mass_at(mode, s, w0, wd0, a, L0, uh, uhd, v, vd)
        t = te
        if L0 + v <= 2.0 * B0:
            status, t_status = STATUS_PINCHED, te
            break
        # apply the law
        if name == FN_HREL or name == FN_RELEASE:
            body = BODY_HORN if name == FN_HREL else BODY_TOOL
            if name == FN_HREL:
                # the horn did the work that moved the riding mass (its reaction on the modes is neglected)
                work += _riding_work(m_free, a, wd, w, stick_E)
            skip_h, skip_t = te, te
            stk, n_stk = close_stick(stk, n_stk, record, stats, body, stick_start, te, t_from, t_end)
            mode = FREE
            continue
        if name == FN_HORN and hc[0] > 0.0:
            # compliant contact (Hunt-Crossley): integrated until the penetration is gone
            kind, x, wb, ub = KIND_HORN, uh, wd, uhd
            t1, w1, wd1, J, diss, ok = hc_contact(te, w, wd, q, qd, tab, xs, n, hc[0], hc[1], m_free, a,
                                                  uhd - wd, t_end, t_from, stats)
            if not ok:
                status, t_status = STATUS_CONTACT, te
                break
            work += (0.5 * m_free * wd1 * wd1 - m_free * a * w1) - (0.5 * m_free * wd * wd - m_free * a * w) + diss
            v, vd = osc_pv(o, t1 - t0)
            t, w, wd, wa = t1, w1, wd1, wd1
            ua = _tip_velocity(t1, xs, tab, n, qd)
            skip_rel = 2.0 * max(wd1 - ua, 0.0)
            skip_t = t1
            vb, va = vd, vd
        elif name == FN_HORN:
            kind, x, wb, vb, va, ub = KIND_HORN, uh, wd, vd, vd, uhd
            J, wa, ua, mode, stick_start, stick_E, skip_rel = _horn_event(
                te, x, wd, uhd, cp, tab, ho, n, xs, e2, m_free, a, v_stick, Sg, series, q, qd, t_from, t_end, stats,
                mode, stick_start, stick_E, skip_rel)
            work += J * 0.5 * (uhd + ua)
            skip_t = te
            w, wd = x, wa
        else:
            kind, x, vb, wb, ub, ua = KIND_TOOL, L0 + v, vd, wd, uhd, uhd
            va, wa, mode, stick_start, skip_h, skip_t = tool_event(o2, te, m_free, m_tool, e1, c, k0, a, v_stick, v, vd,
                                                                   wd, mode, stick_start, skip_h, skip_t)
            J = m_free * (wa - wd)
            w, wd, vd = x, wa, va
        # record
        if record:
            ev, kinds = record_event(ev, kinds, n_rec, kind, te, x, wb, wa, vb, va,
                                     mech_energy(m_free, m_tool, k0, a, w, wd, v, vd), work)
            ev[n_rec, 8], ev[n_rec, 9], ev[n_rec, 10] = J, ub, ua
            n_rec += 1
        w_from, w_last = count_impact(stats, te, t_from, t_end, kind, m_tool, vb, va, work, w_from), work
    stk, n_stk = close_run(stk, n_stk, record, stats, status, mode, stick_start, t_from, t_end, w_last - w_from, n_ev)
    return ev, kinds, n_rec, segs, n_seg, stk, n_stk, E0, status, t_status, n_ev


def _hc_array(contact) -> np.ndarray:
    """(k, chi) of a compliant contact, (0, 0) for Newton's law."""
    if contact is None:
        return np.zeros(2)
    return np.array([float(contact.stiffness), float(contact.chi)])


def _kernel_data(horn: ModalHorn, freq_hz: float):
    """``(tab, xs, lam, G1, G2)``: the packed horn and, with a series-resistance drive, the tables of
    its closed-form energy integrals (:meth:`impact.drive.SeriesModel.kernel_tables`; one-element
    placeholders with the voltage drive)."""
    if horn.series_resistance > 0:
        from .drive import pack_series, series_model

        model = series_model(horn, freq_hz)
        tab, xs = pack_series(horn, model)
        lam, G1, G2 = model.kernel_tables(horn)
        return np.ascontiguousarray(tab), xs, lam, G1, G2
    tab, xs = horn.pack(freq_hz)
    return np.ascontiguousarray(tab), xs, np.zeros(1, complex), np.zeros((4, 1, 1), complex), np.zeros((4, 1, 1), complex)


def run_events(params: ImpactParams, horn: ModalHorn, contact=None) -> tuple:
    """One coupled run (compiled): every event and segment.

    ``contact``: an :class:`impact.contact.HuntCrossley` for compliant horn contacts (integrated
    by an adaptive Dormand-Prince 5(4) scheme, rtol 1e-10, separation located by bisection of the
    step), or None (Newton's law). With a compliant contact the segments cover the free phases only.

    Returns
    -------
    tuple
        ``(ev, kinds, segs, stick, E0, status, t_status, n_events, window)``: ``ev`` (k, 11) columns
        t, x, w_before, w_after, v_before, v_after, energy, cumulative horn work, impulse on the free
        mass, tip velocity before / after (SI); ``kinds`` (k,) int8 ``KIND_*``; ``segs`` (s, 6 + 2n)
        segment starts: t, mode, w, w', v, v', then the n modal coordinates and n modal velocities;
        ``stick`` (p, 3): start, end, ``BODY_*``; initial energy (J); ``STATUS_*`` and its time (s);
        number of events; ``window`` the whole run's statistics row (``N_CSTATS``).
    """
    tab, xs, lam, G1, G2 = _kernel_data(horn, params.freq)
    stats = np.zeros(N_CSTATS)
    ev, kinds, nr, segs, ns, stk, nk, E0, status, t_status, n_ev = _core(
        pack(params), tab, xs, _hc_array(contact), float(params.t_end), int(params.max_events), True, 0.0, stats,
        lam, G1, G2)
    return (ev[:nr].copy(), kinds[:nr].copy(), segs[:ns].copy(), stk[:nk].copy(), float(E0), int(status),
            float(t_status), int(n_ev), stats)


@njit(cache=True, parallel=True)
def _ensemble(pmat, tab, xs, hc, t_from, t_end, max_events, out, lam, G1, G2):
    for i in prange(pmat.shape[0]):
        _core(pmat[i], tab, xs, hc, t_end, max_events, False, t_from, out[i], lam, G1, G2)


def ensemble_coupled(pmat: np.ndarray, horn: ModalHorn, freq_hz: float, t_from: float, t_end: float,
                     max_events: int, contact=None) -> np.ndarray:
    """Window statistics of many coupled runs (one horn, members differ in ``pmat`` rows).

    Parameters
    ----------
    pmat : ndarray (n_members, N_PARAMS)
        Packed impact parameters (:func:`impact.kernel.pack`); their ``freq`` must equal ``freq_hz``.
    horn : ModalHorn
    freq_hz : float
        Drive frequency, Hz.
    t_from, t_end : float
        Window, s.
    max_events : int
    contact : impact.contact.HuntCrossley, optional
        Compliant horn contact (see :func:`run_events`); None: Newton's law.

    Returns
    -------
    ndarray (n_members, N_CSTATS)
        The columns of :func:`impact.kernel.ensemble_stats` and ``C_DRIVE``, ``C_DAMP`` (J), ``C_FUND_RE``, ``C_FUND_IM`` (m s).
    """
    pmat = np.ascontiguousarray(np.atleast_2d(pmat), dtype=np.float64)
    if pmat.shape[1] != N_PARAMS:
        raise ValueError(f"pmat has {pmat.shape[1]} columns, expected {N_PARAMS}")
    tab, xs, lam, G1, G2 = _kernel_data(horn, freq_hz)
    out = np.zeros((pmat.shape[0], N_CSTATS))
    _ensemble(pmat, tab, xs, _hc_array(contact), float(t_from), float(t_end), int(max_events), out, lam, G1, G2)
    return out


def warmup() -> None:
    """Compile both entry points (or load them from numba's disk cache) on a tiny case;
    ``make install`` calls it beside :func:`impact.kernel.warmup`."""
    horn = ModalHorn([2 * math.pi * 20.5e3], [0.005], [1.0], [3.0], [0.5], [0.0], 1.0)
    p = ImpactParams(t_end=1e-3)
    run_events(p, horn)
    ensemble_coupled(pack(p)[None, :], horn, p.freq, 0.0, 1e-3, 1000)
