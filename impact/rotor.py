"""The rotary unit: the coupler's teeth turn a preloaded rotor by friction.

Model (SI units; one cycle of the drive, phase ``theta = omega t``)
-------------------------------------------------------------------
* **Teeth**: every tooth tip moves as the converged harmonic response gives it, axially
  ``w = W cos(theta)`` (toward the rotor) and tangentially ``u = U cos(theta + phi)``. The teeth
  are a kinematic driver: the contact forces (tens of N) do not change the motion of a transducer
  driven at resonance with hundreds of watts (as the horn in :mod:`impact.model`). All teeth of
  the axisymmetric coupler move in phase, so the rotor sees ``n_teeth`` identical contacts.
* **Rotor**: rigid, pressed on the teeth by the preload spring (force ``preload``, stiffness
  ``spring_stiffness``), axial position constant over the cycle and angular speed ``Omega``
  constant over the cycle. Both hold when the rotor's mass and inertia filter the drive
  frequency; :class:`RotorResult` reports the axial and angular ripple they leave
  (``axial_ripple_ratio``, ``speed_ripple_ratio``) and checks the constant axial position by
  integrating the rotor's axial motion directly (:func:`hover_check`), so a design that breaks
  them shows it: a rotor thrown off the teeth bounces, a state this model does not describe.
  The axial position follows from the mean force balance: the cycle mean of the contact force
  equals the preload. The contact window is where the tooth reaches past that position.
* **Contact**: normal compliance of a rigid flat punch (the tooth top, area ``tooth_area``,
  taken as a circle of the same area) on an elastic half-space, both bodies elastic:
  ``k_n = 2 a E*``, ``1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2``; tangential compliance of the
  same punch, ``k_t = 8 a / ((2 - nu1)/G1 + (2 - nu2)/G2)`` (Johnson, *Contact Mechanics*, 1985,
  chapters 3 and 7). Coulomb friction with coefficient ``mu``: an elastic tangential spring
  ``k_t`` in series with a friction slider (stick while ``|q| < mu p``), the contact model of
  Storck and Wallaschek (2003) for travelling-wave motors, solved here event by event: the
  stick and slip phases are found by root finding and every integral is a Gauss-Legendre
  quadrature of the smooth phase-wise solution, so the energy balance of a cycle closes to
  round-off.

Outputs: mean driving torque against rotor speed, no-load speed, stall torque, mechanical power,
the teeth's power into the contact, the friction loss, contact efficiency, and the rotor speed
under a load torque (the drill tool's friction in rock, :func:`bit_friction_torque`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace

import numpy as np

from rpud_common import (ParameterError, check_integer, check_range, dump_toml, from_mapping, load_toml,
                         to_mapping, toml_section)
from rpud_common.result import Result

__all__ = ["TeethMotion", "RotorParams", "CycleSolution", "RotorResult", "contact_stiffness", "solve_cycle",
           "rotor_performance", "bit_friction_torque", "hover_check",
           "marched_mean_force"]

log = logging.getLogger(__name__)

_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(24)
_MAX_PIECE = 0.25
"""Longest phase interval (rad) one 24-point Gauss-Legendre rule integrates: the integrands are
products of two sines of theta, exact to round-off on a quarter radian."""
HOVER_VERIFIED = 0.05
"""Axial ripple / peak penetration up to which direct integration confirmed the constant axial
position (contact fraction and peak penetration within 3 % and 0.3 %); at 0.47 (a 61 g rotor on
the default coupler at 9.7 um) the rotor was thrown off the teeth."""
_SCAN = 256
"""Samples per radian when a stick or slip phase's end is bracketed before root finding."""


@dataclass(frozen=True)
class TeethMotion:
    """The motion of the teeth tips at the drive (amplitudes of the harmonic response).

    Parameters
    ----------
    freq : float
        Drive frequency, Hz, in [1, 1e6].
    axial : float
        Axial displacement amplitude ``W`` of a tooth top toward the rotor, m, in (0, 1e-3].
    tangential : float
        Tangential (circumferential) displacement amplitude ``U``, m, in [0, 1e-3].
    phase_deg : float
        Phase of the tangential relative to the axial motion, degrees, in [-360, 360]
        (0 or 180: a straight stroke, no net drive; 90 or -90: an ellipse on its axes).
    """

    freq: float
    axial: float
    tangential: float
    phase_deg: float

    def __post_init__(self):
        check_range("freq", self.freq, 1.0, 1e6, "Hz")
        check_range("axial", self.axial, 0.0, 1e-3, "m", lo_open=True)
        check_range("tangential", self.tangential, 0.0, 1e-3, "m")
        check_range("phase_deg", self.phase_deg, -360.0, 360.0, "degrees")

    @classmethod
    def from_ellipse(cls, freq: float, axial: float, ratio: float, phase_deg: float) -> "TeethMotion":
        """From the pipeline's report: axial amplitude (m), ellipse ratio ``U / W`` and phase (deg)."""
        check_range("ratio", ratio, 0.0, 100.0)
        return cls(freq=freq, axial=axial, tangential=ratio * axial, phase_deg=phase_deg)

    @property
    def omega(self) -> float:
        return 2.0 * math.pi * self.freq

    @property
    def sense(self) -> int:
        """+1 if the rotor turns toward +tangential (the tooth's tangential velocity at the crest
        of its axial stroke, ``-U omega sin(phi)``, is positive), -1 otherwise."""
        return 1 if -math.sin(math.radians(self.phase_deg)) >= 0.0 else -1

    @property
    def crest_speed(self) -> float:
        """Tangential speed of the tooth tip at the crest of its axial stroke, m/s (>= 0)."""
        return abs(self.tangential * self.omega * math.sin(math.radians(self.phase_deg)))


