"""The results of a coupled run with a series-resistance drive (:mod:`impact.drive`): tip history,
fundamental, source power and current, and the energy balance of the port and of the modes, from
the run's pseudo-modal segments (closed form, the kernel's integrals)."""

from __future__ import annotations

import math

import numpy as np

from .drive import SeriesModel, pack_series, physical_states, series_model
from .kernel_energy import segment_energy_series

__all__ = ["model_of", "tip_series", "fundamental", "drive_power", "port_terms", "physical"]


def model_of(res) -> SeriesModel:
    """The :class:`SeriesModel` of a coupled result (built once, kept in ``res.extra``)."""
    m = res.extra.get("series_model")
    if m is None:
        m = series_model(res.horn, res.freq_hz)
        res.extra["series_model"] = m
    return m


def physical(res, t):
    """Physical states ``[x, x', x'']`` (each (p, 2n + 1)) of a run at sorted times ``t``."""
    m = model_of(res)
    return physical_states(m, res.seg_t0, res.seg_q, res.seg_qd, np.atleast_1d(np.asarray(t, float)), order=2)


def tip_series(res, t) -> tuple[np.ndarray, np.ndarray]:
    """Tip displacement (m) and velocity (m/s) at sorted times ``t``."""
    x, xd, _ = physical(res, t)
    n = res.horn.n_modes
    return x[:, :n] @ res.horn.tip, xd[:, :n] @ res.horn.tip


def _segment_sums(res, a: float, b: float) -> np.ndarray:
    """(source work, source loss, conversion, damping, fundamental) over [a, b], closed form."""
    m = model_of(res)
    packed = res.extra.get("series_tables")
    if packed is None:
        # built once per result: the envelope asks for hundreds of windows
        packed = pack_series(res.horn, m) + m.kernel_tables(res.horn)
        res.extra["series_tables"] = packed
    tab, xs, lam, G1, G2 = packed
    cw = np.empty(m.n_pseudo + 1, complex)
    ends = np.append(res.seg_t0[1:], res.impact.params.t_end)
    out = np.zeros(5, complex)
    for j in np.flatnonzero((ends > a) & (res.seg_t0 < b)):
        t0 = res.seg_t0[j]
        lo, hi = max(t0, a), min(ends[j], b)
        if hi > lo:
            out += np.array(segment_energy_series(tab, xs, m.n_pseudo, t0, res.seg_q[j], res.seg_qd[j], lo - t0, hi - t0,
                                              lam, G1, G2, cw))
    return out


def fundamental(res, a: float, b: float) -> complex:
    """``int_a^b u e^{-jWt} dt`` of the tip, m s."""
    return complex(_segment_sums(res, a, b)[4])


def drive_power(res, t_from: float, t_to: float, dt: float | None = None) -> tuple[float, float]:
    """Mean power drawn from the source (W) and RMS source current (A) over [t_from, t_to]:
    ``V_s i``, ``i = (V_s - V_p) / R`` sampled at ``dt`` (default: 64 points per drive period)."""
    m = model_of(res)
    dt = dt or 1.0 / (64 * res.freq_hz)
    t = np.arange(t_from, t_to, dt)
    x = physical(res, t)[0]
    vs = res.horn.voltage * np.sin(2 * math.pi * res.freq_hz * t)
    i = (vs - x[:, -1]) / m.R
    return float(np.mean(vs * i)), float(np.sqrt(np.mean(i ** 2)))


def port_terms(res, a: float, b: float) -> dict:
    """The series drive's energy terms over [a, b], J (the impact terms are the voltage drive's).

    ``electric_j``: the source's work ``int V_s i dt``; ``source_loss_j``: resistor and dielectric
    loss ``int (R i^2 + G V_p^2) dt``; ``electrode_change_j``: change of ``C0 V_p^2 / 2``;
    ``drive_j``: the conversion to mechanics ``int V_p sum theta_i q_i' dt``; ``damping_j``: modal
    damping loss; ``stored_change_j``: modal energy change; ``electric_residual_j`` = electric -
    source loss - electrode change - drive (the port's balance, 0 up to round-off).
    """
    m = model_of(res)
    src, loss, conv, damp, _ = (float(v.real) for v in _segment_sums(res, a, b))
    xa, xb = physical(res, [a, b])[0]
    mech = m.modal_energy(res.horn, np.vstack([xa, xb]))
    de = float(0.5 * m.C0 * (xb[-1] ** 2 - xa[-1] ** 2))
    return {"electric_j": src, "source_loss_j": loss, "electrode_change_j": de, "drive_j": conv, "damping_j": damp,
            "stored_change_j": float(mech[1] - mech[0]), "electric_residual_j": src - loss - de - conv}
