"""Heat of the driven transducer and its temperature in a lumped thermal model.

Heat
----
With the hysteretic loss matrix ``L`` (:func:`fem.harmonic.loss_matrix`) the time-averaged power
dissipated by a harmonic state ``x`` (complex amplitudes, ``exp(j w t)``) is::

    P = (w / 2) x^H L x

its displacement block the mechanical loss, its potential block (the hot electrode included) the
dielectric loss. Energy is conserved: ``P`` equals the cycle-averaged electrical input
``Re(V conj(I)) / 2`` minus the power delivered to a load (a tip damper ``c``: ``c w^2 |u|^2 / 2``);
the tests check that balance to 1e-6 on direct solutions.

Lumped thermal model
--------------------
The transducer is one body at one temperature ``T`` (conduction inside it neglected: the metal
parts conduct far faster than air carries heat away, but the ceramic, in the middle, runs hotter
than the mean; the result is the mean temperature, a lower bound for the ceramic's):

    C dT/dt = P s(t) - h A (T - T_amb),

``C`` the heat capacity (the parts' masses times their specific heats, :data:`SPECIFIC_HEAT`),
``A`` the outer surface, ``h`` the convective coefficient (a stated input: natural convection in
air is 5-25 W/m^2/K; in vacuum only radiation is left), ``s(t)`` the duty cycle (on for
``duty * period`` of every ``period``). Each on or off stretch is solved exactly (an exponential
approach to ``T_amb + P / (h A)`` or to ``T_amb`` with the time constant ``tau = C / (h A)``).
The time to each material's rated temperature (:data:`RATED_TEMPERATURE_C`) is found inside the
stretch where it is crossed.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np

from rpud_common import ParameterError, check_range
from rpud_common.result import Result

__all__ = ["SPECIFIC_HEAT", "RATED_TEMPERATURE_C", "HeatSplit", "heat_generation", "LumpedBody", "lumped_body",
           "ThermalSettings", "ThermalResult", "lumped_temperature", "H_RANGE", "thermal_summary",
           "thermal_verdict"]

log = logging.getLogger(__name__)

SPECIFIC_HEAT = {"steel_45": 486.0, "ti6al4v": 526.3, "al7075": 960.0, "copper": 385.0, "epoxy": 1100.0,
                 "PZT-4": 420.0, "PZT-8": 420.0, "PZT-5A": 420.0}
"""Specific heat capacity of the library materials, J/kg/K: MatWeb / ASM data sheets for AISI
1045 (486), Ti-6Al-4V grade 5 (526.3), 7075-T6 (960) and copper (385); cured epoxies
1000-1200; hard and soft PZT 350-420 (manufacturers' data sheets). A material not listed makes
the thermal model refuse the design, naming it."""

RATED_TEMPERATURE_C = {"PZT-4": 164.0, "PZT-8": 150.0, "PZT-5A": 182.0}
"""Highest operating temperature of the ceramics, deg C: half the Curie temperature (PZT-4 328,
PZT-8 300, PZT-5A 365 deg C, Morgan Electro Ceramics TP-226), the manufacturers' rule above
which ageing and depoling accelerate."""

H_RANGE = (5.0, 25.0)
"""Natural convection in air, W/m^2/K: the range the report brackets the default with."""


@dataclass(frozen=True)
class HeatSplit:
    """Time-averaged heat of a harmonic state, W: mechanical, dielectric and their sum."""

    mechanical_w: float
    dielectric_w: float

    @property
    def total_w(self) -> float:
        return self.mechanical_w + self.dielectric_w

    def record(self) -> dict:
        return {"mechanical_w": self.mechanical_w, "dielectric_w": self.dielectric_w, "total_w": self.total_w}


def heat_generation(system, x: np.ndarray, freq_hz: float, loss_matrix) -> HeatSplit:
    """The heat ``(w/2) x^H L x`` of the full solution ``x`` at ``freq_hz`` (module docstring),
    split into the displacement (mechanical) and potential (dielectric) blocks of ``L``."""
    x = np.asarray(x)
    if x.shape != (system.ndof,):
        raise ParameterError("x", x.shape, f"must be one solution vector of length {system.ndof}")
    w = 2 * np.pi * float(freq_hz)
    L = loss_matrix.tocsr()
    Lx = L @ x
    n = system.n_u
    mech = 0.5 * w * float(np.real(np.vdot(x[:n], Lx[:n])))
    diel = 0.5 * w * float(np.real(np.vdot(x[n:], Lx[n:])))
    return HeatSplit(mech, diel)


@dataclass(frozen=True)
class LumpedBody:
    """Heat capacity ``capacity_j_per_k`` (J/K), outer surface ``area_m2`` (m^2), mass ``mass_kg``
    and the rated temperatures of the materials it contains (deg C)."""

    capacity_j_per_k: float
    area_m2: float
    mass_kg: float
    rated_c: dict = field(default_factory=dict)


def lumped_body(system) -> LumpedBody:
    """The lumped body of an assembled system: its regions' volumes on the mesh times their
    densities and :data:`SPECIFIC_HEAT`, and the area of its outer boundary. A
    :class:`fem.sector_system.SectorSystem` stands for its whole drill: its sector's volumes and
    outer area (the cut faces left out) times the number of sectors."""
    from .facets import facet_basis

    n = int(getattr(system, "sectors", 1) or 1)
    geo = getattr(system, "sector", None) or system
    vol = np.asarray(geo.basis.dx).sum(axis=1)
    cell_region = np.asarray(geo.mesh.cell_region)
    cap = mass = 0.0
    rated = {}
    for r, reg in enumerate(system.regions):
        if reg.material not in SPECIFIC_HEAT:
            raise ParameterError("material", reg.material, "has no specific heat in fem.thermal.SPECIFIC_HEAT: "
                                 "the thermal model needs one")
        m = float(vol[cell_region == r].sum()) * reg.density
        mass += m
        cap += m * SPECIFIC_HEAT[reg.material]
        if reg.material in RATED_TEMPERATURE_C:
            rated[reg.material] = RATED_TEMPERATURE_C[reg.material]
    facets = geo.skmesh.boundary_facets()
    if n > 1:
        facets = facets[~_on_cut_planes(geo.skmesh, facets, 2 * np.pi / n)]
    fb = facet_basis(geo.skmesh, geo.basis.elem, facets, intorder=2 * geo.order + 2)
    return LumpedBody(n * cap, n * float(np.sum(fb.dx)), n * mass, rated)


def _on_cut_planes(mesh, facets, alpha: float) -> np.ndarray:
    """Facets of a sector (about the z axis, from angle 0 to ``alpha``) lying on its cut planes:
    every corner on the axis or at the angle 0 or ``alpha``."""
    p = mesh.p[:, mesh.facets[:, facets]]                        # (3, 3 corners, n)
    r = np.hypot(p[0], p[1])
    theta = np.arctan2(p[1], p[0])
    tol = 1e-9 * max(float(r.max()), 1.0)
    on0 = (r <= tol) | (np.abs(r * np.sin(theta)) <= tol)
    on1 = (r <= tol) | (np.abs(r * np.sin(theta - alpha)) <= tol)
    return np.all(on0, axis=0) | np.all(on1, axis=0)


@dataclass(frozen=True)
class ThermalSettings:
    """Inputs of the lumped model.

    Attributes
    ----------
    h_w_per_m2k : convective coefficient, W/m^2/K (default 10: natural convection in air)
    ambient_c : ambient and starting temperature, deg C
    duty : fraction of every period the drive is on (1: continuous)
    period_s : length of one on/off period, s
    duration_s : time simulated, s (default 300: the article's 5-minute drilling)
    """

    h_w_per_m2k: float = 10.0
    ambient_c: float = 25.0
    duty: float = 1.0
    period_s: float = 10.0
    duration_s: float = 300.0

    def __post_init__(self):
        check_range("h_w_per_m2k", self.h_w_per_m2k, 0.0, 1e5, "W/m^2/K", lo_open=True)
        check_range("ambient_c", self.ambient_c, -273.15, 500.0, "deg C", lo_open=True)
        check_range("duty", self.duty, 0.0, 1.0, lo_open=True)
        check_range("period_s", self.period_s, 1e-3, 1e6, "s")
        check_range("duration_s", self.duration_s, 1e-3, 1e7, "s")


@dataclass(eq=False, repr=False)
class ThermalResult(Result):
    """Temperature against time: ``t_s``, ``temperature_c`` (the ends of every stretch, and a few
    points inside), ``tau_s`` the time constant, ``steady_c`` the steady mean temperature
    (continuous drive: ``T_amb + duty P / (h A)`` on average), ``time_to_rated_s`` material ->
    seconds (None: not reached within ``duration_s``)."""

    t_s: np.ndarray
    temperature_c: np.ndarray
    heat_w: float
    tau_s: float
    steady_c: float
    time_to_rated_s: dict
    settings: ThermalSettings
    body: LumpedBody

    @property
    def final_c(self) -> float:
        return float(self.temperature_c[-1])

    def _headline(self) -> str:
        reach = ", ".join(f"{m} {self.body.rated_c[m]:g} C " + ("not reached" if t is None else f"after {t:.0f} s")
                          for m, t in self.time_to_rated_s.items())
        return (f"{self.heat_w:.3g} W, duty {self.settings.duty:g}: {self.final_c:.1f} C after "
                f"{self.settings.duration_s:g} s (tau {self.tau_s:.0f} s, steady {self.steady_c:.0f} C); {reach}")

    def _record(self) -> dict:
        return {"heat_w": self.heat_w, "tau_s": self.tau_s, "steady_c": self.steady_c, "final_c": self.final_c,
                "duration_s": self.settings.duration_s, "h_w_per_m2k": self.settings.h_w_per_m2k,
                "ambient_c": self.settings.ambient_c, "duty": self.settings.duty, "period_s": self.settings.period_s,
                "heat_capacity_j_per_k": self.body.capacity_j_per_k, "area_m2": self.body.area_m2,
                "mass_kg": self.body.mass_kg, "rated_c": dict(self.body.rated_c),
                "time_to_rated_s": dict(self.time_to_rated_s),
                "t_s": self.t_s.tolist(), "temperature_c": self.temperature_c.tolist()}


def lumped_temperature(heat_w: float, body: LumpedBody, settings: ThermalSettings = ThermalSettings(),
                       samples: int = 8) -> ThermalResult:
    """Temperature of the lumped body under ``heat_w`` (W while the drive is on) over
    ``settings.duration_s`` (module docstring); ``samples`` points inside every stretch."""
    check_range("heat", heat_w, 0.0, 1e7, "W")
    s = settings
    hA = s.h_w_per_m2k * body.area_m2
    tau = body.capacity_j_per_k / hA
    rise = heat_w / hA                                   # steady rise of a continuous drive
    on = s.duty * s.period_s
    ts, Ts = [0.0], [s.ambient_c]
    reach = {m: None for m in body.rated_c}
    t, T = 0.0, s.ambient_c
    while t < s.duration_s - 1e-12:
        phase = (t / s.period_s) % 1.0 * s.period_s
        driving = s.duty >= 1.0 or phase < on - 1e-12
        end = s.duration_s if s.duty >= 1.0 else min(s.duration_s, t - phase + (on if driving else s.period_s))
        target = s.ambient_c + (rise if driving else 0.0)
        dt = end - t
        for m, Tr in body.rated_c.items():
            if reach[m] is None and driving and target > Tr >= T:
                cross = tau * math.log((target - T) / (target - Tr))
                if cross <= dt:
                    reach[m] = t + cross
        sub = np.linspace(0.0, dt, samples + 1)[1:]
        ts.extend(t + sub)
        Ts.extend(target + (T - target) * np.exp(-sub / tau))
        t, T = end, target + (T - target) * math.exp(-dt / tau)
    return ThermalResult(np.array(ts), np.array(Ts), float(heat_w), tau, s.ambient_c + s.duty * rise, reach, s, body)


def thermal_summary(system, x: np.ndarray, freq_hz: float, loss_matrix, input_w: float, delivered_w: float = 0.0,
                    settings: ThermalSettings = ThermalSettings()) -> dict:
    """Heat of the state ``x`` and the lumped temperature it drives, as a JSON-ready record with a
    ``lines`` entry for the terminal. ``input_w`` / ``delivered_w``: the electrical input and the
    power taken by a load at the same state (W), for the balance check; the temperature after
    ``settings.duration_s`` is bracketed over :data:`H_RANGE` (the convective coefficient is the
    least known input). A material without a specific heat gives a record saying so."""
    heat = heat_generation(system, x, freq_hz, loss_matrix)
    rec = {"heat": heat.record(), "input_w": float(input_w), "delivered_w": float(delivered_w),
           "balance_residual_w": float(input_w - delivered_w - heat.total_w)}
    lines = [f"heat: {heat.total_w:.4g} W (mechanical {heat.mechanical_w:.4g} W, dielectric {heat.dielectric_w:.3g} W) "
             f"of {input_w:.4g} W drawn" + (f", {delivered_w:.3g} W delivered to the load" if delivered_w else "")]
    try:
        body = lumped_body(system)
    except ParameterError as exc:
        rec["temperature"] = None
        rec["lines"] = lines + [f"temperature: not modelled ({exc})"]
        return rec
    res = lumped_temperature(max(heat.total_w, 0.0), body, settings)
    brk = {h: lumped_temperature(max(heat.total_w, 0.0), body, ThermalSettings(
        h, settings.ambient_c, settings.duty, settings.period_s, settings.duration_s)).final_c for h in H_RANGE}
    rec["temperature"] = res.to_dict()
    rec["final_c_h_range"] = {f"{h:g}": v for h, v in brk.items()}
    reach = "; ".join(f"{m} rated {body.rated_c[m]:g} C " + ("not reached" if t is None else f"reached after {t:.0f} s")
                      for m, t in res.time_to_rated_s.items())
    lines.append(f"temperature (lumped: {body.mass_kg * 1e3:.0f} g, {body.capacity_j_per_k:.0f} J/K, "
                 f"{body.area_m2 * 1e4:.0f} cm^2, h {settings.h_w_per_m2k:g} W/m^2/K, duty {settings.duty:g}): "
                 f"{res.final_c:.0f} C after {settings.duration_s:g} s ({brk[H_RANGE[0]]:.0f} C at h {H_RANGE[0]:g}, "
                 f"{brk[H_RANGE[1]]:.0f} C at h {H_RANGE[1]:g}), time constant {res.tau_s:.0f} s, steady {res.steady_c:.0f} C; "
                 + (reach or "no rated material"))
    rec["verdict"] = thermal_verdict(res)
    rec["lines"] = lines + [rec["verdict"]]
    return rec


def thermal_verdict(res: ThermalResult) -> str:
    """One sentence: whether a rated temperature is reached, and if so what keeps the body below it
    (the heat balance at the rated temperature: shorter runs, a duty cycle, a lower drive, cooling)."""
    hit = {m: t for m, t in res.time_to_rated_s.items() if t is not None}
    if not res.body.rated_c:
        return "thermal: no material with a rated temperature"
    m = min(res.body.rated_c, key=res.body.rated_c.get)
    Tr, s = res.body.rated_c[m], res.settings
    hA = s.h_w_per_m2k * res.body.area_m2
    removable = hA * (Tr - s.ambient_c)                     # what convection removes at the rating
    if not hit:
        return (f"thermal: {m} stays below its rated {Tr:g} C over {s.duration_s:g} s (steady mean "
                f"{res.steady_c:.0f} C)")
    t = min(hit.values())
    return (f"thermal: FAILS: {m} reaches its rated {Tr:g} C after {t:.0f} s: the {res.heat_w:.3g} W of heat exceed "
            f"the {removable:.3g} W convection removes at {Tr:g} C; fix: runs shorter than {t:.0f} s, a duty cycle "
            f"<= {removable / res.heat_w:.2f}, a drive <= {100 * math.sqrt(removable / res.heat_w):.0f} % of this "
            f"voltage (heat ~ V^2), or cooling with h >= {res.heat_w / (res.body.area_m2 * (Tr - s.ambient_c)):.0f} "
            "W/m^2/K (forced air or a heat path)")
