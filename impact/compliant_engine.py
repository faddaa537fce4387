"""The compiled compliant engine (:mod:`impact.kernel_compliant`) behind the Python API.

* :func:`run_compliant`: one run, the same inputs and :class:`impact.compliant_loop.CompliantRun`
  as the Python reference :func:`impact.compliant_loop.simulate_compliant` (which calls it with
  ``engine="kernel"``);
* :func:`compliant_batch`: converged ensemble statistics of several cases (e.g. free masses) on
  one horn, each case with its own contact laws: the members, scenarios, Student-t intervals and
  the doubling rule of :func:`impact.stats.ensemble_batch`, with the coupled model's quantities
  (:data:`impact.coupled.COUPLED_QUANTITIES`) and the window's energy balance.

Contacts in place of impacts: a tool or horn "impact" of the statistics is one contact, counted
at its separation; the tool's kinetic energy "after impact" is at the separation, its gain is
over the contact; ``frac_on_tool`` / ``frac_on_horn`` are the fractions of the window a contact
is closed (the compliant model has no sticking rule: a resting free mass is a long contact).
"""

from __future__ import annotations

import logging
import math

import numpy as np

from rpud_common import ParameterError, check_positive

from .hertz import HertzLaw
from .horn import ModalHorn
from .params import ImpactParams

__all__ = ["run_compliant", "compliant_batch", "COMPLIANT_QUANTITIES", "warmup"]

log = logging.getLogger(__name__)

#: the window energy balance every member of a batch must close to, relative to its drive work
LEDGER_TOL = 1e-9
#: the tightest rtol a member is run again at to close its balance
RTOL_FLOOR = 1e-12

#: quantities added to the coupled model's by the compliant batch
COMPLIANT_QUANTITIES = (
    ("contact_loss_power_w", "W", "energy lost in the contacts per second"),
    ("ledger_rel", "1", "energy balance of the window over its drive work (0 up to the integration error)"),
)


def check_compliant(horn: ModalHorn, horn_law, tool_law, horn_residual: float, rtol: float) -> None:
    """Refuse inputs the compliant engines do not cover (ParameterError)."""
    if not isinstance(horn, ModalHorn):
        raise ParameterError("horn", type(horn).__name__, "must be an impact.horn.ModalHorn")
    if horn.series_resistance > 0:
        raise ParameterError("series_resistance", horn.series_resistance,
                             "must be 0 with compliant contacts (a voltage-driven horn)")
    for name, law in (("horn_law", horn_law), ("tool_law", tool_law)):
        if not isinstance(law, HertzLaw):
            raise ParameterError(name, type(law).__name__, "must be an impact.hertz.HertzLaw")
    if not (horn_residual >= 0.0 and math.isfinite(horn_residual)):
        raise ParameterError("horn_residual", horn_residual, "must be a finite number >= 0 m/N")
    check_positive("rtol", rtol)
    if not 1e-14 <= rtol <= 1e-6:
        raise ParameterError("rtol", rtol, "must lie in [1e-14, 1e-6]")


