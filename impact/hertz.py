"""Hertz contact with the contact geometry as design data, and a restitution law built on it.

Force-approach law (Hertz 1882; Johnson, *Contact Mechanics*, sections 3.4-3.5, 4.2). Two bodies
whose gap near the first point of contact is ``h = x^2 / (2 R1) + y^2 / (2 R2)`` (``R1 >= R2`` the
principal relative radii of curvature) pressed together by the approach ``d`` carry::

    F = k d^{3/2},      1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2

with ``k = (4/3) E* sqrt(R)`` for ``R1 = R2 = R`` (a crowned face of radius R on a flat) and, for
``R1 > R2``, the exact elliptic-contact value of :func:`hertz_stiffness` (the eccentricity of the
contact ellipse from the ratio of the radii through the complete elliptic integrals K and E; no
equivalent-radius approximation).

Contact geometry as design data (:class:`ContactGeometry`):

* ``crowned(face_radius)``: the free mass's face is a spherical crown of radius R striking a flat;
* ``rounded_edge(edge_radius, face_radius, tilt)``: a flat face of radius ``a`` whose rim is rounded
  with radius ``r`` striking a flat tilted by ``theta``: it touches on the rim, a torus, whose
  principal radii there are ``r`` across the rim and ``(a - r) / sin(theta) + r`` along it
  (Meusnier: the radius of the rim's parallel circle over the sine of the normal's angle to the
  axis). A perfectly square flat face (theta = 0) is a flat punch, not a Hertz contact; it is
  refused.

Dissipation (:class:`HertzLaw`). Loading follows Hertz; from the largest approach ``d_m`` the
contact unloads along the power law ``F = k d_m^{3/2} (d / d_m)^p`` with ``p = 5 / (2 e^2) - 1`` and
reloads along the same curve up to ``d_m`` (then Hertz again). The unloading curve returns
``k d_m^{5/2} / (p + 1) = e^2 (2/5) k d_m^{5/2}``, ``e^2`` of the energy stored on loading, so a mass
striking a rigid flat leaves with exactly ``e`` times its approach speed at any speed and mass (the
definition of the coefficient of restitution), and one contact loses ``(1 - e^2) (2/5) k d_m^{5/2}``
in closed form. The curve ends at ``d = 0`` (no permanent set: repeated impacts keep the contact
geometry) and for ``e = 1`` it is Hertz's. The force is a function of the approach and of ``d_m``
alone (rate-independent, unlike a Hunt-Crossley dashpot): in series with a static compliance (the
residual of modes left out of a modal model) the force is the root of one monotone scalar equation,
and the energy ledger stays closed without integrating a damping power.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from rpud_common import ParameterError, check_positive, check_range

__all__ = ["ContactGeometry", "HertzLaw", "effective_modulus", "hertz_stiffness"]


def effective_modulus(E1: float, nu1: float, E2: float, nu2: float) -> float:
    """The contact modulus ``E* = 1 / ((1 - nu1^2)/E1 + (1 - nu2^2)/E2)``, Pa.

    Parameters
    ----------
    E1, E2 : float
        Young's moduli of the two bodies, Pa.
    nu1, nu2 : float
        Their Poisson ratios, in (-1, 0.5].
    """
    check_positive("E1", E1, "Pa")
    check_positive("E2", E2, "Pa")
    check_range("nu1", nu1, -1.0, 0.5, lo_open=True)
    check_range("nu2", nu2, -1.0, 0.5, lo_open=True)
    return 1.0 / ((1.0 - nu1 * nu1) / E1 + (1.0 - nu2 * nu2) / E2)


@dataclass(frozen=True)
class ContactGeometry:
    """Principal relative radii of curvature at the first point of contact (see the module docstring).

    Attributes
    ----------
    radius_1, radius_2 : float
        The two principal relative radii, m (``radius_1 >= radius_2 > 0``; equal for a crowned face).
    description : str
        What the radii were made from (reported with the results).
    """

    radius_1: float
    radius_2: float
    description: str = ""

    def __post_init__(self):
        check_range("radius_1", self.radius_1, 1e-6, 1e3, "m")
        check_range("radius_2", self.radius_2, 1e-6, 1e3, "m")
        if self.radius_2 > self.radius_1:
            raise ParameterError("radius_2", self.radius_2, f"must be <= radius_1 = {self.radius_1:g} m "
                                 "(radius_1 is the larger principal radius)")
        if self.radius_1 / self.radius_2 > 1e4:
            raise ParameterError("radius_1", self.radius_1, f"must be at most 1e4 radius_2 = {1e4 * self.radius_2:g} m "
                                 "(beyond it the contact is a line contact, not a Hertz point contact)")

    @classmethod
    def crowned(cls, face_radius: float) -> "ContactGeometry":
        """A spherical face (crown) of radius ``face_radius`` (m) on a flat."""
        check_range("face_radius", face_radius, 1e-6, 1e3, "m")
        return cls(float(face_radius), float(face_radius), f"crowned face R = {face_radius * 1e3:g} mm on a flat")

    @classmethod
    def rounded_edge(cls, edge_radius: float, face_radius: float, tilt: float) -> "ContactGeometry":
        """A flat face of radius ``face_radius`` (m) whose rim is rounded with ``edge_radius`` (m),
        striking a flat tilted by ``tilt`` (rad, in (0, pi/2)): the rim touches first."""
        check_range("face_radius", face_radius, 1e-6, 1e3, "m")
        check_range("edge_radius", edge_radius, 1e-6, face_radius, "m")
        check_range("tilt", tilt, 0.0, math.pi / 2, "rad", lo_open=True)
        along = (face_radius - edge_radius) / math.sin(tilt) + edge_radius
        return cls(max(along, edge_radius), min(along, edge_radius),
                   f"flat face a = {face_radius * 1e3:g} mm, edge radius {edge_radius * 1e3:g} mm, "
                   f"tilt {math.degrees(tilt):g} deg")


def _ellipse(ratio: float) -> tuple[float, float, float]:
    """``(e2, K, R)`` of the Hertz contact ellipse whose gap curvatures are in the ratio ``B / A =
    ratio`` (>= 1): its squared eccentricity, the complete elliptic integral ``K(e2)`` and Carlson's
    ``R = R_D(0, 1 - e2, 1)``, through which ``K - E = e2 R / 3`` and ``E - (1 - e2) K = e2 (K - R / 3)``
    carry no cancellation at small eccentricity."""
    from scipy.optimize import brentq
    from scipy.special import elliprd, elliprf

    def curvature_ratio(e2):
        # (E / (1 - e2) - K) / (K - E)
        K, R = elliprf(0.0, 1.0 - e2, 1.0), elliprd(0.0, 1.0 - e2, 1.0)
        return (K - R / 3.0) / ((1.0 - e2) * R / 3.0)

    # curvature_ratio grows from 1 (circle, e -> 0) to infinity (e -> 1)
    e2 = 0.0 if ratio == 1.0 else brentq(lambda x: curvature_ratio(x) - ratio, 0.0, 1.0 - 1e-15, xtol=1e-300,
                                         rtol=1e-15)
    return e2, float(elliprf(0.0, 1.0 - e2, 1.0)), float(elliprd(0.0, 1.0 - e2, 1.0))


def hertz_stiffness(e_star: float, geometry: ContactGeometry) -> float:
    """Hertz stiffness ``k`` of ``F = k d^{3/2}``, N/m^1.5, for the contact modulus ``e_star`` (Pa).

    With ``A = 1/(2 R1) <= B = 1/(2 R2)`` the gap's curvatures, the contact ellipse's eccentricity
    ``e`` solves ``B/A = (E(e)/(1 - e^2) - K(e)) / (K(e) - E(e))``; with ``b/a = sqrt(1 - e^2)`` and
    ``c = A e^2 / ((b/a) (K - E))`` (``p0 / (a E*)``) the approach is ``d = c a^2 (b/a) K`` and the
    load ``F = (2/3) pi (b/a) c E* a^3``, so ``k = (2/3) pi E* / (K^{3/2} sqrt(c b/a))`` (Johnson
    section 3.5). For equal radii it is ``(4/3) E* sqrt(R)``.
    """
    check_positive("e_star", e_star, "Pa")
    R1, R2 = geometry.radius_1, geometry.radius_2
    if R1 == R2:
        return 4.0 / 3.0 * e_star * math.sqrt(R1)
    e2, K, RD = _ellipse(R1 / R2)
    beta = math.sqrt(1.0 - e2)
    c = 3.0 * (0.5 / R1) / (beta * RD)
    return 2.0 / 3.0 * math.pi * e_star / (K ** 1.5 * math.sqrt(c * beta))


@dataclass(frozen=True)
class HertzLaw:
    """Hertz loading with the restitution unloading of the module docstring.

    Attributes
    ----------
    stiffness : float
        Hertz stiffness k, N/m^1.5 (:func:`hertz_stiffness`).
    restitution : float
        Coefficient of restitution of an impact on a rigid flat, in (0, 1] (1: elastic).
    """

    stiffness: float
    restitution: float = 1.0

    def __post_init__(self):
        check_range("stiffness", self.stiffness, 1e3, 1e20, "N/m^1.5")
        check_range("restitution", self.restitution, 0.0, 1.0, lo_open=True)

    @property
    def exponent(self) -> float:
        """Exponent ``p = 5 / (2 e^2) - 1`` of the unloading curve (3/2 for e = 1)."""
        return 2.5 / self.restitution ** 2 - 1.0

    def branch(self, d_max: float | None) -> tuple[float, float]:
        """``(K, p)``: the force is ``K d^p`` on the loading curve (``d_max`` None) or on the
        unloading curve from ``d_max`` (m)."""
        if d_max is None:
            return self.stiffness, 1.5
        p = self.exponent
        return self.stiffness * d_max ** (1.5 - p), p

    def force(self, d: float, d_max: float) -> float:
        """Contact force (N, >= 0) at approach ``d`` (m) after the largest approach ``d_max`` (m)."""
        if d <= 0.0:
            return 0.0
        K, p = self.branch(None if d >= d_max else d_max)
        return K * d ** p

    def stored(self, d: float, d_max: float) -> float:
        """Elastic energy the contact would return on unloading from ``d`` (J):
        ``K d^{p+1} / (p + 1)`` on the unloading curve from ``max(d, d_max)``."""
        if d <= 0.0:
            return 0.0
        K, p = self.branch(max(d, d_max))
        return K * d ** (p + 1.0) / (p + 1.0)

    def dissipated(self, d_max: float) -> float:
        """Energy lost in a contact whose largest approach was ``d_max`` (J):
        ``(1 - e^2) (2/5) k d_m^{5/2}``."""
        return (1.0 - self.restitution ** 2) * 0.4 * self.stiffness * max(d_max, 0.0) ** 2.5

    def contact_time(self, mass: float, speed: float) -> float:
        """Duration of the elastic Hertz impact of ``mass`` (kg) at ``speed`` (m/s) on a rigid flat, s:
        ``2 d_m / v * int_0^1 dx / sqrt(1 - x^{5/2})`` with ``d_m = (5 m v^2 / (4 k))^{2/5}`` (the energy
        integral; the loading and the elastic unloading take the same time). The scale on which a
        modal model must resolve the contact."""
        check_positive("mass", mass, "kg")
        check_positive("speed", speed, "m/s")
        d_m = (1.25 * mass * speed * speed / self.stiffness) ** 0.4
        # int_0^1 (1 - x^{5/2})^{-1/2} dx = (2/5) B(2/5, 1/2)
        integral = 0.4 * math.gamma(0.4) * math.gamma(0.5) / math.gamma(0.9)
        return 2.0 * d_m / speed * integral
