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
``b_k,i`` the bound of the i-th free oscillation's k-th derivative (:class:`impact.oscillator.Oscillator`); the
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

Engines: :mod:`impact.kernel_modal` is the compiled kernel; :class:`impact.reference.modal.ModalEngine`
the readable reference of the same algorithm, operation for operation (tests compare them). The
run's outcome is a :class:`impact.coupled_result.CoupledResult`.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from rpud_common import ParameterError

from .columns import BODY_TOOL, KIND_TOOL, ON_HORN, STATUS_CONTACT, STATUS_MAX_EVENTS, STATUS_PINCHED
from .coupled_result import CoupledResult, states_on
from .horn import ModalHorn
from .params import ImpactParams
from .result import HORN, TOOL, ImpactResult, SimulationError, max_events_message, pinch_message, sample_series

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



def _series(res: CoupledResult) -> None:
    """Sample tip, free mass and tool face on the grid ``sample_dt`` (analytic per segment)."""
    p = res.impact.params
    seg = res.extra["segments"]
    # the free mass and tool face as in the kinematic model; riding the horn: below
    sample_series(res.impact, seg)
    tg = res.impact.t_grid
    res.t_grid = tg
    h = res.horn
    if h.series_resistance > 0:
        from . import drive_result as drive

        res.u, res.tip_velocity = drive.tip_series(res, tg)
    else:
        q, qd, _ = states_on(res, tg)
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
    from . import kernel_modal

    ev, kinds, segs, stk, E0, status, t_status, n_ev, window = kernel_modal.run_events(params, horn, contact)
    if status == STATUS_PINCHED:
        raise SimulationError(pinch_message(t_status))
    if status == STATUS_MAX_EVENTS:
        raise SimulationError(max_events_message(params.max_events, t_status))
    if status == STATUS_CONTACT:
        raise SimulationError(f"the compliant contact starting at t = {t_status:.9g} s was not resolved in 1e6 "
                              "integration steps (contact stiffness or damping out of range)")
    n = (segs.shape[1] - 6) // 2
    contact = np.where(kinds == KIND_TOOL, TOOL, HORN).astype("<U4")
    stick = [(float(a), float(b), "tool" if body == BODY_TOOL else "horn") for a, b, body in stk]
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


def _reference(params: ImpactParams, horn: ModalHorn, contact=None) -> CoupledResult:
    from .reference.modal import ModalEngine

    return ModalEngine(params, horn, contact).run()


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
        The compiled kernel (:mod:`impact.kernel_modal`) or the readable reference
        :class:`impact.reference.modal.ModalEngine`.
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
            return _reference(params, horn, contact)
        if engine != "kernel":
            raise ParameterError("engine", engine, "must be 'kernel' or 'python'")
        res = _run_kernel(params, horn, contact)
        res.extra["compliant"] = True
        return res
    if engine == "python":
        res = _reference(params, horn)
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
    from .stats import (DRIVING, QUANTITIES, EnsembleStats, Estimate, StatsSettings, ensemble_members,
                        get_scenario, window_estimates, mean_ci)

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
            est = window_estimates(r[:, :kernel.N_STATS], T, st.level)
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