_TI = (113.8e9, 0.342)       # Ti-6Al-4V, the coupler's material (geometry/materials.toml)
_STEEL = (209e9, 0.269)      # steel 45, the rotor's assumed material (geometry/materials.toml)
_DISC = (0.035, 0.008, 7890.0)   # rotor taken as a steel disc: diameter, thickness (m), density
_DISC_MASS = math.pi * (_DISC[0] / 2) ** 2 * _DISC[1] * _DISC[2]


@dataclass(frozen=True)
class RotorParams:
    """The rotary unit's design data (SI units). TOML: top-level keys or one ``[rotor]`` table.

    Parameters
    ----------
    preload : float
        Preload spring force pressing the rotor on the teeth, N (article section 2: about 18 N).
    spring_stiffness : float
        Preload spring stiffness, N/m (default 6000: 18 N at 3 mm compression; assumed, the
        article gives the force only). Sets the rotor's axial suspension in the ripple check.
    mu : float
        Coulomb friction coefficient teeth/rotor, in (0, 2]. Default 0.2: assumed, no measured
        value for the pair is at hand; the stall torque is proportional to it.
    radius : float
        Contact radius, m (default 12.5 mm: the mean radius of the default coupler's teeth).
    n_teeth : int
        Number of driving teeth (default 6, the default coupler's).
    tooth_area : float
        Top face area of one tooth, m^2 (default 5.71e-5: an 8 mm arc on a 10 mm wall).
    e_tooth, nu_tooth, e_rotor, nu_rotor : float
        Young's moduli (Pa) and Poisson ratios of the coupler (Ti-6Al-4V) and the rotor
        (steel 45, assumed).
    rotor_mass, rotor_inertia : float
        Rotor mass (kg) and polar moment of inertia (kg m^2) about the drill axis (default: a
        steel disc 35 mm x 8 mm; the drill string adds to both).
    k_normal, k_tangential : float
        Contact stiffness per tooth, N/m; 0 (default) takes the flat-punch values of the
        materials and ``tooth_area`` (:func:`contact_stiffness`).
    """

    preload: float = 18.0
    spring_stiffness: float = 6000.0
    mu: float = 0.2
    radius: float = 0.0125
    n_teeth: int = 6
    tooth_area: float = 5.71e-5
    e_tooth: float = _TI[0]
    nu_tooth: float = _TI[1]
    e_rotor: float = _STEEL[0]
    nu_rotor: float = _STEEL[1]
    rotor_mass: float = round(_DISC_MASS, 4)
    rotor_inertia: float = float(f"{_DISC_MASS * (_DISC[0] / 2) ** 2 / 2:.3g}")
    k_normal: float = 0.0
    k_tangential: float = 0.0

    def __post_init__(self):
        check_range("preload", self.preload, 0.0, 1e5, "N", lo_open=True)
        check_range("spring_stiffness", self.spring_stiffness, 0.0, 1e9, "N/m")
        check_range("mu", self.mu, 0.0, 2.0, lo_open=True)
        check_range("radius", self.radius, 1e-4, 1.0, "m")
        check_integer("n_teeth", self.n_teeth, 1, 1000)
        check_range("tooth_area", self.tooth_area, 1e-10, 1e-2, "m^2")
        for name in ("e_tooth", "e_rotor"):
            check_range(name, getattr(self, name), 1e6, 2e12, "Pa")
        for name in ("nu_tooth", "nu_rotor"):
            check_range(name, getattr(self, name), -0.99, 0.5, lo_open=True)
        check_range("rotor_mass", self.rotor_mass, 1e-6, 1e3, "kg")
        check_range("rotor_inertia", self.rotor_inertia, 1e-12, 1e3, "kg m^2")
        for name in ("k_normal", "k_tangential"):
            value = getattr(self, name)
            if not (value == 0.0 or 1.0 <= value <= 1e16):
                raise ParameterError(name, value, "must be 0 (from the materials) or in [1, 1e16] N/m")

    def with_(self, **changes) -> "RotorParams":
        return replace(self, **changes)

    def to_dict(self) -> dict:
        return to_mapping(self)

    def to_toml(self) -> str:
        return dump_toml({"rotor": self.to_dict()})

    @classmethod
    def from_toml(cls, path, source: str = "config") -> "RotorParams":
        """Load from a TOML file: top-level keys, or a ``[rotor]`` table (not both)."""
        return from_mapping(cls, toml_section(load_toml(path, source), "rotor", source))

    @property
    def stiffness(self) -> tuple[float, float]:
        """(k_n, k_t) per tooth, N/m: the given values, else the flat punch's."""
        kn, kt = contact_stiffness(self)
        return (self.k_normal or kn, self.k_tangential or kt)


