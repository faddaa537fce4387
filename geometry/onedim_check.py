"""Where the 1-D longitudinal reference (:mod:`geometry.onedim`) applies to a design, and how far off it is.

The 1-D chain is a bar model: plane sections stay plane, no lateral inertia, and every
piezoceramic slice has the axial modulus 1/s33^E, i.e. a field-free ceramic. Two first-order
estimates say how far a real (3-D, electroded) design departs from that, from the 1-D mode
shape ``u(z)`` itself (Rayleigh quotient ``omega^2 = U / T``, ``U = int E A u'^2``,
``T = int rho A u^2``):

- **lateral inertia** (Rayleigh-Love, ``shared/references.md``): the radial Poisson motion
  ``-nu r u'`` adds ``int rho nu^2 J u'^2`` to ``T`` (``J = A r_g^2``, polar), so
  ``df/f = -(1/2) int rho nu^2 J u'^2 / T`` (a uniform rod: ``-(1/2) nu^2 (R^2/2) (n pi/L)^2``);
- **electrode stiffening**: between two shorted electrodes the charge density ``D`` is uniform,
  so only the *mean* strain of the layer is field free; the strain's variation inside it is
  stiffened to ``c^D = 1/s33^D``: ``df/f = +(1/2) sum (c^D - c^E) A int (u' - <u'>)^2 / U``
  (a floating ceramic without electrodes: all of its strain). Thin rings (the RPUD stack) are
  field free; a rod electroded on its ends (IEEE k33) is not: its short-circuit resonance lies
  between the 1/s33^E and 1/s33^D bar frequencies.

Outside ``TOLERANCE`` on either estimate, or with a ceramic poled across the axis (the chain
knows axial poling only), the 1-D number is not a reference for the design.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .onedim import Mode1D, axial_modulus, mode_shape
from .piezo_forms import strain_charge

__all__ = ["OneDimCheck", "check_1d", "TOLERANCE", "MEANING"]

TOLERANCE = 0.02
"""Largest estimated relative error (each estimate) for which the 1-D number is a reference."""

MEANING = ("1-D bar chain: plane sections, no lateral inertia, ceramics field free (1/s33^E), "
           "free-free, short circuit")
"""What the 1-D number is, in one line."""


@dataclass(frozen=True)
class OneDimCheck:
    """The 1-D reference's validity for one design and mode.

    Attributes
    ----------
    rayleigh_love : float
        Estimated relative frequency change from lateral inertia (< 0).
    electrode_stiffening : float
        Estimated relative frequency change from the field inside electroded ceramics (>= 0).
    reasons : tuple of str
        Why the 1-D number does not apply (empty: it does, within :data:`TOLERANCE`).
    caveats : tuple of str
        What it ignores even where it applies (e.g. the 3-D compliance of slots).
    """

    rayleigh_love: float
    electrode_stiffening: float
    reasons: tuple[str, ...] = ()
    caveats: tuple[str, ...] = field(default_factory=tuple)

    @property
    def valid(self) -> bool:
        return not self.reasons

    def as_dict(self) -> dict:
        return {"meaning": MEANING, "valid": self.valid, "rayleigh_love_rel": self.rayleigh_love,
                "electrode_stiffening_rel": self.electrode_stiffening, "tolerance_rel": TOLERANCE,
                "reasons": list(self.reasons), "caveats": list(self.caveats)}


@dataclass(frozen=True)
class _Slice:
    z0: float
    z1: float
    area: float
    gyration2: float          # polar radius of gyration squared, m^2
    material: object          # Material
    layer: str | None         # electroded layer name (short), "floating:<name>", or None


def _stack_slices(design, lib, n_taper=200) -> tuple[list[_Slice], list[str]]:
    ext = design.segment_extents()
    planes = [z for pl in design.electrode_planes().values() for axis, z in pl if axis == "z"]
    out, reasons = [], []
    for seg in design.segments:
        z0, z1 = ext[seg.name]
        m = lib[seg.material]
        layer = None
        if seg.poling != "none":
            if seg.poling not in ("+z", "-z"):
                reasons.append(f"segment {seg.name} is poled across the axis ({seg.poling}); the 1-D chain "
                               "models axially poled ceramic only")
            else:
                # electrode planes on both faces (an electrode may be named on the neighbour's face)
                both = all(any(abs(z - zp) <= 1e-9 for zp in planes) for z in (z0, z1))
                layer = seg.name if both else f"floating:{seg.name}"
        n = n_taper if seg.kind == "cone" else 1
        dz = (z1 - z0) / n
        for i in range(n):
            if seg.kind == "box":
                g2 = (seg.thickness ** 2 + seg.width ** 2) / 12.0
            else:
                s = (i + 0.5) * dz
                d_out = seg.outer_diameter + (seg.end_diameter - seg.outer_diameter) * s / seg.length \
                    if seg.kind == "cone" else seg.outer_diameter
                g2 = ((d_out / 2) ** 2 + (seg.inner_diameter / 2) ** 2) / 2.0
            out.append(_Slice(z0 + i * dz, z0 + (i + 1) * dz, seg.area_at((i + 0.5) * dz), g2, m, layer))
    return out, reasons


def _rpud_slices(design, lib) -> tuple[list[_Slice], list[str]]:
    """RPUD slices from ``sections_1d``; the radius of gyration of an annulus of the slice's
    area inside the part's outer radius (exact for rings, flange and horn; an upper bound where
    slots or teeth remove material at the outside)."""
    ext = design.part_extents()
    z0h = ext["horn"][0]
    radius = {"coupler": design.coupler.outer_diameter / 2, "stack": design.stack.outer_diameter / 2,
              "electrodes": design.stack.outer_diameter / 2, "flange": design.flange.outer_diameter / 2}
    rings = {z0: name for name, kind, z0, _z1 in design.stack_layers() if kind == "ring"}
    out = []
    z = design.axial_breakpoints()[0][1]
    for length, area, mat in design.sections_1d():
        zm = z + length / 2
        part = next(p for p, (a, b) in ext.items() if a - 1e-12 <= zm <= b + 1e-12)
        R = float(design.horn.diameter_at(zm - z0h)) / 2 if part == "horn" else radius[part]
        g2 = max(R ** 2 - area / (2 * math.pi), area / (2 * math.pi))
        layer = next((n for z0r, n in rings.items() if abs(z0r - z) < 1e-12), None) if part == "stack" else None
        out.append(_Slice(z, z + length, area, g2, lib[mat], layer))
        z += length
    return out, []


def check_1d(design, mode: Mode1D, n_grid: int = 20001) -> OneDimCheck:
    """Estimate how far ``mode`` (a 1-D mode of ``design``, :func:`geometry.onedim.design_modes`)
    is from the design's 3-D behaviour; see the module docstring."""
    lib = design.library
    if design.kind == "stack":
        slices, reasons = _stack_slices(design, lib)
    else:
        slices, reasons = _rpud_slices(design, lib)
    # the mode's shape again, finely sampled (the 1-D mode keeps 8 samples per section)
    props = [(s.z1 - s.z0, s.area, axial_modulus(s.material, "short"), s.material.density) for s in slices]
    fine = mode_shape(props, mode.frequency, slices[0].z0, max(8, n_grid // len(props)))
    z, u = fine.z, fine.displacement
    du = np.gradient(u, z)
    w = np.gradient(z)                       # trapezoid-like weights
    U = T = dT = 0.0
    dU: dict[str, float] = {}
    for s in slices:
        sel = (z >= s.z0) & (z <= s.z1)
        if not sel.any():
            continue
        m = s.material
        E = axial_modulus(m, "short")
        if m.is_piezo:
            sE, _d, _eT = strain_charge(*m.voigt_matrices())
            nu = -sE[0, 2] / sE[2, 2]
        else:
            nu = m.poisson_ratio
        U += E * s.area * float(np.sum(w[sel] * du[sel] ** 2))
        T += m.density * s.area * float(np.sum(w[sel] * u[sel] ** 2))
        dT += m.density * nu ** 2 * s.area * s.gyration2 * float(np.sum(w[sel] * du[sel] ** 2))
        if s.layer is not None:
            key = s.layer
            dc = axial_modulus(m, "open") - E
            strain = du[sel] if key.startswith("floating:") else du[sel] - np.average(du[sel], weights=w[sel])
            dU[key] = dU.get(key, 0.0) + dc * s.area * float(np.sum(w[sel] * strain ** 2))
    rl = -0.5 * dT / T if T > 0 else 0.0
    el = 0.5 * sum(dU.values()) / U if U > 0 else 0.0
    reasons = list(reasons)
    if abs(rl) > TOLERANCE:
        reasons.append(f"lateral inertia: the Rayleigh-Love estimate is {100 * rl:+.1f} % (the parts are not "
                       f"slender for this mode)")
    if el > TOLERANCE:
        worst = max(dU, key=dU.get).removeprefix("floating:")
        reasons.append(f"electrode stiffening: the ceramic {worst} is not field free (estimate {100 * el:+.1f} %: "
                       "electrodes too far apart for the wavelength, or none)")
    caveats = []
    if design.kind == "rpud" and design.coupler.n_slots:
        caveats.append("the coupler's slots enter as areas only: their 3-D compliance lowers the real frequency")
    return OneDimCheck(rl, el, tuple(reasons), tuple(caveats))
