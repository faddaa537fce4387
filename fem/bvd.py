"""Butterworth-Van Dyke fit of a measured admittance sweep: the drill's own losses.

An impedance analyser sweeps the transducer's terminals through a resonance and writes a CSV of
frequency and either ``|Z|`` and its phase, or the conductance ``G`` and susceptance ``B``.
Near one resonance the admittance is the Butterworth-Van Dyke circuit: the motional branch
``R, L, C`` in series, in parallel with the clamped capacitance ``C0`` and its dielectric loss::

    Y(w) = w C0 tan(delta) + j w C0 + 1 / (R (w_s / w) + j w L + 1 / (j w C))

The motional resistance is hysteretic (``R w_s / w``: a loss factor independent of frequency,
the loss the FE model carries, :class:`fem.harmonic.LossModel`); it equals ``R`` at the series
resonance, where the viscous circuit's constant ``R`` is indistinguishable from it, but over a
window that spans the anti-resonance of a strongly coupled mode the constant ``R`` would misfit
the conductance and push the fitted ``tan(delta)`` negative. Then ``f_s = 1 / (2 pi sqrt(L C))`` (series resonance, the short-circuit eigenfrequency),
``f_p = f_s sqrt(1 + C / C0)`` (parallel resonance), ``Q_m = 2 pi f_s L / R`` and
``k_eff^2 = 1 - (f_s / f_p)^2 = C / (C + C0)``.

Fit
---
Each resonance (a peak of ``G``) is fitted on its own window (between the midpoints to the
neighbouring peaks) by nonlinear least squares on the complex admittance relative to its
modulus (an analyser's error is a fraction of the reading), in the parameters ``ln f_s, ln Q_m,
ln C, ln C0, tan(delta)``. Start values come from the curve: the ``G`` peak (``f_s``, ``R``), its
half-power width (``Q_m``), the ``|Y|`` minimum above it (``f_p``, hence ``C0``). The 95 %
confidence intervals are the linearised ones: covariance ``s^2 (J^T J)^-1`` with ``s^2`` the
residual variance (``2n - p`` degrees of freedom), Student-t quantile, propagated to ``R, L, C``,
``f_p`` and ``k_eff`` through their Jacobians.

Use in the models
-----------------
A uniform mechanical ``q_mech`` on every part gives the driven mode a modal loss factor
``eta = a / q_mech + b tan(delta)`` (``a``: the share of its stiffness that carries the mechanical
loss; ``b`` the dielectric share), not ``1 / q_mech``. :func:`calibrated_losses` picks the
``q_mech`` for which the FE working mode's modal quality factor ``1 / eta`` equals the measured
``Q_m``, with the measured ``tan(delta)``.
"""

from __future__ import annotations

import csv
import logging
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rpud_common import ParameterError

__all__ = ["AdmittanceData", "read_admittance", "BVDFit", "bvd_admittance", "fit_resonance", "fit_bvd",
           "calibrated_losses", "measured_losses", "MIN_POINTS", "MAX_MISMATCH", "MISFIT"]

log = logging.getLogger(__name__)

MISFIT = 0.01
"""Relative rms misfit above which a fit is flagged (an analyser's reading error is ~0.1-1 %)."""

MIN_POINTS = 12
"""Fewest rows of a sweep (and of one resonance's window): 5 parameters need a margin."""

_UNITS = {"frequency": {"hz": 1.0, "khz": 1e3, "mhz": 1e6},
          "z": {"ohm": 1.0, "ohms": 1.0, "kohm": 1e3, "mohm": 1e6},
          "phase": {"deg": 1.0, "degree": 1.0, "degrees": 1.0, "rad": 180 / math.pi},
          "g": {"s": 1.0, "ms": 1e-3, "us": 1e-6}, "b": {"s": 1.0, "ms": 1e-3, "us": 1e-6}}
_NAMES = {"frequency": ("frequency", "freq", "f"), "z": ("|z|", "z", "zabs", "z_abs", "impedance"),
          "phase": ("phase", "theta", "phase_z"), "g": ("g", "conductance"), "b": ("b", "susceptance")}
_DEFAULT_UNIT = {"frequency": "hz", "z": "ohm", "phase": "deg", "g": "s", "b": "s"}


@dataclass(frozen=True, eq=False)
class AdmittanceData:
    """A measured sweep: ``freqs_hz`` (increasing, Hz), complex ``admittance`` (S), ``source``."""

    freqs_hz: np.ndarray
    admittance: np.ndarray
    source: str = ""