def run_compliant(params: ImpactParams, horn: ModalHorn, *, horn_law: HertzLaw, tool_law: HertzLaw,
                  horn_residual: float = 0.0, rtol: float = 1e-10):
    """One compliant run by the compiled engine (see :func:`impact.compliant_loop.simulate_compliant`).

    Parameters
    ----------
    params, horn, horn_law, tool_law, horn_residual
        As :func:`impact.compliant_loop.simulate_compliant`.
    rtol : float
        Relative tolerance of the contact phases' DOP853 steps (the flights are closed form).
        The energy balance's error grows with it: ~4e-11 of the drive work in the device
        scenario at 1e-10, ~2e-10 at 1e-9 (8 g and 1 g, 16 modes); a free mass pressed onto a
        weakly driven horn (long contacts, little drive work) needs a tighter rtol for 1e-9.
        A decade costs ~1.15x the time.

    Returns
    -------
    impact.compliant_loop.CompliantRun
    """
    from . import kernel_compliant as KC
    from .compliant_result import CompliantRun, Contact
    from .kernel import pack
    from .result import SimulationError

    check_compliant(horn, horn_law, tool_law, horn_residual, rtol)
    tab, xs = horn.pack(params.freq)
    lw = KC.pack_laws(horn_law, tool_law, float(horn_residual), float(rtol))
    rows, y, t, status, E0, acc, window = KC.run_contacts(pack(params), lw, tab, xs, 0.0, params.t_end,
                                                          params.max_events)
    if status != 0:
        raise SimulationError(f"the compliant run stopped at t = {t:.9g} s (status {status}: too many contacts "
                              "or a contact phase not resolved in its step budget)")
    contacts = [Contact("horn" if r[0] == 0 else "tool", *(float(v) for v in r[1:])) for r in rows]
    contacts.sort(key=lambda c: c.t_start)
    n = horn.n_modes
    u0 = float(horn.tip @ horn.initial_state(params.freq)[0]) + horn.residual_phasor().real
    ledger = {"drive_j": float(acc[KC.C_DRIVE]), "gravity_j": params.m_free * params.a_free * float(y[0] - u0),
              "modal_damping_j": float(acc[KC.C_DAMP]), "tool_damping_j": float(acc[KC.K_TOOL_DAMP]),
              "contact_loss_j": float(acc[KC.K_LOSS])}
    # the kernel's stored energy holds the constant force's potential: the gravity term is apart here
    ledger["stored_change_j"] = float(window[KC.K_STORED]) + ledger["gravity_j"]
    ledger["residual_j"] = float(window[KC.K_LEDGER])
    return CompliantRun(contacts=contacts, t_end=t, state=y[:4 + 2 * n].copy(), ledger=ledger)


def _per_case(name: str, value, n: int, kind) -> list:
    """``value`` for every case: one ``kind`` for all, or a list with one per case."""
    values = list(value) if isinstance(value, (list, tuple)) else [value] * n
    if len(values) != n or not all(isinstance(v, kind) for v in values):
        raise ParameterError(name, f"{len(values)} values", f"must be one {kind.__name__} or one per case ({n})")
    return values


def _estimates(r: np.ndarray, T: float, level: float) -> dict:
    """The statistics of one case's member rows (``N_KSTATS`` columns)."""
    from . import kernel_compliant as KC
    from .columns import N_STATS
    from .stats import mean_ci, window_estimates

    est = window_estimates(r[:, :N_STATS], T, level)
    amp = np.abs(2.0 / T * (r[:, KC.C_FUND_RE] + 1j * r[:, KC.C_FUND_IM]))
    est["tip_amplitude_m"] = mean_ci(amp, level)
    est["drive_power_w"] = mean_ci(r[:, KC.C_ELEC] / T, level)
    est["mech_drive_power_w"] = mean_ci(r[:, KC.C_DRIVE] / T, level)
    est["damping_power_w"] = mean_ci(r[:, KC.C_DAMP] / T, level)
    est["contact_loss_power_w"] = mean_ci(r[:, KC.K_LOSS] / T, level)
    est["ledger_rel"] = mean_ci(r[:, KC.K_LEDGER] / r[:, KC.C_DRIVE], level)
    return est


