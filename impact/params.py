"""Parameters of the free-mass impact model (SI units), with Table 1 of the article as defaults.

Sign convention: the x axis runs along the drill from the horn tip toward the drill tool.
``g`` is the acceleration of gravity along +x (positive = drill pointing down, gravity pulls
the free mass away from the horn toward the tool; 0 = weightless; negative = drill pointing up).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Literal

from rpud_common import (
    ParameterError, check_choice, check_range, dump_toml, from_mapping, load_toml, to_mapping,
)

__all__ = ["ImpactParams", "HORN_LAWS"]

HORN_LAWS = ("kinematic", "article")


@dataclass(frozen=True)
class ImpactParams:
    """Every input of one impact simulation (SI units).

    Every field must be finite and inside a physical range (checked on construction; the
    error names the field, the value and the range with its unit): m_free in [1e-6, 10] kg,
    A0 0 or in [1e-12, 1e-3] m, freq in [1, 1e6] Hz, e1 and e2 in [0, 1], m_horn and m_tool in
    [1e-6, 100] kg, k0 in (0, 1e10] N/m, c in [0, 1e6] N s/m, gap in (2 A0, 1] m and beyond the
    tool's static deflection under the resting free mass, ``|g| <= 1e4`` m/s^2, v0 in [0, 100] m/s,
    t_end in (0, 100] s, spring_force in [0, 1e4] N, v_stick in (0, 1] m/s, sample_dt in
    [1e-9, 1e-2] s with at most 2e7 samples, max_events an integer in [1, 1e8].

    Parameters
    ----------
    m_free : float
        Free mass m_w, kg (Table 1: 0.008).
    A0 : float
        Horn-tip vibration amplitude, m (Table 1: 15 µm). 0 gives a fixed horn (a table).
    freq : float
        Horn vibration frequency f, Hz (Table 1: 20 kHz).
    e1 : float
        Coefficient of restitution free mass / drill tool, in [0, 1] (Table 1: 0.8).
    e2 : float
        Coefficient of restitution free mass / horn, in [0, 1] (Table 1: 0.9).
    m_horn : float
        Horn mass m_u, kg (Table 1: 0.08). Used by ``horn_law="article"`` only; with the
        default kinematic law it only scales the reported horn momentum.
    m_tool : float
        Drill-tool mass m_v, kg (Table 1: 0.05).
    k0 : float
        Equivalent axial stiffness holding the drill tool, N/m (not in the article; calibrated,
        see the module docstring of :mod:`impact.model`).
    c : float
        Viscous damping of the drill tool, N s/m (calibrated), in [0, 1e6]. Under-, critically
        (``c = 2 sqrt(k0 m_tool)``) and over-damped tools are all allowed.
    gap : float
        L0: free stroke of the free mass between the horn tip at rest and the tool face at
        rest, m (the free mass is a point; its own length is already subtracted). Calibrated.
    g : float
        Gravity along +x (toward the tool), m/s^2 (Table 1: 9.8). Any sign.
    v0 : float
        Free-mass velocity at t = 0 as it leaves the horn tip (u(0) = A0), m/s, >= 0.
        The tool is at rest at t = 0.
    t_end : float
        Simulated time, s.
    spring_force : float
        Optional restoring-spring force on the free mass toward the horn, N (soft spring: taken
        constant over the mm stroke). 0 = off (the article's model); the device preloads ~5 N.
    horn_law : {"kinematic", "article"}
        "kinematic": the horn is an infinite-mass driver, w' = u' - e2 (w - u') (assumption 1).
        "article": eq. 21 as printed, w' = w - m_u/(m_u+m_w) (1+e2)(w - u'), horn unchanged.
    v_stick : float
        Relative speed below which an impact ends a chattering sequence: the free mass sticks
        to the body if the contact force would be compressive, m/s.
    sample_dt : float
        Spacing of the uniform output grid of displacements, s.
    max_events : int
        Safety cap on the number of events (a bug or a pinched free mass raises).
    """

    m_free: float = 0.008
    A0: float = 15e-6
    freq: float = 20e3
    e1: float = 0.8
    e2: float = 0.9
    m_horn: float = 0.08
    m_tool: float = 0.05
    k0: float = 1.8e5
    c: float = 38.0
    gap: float = 2.15e-3
    g: float = 9.8
    v0: float = 4.0
    t_end: float = 0.05
    spring_force: float = 0.0
    horn_law: Literal["kinematic", "article"] = "kinematic"
    v_stick: float = 1e-6
    sample_dt: float = 2.5e-6
    max_events: int = 5_000_000

    def __post_init__(self) -> None:
        # Physical ranges: wide enough for any drill of this kind (and for the fuzzing tests),
        # narrow enough that every run finishes and no float overflows (e.g. k0 / m_tool).
        check_range("m_free", self.m_free, 1e-6, 10.0, "kg")
        check_range("A0", self.A0, 0.0, 1e-3, "m")
        if 0.0 < self.A0 < 1e-12:
            raise ParameterError("A0", self.A0, "must be 0 (a fixed horn) or in [1e-12, 1e-3] m")
        check_range("freq", self.freq, 1.0, 1e6, "Hz")
        check_range("e1", self.e1, 0.0, 1.0)
        check_range("e2", self.e2, 0.0, 1.0)
        check_range("m_horn", self.m_horn, 1e-6, 100.0, "kg")
        check_range("m_tool", self.m_tool, 1e-6, 100.0, "kg")
        check_range("k0", self.k0, 0.0, 1e10, "N/m", lo_open=True)
        # under-, critically and over-damped tools are all supported (impact.oscillator.Oscillator)
        check_range("c", self.c, 0.0, 1e6, "N s/m")
        check_range("gap", self.gap, 0.0, 1.0, "m", lo_open=True)
        if not self.gap > 2.0 * self.A0:
            raise ParameterError("gap", self.gap, f"must lie in (2 A0, 1] m = ({2 * self.A0:g}, 1] m")
        check_range("g", self.g, -1e4, 1e4, "m/s^2")
        check_range("v0", self.v0, 0.0, 100.0, "m/s")
        check_range("t_end", self.t_end, 0.0, 100.0, "s", lo_open=True)
        check_range("spring_force", self.spring_force, 0.0, 1e4, "N")
        check_choice("horn_law", self.horn_law, HORN_LAWS)
        check_range("v_stick", self.v_stick, 0.0, 1.0, "m/s", lo_open=True)
        check_range("sample_dt", self.sample_dt, 1e-9, 1e-2, "s")
        if self.t_end / self.sample_dt > 2e7:
            raise ParameterError("sample_dt", self.sample_dt,
                                 f"must be >= t_end / 2e7 = {self.t_end / 2e7:g} s "
                                 "(at most 2e7 output samples)")
        if not (isinstance(self.max_events, int) and not isinstance(self.max_events, bool)
                and 1 <= self.max_events <= 100_000_000):
            raise ParameterError("max_events", self.max_events, "must be an integer in [1, 1e8]")
        # A free mass resting on the tool deflects it by m_free a / k0 toward the horn: a gap
        # smaller than that plus the horn's stroke pinches as soon as the mass settles.
        defl = self.m_free * self.a_free / self.k0
        if defl > 0.0 and not self.gap > 2.0 * self.A0 + defl:
            raise ParameterError(
                "gap", self.gap,
                f"must be > 2 A0 + m_free a_free / k0 = {2.0 * self.A0 + defl:g} m (the resting "
                "free mass pushes the tool into the horn's stroke): increase gap or k0")

    # ------------------------------------------------------------------ derived values
    @property
    def omega(self) -> float:
        """Horn angular frequency 2 pi f, rad/s."""
        return 2.0 * math.pi * self.freq

    @property
    def a_free(self) -> float:
        """Acceleration of the free mass in free flight along +x, m/s^2 (gravity - spring)."""
        return self.g - self.spring_force / self.m_free

    @property
    def tool_fn(self) -> float:
        """Undamped natural frequency of the drill tool sqrt(k0/m_tool)/(2 pi), Hz."""
        return math.sqrt(self.k0 / self.m_tool) / (2.0 * math.pi)

    @property
    def tool_zeta(self) -> float:
        """Damping ratio of the drill tool c / (2 sqrt(k0 m_tool))."""
        return self.c / (2.0 * math.sqrt(self.k0 * self.m_tool))

    # ------------------------------------------------------------------ TOML
    def with_(self, **changes) -> "ImpactParams":
        """A copy with some fields changed (validated again)."""
        return replace(self, **changes)

    def to_dict(self) -> dict:
        return to_mapping(self)

    @classmethod
    def from_dict(cls, data) -> "ImpactParams":
        return from_mapping(cls, data)

    def to_toml(self) -> str:
        return dump_toml(self.to_dict())

    @classmethod
    def from_toml(cls, path) -> "ImpactParams":
        """Load from a TOML file: top-level keys, or an ``[impact]`` table."""
        data = load_toml(path)
        if "impact" in data and isinstance(data["impact"], dict):
            data = data["impact"]
        return from_mapping(cls, data)