def _column(header: str, path: str) -> tuple[str, float]:
    """The quantity and unit factor of one header cell: ``"Frequency (kHz)"`` -> ("frequency", 1e3)."""
    h = header.strip().lower()
    m = re.fullmatch(r"(.+?)\s*(?:[\(\[]\s*([a-z]+)\s*[\)\]]|_(hz|khz|mhz|ohm|kohm|deg|rad|s|ms|us))?", h)
    name, unit = (m.group(1).strip(), m.group(2) or m.group(3)) if m else (h, None)
    for q, names in _NAMES.items():
        if name in names:
            unit = unit or _DEFAULT_UNIT[q]
            if unit not in _UNITS[q]:
                raise ParameterError(f"admittance file {path}", header,
                                     f"unit '{unit}' not known for {q}; use one of {', '.join(_UNITS[q])}")
            return q, _UNITS[q][unit]
    raise ParameterError(f"admittance file {path}", header,
                         "is not a known column: give frequency and either |Z| and phase, or G and B "
                         "(e.g. 'frequency (Hz), |Z| (ohm), phase (deg)')")


def read_admittance(path) -> AdmittanceData:
    """Read an impedance-analyser CSV: a header row, then one row per frequency.

    Columns (case-insensitive, unit in parentheses/brackets or as a suffix, default unit in
    brackets): ``frequency`` [Hz; kHz, MHz] and either ``|Z|`` [ohm; kohm] with ``phase`` [deg;
    rad], or ``G`` and ``B`` [S; mS, uS]. Lines starting with ``#`` are comments. Every problem
    (missing file, unknown column, a non-number, frequencies not increasing, a passive element
    with negative conductance) is a :class:`ParameterError` naming the file and line.
    """
    p = Path(path)
    where = f"admittance file {p}"
    if not p.is_file():
        raise ParameterError(where, str(p), "is not a readable file")
    try:
        text = p.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise ParameterError(where, str(p), f"cannot be read as text ({exc.__class__.__name__})") from None
    rows = [(i + 1, r) for i, r in enumerate(csv.reader(text.splitlines()))
            if r and any(c.strip() for c in r) and not r[0].lstrip().startswith("#")]
    if not rows:
        raise ParameterError(where, "empty", "has no header and no data")
    line, header = rows[0]
    cols = [_column(h, str(p)) for h in header]
    names = [c[0] for c in cols]
    if len(set(names)) != len(names):
        raise ParameterError(where, ", ".join(header), f"line {line}: a quantity appears twice")
    if "frequency" not in names or not ({"z", "phase"} <= set(names) or {"g", "b"} <= set(names)):
        raise ParameterError(where, ", ".join(header), f"line {line}: needs frequency and either |Z| and phase, "
                                                       "or G and B")
    data = []
    for line, r in rows[1:]:
        if len(r) != len(cols):
            raise ParameterError(where, ",".join(r), f"line {line}: {len(r)} values, the header has {len(cols)}")
        try:
            vals = [float(v) for v in r]
        except ValueError:
            raise ParameterError(where, ",".join(r), f"line {line}: not a number") from None
        if not all(math.isfinite(v) for v in vals):
            raise ParameterError(where, ",".join(r), f"line {line}: values must be finite")
        data.append([v * f for v, (_, f) in zip(vals, cols)] + [line])
    if len(data) < MIN_POINTS:
        raise ParameterError(where, f"{len(data)} rows", f"needs at least {MIN_POINTS} frequencies")
    arr = np.array(data)
    col = {q: arr[:, i] for i, q in enumerate(names)}
    lines = arr[:, -1].astype(int)
    f = col["frequency"]
    bad = np.flatnonzero((f <= 0) | np.r_[False, np.diff(f) <= 0])
    if bad.size:
        raise ParameterError(where, f"{f[bad[0]]:g} Hz", f"line {lines[bad[0]]}: frequencies must be > 0 and "
                                                         "strictly increasing")
    if "z" in col and {"z", "phase"} <= set(names):
        z, ph = col["z"], col["phase"]
        bad = np.flatnonzero((z <= 0) | (np.abs(ph) > 90.0 + 1e-6))
        if bad.size:
            raise ParameterError(where, f"|Z| {z[bad[0]]:g} ohm, phase {ph[bad[0]]:g} deg",
                                 f"line {lines[bad[0]]}: |Z| must be > 0 and the phase of a passive element within "
                                 "+-90 deg")
        y = 1.0 / (z * np.exp(1j * np.radians(ph)))
    else:
        g, b = col["g"], col["b"]
        bad = np.flatnonzero((g < 0) | ((g == 0) & (b == 0)))
        if bad.size:
            raise ParameterError(where, f"G {g[bad[0]]:g} S", f"line {lines[bad[0]]}: a passive element has G >= 0 "
                                                              "and a non-zero admittance")
        y = g + 1j * b
    return AdmittanceData(f, y, str(p))