def compliant_batch(cases: list[ImpactParams], horn: ModalHorn, *, horn_law, tool_law, horn_residual: float = 0.0,
                    scenario="device", settings=None, progress=None, rtol: float = 1e-9) -> list:
    """Converged ensemble statistics of compliant runs (one horn, several cases).

    Every case starts with ``n_start`` members. A case whose widest driving 95 % CI (impact.stats'
    ``DRIVING``) is above its ``rel_tol`` grows to the members that CI asks for (a half-width
    falls as ``1 / sqrt(n)``: ``n (h / rel_tol)^2``, plus 20 %, at least 1.25 n, in steps of 8)
    up to ``n_max``. Each round runs the new members of every growing case in one parallel call,
    handed to the threads one member at a time, so both cores stay busy whatever the cases cost.
    Member ``i`` of a case is the same run however the rounds and threads fall (the ``i``-th
    launch speed of the seeded ensemble, :func:`impact.stats.ensemble_members`): the numbers
    do not depend on the scheduling.

    Parameters
    ----------
    cases : list of ImpactParams
        Base cases (their ``freq`` the drive frequency, shared).
    horn : ModalHorn
    horn_law, tool_law : HertzLaw or list of HertzLaw
        One law for every case, or one per case (the contact stiffness follows the free mass's
        face radius).
    horn_residual : float
        Static compliance of the horn's modes left out, at the tip, m/N.
    scenario, progress
        As :func:`impact.stats.ensemble_batch`.
    settings : impact.stats.StatsSettings or list of them
        One for every case, or one per case (e.g. a looser ``rel_tol`` for a study's cases).
    rtol : float
        Relative tolerance of the contact phases. A member whose window energy balance misses
        :data:`LEDGER_TOL` of its drive work (the integration's error shows there) runs again at a
        tenth of its rtol, down to :data:`RTOL_FLOOR`: every member's balance closes to the target
        whatever its contacts (a free mass pressed onto a weakly driven horn does little drive work
        in many steps and needs a tighter rtol than a bouncing one). At 1e-9 the device members'
        balance is ~1e-10 of the drive work (~1.2x less CPU than 1e-10, where it is ~4e-11). The
        decision is the member's own: its row does not depend on the other members.

    Returns
    -------
    list of impact.stats.EnsembleStats
        The quantities of :data:`impact.stats.QUANTITIES`, :data:`impact.coupled.COUPLED_QUANTITIES`
        and :data:`COMPLIANT_QUANTITIES`, 95 % Student-t intervals over the members.
    """
    from . import kernel_compliant as KC
    from .stats import StatsSettings, get_scenario

    sc = get_scenario(scenario)
    n = len(cases)
    h_laws = _per_case("horn_law", horn_law, n, HertzLaw)
    t_laws = _per_case("tool_law", tool_law, n, HertzLaw)
    sts = _per_case("settings", settings or StatsSettings(), n, StatsSettings)
    for hl, tl in zip(h_laws, t_laws):
        check_compliant(horn, hl, tl, horn_residual, rtol)
    bases = [sc.apply(p) for p in cases]
    if len({p.freq for p in bases}) > 1:
        raise ParameterError("freq", sorted({p.freq for p in bases}), "every case must share the drive frequency")
    tab, xs = horn.pack(bases[0].freq) if bases else (None, None)
    laws = [KC.pack_laws(h, t, float(horn_residual), float(rtol)) for h, t in zip(h_laws, t_laws)]
    raws = [np.empty((0, KC.N_KSTATS)) for _ in bases]
    want = [st.n_start for st in sts]
    out = [None] * n
    while any(r is None for r in out):
        grow = [i for i in range(n) if out[i] is None]
        _run_round(grow, bases, sts, laws, raws, want, tab, xs, sc)
        for i in grow:
            out[i], want[i] = _judge(bases[i], sc, sts[i], raws[i])
            if out[i] is not None:
                msg = f"{sc.name} (compliant, {horn.n_modes} modes): case {i + 1}/{n} done, {out[i].members} members"
                log.info("%s", msg)
                if progress is not None:
                    progress(msg)
    return out


def _run_round(grow, bases, sts, laws, raws, want, tab, xs, sc) -> None:
    """The new members of the cases ``grow`` (up to ``want`` each) in one parallel call, appended to ``raws``."""
    from . import kernel_compliant as KC
    from .kernel import pack
    from .stats import ensemble_members

    rows, lw, owner = [], [], []
    for i in grow:
        have = raws[i].shape[0]
        for p in ensemble_members(bases[i], want[i] - have, sts[i], start=have):
            rows.append(pack(p))
            lw.append(laws[i])
            owner.append(i)
    max_events = max(bases[i].max_events for i in grow)
    pmat, lmat = np.array(rows), np.array(lw)
    new = KC.ensemble_rows(pmat, lmat, tab, xs, sc.t_from, sc.t_end, max_events)
    _close_balances(new, pmat, lmat, tab, xs, sc, max_events)
    owner = np.array(owner)
    for i in grow:
        raws[i] = np.vstack([raws[i], new[owner == i]])