def contact_stiffness(p: RotorParams) -> tuple[float, float]:
    """Normal and tangential stiffness (N/m) of one tooth top on the rotor: a flat circular punch
    of the tooth's area on an elastic half-space, both bodies elastic (Johnson 1985).

    ``k_n = 2 a E*`` and ``k_t = 8 a / ((2 - nu1)/G1 + (2 - nu2)/G2)``, ``a = sqrt(A / pi)``.
    """
    a = math.sqrt(p.tooth_area / math.pi)
    e_star = 1.0 / ((1 - p.nu_tooth ** 2) / p.e_tooth + (1 - p.nu_rotor ** 2) / p.e_rotor)
    g1, g2 = p.e_tooth / (2 * (1 + p.nu_tooth)), p.e_rotor / (2 * (1 + p.nu_rotor))
    return 2.0 * a * e_star, 8.0 * a / ((2 - p.nu_tooth) / g1 + (2 - p.nu_rotor) / g2)


def bit_friction_torque(wob: float, bit_diameter: float, mu_rock: float) -> float:
    """Friction torque (N m) of a flat-bottomed bit turning on rock under the weight on bit
    ``wob`` (N): a uniformly loaded disc of diameter ``bit_diameter`` (m), ``(2/3) mu F R``."""
    check_range("wob", wob, 0.0, 1e4, "N")
    check_range("bit_diameter", bit_diameter, 1e-4, 0.5, "m")
    check_range("mu_rock", mu_rock, 0.0, 2.0)
    return 2.0 / 3.0 * mu_rock * wob * bit_diameter / 2.0


# --------------------------------------------------------------------------- one cycle


class _Tooth:
    """The kinematics of one tooth against the rotor at one rotor speed, as functions of theta
    (lengths in m, derivatives per radian of phase)."""

    def __init__(self, teeth: TeethMotion, p: RotorParams, surface_speed: float):
        self.W, self.U = teeth.axial, teeth.tangential
        # the tangential axis turned so that the drive at the crest is positive
        self.phi = math.radians(teeth.phase_deg) + (0.0 if teeth.sense > 0 else math.pi)
        self.kn, self.kt = p.stiffness
        self.mu = p.mu
        self.slide = surface_speed / teeth.omega           # rotor surface travel per radian, m
        self.z0 = _rotor_position(self.W, p.preload / (p.n_teeth * self.kn))

    def p(self, th):
        return self.kn * (self.W * np.cos(th) - self.z0)

    def p_th(self, th):
        return -self.kn * self.W * np.sin(th)

    def u(self, th):
        return self.U * np.cos(th + self.phi)

    def u_th(self, th):
        return -self.U * np.sin(th + self.phi)

    def g(self, th):                   # tooth travel relative to the rotor surface
        return self.u(th) - self.slide * th

    def g_th(self, th):
        return self.u_th(th) - self.slide

    def sigma(self, th, s):            # slip rate in a slip phase of sign s
        return self.g_th(th) - s * self.mu * self.p_th(th) / self.kt


def _rotor_position(W: float, mean_pen: float) -> float:
    """The rotor's axial position z0 (m, in the teeth's frame) at which the cycle mean of
    ``(W cos(theta) - z0)+`` equals ``mean_pen`` (the preload over n_teeth k_n)."""
    if mean_pen >= W:                  # never lifts off: the mean of W cos - z0 is -z0
        return -mean_pen
    from scipy.optimize import brentq

    def excess(tc):                    # half-window tc: mean of (cos - cos tc)+ is (sin tc - tc cos tc)/pi
        return W * (math.sin(tc) - tc * math.cos(tc)) / math.pi - mean_pen

    tc = brentq(excess, 0.0, math.pi, xtol=1e-15, rtol=4 * np.finfo(float).eps)
    return W * math.cos(tc)


