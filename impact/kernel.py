"""Compiled event kernel of the impact model (numba).

The algorithm of :mod:`impact.model` (read its module docstring for the model, the corrections
to the article, the sticking rule and the event search) as one loop, :func:`_core`, on the
compiled building blocks of :mod:`impact.kernel_blocks`: plan the contact functions of the
segment, find the earliest root, apply the impact law or release, record. The readable reference
:class:`impact.reference.events.EventEngine` runs the same steps in Python; every floating
point operation is written in the same order and ``fastmath`` is off, so both engines return
the same events (to the last bit in practice).

Functions are compiled on first use (``cache=True`` keeps the machine code on disk in
``__pycache__``); :mod:`impact.model` imports this module lazily.

Packed parameters (``pack``): a float64 vector, indices ``P_*``; ``horn_law`` is 0 kinematic,
1 article. Ensemble statistics (``ensemble_stats``): columns ``S_*``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .columns import (BODY_HORN, BODY_TOOL, FREE, KIND_HORN, KIND_TOOL, N_STATS, ON_HORN, ON_TOOL,
                      S_HORN_WORK, S_KE_AFTER, S_KE_GAIN, S_N_EVENTS, S_N_HORN, S_N_TOOL, S_STATUS,
                      S_T_ON_HORN, S_T_ON_TOOL, STATUS_MAX_EVENTS, STATUS_OK, STATUS_PINCHED)
from .kernel_blocks import (event_status, free_mass_at, C_A, C_L0, C_N, C_T0, C_UC, C_W, C_W0, C_WD0, E_N, FN_HORN,
                            FN_RELEASE, O_B0, O_B2, O_N, PL_ROWS, count_impact, close_run, close_stick, earliest,
                            horn_impact_kinematic, mech_energy, next_cross, osc_pv, plan_flight,
                            plan_on_tool, plan_pinch, record_event, record_segment,
                            sticks, tool_event, tool_osc)
from .params import ImpactParams

__all__ = ["pack", "run_events", "ensemble_stats", "warmup", "N_PARAMS", "N_STATS", "P_M_FREE", "P_A0",
           "P_FREQ", "P_E1", "P_E2", "P_M_HORN", "P_M_TOOL", "P_K0", "P_C", "P_GAP", "P_G", "P_V0", "P_T_END",
           "P_SPRING_FORCE", "P_HORN_LAW", "P_V_STICK", "P_SAMPLE_DT", "P_MAX_EVENTS", "HORN_LAW_KINEMATIC",
           "HORN_LAW_ARTICLE", "S_N_TOOL", "S_N_HORN", "S_KE_AFTER", "S_KE_GAIN", "S_HORN_WORK", "S_T_ON_HORN",
           "S_T_ON_TOOL", "S_STATUS", "S_N_EVENTS", "STATUS_OK", "STATUS_PINCHED", "STATUS_MAX_EVENTS",
           "KIND_HORN", "KIND_TOOL", "BODY_HORN", "BODY_TOOL", "FREE", "ON_HORN", "ON_TOOL"]

# ----------------------------------------------------------------------------- layouts

#: indices of the packed parameter vector (SI units, as in ImpactParams)
P_M_FREE, P_A0, P_FREQ, P_E1, P_E2, P_M_HORN, P_M_TOOL, P_K0, P_C, P_GAP, P_G, P_V0, P_T_END, \
    P_SPRING_FORCE, P_HORN_LAW, P_V_STICK, P_SAMPLE_DT, P_MAX_EVENTS = range(18)
N_PARAMS = 18
HORN_LAW_KINEMATIC, HORN_LAW_ARTICLE = 0, 1


def pack(p: ImpactParams) -> np.ndarray:
    """Parameters as a float64 vector of length ``N_PARAMS`` (indices ``P_*``, SI units).

    Parameters
    ----------
    p : ImpactParams
        Validated parameters.

    Returns
    -------
    ndarray
        ``horn_law`` is ``HORN_LAW_KINEMATIC`` (0) or ``HORN_LAW_ARTICLE`` (1); ``max_events``
        is stored as a float (exact up to 2^53).
    """
    v = np.empty(N_PARAMS)
    v[P_M_FREE], v[P_A0], v[P_FREQ], v[P_E1], v[P_E2] = p.m_free, p.A0, p.freq, p.e1, p.e2
    v[P_M_HORN], v[P_M_TOOL], v[P_K0], v[P_C], v[P_GAP] = p.m_horn, p.m_tool, p.k0, p.c, p.gap
    v[P_G], v[P_V0], v[P_T_END], v[P_SPRING_FORCE] = p.g, p.v0, p.t_end, p.spring_force
    v[P_HORN_LAW] = HORN_LAW_ARTICLE if p.horn_law == "article" else HORN_LAW_KINEMATIC
    v[P_V_STICK], v[P_SAMPLE_DT], v[P_MAX_EVENTS] = p.v_stick, p.sample_dt, p.max_events
    return v


# ----------------------------------------------------------------------------- the event loop


@njit(cache=True)
def _core(pv, t_end, max_events, record, t_from, stats):
    """One run: plan the contacts of the segment -> earliest root -> apply the law -> record.
    With ``record`` the events, sticking phases and segments are stored (growable arrays);
    ``stats`` (length N_STATS) is filled with the window statistics either way."""
    m_free, A0, e1, e2 = pv[P_M_FREE], pv[P_A0], pv[P_E1], pv[P_E2]
    m_horn, m_tool, k0, c, L0 = pv[P_M_HORN], pv[P_M_TOOL], pv[P_K0], pv[P_C], pv[P_GAP]
    v_stick = pv[P_V_STICK]
    article = pv[P_HORN_LAW] == HORN_LAW_ARTICLE
    om = 2.0 * math.pi * pv[P_FREQ]
    om2 = om * om
    a = pv[P_G] - pv[P_SPRING_FORCE] / m_free
    Bh = abs(a) + A0 * om2
    cap = 1024 if record else 1
    ev, kinds, segs, stk = np.empty((cap, E_N)), np.empty(cap, np.int8), np.empty((cap, 6)), np.empty((cap, 3))
    n_rec = n_seg = n_stk = 0
    o, o2, plan, stack = np.empty(O_N), np.empty(O_N), np.empty((PL_ROWS, 5)), np.empty((128, 6))
    cp = np.zeros(C_N)
    cp[C_A], cp[C_L0], cp[C_W], cp[C_UC] = a, L0, om, A0
    stats[:] = 0.0
    w_from = w_last = 0.0
    t, mode, w, wd, v, vd = 0.0, FREE, A0, pv[P_V0], 0.0, 0.0
    # the horn gap is convex while u'' < a: no horn contact before that ends
    skip_h = max(next_cross(0.0, True, A0, om, om2, a) if -A0 * om2 * math.cos(om * 0.0) < a else 0.0,
                 2.0 * pv[P_V0] / Bh)
    skip_t = 0.0
    E0 = mech_energy(m_free, m_tool, k0, a, w, wd, v, vd)
    work = stick_start = stick_E = 0.0
    n_ev, status, t_status = 0, STATUS_OK, 0.0
    while t < t_end:
        # plan the contacts of this segment
        tool_osc(o, mode == ON_TOOL, m_tool, m_free, k0, c, a, v, vd)
        if record:
            segs = record_segment(segs, n_seg, t, mode, w, wd, v, vd)
            n_seg += 1
        t0, w0, wd0 = t, w, wd
        cp[C_T0], cp[C_W0], cp[C_WD0] = t0, w0, wd0
        t_rel = math.inf
        if mode == FREE:
            nf = plan_flight(plan, 0, t0, w0, wd0, a, L0, A0, o[O_B0], skip_h, skip_t, Bh, o[O_B2] + abs(a), t_end)
        elif mode == ON_HORN:
            nf = plan_pinch(plan, 0, o, L0, A0, A0 * om2, max(t0, skip_t), t_end)
            t_rel = next_cross(t0, False, A0, om, om2, a)
        else:
            nf = plan_on_tool(plan, 0, o, L0, a, A0, A0 * om2, t0, t_end)
        # earliest root (a release from the horn is found analytically)
        have, te, name = earliest(plan, nf, min(t_end, t_rel), cp, o, None, None, 0, stack)
        if not have and t_rel <= t_end:
            have, te, name = True, t_rel, FN_RELEASE
        if not have:
            break
        status, n_ev = event_status(name, n_ev, max_events)
        if status != STATUS_OK:
            t_status = te
            break
        # the state at the event
        s = te - t0
        v, vd = osc_pv(o, s)
        ph = om * te
        uh, uhd = A0 * math.cos(ph), -A0 * om * math.sin(ph)
        w, wd = free_mass_at(mode, s, w0, wd0, a, L0, uh, uhd, v, vd)
        t = te
        if L0 + v <= 2.0 * A0:
            status, t_status = STATUS_PINCHED, te
            break
        # apply the law
        if name == FN_RELEASE:
            body = BODY_HORN if mode == ON_HORN else BODY_TOOL
            skip_h, skip_t = te, te
            if mode == ON_HORN:
                # the horn did the work that moved the stuck mass
                work += (0.5 * m_free * wd * wd - m_free * a * w) - stick_E
                skip_h = next_cross(te, True, A0, om, om2, a)
            stk, n_stk = close_stick(stk, n_stk, record, stats, body, stick_start, te, t_from, t_end)
            mode = FREE
            continue
        if name == FN_HORN:
            kind, x, wb, vb, va = KIND_HORN, uh, wd, vd, vd
            wa = horn_impact_kinematic(article, e2, m_horn, m_free, wd, uhd)
            work += m_free * (wa - wd) * uhd
            uacc = -A0 * om2 * math.cos(om * te)
            if sticks(wa - uhd, uacc - a, v_stick):
                wa = uhd
                mode = ON_HORN
                stick_start = te
                stick_E = 0.5 * m_free * wa * wa - m_free * a * x
            else:
                skip_h = te + 2.0 * (wa - uhd) / Bh
                if uacc - a < 0.0:
                    skip_h = max(skip_h, next_cross(te, True, A0, om, om2, a))
            skip_t = te
            w, wd = x, wa
        else:
            kind, x, vb, wb = KIND_TOOL, L0 + v, vd, wd
            va, wa, mode, stick_start, skip_h, skip_t = tool_event(o2, te, m_free, m_tool, e1, c, k0, a, v_stick, v, vd,
                                                                   wd, mode, stick_start, skip_h, skip_t)
            w, wd, vd = x, wa, va
        # record
        if record:
            ev, kinds = record_event(ev, kinds, n_rec, kind, te, x, wb, wa, vb, va,
                                     mech_energy(m_free, m_tool, k0, a, w, wd, v, vd), work)
            n_rec += 1
        w_from, w_last = count_impact(stats, te, t_from, t_end, kind, m_tool, vb, va, work, w_from), work
    stk, n_stk = close_run(stk, n_stk, record, stats, status, mode, stick_start, t_from, t_end, w_last - w_from, n_ev)
    return ev, kinds, n_rec, segs, n_seg, stk, n_stk, E0, status, t_status, n_ev


def run_events(pvec: np.ndarray, t_end: float, max_events: int) -> tuple:
    """Simulate one parameter set and return every event (compiled; see module docstring).

    Parameters
    ----------
    pvec : ndarray
        Packed parameters (:func:`pack`).
    t_end : float
        Simulated time, s.
    max_events : int
        Event cap (impacts and releases); exceeding it ends the run with status 2.

    Returns
    -------
    tuple
        ``(t, kind, x, w_before, w_after, v_before, v_after, energy, horn_work,
        stick_start, stick_end, stick_body, seg_t0, seg_mode, seg_w0, seg_wd0, seg_v0,
        seg_vd0, energy0, status, t_status, n_events)``: event arrays (s, int8 ``KIND_*``, m,
        m/s, m/s, m/s, m/s, J, cumulative J), sticking phases (s, s, int8 ``BODY_*``), segment
        starts (s, int8 mode ``FREE``/``ON_HORN``/``ON_TOOL``, free-mass position m and velocity
        m/s, tool position m and velocity m/s: enough to rebuild each segment's oscillator),
        initial energy (J), ``STATUS_*`` and the time it was reached (s; 0 when ok) and the
        number of events (impacts and releases).
    """
    stats = np.zeros(N_STATS)
    ev, kinds, n, segs, ns, stk, nk, E0, status, t_status, n_ev = _core(
        np.ascontiguousarray(pvec, dtype=np.float64), float(t_end), int(max_events), True, 0.0, stats)
    ev = ev[:n]
    segs = segs[:ns]
    stk = stk[:nk]
    return (ev[:, 0].copy(), kinds[:n].copy(), ev[:, 1].copy(), ev[:, 2].copy(), ev[:, 3].copy(),
            ev[:, 4].copy(), ev[:, 5].copy(), ev[:, 6].copy(), ev[:, 7].copy(),
            stk[:, 0].copy(), stk[:, 1].copy(), stk[:, 2].astype(np.int8),
            segs[:, 0].copy(), segs[:, 1].astype(np.int8), segs[:, 2].copy(), segs[:, 3].copy(),
            segs[:, 4].copy(), segs[:, 5].copy(), float(E0), int(status), float(t_status), int(n_ev))


@njit(cache=True, parallel=True)
def _ensemble(pmat, t_from, t_end, max_events, out):
    for i in prange(pmat.shape[0]):
        _core(pmat[i], t_end, max_events, False, t_from, out[i])


def ensemble_stats(pmat: np.ndarray, t_from: float, t_end: float, max_events: int) -> np.ndarray:
    """Window statistics of many runs, in parallel over the members (no per-event storage).

    Parameters
    ----------
    pmat : ndarray, shape (n_members, N_PARAMS)
        Packed parameters (:func:`pack`), one row per member.
    t_from, t_end : float
        Window [t_from, t_end], s; every member runs from 0 to t_end.
    max_events : int
        Event cap per member.

    Returns
    -------
    ndarray, shape (n_members, N_STATS)
        Columns ``S_N_TOOL``, ``S_N_HORN``, ``S_KE_AFTER`` (J), ``S_KE_GAIN`` (J),
        ``S_HORN_WORK`` (J), ``S_T_ON_HORN``, ``S_T_ON_TOOL`` (s), ``S_STATUS``,
        ``S_N_EVENTS`` (see :func:`impact.model.window_stats`). A member with status != 0
        (pinched, too many events) does not stop the others; its other columns hold the values
        up to the failure and should be discarded.
    """
    pmat = np.ascontiguousarray(np.atleast_2d(pmat), dtype=np.float64)
    if pmat.shape[1] != N_PARAMS:
        raise ValueError(f"pmat has {pmat.shape[1]} columns, expected N_PARAMS = {N_PARAMS}")
    out = np.zeros((pmat.shape[0], N_STATS))
    _ensemble(pmat, float(t_from), float(t_end), int(max_events), out)
    return out


def warmup() -> None:
    """Compile both entry points (or load them from numba's on-disk cache) on a tiny case.

    ``make install`` calls it, so the first real run does not pay
    the compile time (about 20 s from a cold cache, 0.3 s from the cache).
    """
    from .params import ImpactParams

    pv = pack(ImpactParams(t_end=1e-3))
    run_events(pv, 1e-3, 1000)
    ensemble_stats(pv[None, :], 0.0, 1e-3, 1000)
