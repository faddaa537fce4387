"""The shared interface of design kinds (:class:`DesignBase`): dotted paths, TOML, volumes and
masses, axial extents, the exact axial morph, and the design's own material library; and the
constants the kinds share (poling keywords, smallest wall).

Each kind is a module of its own: :mod:`geometry.design_rpud` (the RPUD composition),
:mod:`geometry.design_stack` (generic coaxial stack), :mod:`geometry.design_cad` (a STEP file and
a rule table); :mod:`geometry.design` loads any of them from TOML.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from rpud_common import ParameterError, atomic_write_text, dump_toml, to_mapping
from .design_materials import own_records, resolve_uses
from .dotted import child_named, radial_signature, replace_path
from .materials import Material, builtin_library

__all__ = ["DesignBase", "POLING_VECTORS", "MIN_WALL", "annulus"]

POLING_VECTORS: dict[str, tuple[float, float, float] | None] = {
    "none": None,
    "+z": (0.0, 0.0, 1.0), "-z": (0.0, 0.0, -1.0),
    "+x": (1.0, 0.0, 0.0), "-x": (-1.0, 0.0, 0.0),
    "+y": (0.0, 1.0, 0.0), "-y": (0.0, -1.0, 0.0),
}
"""Poling keywords of a piezoceramic piece and their unit vectors."""

MIN_WALL = 0.5e-3
"""Smallest metal wall (m) left by a bore, a slot or a tooth gap: below it Gmsh needs sliver elements."""


def annulus(d_out: float, d_in: float) -> float:
    """Area (m^2) of an annulus of outer and inner diameter ``d_out``, ``d_in`` (m)."""
    return math.pi / 4.0 * (d_out ** 2 - d_in ** 2)


class DesignBase:
    """Shared behaviour of design kinds: dotted paths, TOML, volumes, extents, morphing."""

    kind: str

    # ------------------------------------------------------------------ dotted paths
    def get(self, path: str) -> Any:
        """Value at a dotted path, e.g. ``"horn.length"`` or ``"segments.rod.length"`` (m)."""
        obj: Any = self
        for key in path.split("."):
            obj = child_named(obj, key, path)
        return obj

    def replace(self, changes: Mapping[str, Any] | None = None, **kw: Any):
        """A new, validated design with the values at the given dotted paths replaced.

        Parameters
        ----------
        changes : mapping of str to value
            ``{"horn.length": 0.062, "coupler.slot_angle_deg": 0.0}``.
        """
        changes = dict(changes or {}, **kw)
        new = self
        for path, value in changes.items():
            new = replace_path(new, path.split("."), value, path)
        return new

    def tunable_lengths(self) -> tuple[str, ...]:
        """Dotted paths of the axial lengths (m) that :meth:`morph_points` maps exactly."""
        raise NotImplementedError

    default_tuned: ClassVar[tuple[str, ...]] = ()
    """Lengths tuned by resonance matching unless the user names others."""

    def length_part(self, path: str) -> str:
        """The part a tunable length belongs to (resonance matching tunes a front and a back
        part): the head of its dotted path (``"horn.length"`` -> ``"horn"``)."""
        return path.split(".")[0]

    # ------------------------------------------------------------------ TOML
    def to_mapping(self) -> dict:
        """Plain dict (TOML/JSON friendly); ``kind`` first; the own material records (if any)
        last, as a ``materials`` table in the layout of ``materials.toml``."""
        data = to_mapping(self)
        data.pop("materials", None)            # the records in their file layout, below
        if self.materials:
            data["materials"] = {n: m.to_record() for n, m in self.materials.items()}
        return {"kind": data.pop("kind"), **data}

    # ------------------------------------------------------------------ materials
    @property
    def library(self) -> dict[str, Material]:
        """Where the design's material names resolve: built-in records overlaid with its own."""
        return {**builtin_library(), **self.materials}

    def material_uses(self) -> list[tuple[str, str, Any]]:
        """``(dotted path, material name, role)`` of every material the design names (see
        :func:`geometry.design_materials.resolve_uses`)."""
        raise NotImplementedError

    def used_materials(self) -> dict[str, Material]:
        """The records of every material the design uses, by name."""
        lib = self.library
        return {name: lib[name] for _p, name, _r in self.material_uses()}

    def _check_materials(self) -> None:
        object.__setattr__(self, "materials", own_records(self.materials))
        resolve_uses(self.material_uses(), self.library)

    def to_toml(self) -> str:
        return dump_toml(self.to_mapping())

    def save(self, path: str | os.PathLike) -> None:
        """Write the design as TOML, atomically."""
        atomic_write_text(path, self.to_toml())

    # ------------------------------------------------------------------ geometry summaries
    def part_volumes(self) -> dict[str, float]:
        """Closed-form volume of every part in m^3 (slots and notches subtracted)."""
        out: dict[str, float] = {}
        for region, part, _mat, vol in self.region_table():
            out[part] = out.get(part, 0.0) + vol
        return out

    def part_masses(self) -> dict[str, float]:
        """Closed-form mass of every part in kg."""
        out: dict[str, float] = {}
        lib = self.library
        for region, part, mat, vol in self.region_table():
            out[part] = out.get(part, 0.0) + vol * lib[mat].density
        return out

    def region_table(self) -> list[tuple[str, str, str, float]]:
        """``(region, part, material, closed-form volume m^3)`` for every region."""
        raise NotImplementedError

    def part_material(self, part: str) -> str:
        """Material name of a part (of its first region)."""
        for _region, p, material, _vol in self.region_table():
            if p == part:
                return material
        raise ParameterError("part", part, "unknown; known: " + ", ".join(sorted(self.part_volumes())))

    def total_mass(self) -> float:
        """Closed-form mass of the whole design in kg."""
        return float(sum(self.part_masses().values()))

    def part_extents(self) -> dict[str, tuple[float, float]]:
        """Axial extent ``(z0, z1)`` in m of every part."""
        out: dict[str, tuple[float, float]] = {}
        for label, part, z0, z1 in self._zones():
            if part in out:
                out[part] = (min(out[part][0], z0), max(out[part][1], z1))
            else:
                out[part] = (z0, z1)
        return out

    def axial_breakpoints(self) -> list[tuple[str, float]]:
        """Ordered ``(label, z)`` boundaries of the axial zones (m).

        Inside each zone the geometry is an affine function of z, so a piecewise-linear map
        of z between the breakpoints of two designs of the same structure maps one mesh onto
        the other exactly (see :meth:`morph_points`).
        """
        zones = self._zones()
        pts = [(f"{zones[0][0]}:start", zones[0][2])]
        pts += [(f"{label}:end", z1) for label, _p, _z0, z1 in zones]
        return pts

    def _zones(self) -> list[tuple[str, str, float, float]]:
        """``(label, part, z0, z1)`` of the axial zones, ordered along z."""
        raise NotImplementedError

    def morph_points(self, points: np.ndarray, new: "DesignBase") -> np.ndarray:
        """Move mesh points of this design onto the geometry of ``new`` by an axial map.

        Exact when ``new`` differs from this design only in lengths listed by
        :meth:`tunable_lengths` (radial data, angles and counts unchanged): z is mapped
        piecewise linearly between :meth:`axial_breakpoints`; x and y are kept.

        Parameters
        ----------
        points : (n, 3) array, m
        new : design of the same kind and structure

        Returns
        -------
        (n, 3) array, m
        """
        if type(new) is not type(self):
            raise ParameterError("design", type(new).__name__, f"must be a {type(self).__name__} to morph")
        old_bp, new_bp = self.axial_breakpoints(), new.axial_breakpoints()
        if [b[0] for b in old_bp] != [b[0] for b in new_bp]:
            raise ParameterError("design", new.name, "has a different zone structure; re-mesh instead of morphing")
        changed = radial_signature(self) != radial_signature(new)
        if changed:
            raise ParameterError("design", new.name, "differs in more than axial lengths; re-mesh instead of morphing")
        zo = np.array([b[1] for b in old_bp])
        zn = np.array([b[1] for b in new_bp])
        out = np.array(points, dtype=float, copy=True)
        z = out[:, 2]
        # extrapolate linearly beyond the ends (points sit exactly on them up to round-off)
        znew = np.interp(z, zo, zn)
        below, above = z < zo[0], z > zo[-1]
        znew[below] = zn[0] + (z[below] - zo[0])
        znew[above] = zn[-1] + (z[above] - zo[-1])
        out[:, 2] = znew
        return out

    def electrode_planes(self) -> dict[str, list[tuple[str, float]]]:
        """Electrode name -> the planes ``(axis "x"/"y"/"z", coordinate m)`` of its ceramic faces."""
        raise NotImplementedError