def _first_root(f, a: float, b: float) -> float | None:
    """First theta in (a, b] where ``f`` turns negative (``f(a)`` is taken as >= 0: a phase
    starts where its condition holds), bracketed on a scan and bisected to round-off; None if
    ``f`` stays >= 0 on the scan."""
    n = max(8, int(math.ceil((b - a) * _SCAN)))
    x = np.linspace(a, b, n + 1)
    bad = np.nonzero(f(x[1:]) < 0.0)[0]
    if bad.size == 0:
        return None
    lo, hi = x[bad[0]], x[bad[0] + 1]
    while hi - lo > 4 * np.finfo(float).eps * max(1.0, abs(hi)):
        mid = 0.5 * (lo + hi)
        if mid in (lo, hi):
            break
        if f(np.array([mid]))[0] < 0.0:
            hi = mid
        else:
            lo = mid
    return float(lo) if lo > a else float(hi)


def _start_kind(t: _Tooth, a: float, delta: float) -> int:
    """The phase at ``a`` with the slider's deflection ``delta``: 0 stick, +-1 slip."""
    limit = t.mu * float(t.p(a))
    if t.kt * abs(delta) < limit:
        return 0
    if limit <= 0.0:                   # the window opens: stick if the limit grows faster than the load
        rate = float(t.g_th(a))
        return 0 if t.kt * abs(rate) <= t.mu * float(t.p_th(a)) else (1 if rate > 0 else -1)
    s = 1 if delta > 0 else -1         # at the limit: slip goes on while its rate points along the force
    return s if s * float(t.sigma(a, s)) > 0.0 else 0


def _phases(t: _Tooth, a: float, b: float, delta: float = 0.0):
    """The stick and slip phases of the contact window [a, b] starting with the slider's
    deflection ``delta`` (m): a list of (start, end, kind, delta_start), kind 0 = stick,
    +1/-1 = slip in that direction, and the deflection at ``b``."""
    out, th, kind = [], a, _start_kind(t, a, delta)
    while th < b:
        if len(out) > 10000:
            raise RuntimeError("more than 10000 stick/slip phases in one cycle")
        if kind == 0:
            d0, g0 = delta, float(t.g(th))
            end = _first_root(lambda x: t.mu * t.p(x) - t.kt * np.abs(d0 + t.g(x) - g0), th, b)
            end = b if end is None else end
            out.append((th, end, 0, d0))
            delta = d0 + float(t.g(end)) - g0
            kind = 1 if delta > 0 else -1
        else:
            s = kind
            end = _first_root(lambda x: s * t.sigma(x, s), th, b)
            end = b if end is None else end
            out.append((th, end, s, s * t.mu * float(t.p(th)) / t.kt))
            delta, kind = s * t.mu * float(t.p(end)) / t.kt, 0
        th = end
    return out, delta


def _pieces(a: float, b: float):
    n = max(1, int(math.ceil((b - a) / _MAX_PIECE)))
    edges = np.linspace(a, b, n + 1)
    for lo, hi in zip(edges[:-1], edges[1:]):
        yield 0.5 * (hi - lo) * _GAUSS_X + 0.5 * (hi + lo), 0.5 * (hi - lo) * _GAUSS_W


@dataclass(eq=False, repr=False)
class CycleSolution(Result):
    """One tooth over one drive cycle at one rotor speed (per-tooth values; SI units).

    ``phases``: (start, end, kind) with theta in rad and kind ``"stick"``, ``"slip+"`` (the
    tooth faster than the rotor surface) or ``"slip-"``. Works per cycle in J: ``teeth_work``
    (normal plus tangential work of the tooth on the contact), ``normal_work`` (its normal part),
    ``rotor_work`` (tangential force times rotor surface travel), ``friction_loss`` (``mu p``
    times the slip distance), ``force_samples`` (theta, normal force, tangential force at the
    quadrature points, rad and N), ``elastic_change`` (energy stored in the tangential spring at the
    cycle's end less at its start: 0 when the contact opens). ``mean_force``: cycle mean of the tangential force, N.
    """

    speed: float
    window: tuple[float, float]
    phases: list
    mean_force: float
    teeth_work: float
    normal_work: float
    rotor_work: float
    friction_loss: float
    elastic_change: float
    force_samples: tuple

    def fraction(self, kind: str) -> float:
        """Fraction of the cycle spent in phases of ``kind`` ("stick", "slip+", "slip-", "contact")."""
        span = sum(e - s for s, e, k in self.phases if kind == "contact" or k == kind)
        return span / (2.0 * math.pi)

    def _headline(self) -> str:
        return (f"surface speed {self.speed:.4g} m/s, mean force {self.mean_force:.4g} N, "
                f"contact {self.fraction('contact'):.3f}, stick {self.fraction('stick'):.3f}")

    def _record(self) -> dict:
        return {"surface_speed_m_s": self.speed, "window_rad": list(self.window),
                "phases": [{"start_rad": s, "end_rad": e, "kind": k} for s, e, k in self.phases],
                "mean_force_n": self.mean_force, "teeth_work_j": self.teeth_work, "normal_work_j": self.normal_work,
                "rotor_work_j": self.rotor_work, "friction_loss_j": self.friction_loss,
                "fractions": {k: self.fraction(k) for k in ("contact", "stick", "slip+", "slip-")}}


