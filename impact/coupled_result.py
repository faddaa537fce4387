"""The outcome of a coupled run (modal horn in the impact loop): :class:`CoupledResult`, the
horn's state between events (:func:`propagate`, :func:`states_on`, :func:`tip_of`) and its energy
balance."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rpud_common import ParameterError

from .horn import ModalHorn, segment_integrals
from .result import ImpactResult

__all__ = ["CoupledResult", "propagate", "states_on", "tip_of"]


@dataclass
class CoupledResult:
    """A coupled run: the impact events plus the horn's history.

    Attributes
    ----------
    impact : ImpactResult
        Events as in :func:`impact.model.simulate` (``horn_work``: cumulative work of the horn on
        the free mass, J; ``energy``: free mass + tool mechanical energy, J).
    horn : ModalHorn
    freq_hz : float
        Drive frequency, Hz.
    seg_t0 : ndarray (k,)
        Segment starts, s (segments end at the next start or ``t_end``).
    seg_q, seg_qd : ndarray (k, n)
        Modal coordinates and velocities at the segment starts (with a series-resistance drive the
        ``n + 1`` pseudo-modal ones of :mod:`impact.drive`).
    impulse : ndarray (n_events,)
        Impulse on the free mass at each impact (N s; tool impacts included).
    tip_v_before, tip_v_after : ndarray (n_events,)
        Horn-tip velocity just before / after each impact, m/s.
    t_grid, u, tip_velocity : ndarray
        Tip displacement (m) and velocity (m/s) on the uniform grid ``sample_dt`` (with ``series``).
    """

    impact: ImpactResult
    horn: ModalHorn
    freq_hz: float
    seg_t0: np.ndarray
    seg_q: np.ndarray
    seg_qd: np.ndarray
    impulse: np.ndarray
    tip_v_before: np.ndarray
    tip_v_after: np.ndarray
    t_grid: np.ndarray | None = None
    u: np.ndarray | None = None
    tip_velocity: np.ndarray | None = None
    extra: dict = field(default_factory=dict)

    # ------------------------------------------------------------------ energy
    def stored_energy(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Modal kinetic + strain energy of states (k, n), J."""
        h = self.horn
        return 0.5 * (h.modal_mass * qd ** 2 + h.modal_mass * h.omega ** 2 * q ** 2).sum(axis=-1)

    def state_at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Modal coordinates and velocities at time t (from the segment containing it)."""
        if self.horn.series_resistance > 0:
            from . import drive_result as drive

            x, xd, _ = drive.physical(self, [t])
            return x[0, :self.horn.n_modes], x[0, self.horn.n_modes:2 * self.horn.n_modes]
        j = int(np.searchsorted(self.seg_t0, t, side="right") - 1)
        return propagate(self.horn, self.freq_hz, self.seg_t0[j], self.seg_q[j], self.seg_qd[j], t - self.seg_t0[j])

    def energy_balance(self, edges) -> list[dict]:
        """Energy per interval between consecutive ``edges`` (s), every term in J.

        ``electric_j``: electrical energy drawn from the source, ``int V I dt``;
        ``drive_j``: work of the drive on the modes plus on the quasi-static residual during
        impacts (the electrical input converted to mechanics); ``damping_j``: modal damping loss
        (mechanical and dielectric, as the LossModel's modal loss factors); ``stored_change_j``;
        ``to_free_mass_j``: work of the horn on the free mass at horn impacts; ``restitution_horn_j``
        and ``restitution_tool_j``: energy lost in the impacts; ``to_tool_j``: kinetic energy given
        to the drill tool at tool impacts; ``riding_j``: work of the tip on a free mass riding it
        (sticking phases ending in the interval; not drawn from the modes, see the module
        docstring). ``residual_j`` = drive - damping - stored change - to_free_mass (0 up to
        round-off). With a series-resistance drive the port adds ``source_loss_j``,
        ``electrode_change_j`` and ``electric_residual_j`` (:func:`impact.drive_result.port_terms`).
        """
        if self.extra.get("compliant"):
            raise ParameterError("energy_balance", "compliant contact",
                                 "needs closed-form segments; not available with the Hunt-Crossley option")
        edges = np.asarray(edges, float)
        rows = []
        for a, b in zip(edges[:-1], edges[1:]):
            if self.horn.series_resistance > 0:
                from . import drive_result

                row = drive_result.port_terms(self, a, b)
            else:
                row = self._voltage_terms(a, b)
            row.update(self._impact_terms(a, b))
            row["residual_j"] = row["drive_j"] - row["damping_j"] - row["stored_change_j"] - row["to_free_mass_j"]
            rows.append({"t_from_s": float(a), "t_to_s": float(b), **row})
        return rows

    def _integrals(self, a: float, b: float) -> dict:
        """:func:`impact.horn.segment_integrals` summed over the parts of the segments in [a, b]."""
        ends = np.append(self.seg_t0[1:], self.impact.params.t_end)
        lo = np.maximum(self.seg_t0, a)
        hi = np.minimum(ends, b)
        sel = hi > lo
        return segment_integrals(self.horn, self.freq_hz, self.seg_t0[sel], self.seg_q[sel], self.seg_qd[sel],
                                 lo[sel] - self.seg_t0[sel], hi[sel] - self.seg_t0[sel])

    def _voltage_terms(self, a: float, b: float) -> dict:
        """Electrical input, work on the modes, damping loss and stored change over [a, b] (voltage drive)."""
        integ = self._integrals(a, b)
        # the residual is a driven displacement: the source's work on the free mass at horn impacts
        W = 2 * math.pi * self.freq_hz
        imp = self.impact
        hw = ~imp.is_tool & (imp.t >= a) & (imp.t < b)
        res_vel = (1j * W * self.horn.residual_phasor() * np.exp(1j * W * imp.t[hw])).real
        q_a, qd_a = self.state_at(a)
        q_b, qd_b = self.state_at(b)
        return {"electric_j": float(integ["electric_j"].sum()),
                "drive_j": float(integ["drive_j"].sum() + np.sum(self.impulse[hw] * res_vel)),
                "damping_j": float(integ["damping_j"].sum()),
                "stored_change_j": float(self.stored_energy(q_b, qd_b) - self.stored_energy(q_a, qd_a))}

    def tip_at(self, t: float) -> tuple[float, float]:
        """Tip displacement (m) and velocity (m/s) at time t."""
        if self.horn.series_resistance > 0:
            from . import drive_result

            u, ud = drive_result.tip_series(self, [t])
            return float(u[0]), float(ud[0])
        return tip_of(self, t, *self.state_at(t))

    def _impact_terms(self, a: float, b: float) -> dict:
        """Work on the free mass, restitution losses, energy to the tool and riding work over [a, b]."""
        p = self.impact.params
        imp = self.impact
        inw = (imp.t >= a) & (imp.t < b)
        hw = ~imp.is_tool & inw
        tw = imp.is_tool & inw
        J = self.impulse
        rel_h = imp.w_before[hw] - self.tip_v_before[hw]
        mu_h = 1.0 / (1.0 / p.m_free + 1.0 / self.horn.tip_mass)
        rel_t = imp.w_before[tw] - imp.v_before[tw]
        mu_t = p.m_free * p.m_tool / (p.m_free + p.m_tool)
        riding = 0.0
        for s0, s1, body in imp.stick:
            if body == "horn" and a <= s1 < b and s1 < p.t_end:
                (u0, ud0), (u1, ud1) = self.tip_at(s0), self.tip_at(s1)
                riding += (0.5 * p.m_free * ud1 ** 2 - p.m_free * p.a_free * u1) - \
                          (0.5 * p.m_free * ud0 ** 2 - p.m_free * p.a_free * u0)
        return {"to_free_mass_j": float(np.sum(J[hw] * 0.5 * (self.tip_v_before[hw] + self.tip_v_after[hw]))),
                "restitution_horn_j": float(np.sum(0.5 * mu_h * (1 - p.e2 ** 2) * rel_h ** 2)),
                "restitution_tool_j": float(np.sum(0.5 * mu_t * (1 - p.e1 ** 2) * rel_t ** 2)),
                "to_tool_j": float(np.sum(0.5 * p.m_tool * (imp.v_after[tw] ** 2 - imp.v_before[tw] ** 2))),
                "riding_j": float(riding)}

    def envelope(self, cycles: int = 4) -> tuple[np.ndarray, np.ndarray]:
        """Running amplitude of the tip: the fundamental at the drive over consecutive windows of
        ``cycles`` drive periods, ``|2/T int u e^{-jWt} dt|`` (closed form). Returns window
        centres (s) and amplitudes (m)."""
        T = cycles / self.freq_hz
        n = int(math.floor(self.impact.params.t_end / T + 1e-9))
        edges = np.arange(n + 1) * T
        amp = np.array([abs(2.0 / T * self._fundamental(a, b)) for a, b in zip(edges[:-1], edges[1:])])
        return 0.5 * (edges[:-1] + edges[1:]), amp

    def _fundamental(self, a: float, b: float) -> complex:
        if self.horn.series_resistance > 0:
            from . import drive_result as drive

            return drive.fundamental(self, a, b)
        integ = self._integrals(a, b)
        return complex(integ["fundamental"].sum())

    def mean_amplitude(self, t_from: float, t_to: float) -> float:
        """Amplitude of the tip's fundamental over [t_from, t_to], m."""
        return abs(2.0 / (t_to - t_from) * self._fundamental(t_from, t_to))

    def drive_power(self, t_from: float, t_to: float, dt: float | None = None) -> tuple[float, float]:
        """Mean electrical power drawn (W) and RMS drive current (A) over [t_from, t_to], from
        the current ``I = dQ/dt`` sampled at ``dt`` (default: 64 points per drive period); with a
        series resistance the source's power and current (:func:`impact.drive.drive_power`)."""
        if self.horn.series_resistance > 0:
            from . import drive_result as drive

            return drive.drive_power(self, t_from, t_to, dt)
        dt = dt or 1.0 / (64 * self.freq_hz)
        t = np.arange(t_from, t_to, dt)
        q, qd, qdd = states_on(self, t)
        h = self.horn
        W = 2 * math.pi * self.freq_hz
        I = h.drive_current(self.freq_hz, t, qd, qdd)
        V = h.voltage * np.sin(W * t)
        return float(np.mean(V * I)), float(np.sqrt(np.mean(I ** 2)))


def tip_of(res: "CoupledResult", t: float, q, qd) -> tuple[float, float]:
    """Tip displacement and velocity from the modal state at time t."""
    W = 2 * math.pi * res.freq_hz
    r = res.horn.residual_phasor() * np.exp(1j * W * t)
    return float(q @ res.horn.tip + r.real), float(qd @ res.horn.tip + (1j * W * r).real)


def propagate(horn: ModalHorn, freq_hz: float, t0: float, q0, qd0, s):
    """Modal state at t0 + s from (q0, qd0) at t0 (free evolution under the drive)."""
    W = 2 * math.pi * freq_hz
    qs = horn.steady_modal(freq_hz)
    e0 = np.exp(1j * W * t0)
    h0 = q0 - (qs * e0).real
    hd0 = qd0 - (1j * W * qs * e0).real
    mu = -horn.zeta * horn.omega + 1j * horn.omega * np.sqrt(1 - horn.zeta ** 2)
    C = h0 - 1j * (hd0 - h0 * mu.real) / mu.imag
    es = np.exp(mu * s)
    e1 = np.exp(1j * W * (t0 + s))
    return (qs * e1).real + (C * es).real, (1j * W * qs * e1).real + (C * mu * es).real


def states_on(res: CoupledResult, t: np.ndarray):
    """Modal q, q', q'' at sorted times t (len(t), n)."""
    h = res.horn
    W = 2 * math.pi * res.freq_hz
    qs = h.steady_modal(res.freq_hz)
    mu = -h.zeta * h.omega + 1j * h.omega * np.sqrt(1 - h.zeta ** 2)
    idx = np.searchsorted(res.seg_t0, t, side="right") - 1
    t0 = res.seg_t0[idx][:, None]
    e0 = np.exp(1j * W * t0)
    h0 = res.seg_q[idx] - (qs * e0).real
    hd0 = res.seg_qd[idx] - (1j * W * qs * e0).real
    C = h0 - 1j * (hd0 - h0 * mu.real) / mu.imag
    es = np.exp(mu * (t[:, None] - t0))
    e1 = np.exp(1j * W * t[:, None])
    q = (qs * e1).real + (C * es).real
    qd = (1j * W * qs * e1).real + (C * mu * es).real
    qdd = (-W * W * qs * e1).real + (C * mu * mu * es).real
    return q, qd, qdd