# --------------------------------------------------------------------------- the circuit


def bvd_admittance(freqs_hz, R: float, L: float, C: float, C0: float, tan_delta: float = 0.0) -> np.ndarray:
    """Admittance (S) of the Butterworth-Van Dyke circuit with hysteretic motional loss
    (module docstring; ``R`` is the motional resistance at the series resonance)."""
    w = 2 * np.pi * np.asarray(freqs_hz, float)
    ws = 1.0 / math.sqrt(L * C)
    return w * C0 * tan_delta + 1j * w * C0 + 1.0 / (R * ws / w + 1j * w * L + 1.0 / (1j * w * C))


def _circuit(theta):
    """(R, L, C, C0, tan delta) of the fit parameters (ln f_s, ln Q_m, ln C, ln C0, tan delta)."""
    fs, q, c, c0, td = math.exp(theta[0]), math.exp(theta[1]), math.exp(theta[2]), math.exp(theta[3]), theta[4]
    ws = 2 * math.pi * fs
    L = 1.0 / (ws ** 2 * c)
    return ws * L / q, L, c, c0, td


def _derived(theta) -> np.ndarray:
    """The reported quantities of the fit parameters: R, L, C, C0, tan delta, f_s, f_p, Q_m, k_eff."""
    R, L, C, C0, td = _circuit(theta)
    fs, q = math.exp(theta[0]), math.exp(theta[1])
    return np.array([R, L, C, C0, td, fs, fs * math.sqrt(1 + C / C0), q, math.sqrt(C / (C + C0))])


NAMES = ("R_ohm", "L_h", "C_f", "C0_f", "tan_delta", "f_s_hz", "f_p_hz", "q_m", "k_eff")


@dataclass(frozen=True, eq=False)
class BVDFit:
    """One resonance's Butterworth-Van Dyke fit.

    ``values`` and ``ci95`` map :data:`NAMES` (R ohm, L H, C F, C0 F, tan delta, f_s Hz, f_p Hz,
    Q_m, k_eff) to the estimate and its 95 % CI half-width; ``band_hz`` the fitted window,
    ``n_points`` its frequencies, ``rms_residual`` the relative rms misfit.
    """

    values: dict
    ci95: dict
    band_hz: tuple[float, float]
    n_points: int
    rms_residual: float
    source: str = ""
    covariance: np.ndarray = field(default=None, repr=False)

    def __getattr__(self, name):
        vals = self.__dict__.get("values") or {}
        if name in vals:
            return vals[name]
        raise AttributeError(name)

    @property
    def misfit(self) -> bool:
        """The circuit misses the sweep by more than :data:`MISFIT` rms (relative): another mode or
        a background the single resonance cannot follow; its values are biased beyond their CIs."""
        return self.rms_residual > MISFIT

    def text(self) -> str:
        v, e = self.values, self.ci95
        warn = (f"; MISFIT: the circuit misses the sweep by {self.rms_residual:.1%} rms, its values are biased "
                "beyond their CIs (a neighbouring mode in the window: sweep closer around the resonance)"
                if self.misfit else "")
        return (f"f_s {v['f_s_hz']:.1f} ± {e['f_s_hz']:.2g} Hz, f_p {v['f_p_hz']:.1f} ± {e['f_p_hz']:.2g} Hz, "
                f"Q_m {v['q_m']:.4g} ± {e['q_m']:.2g}, k_eff {v['k_eff']:.4f} ± {e['k_eff']:.2g}, "
                f"R {v['R_ohm']:.4g} ohm, L {v['L_h']:.4g} H, C {v['C_f']:.4g} F, C0 {v['C0_f']:.4g} F, "
                f"tan delta {v['tan_delta']:.3g} ± {e['tan_delta']:.2g} (95 % CI){warn}")

    def record(self) -> dict:
        return {"values": dict(self.values), "ci95_half_width": dict(self.ci95), "band_hz": list(self.band_hz),
                "n_points": self.n_points, "rms_relative_residual": self.rms_residual, "source": self.source}