_KINDS = {0: "stick", 1: "slip+", -1: "slip-"}


def _window(t: _Tooth) -> tuple[float, float, int]:
    """The contact window (a, b) in theta and the cycles to march (1; 3 if contact never opens,
    the last kept: the friction slider forgets its start within a cycle of slip)."""
    if t.z0 <= -t.W:
        return -math.pi, math.pi, 3
    tc = math.acos(min(1.0, t.z0 / t.W))
    return -tc, tc, 1


def solve_cycle(teeth: TeethMotion, p: RotorParams, surface_speed: float) -> CycleSolution:
    """Steady contact of one tooth over one cycle with the rotor surface moving at
    ``surface_speed`` (m/s, ``radius * Omega``, positive in the drive direction)."""
    check_range("surface_speed", surface_speed, -1e3, 1e3, "m/s")
    t = _Tooth(teeth, p, surface_speed)
    a, b, laps = _window(t)
    delta = delta_start = 0.0
    for _ in range(laps):
        delta_start = delta
        phases, delta = _phases(t, a, b, delta)
    F = teeth_t = normal = loss = 0.0
    xs, ps, qs = [], [], []
    for s, e, kind, d0 in phases:
        g0 = float(t.g(s))
        for x, w in _pieces(s, e):
            q = t.kt * (d0 + t.g(x) - g0) if kind == 0 else kind * t.mu * t.p(x)
            F += w @ q
            teeth_t += w @ (q * t.u_th(x))
            normal += w @ (t.p(x) * -t.W * np.sin(x))
            if kind:
                loss += w @ (t.mu * t.p(x) * np.abs(t.sigma(x, kind)))
            xs.append(x)
            ps.append(t.p(x))
            qs.append(q)
    return CycleSolution(speed=surface_speed, window=(a, b), phases=[(s, e, _KINDS[k]) for s, e, k, _ in phases],
                         mean_force=F / (2 * math.pi), teeth_work=teeth_t + normal, normal_work=normal,
                         rotor_work=F * t.slide, friction_loss=loss,
                         elastic_change=0.5 * t.kt * (delta ** 2 - delta_start ** 2),
                         force_samples=tuple(np.concatenate(v) if v else np.zeros(0) for v in (xs, ps, qs)))


def marched_mean_force(teeth: TeethMotion, p: RotorParams, surface_speed: float, steps: int) -> float:
    """Mean tangential force of one tooth (N) by a second method: a return mapping (backward Euler
    for the slider) on ``steps`` equal steps across the contact window, trapezoidal mean.

    Independent of :func:`solve_cycle`'s events and quadrature: the window's half-width solves
    ``W (sin tc - tc cos tc) / pi = F / (n_teeth k_n)`` here again. Converges to the event
    solution at second order; the tests and ``benchmarks/bench_rotor.py`` compare the two. Opening
    contacts only (the slider starts and ends each window unloaded).
    """
    from scipy.optimize import brentq

    check_integer("steps", steps, 2, 10_000_000)
    kn, kt = p.stiffness
    mean_pen = p.preload / (p.n_teeth * kn)
    if mean_pen >= teeth.axial:
        raise ParameterError("preload", p.preload, "keeps the contact closed: the march needs an opening window")
    tc = brentq(lambda x: teeth.axial * (math.sin(x) - x * math.cos(x)) / math.pi - mean_pen, 1e-12, math.pi,
                xtol=1e-15)
    phi = math.radians(teeth.phase_deg) + (0.0 if teeth.sense > 0 else math.pi)
    th = np.linspace(-tc, tc, steps + 1)
    g = teeth.tangential * np.cos(th + phi) - surface_speed / teeth.omega * th
    lim = p.mu * kn * teeth.axial * (np.cos(th) - math.cos(tc)) / kt
    q, delta = np.zeros(steps + 1), 0.0
    for i in range(steps):
        trial = delta + g[i + 1] - g[i]
        delta = trial if abs(trial) <= lim[i + 1] else math.copysign(lim[i + 1], trial)
        q[i + 1] = kt * delta
    return float(np.sum(0.5 * (q[1:] + q[:-1]) * np.diff(th))) / (2 * math.pi)


