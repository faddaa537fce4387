"""The outcome of an impact run: :class:`ImpactResult`, its window statistics
(:func:`window_stats`), sampled positions (:func:`sample_series`), and the failures
(:class:`SimulationError`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rpud_common.result import Result

from .columns import (FREE, N_STATS, ON_HORN, ON_TOOL, S_HORN_WORK, S_KE_AFTER, S_KE_GAIN, S_N_EVENTS, S_N_HORN,
                      S_N_TOOL, S_STATUS, S_T_ON_HORN, S_T_ON_TOOL)
from .oscillator import Oscillator
from .params import ImpactParams

__all__ = ["ImpactResult", "SimulationError", "window_stats", "sample_series", "amplitude_spectrum",
           "pinch_message", "max_events_message", "HORN", "TOOL", "N_STATS"]

#: contact names of :attr:`ImpactResult.contact`
HORN, TOOL = "horn", "tool"


class SimulationError(RuntimeError):
    """The simulation cannot continue (pinched free mass, event cap reached)."""


def max_events_message(max_events: int, te: float) -> str:
    """The message of a run stopped by its event cap at te (s)."""
    return f"more than max_events = {max_events} events by t = {te:.9g} s"


def pinch_message(te: float) -> str:
    return (f"free mass pinched between horn and tool at t = {te:.9g} s: the tool face swings "
            f"back into the horn's stroke; increase gap or k0")

def amplitude_spectrum(x: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Single-sided amplitude spectrum of a uniformly sampled signal (mean removed).

    Parameters
    ----------
    x : ndarray
        Samples (any unit).
    dt : float
        Sample spacing, s.

    Returns
    -------
    freq : ndarray
        Frequencies, Hz.
    amp : ndarray
        Amplitude of each sinusoidal component, same unit as ``x`` (2|X|/N, DC as |X|/N).
    """
    x = np.asarray(x, dtype=float)
    n = x.size
    X = np.fft.rfft(x - x.mean())
    amp = np.abs(X) / n
    amp[1:] *= 2.0
    if n % 2 == 0:
        amp[-1] /= 2.0
    return np.fft.rfftfreq(n, dt), amp


@dataclass(repr=False)
class ImpactResult(Result):
    """Outcome of :func:`simulate`: one trajectory, i.e. one sample of a chaotic motion (for
    numbers to read, use the ensemble statistics of :func:`impact.ensemble_statistics`).

    Event arrays (one entry per impact, time-ordered):

    ``t`` (s), ``contact`` ("horn"/"tool"), ``x`` (contact position, m), ``w_before``/``w_after``
    (free-mass velocity, m/s), ``v_before``/``v_after`` (tool velocity, m/s; at a horn impact
    the tool is not involved and both equal its velocity at that time), ``energy`` (mechanical
    energy of free mass + tool after the event, J: kinetic + tool spring - m_w a w),
    ``horn_work`` (cumulative work done by the horn up to and including the event, J).

    ``stick`` lists (t_start, t_end, body) of sticking phases. ``n_events`` counts impacts and
    releases (the solver's events). ``t_grid`` (s), ``u``, ``w``
    and ``tool_face`` (m) are the horn tip, free mass and tool face positions on a uniform grid.
    """

    params: ImpactParams
    t: np.ndarray
    contact: np.ndarray
    x: np.ndarray
    w_before: np.ndarray
    w_after: np.ndarray
    v_before: np.ndarray
    v_after: np.ndarray
    energy: np.ndarray
    horn_work: np.ndarray
    energy0: float
    stick: list = field(default_factory=list)
    n_events: int = 0
    t_grid: np.ndarray | None = None
    u: np.ndarray | None = None
    w: np.ndarray | None = None
    tool_face: np.ndarray | None = None

    @property
    def is_tool(self) -> np.ndarray:
        return self.contact == TOOL

    @property
    def tool_impacts(self) -> int:
        return int(np.count_nonzero(self.is_tool))

    @property
    def horn_impacts(self) -> int:
        return int(self.t.size - self.tool_impacts)

    @property
    def tool_impact_rate_hz(self) -> float:
        """Mean free-mass/tool collision rate over the simulated time, Hz."""
        return self.tool_impacts / self.params.t_end

    @property
    def horn_impact_rate_hz(self) -> float:
        return self.horn_impacts / self.params.t_end

    @property
    def tool_ke_after(self) -> np.ndarray:
        """Drill-tool kinetic energy just after each tool impact, J."""
        return 0.5 * self.params.m_tool * self.v_after[self.is_tool] ** 2

    @property
    def mean_tool_ke_after_impact_j(self) -> float:
        ke = self.tool_ke_after
        return float(ke.mean()) if ke.size else 0.0

    def spectrum(self) -> tuple[np.ndarray, np.ndarray]:
        """Amplitude spectrum of the free-mass displacement (Hz, m): the Fig. 12 analogue."""
        if self.w is None:
            raise ValueError("simulate(..., series=False) recorded no time series")
        return amplitude_spectrum(self.w, self.params.sample_dt)

    def events(self) -> list[dict]:
        return [
            {"t": float(self.t[i]), "contact": str(self.contact[i]),
             "w_before": float(self.w_before[i]), "w_after": float(self.w_after[i]),
             "v_before": float(self.v_before[i]), "v_after": float(self.v_after[i])}
            for i in range(self.t.size)
        ]

    def summary(self) -> dict:
        return {
            "tool_impacts": self.tool_impacts,
            "horn_impacts": self.horn_impacts,
            "tool_impact_rate_hz": self.tool_impact_rate_hz,
            "horn_impact_rate_hz": self.horn_impact_rate_hz,
            "mean_tool_ke_after_impact_j": self.mean_tool_ke_after_impact_j,
            "sticking_phases": len(self.stick),
        }

    def _headline(self) -> str:
        p = self.params
        return (f"one sample, {p.m_free * 1e3:g} g free mass, A0 {p.A0 * 1e6:.3g} um, {p.t_end * 1e3:g} ms: "
                f"{self.tool_impacts} tool and {self.horn_impacts} horn impacts, "
                f"mean tool KE after impact {self.mean_tool_ke_after_impact_j * 1e3:.3g} mJ")

    def _arrays(self) -> dict:
        out = {k: getattr(self, k) for k in ("t", "x", "w_before", "w_after", "v_before", "v_after", "energy",
                                             "horn_work")}
        out["is_tool"] = self.is_tool
        if self.t_grid is not None:
            out.update(t_grid=self.t_grid, u=self.u, w=self.w, tool_face=self.tool_face)
        return out

    def _record(self) -> dict:
        """The CLI's JSON document: params, counts, rates, mean tool KE, events."""
        out = {"params": self.params.to_dict()}
        out.update(self.summary())
        out["events"] = self.events()
        return out

