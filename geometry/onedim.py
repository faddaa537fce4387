"""1-D longitudinal resonance of a coaxial stack by transfer matrices (independent reference).

Each uniform slice of length l, area S, modulus E and density rho relates force and velocity
at its ends by (``shared/references.md``)::

    [F1; v1] = [[cos kl, j Z sin kl], [j sin kl / Z, cos kl]] [F2; v2],  k = w / c, Z = rho c S

and a free-free chain resonates where the (1, 2) entry of the product vanishes. Tapered parts
are cut into thin uniform slices by the designs (``sections_1d``). Piezoceramic slices use the
axial modulus 1/s33^E (short-circuit electrodes: resonance) or 1/s33^D (open circuit:
anti-resonance), lateral inertia neglected (see the Rayleigh-Love pitfall in the references).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Literal, Sequence

import numpy as np
from scipy.optimize import brentq

from rpud_common import ParameterError, check_positive
from .materials import Material, get_material
from .piezo_forms import strain_charge

__all__ = ["Mode1D", "axial_modulus", "longitudinal_modes", "design_modes", "first_longitudinal", "mode_shape"]

log = logging.getLogger(__name__)


def axial_modulus(material: str | Material, electrical: Literal["short", "open"] = "short") -> float:
    """Young's modulus along the axis (Pa) for a slender bar of ``material``.

    Isotropic: E. Piezoceramic poled along the axis: 1/s33^E (short circuit) or 1/s33^D
    (open circuit), with s^E = (c^E)^-1, d = e s^E, eps^T = eps^S + d e^T and
    s33^D = s33^E - d33^2 / eps33^T.
    """
    m = get_material(material) if isinstance(material, str) else material
    if not m.is_piezo:
        return float(m.youngs_modulus)
    s, d, epsT = strain_charge(*m.voigt_matrices())
    if electrical == "short":
        return float(1.0 / s[2, 2])
    return float(1.0 / (s[2, 2] - d[2, 2] ** 2 / epsT[2, 2]))


@dataclass(frozen=True)
class Mode1D:
    """A free-free longitudinal mode of a 1-D chain.

    Attributes
    ----------
    frequency : float
        Hz.
    z : (n,) array
        Sample positions along the axis, m.
    displacement : (n,) array
        Axial displacement, normalised to max |u| = 1 (sign: +1 at the largest |u|).
    nodes : tuple of float
        z of the displacement nodes, m.
    """

    frequency: float
    z: np.ndarray
    displacement: np.ndarray
    nodes: tuple[float, ...]

    def amplitude_at(self, z: float) -> float:
        """Normalised displacement at ``z`` (m), linear interpolation."""
        return float(np.interp(z, self.z, self.displacement))


def _chain(sections, omega):
    """(1, 2) entry divided by j of the chain's transfer matrix, for an array of omega."""
    omega = np.atleast_1d(np.asarray(omega, dtype=float))
    a = np.ones_like(omega, dtype=float)  # T11, T22 real; T12 = j b, T21 = j c
    b = np.zeros_like(a)
    c_ = np.zeros_like(a)
    d = np.ones_like(a)
    for length, area, E, rho in sections:
        c = math.sqrt(E / rho)
        kl = omega / c * length
        Z = rho * c * area
        ck, sk = np.cos(kl), np.sin(kl)
        # [[a, j b], [j c, d]] @ [[ck, j Z sk], [j sk / Z, ck]]
        a, b, c_, d = (a * ck - b * sk / Z, a * Z * sk + b * ck, c_ * ck + d * sk / Z, -c_ * Z * sk + d * ck)
    return b