# --------------------------------------------------------------------------- torque against speed


def _torque(teeth: TeethMotion, p: RotorParams, omega_rotor: float) -> float:
    return p.n_teeth * p.radius * solve_cycle(teeth, p, p.radius * omega_rotor).mean_force


def _speed_at(teeth: TeethMotion, p: RotorParams, torque: float, top: float) -> float:
    """Rotor speed (rad/s) in [0, top] at which the mean driving torque equals ``torque``."""
    from scipy.optimize import brentq

    return brentq(lambda w: _torque(teeth, p, w) - torque, 0.0, top, xtol=1e-13 * max(top, 1e-300), rtol=1e-13)


def _axial_ripple(teeth: TeethMotion, p: RotorParams, harmonics: int = 40) -> float:
    """Peak axial excursion of the rotor (m, a bound: the sum of the harmonics' amplitudes) under
    the periodic part of the teeth's total contact force, the rotor a mass on the preload spring."""
    t = _Tooth(teeth, p, 0.0)
    a, b, _ = _window(t)
    n = np.arange(1, harmonics + 1)
    amp = np.zeros(harmonics)
    for x, w in _pieces(a, b):
        amp += (p.n_teeth * t.p(x) * np.cos(np.outer(n, x))) @ w / math.pi
    return float(np.sum(np.abs(amp) / np.abs(p.spring_stiffness - p.rotor_mass * (n * teeth.omega) ** 2)))


def _speed_ripple(cyc: CycleSolution, teeth: TeethMotion, p: RotorParams) -> float:
    """Peak-to-peak rotor speed ripple over a cycle, rad/s: the torque's excursion from its mean
    integrated over the cycle, divided by the rotor's inertia."""
    x, _, q = cyc.force_samples
    grid = np.linspace(-math.pi, math.pi, 8193)
    order = np.argsort(x)
    inside = (grid >= cyc.window[0]) & (grid <= cyc.window[1])
    force = np.where(inside, np.interp(grid, x[order], q[order]) if x.size else 0.0, 0.0)
    torque = p.n_teeth * p.radius * (force - cyc.mean_force)
    h = np.concatenate([[0.0], np.cumsum(0.5 * (torque[1:] + torque[:-1]) * np.diff(grid))]) / teeth.omega
    return float((h.max() - h.min()) / p.rotor_inertia)


def hover_check(teeth: TeethMotion, p: RotorParams, z0: float, ripple: float, *, cycles: int = 60,
                steps: int = 400, last: int = 20) -> dict:
    """The constant axial position checked by direct integration: the rotor (mass on the preload
    spring, pressed by the teeth's contact forces ``n_teeth k_n (w - z)+``) started at rest at
    ``z0`` and integrated by classical Runge-Kutta (``steps`` per cycle) over ``cycles`` cycles.

    It ``holds`` when over the ``last`` cycles the rotor touches the teeth in every cycle and the
    peak penetration of every cycle stays within ``2 ripple`` (the start from rest leaves the
    rotor's own axial mode ringing at up to the ripple, undamped here) plus the sampling error
    ``W (pi/steps)^2 / 2`` of the model's. When it fails, the rotor leaves the teeth for whole
    cycles and bounces: the hovering model's outputs do not describe that state.
    """
    kn = p.stiffness[0]
    K, m, F, ks = p.n_teeth * kn, p.rotor_mass, p.preload, p.spring_stiffness
    W, w = teeth.axial, teeth.omega

    def acc(t, z):
        return (K * max(W * math.cos(w * t) - z, 0.0) - F - ks * (z - z0)) / m

    h = 1.0 / (teeth.freq * steps)
    z, v, t = z0, 0.0, 0.0
    pen = np.full(cycles * steps, -np.inf)
    for i in range(pen.size):
        a1 = acc(t, z)
        a2 = acc(t + h / 2, z + h / 2 * v)
        a3 = acc(t + h / 2, z + h / 2 * (v + h / 2 * a1))
        a4 = acc(t + h, z + h * (v + h / 2 * a2))
        z, v, t = (z + h * v + h * h / 6 * (a1 + a2 + a3), v + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4), t + h)
        pen[i] = W * math.cos(w * t) - z
        if pen[i] < -10 * W:            # thrown off the teeth: the rest of the flight changes nothing
            break
    peaks = pen.reshape(cycles, steps)[-last:].max(axis=1)
    model = W - z0
    slack = 2 * ripple + W * (math.pi / steps) ** 2 / 2
    off = not np.all(np.isfinite(peaks))
    holds = bool(not off and np.all(peaks > 0) and np.all(np.abs(peaks - model) <= slack))
    left = np.nonzero(pen.reshape(cycles, steps).max(axis=1) <= 0)[0]
    return {"holds": holds, "cycles": cycles, "steps_per_cycle": steps,
            "first_cycle_without_contact": int(left[0]) if left.size else None,
            "peak_penetration_range_m": None if off else [float(peaks.min()), float(peaks.max())],
            "model_peak_penetration_m": model, "allowed_departure_m": slack}