def _close_balances(new, pmat, lmat, tab, xs, sc, max_events) -> None:
    """Members of ``new`` whose window balance misses :data:`LEDGER_TOL` of their drive work, run
    again at a tenth of their rtol (``lmat``'s, changed in place) until it closes or the rtol is
    :data:`RTOL_FLOOR`; their rows replaced in place."""
    from . import kernel_compliant as KC

    while True:
        bad = np.abs(new[:, KC.K_LEDGER]) > LEDGER_TOL * np.abs(new[:, KC.C_DRIVE])
        bad &= lmat[:, KC.L_RTOL] > 1.001 * RTOL_FLOOR
        if not bad.any():
            return
        tighter = lmat[bad, KC.L_RTOL] / 10.0
        lmat[bad, KC.L_RTOL] = np.where(tighter <= 1.001 * RTOL_FLOOR, RTOL_FLOOR, tighter)
        log.info("compliant batch: %d members run again at a tighter rtol to close their energy balance",
                 int(bad.sum()))
        new[bad] = KC.ensemble_rows(pmat[bad], lmat[bad], tab, xs, sc.t_from, sc.t_end, max_events)


def _judge(base, sc, st, raw) -> tuple:
    """``(EnsembleStats, members wanted)``: the case's statistics when it is done (converged, failed
    or at ``n_max``), else ``(None, the members its widest driving CI asks for)``."""
    from . import kernel_compliant as KC
    from .stats import DRIVING, EnsembleStats, Estimate

    n = raw.shape[0]
    failed = int(np.sum(raw[:, KC.S_STATUS] != 0))
    if failed:
        why = f"{failed} of {n} members failed (too many contacts or an unresolved contact phase)"
        est = {q: Estimate(math.nan, math.nan, n, st.level, why) for q in _names()}
        return EnsembleStats(params=base, scenario=sc, estimates=est, members=n, failed=failed, converged=False,
                             settings=st, note=why, raw=raw), n
    est = _estimates(raw, sc.window_s, st.level)
    rel = [est[q].rel_half_width for q in DRIVING]
    worst = max((x if math.isfinite(x) else math.inf) for x in rel)
    conv = bool(n >= 2 and worst <= st.rel_tol)
    if conv or n >= st.n_max:
        note = "" if conv else f"member cap n_max = {st.n_max} reached before the {st.rel_tol:.0%} target"
        return EnsembleStats(params=base, scenario=sc, estimates=est, members=n, failed=0, converged=conv,
                             settings=st, note=note, events=int(raw[:, KC.S_N_EVENTS].sum()), raw=raw), n
    return None, _members_wanted(n, worst, st)


def _members_wanted(n: int, worst: float, st) -> int:
    """Members for a widest relative half-width ``worst`` at ``n`` to reach ``st.rel_tol`` (it falls
    as ``1 / sqrt(n)``; +20 % for the noise of that estimate), at least ``1.25 n``, in steps of 8, at
    most ``st.n_max``."""
    need = 1.2 * n * (worst / st.rel_tol) ** 2 if math.isfinite(worst) else 2.0 * n
    return int(min(st.n_max, 8 * math.ceil(max(need, 1.25 * n) / 8)))


def _names() -> list:
    from .coupled import COUPLED_QUANTITIES
    from .stats import QUANTITIES

    return [q for q, _, _ in QUANTITIES + COUPLED_QUANTITIES + COMPLIANT_QUANTITIES]


def warmup() -> None:
    """Compile the engine's two entry points (or load them from numba's disk cache) on a tiny
    case; ``make install`` calls it beside :func:`impact.kernel.warmup`, so the first compliant
    run does not spend ~40 s compiling."""
    from . import kernel_compliant as KC
    from .kernel import pack

    horn = ModalHorn([2 * math.pi * 20.5e3], [0.005], [1.0], [3.0], [0.5], [0.0], 1.0)
    p = ImpactParams(t_end=1e-3)
    laws = {"horn_law": HertzLaw(1e9, p.e2), "tool_law": HertzLaw(1e9, p.e1)}
    run_compliant(p, horn, **laws)
    tab, xs = horn.pack(p.freq)
    KC.ensemble_rows(pack(p)[None, :], KC.pack_laws(laws["horn_law"], laws["tool_law"], 0.0, 1e-10), tab, xs,
                     0.0, 1e-3, p.max_events)