def longitudinal_modes(sections: Sequence[tuple[float, float, str | Material | tuple[float, float]]],
                       f_max: float = 60e3, z0: float = 0.0, electrical: Literal["short", "open"] = "short",
                       n_scan: int = 4000, samples_per_section: int = 8, library=None) -> list[Mode1D]:
    """Free-free longitudinal modes of a chain of uniform slices, below ``f_max``.

    Parameters
    ----------
    sections : sequence of (length m, area m^2, material)
        ``material`` is a library name, a :class:`Material` or ``(E Pa, rho kg/m^3)``.
    f_max : float
        Highest frequency searched, Hz.
    z0 : float
        z of the first slice's -z face, m.
    electrical : {"short", "open"}
        Electrode condition of piezoceramic slices.
    library : mapping name -> Material, optional
        Where material names resolve (default: the built-in library; a design's is
        ``design.library``).

    Returns
    -------
    list of Mode1D, by increasing frequency (rigid-body motion excluded).
    """
    check_positive("f_max", f_max, "Hz")
    props = []
    for i, (length, area, mat) in enumerate(sections):
        check_positive(f"sections[{i}].length", length, "m")
        check_positive(f"sections[{i}].area", area, "m^2")
        if isinstance(mat, tuple):
            E, rho = mat
        else:
            m = get_material(mat, library) if isinstance(mat, str) else mat
            E, rho = axial_modulus(m, electrical), m.density
        props.append((float(length), float(area), float(E), float(rho)))

    def g(f):
        return float(_chain(props, 2 * math.pi * f)[0])

    freqs = np.linspace(f_max / n_scan, f_max, n_scan)
    vals = _chain(props, 2 * math.pi * freqs)
    roots = [brentq(g, freqs[i], freqs[i + 1], xtol=1e-9) for i in range(n_scan - 1)
             if np.sign(vals[i]) != np.sign(vals[i + 1]) and vals[i] != 0]
    return [mode_shape(props, f, z0, samples_per_section) for f in roots]


def mode_shape(props, f, z0, nsamp) -> Mode1D:
    """The free-end displacement shape of a chain of uniform bars at ``f``, by transfer matrices.

    Parameters
    ----------
    props : sequence of (length m, area m^2, E Pa, rho kg/m^3)
        The bars from the free end at ``z0`` on.
    f : float
        Frequency, Hz (an eigenfrequency of the chain, for a mode).
    z0 : float
        z of the first bar's free end, m.
    nsamp : int
        Samples per bar.

    Returns
    -------
    Mode1D
        Axial displacement scaled to a largest magnitude of 1, and its nodes (sign changes).
    """
    omega = 2 * math.pi * f
    F, v = 0j, 1.0 + 0j
    zs, us = [z0], [1.0]
    z = z0
    for length, area, E, rho in props:
        c = math.sqrt(E / rho)
        k, Z = omega / c, rho * c * area
        for s in np.linspace(length / nsamp, length, nsamp):
            ck, sk = math.cos(k * s), math.sin(k * s)
            # [F2; v2] = M^-1 [F1; v1]
            us.append((-1j * sk / Z * F + ck * v).real)
            zs.append(z + s)
        ck, sk = math.cos(k * length), math.sin(k * length)
        F, v = ck * F - 1j * Z * sk * v, -1j * sk / Z * F + ck * v
        z += length
    zs, us = np.array(zs), np.array(us)
    us = us / us[np.argmax(np.abs(us))]
    idx = np.flatnonzero(np.sign(us[:-1]) * np.sign(us[1:]) < 0)
    nodes = tuple(float(zs[i] - us[i] * (zs[i + 1] - zs[i]) / (us[i + 1] - us[i])) for i in idx)
    return Mode1D(frequency=float(f), z=zs, displacement=us, nodes=nodes)


def design_modes(design, f_max: float | None = None, electrical: Literal["short", "open"] = "short") -> list[Mode1D]:
    """1-D longitudinal modes of a design (:class:`~geometry.design_rpud.RPUDDesign` or
    :class:`~geometry.design_stack.StackDesign`), searched up to ``f_max`` (default 3 x target)."""
    f_max = 3.0 * design.target_frequency if f_max is None else f_max
    z0 = design.axial_breakpoints()[0][1]
    return longitudinal_modes(design.sections_1d(), f_max=f_max, z0=z0, electrical=electrical,
                              library=design.library)


def first_longitudinal(design, electrical: Literal["short", "open"] = "short") -> Mode1D:
    """The first free-free longitudinal mode of a design (half-wave mode)."""
    modes = design_modes(design, electrical=electrical)
    if not modes:
        raise ParameterError("design", design.name, "has no longitudinal mode below 3 x target_frequency")
    return modes[0]