@dataclass(eq=False, repr=False)
class RotorResult(Result):
    """Steady operation of the rotary unit (SI units; speeds in rad/s, torques in N m).

    ``curve``: arrays over rotor speed from 0 to the no-load speed (``speed_rad_s``,
    ``torque_n_m``, ``power_w`` mechanical out, ``teeth_power_w`` drawn from the teeth,
    ``friction_loss_w``, ``efficiency`` = out / teeth). ``load``: the operating point under
    ``load_torque`` (its cycle in ``load_cycle``). ``electric_idle_w``: the rotary side's own
    electrical loss, added to the teeth power to make its electrical input.
    """

    teeth: TeethMotion
    params: RotorParams
    k_normal: float
    k_tangential: float
    contact_fraction: float
    peak_penetration: float
    no_load_speed: float
    stall_torque: float
    torque_bound: float
    curve: dict
    load_torque: float
    load_speed: float
    load_cycle: CycleSolution
    electric_idle_w: float
    axial_ripple: float
    speed_ripple: float
    hover: dict | None = None
    stalled: bool = False
    notes: list = field(default_factory=list)

    @property
    def load_power(self) -> float:
        return self.load_torque * self.load_speed

    @property
    def load_teeth_power(self) -> float:
        return self.params.n_teeth * self.teeth.freq * self.load_cycle.teeth_work

    @property
    def load_efficiency(self) -> float:
        """Mechanical power out / the rotary side's electrical input (teeth power + idle loss)."""
        den = self.load_teeth_power + self.electric_idle_w
        return self.load_power / den if den > 0 else 0.0

    @property
    def max_power(self) -> tuple[float, float]:
        """(largest mechanical power on the curve, W; the speed where it is, rad/s)."""
        i = int(np.argmax(self.curve["power_w"]))
        return float(self.curve["power_w"][i]), float(self.curve["speed_rad_s"][i])

    def _headline(self) -> str:
        return (f"no-load {self.no_load_speed * 30 / math.pi:.4g} rpm, stall {self.stall_torque * 1e3:.4g} mN m, "
                f"at {self.load_torque * 1e3:.3g} mN m: {self.load_speed * 30 / math.pi:.4g} rpm, "
                f"{self.load_power * 1e3:.3g} mW, efficiency {self.load_efficiency:.3g}")

    def _record(self) -> dict:
        pmax, wmax = self.max_power
        return {
            "teeth": {"freq_hz": self.teeth.freq, "axial_m": self.teeth.axial, "tangential_m": self.teeth.tangential,
                      "phase_deg": self.teeth.phase_deg, "sense": self.teeth.sense,
                      "crest_speed_m_s": self.teeth.crest_speed},
            "params": self.params.to_dict(),
            "contact": {"k_normal_n_per_m": self.k_normal, "k_tangential_n_per_m": self.k_tangential,
                        "contact_fraction": self.contact_fraction, "peak_penetration_m": self.peak_penetration},
            "no_load_speed_rad_s": self.no_load_speed, "no_load_speed_rpm": self.no_load_speed * 30 / math.pi,
            "stall_torque_n_m": self.stall_torque, "torque_bound_mu_f_r_n_m": self.torque_bound,
            "max_power_w": pmax, "max_power_speed_rad_s": wmax,
            "load": {"torque_n_m": self.load_torque, "speed_rad_s": self.load_speed,
                     "speed_rpm": self.load_speed * 30 / math.pi, "power_w": self.load_power,
                     "teeth_power_w": self.load_teeth_power, "electric_idle_w": self.electric_idle_w,
                     "efficiency": self.load_efficiency, "stalled": self.stalled,
                     "cycle": self.load_cycle.to_dict()},
            "checks": {"axial_ripple_m": self.axial_ripple,
                       "axial_ripple_ratio": self.axial_ripple / self.peak_penetration,
                       "speed_ripple_rad_s": self.speed_ripple,
                       "speed_ripple_ratio": (self.speed_ripple / self.load_speed if self.load_speed > 0 else None),
                       "hover": self.hover},
            "curve": {k: np.asarray(v).tolist() for k, v in self.curve.items()},
            "notes": list(self.notes),
        }