def _start(f: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Start values (ln f_s, ln Q_m, ln C, ln C0, tan delta) read off the curve."""
    g = y.real
    k = int(np.argmax(g))
    fs = float(f[k])
    ws = 2 * np.pi * fs
    w = 2 * np.pi * f
    # clamped capacitance and its loss from the ends of the window, where the motional branch is weak
    c0_edge = float(np.median(y.imag[[0, -1]] / w[[0, -1]]))
    g_bg = float(min(g[0], g[-1]))
    R = 1.0 / max(g[k] - g_bg, 1e-300)
    half = g_bg + 0.5 * (g[k] - g_bg)
    lo = np.flatnonzero(g[:k] < half)
    hi = np.flatnonzero(g[k:] < half)
    if lo.size and hi.size:
        q = fs / max(f[k + hi[0]] - f[lo[-1]], f[1] - f[0])
    else:
        q = 10 * fs / (f[-1] - f[0])
    L = q * R / ws
    C = 1.0 / (ws ** 2 * L)
    above = np.flatnonzero(f > fs)
    if above.size > 2:
        kp = above[int(np.argmin(np.abs(y[above])))]
        ratio = (f[kp] / fs) ** 2 - 1
        C0 = C / ratio if ratio > 1e-6 and kp != len(f) - 1 else max(c0_edge, C)
    else:
        C0 = max(c0_edge, C)
    td = min(max(g_bg / (w[0] * C0), 0.0), 0.1)
    return np.array([math.log(fs), math.log(q), math.log(C), math.log(C0), td])


def fit_resonance(freqs_hz, admittance, source: str = "") -> BVDFit:
    """Fit one resonance (the window holds exactly one peak of ``G``): module docstring."""
    from scipy.optimize import least_squares
    from scipy.stats import t as student_t

    f = np.asarray(freqs_hz, float)
    y = np.asarray(admittance, complex)
    if f.size < MIN_POINTS:
        raise ParameterError("admittance window", f"{f.size} points", f"needs at least {MIN_POINTS}")
    scale = np.abs(y)

    def resid(theta):
        R, L, C, C0, td = _circuit(theta)
        r = (bvd_admittance(f, R, L, C, C0, td) - y) / scale
        return np.concatenate([r.real, r.imag])

    theta0 = _start(f, y)
    sol = least_squares(resid, theta0, method="lm", x_scale="jac", xtol=1e-14, ftol=1e-14, gtol=1e-14,
                        max_nfev=20000)
    J = sol.jac
    dof = 2 * f.size - J.shape[1]
    s2 = float(sol.fun @ sol.fun) / dof
    cov = s2 * np.linalg.pinv(J.T @ J)
    tq = float(student_t.ppf(0.975, dof))
    vals = _derived(sol.x)
    # the derived quantities' Jacobian by central differences in the (well-scaled) fit parameters
    D = np.zeros((len(vals), len(sol.x)))
    for i in range(len(sol.x)):
        h = 1e-6 * max(1.0, abs(sol.x[i])) if i < 4 else 1e-6 * max(abs(sol.x[i]), 1e-6)
        e = np.zeros(len(sol.x))
        e[i] = h
        D[:, i] = (_derived(sol.x + e) - _derived(sol.x - e)) / (2 * h)
    var = np.einsum("ij,jk,ik->i", D, cov, D)
    ci = tq * np.sqrt(np.maximum(var, 0.0))
    if not sol.success or not np.all(np.isfinite(vals)) or vals[0] <= 0:
        raise ParameterError("admittance fit", source or "data", f"did not converge near {math.exp(theta0[0]):.6g} "
                                                                 f"Hz ({sol.message})")
    return BVDFit(dict(zip(NAMES, map(float, vals))), dict(zip(NAMES, map(float, ci))), (float(f[0]), float(f[-1])),
                  int(f.size), float(np.sqrt(np.mean(sol.fun ** 2))), source, cov)


def fit_bvd(data: AdmittanceData, min_prominence: float = 0.1) -> list[BVDFit]:
    """Fit every resonance of a sweep: each peak of ``G`` with a prominence of at least
    ``min_prominence`` of the largest, on the window between the midpoints to its neighbours."""
    from scipy.signal import find_peaks

    f, y = data.freqs_hz, data.admittance
    g = y.real
    peaks, _ = find_peaks(g, prominence=min_prominence * (g.max() - g.min()))
    if peaks.size == 0:
        k = int(np.argmax(g))
        if k in (0, len(g) - 1):
            raise ParameterError(f"admittance file {data.source}", "no resonance",
                                 "the conductance has no peak inside the sweep: widen it around the resonance")
        peaks = np.array([k])
    edges = np.r_[0, (peaks[:-1] + peaks[1:]) // 2, len(f)]
    fits = []
    for a, b in zip(edges[:-1], edges[1:]):
        if b - a < MIN_POINTS:
            log.warning("admittance: resonance at %.6g Hz has %d points; not fitted", f[(a + b) // 2], b - a)
            continue
        fits.append(fit_resonance(f[a:b], y[a:b], data.source))
        if fits[-1].misfit:
            log.warning("admittance: %s", fits[-1].text())
    if not fits:
        raise ParameterError(f"admittance file {data.source}", f"{len(f)} rows",
                             f"no resonance has {MIN_POINTS} points around it: sample the sweep more densely")
    return fits


# --------------------------------------------------------------------------- into the FE model


def calibrated_losses(system, modes, index: int, fit: BVDFit, source: str = ""):
    """The :class:`fem.losses.DriveLosses` with which mode ``index`` of ``modes`` (short-circuit
    modes of ``system``) has the measured modal quality factor ``fit.q_m`` and the measured
    ``tan(delta)`` (module docstring). The ``q_mech`` CI is the measured Q's, scaled alike."""
    from .harmonic import LossModel, loss_matrix
    from .losses import DriveLosses

    phi = modes.vectors[:, index]
    lam = (2 * np.pi * float(modes.f_r_hz[index])) ** 2
    a = float(phi @ (loss_matrix(system, LossModel(1.0, 0.0)) @ phi)) / lam
    b = float(phi @ (loss_matrix(system, LossModel(np.inf, 1.0)) @ phi)) / lam
    td = max(fit.values["tan_delta"], 0.0)
    eta_mech = 1.0 / fit.values["q_m"] - b * td
    if eta_mech <= 0 or a <= 0:
        raise ParameterError("admittance Q_m", fit.values["q_m"],
                             f"is above what the dielectric loss alone gives this mode (tan delta {td:.3g}): the "
                             "fit and the model disagree")
    q = a / eta_mech
    dq = q * fit.ci95["q_m"] / fit.values["q_m"] * (1.0 / fit.values["q_m"]) / eta_mech
    return DriveLosses(q, td, "measured", source or
                       f"BVD fit of the measured admittance {fit.source} at f_s {fit.values['f_s_hz']:.1f} Hz: "
                       f"Q_m {fit.values['q_m']:.4g} ± {fit.ci95['q_m']:.2g}, tan delta {td:.3g} (95 % CI"
                       f"{f'; misfit {fit.rms_residual:.1%} rms: biased beyond the CI' if fit.misfit else ''}); "
                       f"q_mech set so that the FE mode at {modes.f_r_hz[index]:.1f} Hz has that Q_m",
                       q_mech_ci95=dq)


MAX_MISMATCH = 0.25
"""Largest relative distance between a measured series resonance and the FE working mode for the
measurement to be taken as that mode's (beyond it the sweep is of another mode or another drill)."""


def measured_losses(system, modes, index: int, fits: list[BVDFit]):
    """The losses of the measured resonance nearest the FE mode ``index``: ``(DriveLosses, BVDFit)``
    (:func:`calibrated_losses`); a ParameterError when no measured resonance lies within
    :data:`MAX_MISMATCH` of the mode."""
    f_fe = float(modes.f_r_hz[index])
    fit = min(fits, key=lambda ft: abs(ft.values["f_s_hz"] - f_fe))
    f_m = fit.values["f_s_hz"]
    if abs(f_m - f_fe) > MAX_MISMATCH * f_fe:
        raise ParameterError("--admittance", fit.source, f"its resonances ({', '.join(f'{ft.f_s_hz:.0f}' for ft in fits)} Hz) "
                             f"lie more than {MAX_MISMATCH:.0%} from the FE working mode at {f_fe:.0f} Hz: a sweep "
                             "of another mode or another transducer")
    return calibrated_losses(system, modes, index, fit), fit
