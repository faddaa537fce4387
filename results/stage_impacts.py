"""The impact stages: the FE hand-off, the horn amplitude under the impact load, the statistics.

The impact stage is chaotic, so what it receives from the FE stages is rounded at the hand-off
(:func:`handoff`: the amplitude and the horn mass to ``digits`` significant digits, the frequency
to ``digits + 2``), far below the FE discretisation error: threaded round-off in the FE solvers
never reaches it.

:func:`amplitude_stage` iterates ``A0 -> impact power -> tip damper -> A0`` to a fixed point
(:func:`coupled_amplitudes`) and :func:`impact_stage` runs the converged ensemble statistics at
those amplitudes; a design study runs both on one free mass, the end-to-end run on all of them.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .coupled import round_sig

log = logging.getLogger(__name__)

__all__ = ["handoff", "CoupledAmplitude", "coupled_amplitudes", "amplitude_stage", "impact_stage", "stats_settings"]


def handoff(harm, digits: int):
    """The impact parameters the FE stages give (:class:`impact.params.ImpactParams`): the unloaded
    tip amplitude of ``harm`` (:class:`results.stage_harmonic.Harmonic`), its working frequency
    and horn mass (the default horn mass if the mesh has none), rounded as the module says."""
    from impact.params import ImpactParams

    m_horn = harm.horn_mass if harm.horn_mass is not None else ImpactParams().m_horn
    return ImpactParams(A0=round_sig(harm.wp.tip_amplitude_m, digits), freq=round_sig(harm.f_w, digits + 2),
                        m_horn=round_sig(m_horn, digits))


@dataclass
class CoupledAmplitude:
    """Fixed point of the horn amplitude under the impact load (one free mass)."""

    m_free: float
    A0: float
    A0_unloaded: float
    tip_damping: float
    impact_power_w: float
    history: list = field(default_factory=list)
    converged: bool = True
    note: str = ""


def coupled_amplitudes(point_fn: Callable[[float], float], base, masses, *, omega: float, scenario="device",
                       settings=None, rtol: float = 0.03, max_iter: int = 8, digits: int = 4) -> dict:
    """Iterate ``A0 -> impact power -> tip damper -> A0`` to a fixed point for every free mass.

    The masses advance in lockstep: each iteration is one ensemble batch (:func:`impact.stats.
    ensemble_batch`) over the masses not yet converged. The power is the ensemble mean of the
    horn's work on the free mass per second in ``scenario``, and the tip damper that draws it is
    ``c = 2 P / (omega A0)^2``; the loop stops when the amplitude moves by less than ``rtol``
    (3 %, the confidence of that mean), with geometric-mean relaxation (the plain loop
    overshoots). A mass still wandering after ``max_iter`` iterations gets the mean of its last
    three iterates (``converged`` False, ``note`` says so). Every amplitude is rounded to
    ``digits`` significant digits.

    Parameters
    ----------
    point_fn : callable(c) -> tip amplitude (m) of the harmonic working point with a tip damper
        ``c`` (N s/m)
    base : impact.params.ImpactParams (A0 and m_free are replaced)
    masses : free masses, kg
    omega : drive angular frequency, rad/s
    settings : impact.stats.StatsSettings (the ensemble rule)

    Returns
    -------
    dict mass -> CoupledAmplitude
    """
    from impact.stats import ensemble_batch

    a_free = round_sig(point_fn(0.0), digits)
    state = {m: CoupledAmplitude(m_free=m, A0=a_free, A0_unloaded=a_free, tip_damping=0.0,
                                 impact_power_w=0.0, converged=False) for m in masses}
    for _ in range(max_iter):
        active = [m for m in masses if not state[m].converged and not state[m].note]
        if not active:
            break
        stats = ensemble_batch([base.with_(m_free=m, A0=state[m].A0) for m in active], scenario, settings)
        for m, est in zip(active, stats):
            _advance(state[m], est, point_fn, omega, rtol, digits)
    for st in state.values():
        if not st.converged and not st.note and st.history:
            st.A0 = round_sig(float(np.mean([h["A0_next_m"] for h in st.history[-3:]])), digits)
            st.note = f"not within {rtol:.0%} after {max_iter} iterations: mean of the last three iterates"
    return state


def _advance(st: CoupledAmplitude, est, point_fn, omega: float, rtol: float, digits: int) -> None:
    """One step of the fixed-point loop of one free mass, from its ensemble statistics ``est``."""
    power = est["horn_power_w"]
    if not np.isfinite(power.mean):
        st.note = f"no impact statistics at A0 = {st.A0:.3g} m: {est.note}"
        log.warning("m_free %g kg: %s", st.m_free, st.note)
        return
    st.impact_power_w = power.mean
    st.tip_damping = 2.0 * st.impact_power_w / (omega * st.A0) ** 2
    a_new = round_sig(point_fn(st.tip_damping), digits)
    st.history.append({"A0_m": st.A0, "impact_power_w": st.impact_power_w,
                       "impact_power_ci95_w": power.half_width,
                       "tip_damping_ns_per_m": st.tip_damping, "A0_next_m": a_new, "members": est.members})
    if abs(a_new / st.A0 - 1.0) < rtol:
        st.A0, st.converged = a_new, True
    else:
        st.A0 = round_sig(float(np.sqrt(st.A0 * a_new)), digits)


def amplitude_stage(harm, base, masses, *, voltage: float, settings, scenario: str = "device",
                    couple: bool = True, digits: int = 4) -> dict:
    """The horn-tip amplitude at ``voltage`` (V) for every free mass (kg) of ``masses``: the fixed
    point under the impact load in ``scenario`` (:func:`coupled_amplitudes`), or with ``couple``
    False the unloaded amplitude ``base.A0``. Returns mass -> :class:`CoupledAmplitude`."""
    if not couple:
        return {m: CoupledAmplitude(m, base.A0, base.A0, 0.0, 0.0) for m in masses}
    return coupled_amplitudes(harm.tip_amplitude(voltage), base, list(masses), omega=2 * np.pi * harm.f_w,
                              scenario=scenario, settings=settings, digits=digits)


def impact_stage(base, masses, amplitudes: dict, *, scenario: str, settings):
    """Converged ensemble statistics for every free mass (kg) at its amplitude (``amplitudes``:
    mass -> :class:`CoupledAmplitude`) in ``scenario``: an :class:`impact.sweeps.SweepResult`."""
    from impact.sweeps import sweep

    return sweep(base, list(masses), scenario=scenario, settings=settings,
                 A0_values=[amplitudes[m].A0 for m in masses])


def stats_settings(rel_tol: float, max_members: int, seed: int):
    """The ensemble rule (:class:`impact.stats.StatsSettings`): add members, 64 first, until every
    95 % CI half-width is within ``rel_tol`` of its mean or ``max_members`` is reached."""
    from impact.stats import StatsSettings

    return StatsSettings(rel_tol=rel_tol, n_start=min(64, max_members), n_max=max_members, seed=seed)