def window_stats(result: ImpactResult, t_from: float, t_end: float) -> np.ndarray:
    """Statistics of one run over the window ``[t_from, t_end]`` (pure Python).

    Parameters
    ----------
    result : ImpactResult
        A finished simulation.
    t_from, t_end : float
        Window, s.

    Returns
    -------
    ndarray, shape (N_STATS,)
        Columns ``S_N_TOOL``, ``S_N_HORN`` (impacts with t_from <= t <= t_end), ``S_KE_AFTER``
        (sum of 0.5 m_tool v_after^2 over those tool impacts, J), ``S_KE_GAIN`` (sum of
        0.5 m_tool (v_after^2 - v_before^2), J), ``S_HORN_WORK`` (cumulative horn work at the
        last impact <= t_end minus that at the last impact < t_from, J), ``S_T_ON_HORN``,
        ``S_T_ON_TOOL`` (sticking time clipped to the window, s), ``S_STATUS`` (0: a finished
        run) and ``S_N_EVENTS`` (impacts and releases of the whole run).
    """
    r = result
    m_tool = r.params.m_tool
    out = np.zeros(N_STATS)
    inw = (r.t >= t_from) & (r.t <= t_end)
    tool = inw & r.is_tool
    out[S_N_TOOL] = np.count_nonzero(tool)
    out[S_N_HORN] = np.count_nonzero(inw & ~r.is_tool)
    out[S_KE_AFTER] = float(np.sum(0.5 * m_tool * r.v_after[tool] ** 2))
    out[S_KE_GAIN] = float(np.sum(0.5 * m_tool * (r.v_after[tool] ** 2 - r.v_before[tool] ** 2)))
    i_end = np.searchsorted(r.t, t_end, side="right") - 1
    i_from = np.searchsorted(r.t, t_from, side="left") - 1
    w_end = r.horn_work[i_end] if i_end >= 0 else 0.0
    w_from = r.horn_work[i_from] if i_from >= 0 else 0.0
    out[S_HORN_WORK] = w_end - w_from
    for s0, s1, body in r.stick:
        d = max(0.0, min(s1, t_end) - max(s0, t_from))
        out[S_T_ON_HORN if body == "horn" else S_T_ON_TOOL] += d
    out[S_STATUS] = 0.0
    out[S_N_EVENTS] = r.n_events
    return out

def sample_series(res: ImpactResult, seg) -> None:
    """Sample horn, free mass and tool face on the uniform grid ``sample_dt`` from the
    segment starts ``(t0, mode, w0, wd0, v0, vd0)`` (analytic motion within each segment)."""
    p = res.params
    a, L0, A0, om = p.a_free, p.gap, p.A0, p.omega
    M = p.m_tool + p.m_free
    n = int(math.floor(p.t_end / p.sample_dt + 1e-9)) + 1
    tg = np.arange(n) * p.sample_dt
    u = A0 * np.cos(om * tg)
    w = np.empty(n)
    face = np.empty(n)
    seg_t0, seg_mode, seg_w0, seg_wd0, seg_v0, seg_vd0 = seg
    idx = np.searchsorted(tg, seg_t0, side="left")
    idx = np.append(idx, n)
    for j in range(seg_t0.size):
        i0, i1 = idx[j], idx[j + 1]
        if i1 <= i0:
            continue
        t0, mode = float(seg_t0[j]), int(seg_mode[j])
        if mode == ON_TOOL:
            osc = Oscillator(M, p.k0, p.c, p.m_free * a / p.k0, float(seg_v0[j]), float(seg_vd0[j]))
        else:
            osc = Oscillator(p.m_tool, p.k0, p.c, 0.0, float(seg_v0[j]), float(seg_vd0[j]))
        s = tg[i0:i1] - t0
        vv, _ = osc.pv_vec(s)
        face[i0:i1] = L0 + vv
        if mode == FREE:
            w[i0:i1] = seg_w0[j] + s * (seg_wd0[j] + 0.5 * a * s)
        elif mode == ON_HORN:
            w[i0:i1] = u[i0:i1]
        else:
            w[i0:i1] = L0 + vv
    res.t_grid, res.u, res.w, res.tool_face = tg, u, w, face