def _assumption_notes(res: RotorResult) -> None:
    """Append to ``res.notes`` where the constant axial position or speed does not hold."""
    ratio = res.axial_ripple / res.peak_penetration
    if res.hover is not None and not res.hover["holds"]:
        res.notes.append(f"the rotor does not hover: integrated directly it leaves the teeth (axial ripple "
                         f"{ratio:.2g} of the peak penetration); it bounces, a state these results do not describe "
                         "(a heavier rotor, a softer contact layer or a smaller amplitude restores hovering)")
    elif ratio > HOVER_VERIFIED:
        res.notes.append(f"the rotor's axial ripple is {ratio:.2g} of the peak penetration, above the "
                         f"{HOVER_VERIFIED:g} up to which direct integration confirmed the constant axial position")
    if res.load_speed > 0 and res.speed_ripple > 0.1 * res.load_speed:
        res.notes.append(f"speed ripple {res.speed_ripple / res.load_speed:.2g} of the speed: the constant speed "
                         "assumed is rough (more inertia restores it)")


def _curve(teeth: TeethMotion, p: RotorParams, speeds: np.ndarray) -> dict:
    cycles = [solve_cycle(teeth, p, p.radius * w) for w in speeds]
    torque = np.array([p.n_teeth * p.radius * c.mean_force for c in cycles])
    teeth_power = np.array([p.n_teeth * teeth.freq * c.teeth_work for c in cycles])
    power = torque * speeds
    return {"speed_rad_s": speeds, "torque_n_m": torque, "power_w": power, "teeth_power_w": teeth_power,
            "friction_loss_w": np.array([p.n_teeth * teeth.freq * c.friction_loss for c in cycles]),
            "efficiency": np.divide(power, teeth_power, out=np.zeros_like(power), where=teeth_power > 0)}


def rotor_performance(teeth: TeethMotion, p: RotorParams, load_torque: float = 0.0, *, points: int = 41,
                      electric_idle_w: float = 0.0, check_hover: bool = True) -> RotorResult:
    """The torque-speed curve, no-load speed, stall torque, and the operating point under
    ``load_torque`` (N m, >= 0) of the rotary unit driven by ``teeth``.

    Parameters
    ----------
    teeth : TeethMotion
        Teeth tips' motion at the drive.
    p : RotorParams
        Rotor, spring, contact and friction data.
    load_torque : float
        Resisting torque on the rotor, N m (the drill tool's friction in rock).
    points : int
        Speeds on the torque-speed curve, in [3, 2001].
    electric_idle_w : float
        The rotary side's electrical loss without the rotor (W, >= 0): its electrical input is
        this plus the power the teeth put into the contact.
    check_hover : bool
        Check the constant axial position by direct integration (:func:`hover_check`, ~0.5 s).

    Returns
    -------
    RotorResult
    """
    check_range("load_torque", load_torque, 0.0, 1e4, "N m")
    check_integer("points", points, 3, 2001)
    check_range("electric_idle_w", electric_idle_w, 0.0, 1e7, "W")
    kn, kt = p.stiffness
    notes = []
    stall = _torque(teeth, p, 0.0)
    top = teeth.tangential * teeth.omega / p.radius * (1 + 1e-9) + 1e-12
    no_load = _speed_at(teeth, p, 0.0, top) if stall > 0 else 0.0
    if stall <= 0:
        notes.append("the teeth give no net drive (straight stroke): no-load speed and stall torque are 0")
    stalled = load_torque >= stall
    load_speed = 0.0 if stalled else (_speed_at(teeth, p, load_torque, no_load) if load_torque > 0 else no_load)
    if stalled:
        notes.append(f"load torque {load_torque:.4g} N m >= stall torque {stall:.4g} N m: the rotor stalls")
    load_cycle = solve_cycle(teeth, p, p.radius * load_speed)
    z0 = _Tooth(teeth, p, 0.0).z0
    ripple = _axial_ripple(teeth, p)
    res = RotorResult(teeth=teeth, params=p, k_normal=kn, k_tangential=kt,
                      contact_fraction=load_cycle.fraction("contact"), peak_penetration=teeth.axial - z0,
                      no_load_speed=no_load, stall_torque=max(stall, 0.0), torque_bound=p.mu * p.preload * p.radius,
                      curve=_curve(teeth, p, np.linspace(0.0, no_load, points)), load_torque=load_torque,
                      load_speed=load_speed, load_cycle=load_cycle, electric_idle_w=electric_idle_w,
                      axial_ripple=ripple, speed_ripple=_speed_ripple(load_cycle, teeth, p), stalled=stalled,
                      hover=hover_check(teeth, p, z0, ripple) if check_hover else None, notes=notes)
    _assumption_notes(res)
    return res
