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


def _laws_per_case(name: str, law, n: int) -> list:
    laws = list(law) if isinstance(law, (list, tuple)) else [law] * n
    if len(laws) != n:
        raise ParameterError(name, f"{len(laws)} laws", f"must be one HertzLaw or one per case ({n})")
    return laws


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
                    scenario="device", settings=None, progress=None, rtol: float = 1e-10) -> list:
    """Converged ensemble statistics of compliant runs (one horn, several cases).

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
    scenario, settings, progress
        As :func:`impact.stats.ensemble_batch`.
    rtol : float
        Relative tolerance of the contact phases.

    Returns
    -------
    list of impact.stats.EnsembleStats
        The quantities of :data:`impact.stats.QUANTITIES`, :data:`impact.coupled.COUPLED_QUANTITIES`
        and :data:`COMPLIANT_QUANTITIES`, 95 % Student-t intervals over the members.
    """
    from . import kernel_compliant as KC
    from .kernel import pack
    from .stats import DRIVING, EnsembleStats, Estimate, StatsSettings, ensemble_members, get_scenario

    sc = get_scenario(scenario)
    st = settings or StatsSettings()
    h_laws = _laws_per_case("horn_law", horn_law, len(cases))
    t_laws = _laws_per_case("tool_law", tool_law, len(cases))
    for hl, tl in zip(h_laws, t_laws):
        check_compliant(horn, hl, tl, horn_residual, rtol)
    bases = [sc.apply(p) for p in cases]
    if len({p.freq for p in bases}) > 1:
        raise ParameterError("freq", sorted({p.freq for p in bases}), "every case must share the drive frequency")
    tab, xs = horn.pack(bases[0].freq) if bases else (None, None)
    out = []
    for i, base in enumerate(bases):
        lw = KC.pack_laws(h_laws[i], t_laws[i], float(horn_residual), float(rtol))
        raw = np.empty((0, KC.N_KSTATS))
        while True:
            new = ensemble_members(base, (st.n_start if raw.shape[0] == 0 else raw.shape[0]), st, start=raw.shape[0])
            pmat = np.array([pack(p) for p in new])
            raw = np.vstack([raw, KC.ensemble_rows(pmat, lw, tab, xs, sc.t_from, sc.t_end, base.max_events)])
            n = raw.shape[0]
            failed = int(np.sum(raw[:, KC.S_STATUS] != 0))
            if failed:
                why = f"{failed} of {n} members failed (too many contacts or an unresolved contact phase)"
                est = {q: Estimate(math.nan, math.nan, n, st.level, why) for q in _names()}
                out.append(EnsembleStats(params=base, scenario=sc, estimates=est, members=n, failed=failed,
                                         converged=False, settings=st, note=why, raw=raw))
                break
            est = _estimates(raw, sc.window_s, st.level)
            rel = [est[q].rel_half_width for q in DRIVING]
            conv = bool(n >= 2 and all(math.isfinite(x) and x <= st.rel_tol for x in rel))
            if conv or 2 * n > st.n_max:
                note = "" if conv else f"member cap n_max = {st.n_max} reached before the {st.rel_tol:.0%} target"
                out.append(EnsembleStats(params=base, scenario=sc, estimates=est, members=n, failed=0, converged=conv,
                                         settings=st, note=note, events=int(raw[:, KC.S_N_EVENTS].sum()), raw=raw))
                break
        msg = f"{sc.name} (compliant, {horn.n_modes} modes): case {i + 1}/{len(bases)} done, {n} members"
        log.info("%s", msg)
        if progress is not None:
            progress(msg)
    return out


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
