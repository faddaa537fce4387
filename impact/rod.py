"""The drill tool as a slender elastic rod: a rigid collar (struck by the free mass) on a uniform
rod whose far end is the bit (SI units).

Wave model
----------
A uniform rod of impedance ``Z = rho c A`` (``c = sqrt(E / rho)``) carries a right-going wave
(velocity ``a``, toward the bit) and a left-going wave (``b``); particle velocity ``v = a + b``
and compressive force ``N = Z (a - b)`` (d'Alembert). Cut into ``cells`` segments of length
``dx``, with the time step ``dt = dx / c`` both waves move exactly one segment per step: the rod
itself is integrated without error or dispersion (the method of characteristics, as in
Lundberg's percussive-drilling simulations). Only its two ends need a law: the collar (a rigid
mass on the support spring k0, struck by the free mass) at the top and the bit-rock contact
(:mod:`impact.rock`) at the bottom. Each end sees the incoming wave as constant over a step
and emits the step average of its outgoing wave, so the impulse passed into the rod is exact.
A wave takes ``cells`` steps to cross: ring buffers make a step O(1) whatever the cell count.

Why a rod: the 3 mm tool is long compared with the contact time. A collar hit by the free mass
sends a force pulse ``F = Z V exp(-Z t / m_c)`` down the rod (Saint-Venant); it reaches the
rock L/c later, and the rock's reflection comes back. A rigid tool (the no-load model's
oscillator, which stays the model of the article's no-load case) would press the rock with the
whole tool mass at once.

Default tool (assumed; the article gives only the 3 mm diameter and, in Table 1, the tool mass
m_v = 50 g): a 3 mm steel rod 150 mm long (8.4 g) under a rigid collar carrying the rest of
the mass (41.6 g).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from rpud_common import ParameterError, check_integer, check_range

__all__ = ["ToolRod", "saint_venant_force", "saint_venant_exit_speed"]


@dataclass(frozen=True)
class ToolRod:
    """Geometry and material of the tool's slender part (SI units).

    Parameters
    ----------
    diameter : float
        Rod diameter, m, in [1e-4, 0.1] (article: 3 mm).
    length : float
        Rod length from the collar to the bit, m, in [1e-3, 5] (assumed 0.15).
    E : float
        Young's modulus, Pa (steel 45#: 209 GPa, references.md).
    rho : float
        Density, kg/m^3 (7890).
    cells : int
        Segments of the wave model, in [2, 4096]; the time step is length / (cells c).
    """

    diameter: float = 3e-3
    length: float = 0.15
    E: float = 209e9
    rho: float = 7890.0
    cells: int = 32

    def __post_init__(self):
        check_range("diameter", self.diameter, 1e-4, 0.1, "m")
        check_range("length", self.length, 1e-3, 5.0, "m")
        check_range("E", self.E, 1e8, 1e13, "Pa")
        check_range("rho", self.rho, 100.0, 1e5, "kg/m^3")
        check_integer("cells", self.cells, 2, 4096)

    def with_(self, **changes) -> "ToolRod":
        return replace(self, **changes)

    @property
    def area(self) -> float:
        """Cross-section, m^2."""
        return math.pi * self.diameter ** 2 / 4.0

    @property
    def c(self) -> float:
        """Bar wave speed sqrt(E/rho), m/s."""
        return math.sqrt(self.E / self.rho)

    @property
    def impedance(self) -> float:
        """Z = rho c A, N s/m."""
        return self.rho * self.c * self.area

    @property
    def mass(self) -> float:
        """Rod mass, kg."""
        return self.rho * self.area * self.length

    @property
    def dt(self) -> float:
        """Time step of the wave model, s (one segment per step)."""
        return self.length / (self.cells * self.c)

    @property
    def transit(self) -> float:
        """L / c, s."""
        return self.length / self.c

    def collar_mass(self, m_tool: float) -> float:
        """Mass of the rigid collar when the whole tool weighs ``m_tool`` kg."""
        mc = m_tool - self.mass
        if not mc > 0.0:
            raise ParameterError("length", self.length,
                                 f"rod mass {self.mass:g} kg must be < the tool mass m_tool = {m_tool:g} kg")
        return mc

    def to_dict(self) -> dict:
        return {"diameter_m": self.diameter, "length_m": self.length, "E_pa": self.E, "rho_kg_m3": self.rho,
                "cells": self.cells, "impedance_ns_per_m": self.impedance, "wave_speed_m_s": self.c,
                "mass_kg": self.mass, "dt_s": self.dt}


def saint_venant_force(t, V: float, M: float, rod: ToolRod):
    """Contact force of a rigid mass M (kg) striking the end of a free-free rod at V (m/s).

    ``Z V exp(-Z t / M)`` for ``0 <= t < 2 L / c``, 0 after: the wave reflected as tension at the
    free far end returns at 2L/c and the mass separates (whatever the mass ratio). Classical
    (Saint-Venant; e.g. Graff, *Wave Motion in Elastic Solids*, sec. 2.2; Goldsmith, *Impact*).
    """
    import numpy as np

    t = np.asarray(t, dtype=float)
    Z = rod.impedance
    return np.where((t >= 0.0) & (t < 2.0 * rod.transit), Z * V * np.exp(-Z * t / M), 0.0)


def saint_venant_exit_speed(V: float, M: float, rod: ToolRod) -> float:
    """Speed of the striking mass after it separates at 2L/c: V exp(-2 m_rod / M), m/s."""
    return V * math.exp(-2.0 * rod.mass / M)
