"""The generic stack design kind (``kind = "stack"``): coaxial segments along z.

:class:`StackDesign` is any list of coaxial :class:`Segment` (cylinder, annulus, cone,
rectangular box) placed along z, each with a material and, for piezoceramics, a poling
direction; electrodes are named faces of segments (:class:`ElectrodeSpec`). Textbook cases (k33
rod, k31 bar, Langevin sandwich, slender rod, bonded sandwich) are built with
:mod:`geometry.examples`. The shared interface is :class:`geometry.design_base.DesignBase`.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

from rpud_common import ParameterError, check_choice, check_range
from .design_base import MIN_WALL, POLING_VECTORS, DesignBase, annulus
from .design_materials import check_material_name
from .materials import Material
from .validate import (MIN_LAYER, check_bore, check_count, check_frequency, check_length, check_name,
                       finite_or_none)

__all__ = ["Segment", "ElectrodeSpec", "StackDesign"]

log = logging.getLogger(__name__)

_MIN_WALL = MIN_WALL
_annulus = annulus
_material = check_material_name




@dataclass(frozen=True)
class Segment:
    """One coaxial piece of a :class:`StackDesign`, from ``start`` to ``start + length`` on z.

    Attributes
    ----------
    name : str
        Unique name; also the mesh region name.
    length : float
        Axial length, m (down to MIN_LAYER = 10 um: thin layers, see geometry.layers).
    kind : {"cylinder", "cone", "box"}
        Cylinder (or annulus with ``inner_diameter`` > 0); cone (truncated, from
        ``outer_diameter`` at the -z end to ``end_diameter`` at the +z end); box (rectangular
        bar: ``thickness`` along x, ``width`` along y, centred on the axis).
    material : str
        Material name (built-in library or the design's ``[materials]`` table).
    outer_diameter, end_diameter, inner_diameter : float
        m; ``end_diameter`` only for cones; ``inner_diameter`` a central bore (0 = solid).
    thickness, width : float
        Box cross-section, m.
    poling : {"none", "+z", "-z", "+x", "-x", "+y", "-y"}
        Poling of a piezoceramic segment (required for piezo materials, forbidden otherwise).
    part : str
        Part name (defaults to the segment name); several segments may form one part.
    start : float or None
        z of the -z face, m; ``None`` continues from the previous segment (the first starts
        at 0). A start before the previous segment's end is an overlap error.
    """

    name: str
    length: float
    kind: Literal["cylinder", "cone", "box"] = "cylinder"
    material: str = "steel_45"
    outer_diameter: float = 0.0
    end_diameter: float = 0.0
    inner_diameter: float = 0.0
    thickness: float = 0.0
    width: float = 0.0
    poling: Literal["none", "+z", "-z", "+x", "-x", "+y", "-y"] = "none"
    part: str = ""
    start: float | None = None

    def __post_init__(self):
        check_name("segments.name", self.name, dots=False)
        p = f"segments.{self.name}"
        check_length(f"{p}.length", self.length, MIN_LAYER)  # thin layers: geometry.layers
        check_choice(f"{p}.kind", self.kind, ("cylinder", "cone", "box"))
        _material(f"{p}.material", self.material)
        check_choice(f"{p}.poling", self.poling, tuple(POLING_VECTORS))
        if self.kind == "box":
            check_length(f"{p}.thickness", self.thickness)
            check_length(f"{p}.width", self.width)
        else:
            check_length(f"{p}.outer_diameter", self.outer_diameter)
            check_bore(f"{p}.inner_diameter", self.inner_diameter)
            smallest = self.outer_diameter
            if self.kind == "cone":
                check_length(f"{p}.end_diameter", self.end_diameter)
                smallest = min(smallest, self.end_diameter)
            if self.inner_diameter > 0 and self.inner_diameter >= smallest - 2 * _MIN_WALL:
                raise ParameterError(f"{p}.inner_diameter", self.inner_diameter,
                                     f"bore larger than the segment: must be < {smallest - 2 * _MIN_WALL:g} m")
        if self.part != "":
            check_name(f"{p}.part", self.part, dots=False)
        else:
            object.__setattr__(self, "part", self.name)
        finite_or_none(f"{p}.start", self.start)

    @property
    def poling_vector(self) -> tuple[float, float, float] | None:
        return POLING_VECTORS[self.poling]

    def area_at(self, s: float) -> float:
        """Cross-section area (m^2) at distance ``s`` (m) from the -z face."""
        if self.kind == "box":
            return self.thickness * self.width
        d = self.outer_diameter
        if self.kind == "cone":
            d = self.outer_diameter + (self.end_diameter - self.outer_diameter) * s / self.length
        return _annulus(d, self.inner_diameter)

    def volume(self) -> float:
        """Closed-form volume, m^3."""
        if self.kind == "box":
            return self.thickness * self.width * self.length
        if self.kind == "cone":
            D0, D1 = self.outer_diameter, self.end_diameter
            return math.pi * self.length / 12 * (D0 ** 2 + D0 * D1 + D1 ** 2) - _annulus(self.inner_diameter, 0) * self.length
        return _annulus(self.outer_diameter, self.inner_diameter) * self.length

    def max_radius(self) -> float:
        if self.kind == "box":
            return 0.5 * math.hypot(self.thickness, self.width)
        return 0.5 * max(self.outer_diameter, self.end_diameter if self.kind == "cone" else 0.0)


@dataclass(frozen=True)
class ElectrodeSpec:
    """An electrode: face ``face`` of segment ``segment``, wired as ``role``.

    Attributes
    ----------
    name : str
        Facet-set name (e.g. ``"electrode_0"``).
    segment : str
        Name of the (piezoceramic) segment whose face it is.
    face : {"bottom", "top", "+x", "-x", "+y", "-y"}
        "bottom"/"top" are the -z/+z end faces; "+x" etc. the flat sides of a box.
    role : {"hot", "ground"}
        Wiring: ``hot`` electrodes carry the drive voltage, ``ground`` ones 0 V.
    """

    name: str
    segment: str
    face: Literal["bottom", "top", "+x", "-x", "+y", "-y"] = "top"
    role: Literal["hot", "ground"] = "hot"

    def __post_init__(self):
        p = f"electrodes.{self.name}"
        check_name("electrodes.name", self.name, dots=False)
        if not isinstance(self.segment, str):
            raise ParameterError(f"{p}.segment", self.segment, "must be a segment name")
        check_choice(f"{p}.face", self.face, ("bottom", "top", "+x", "-x", "+y", "-y"))
        check_choice(f"{p}.role", self.role, ("hot", "ground"))


@dataclass(frozen=True)
class StackDesign(DesignBase):
    """A generic coaxial stack of segments along z (Langevin transducers, test rods and bars).

    Attributes
    ----------
    kind : "stack"
        The design kind.
    name : str
        Design name; it names the results folder and the tuned design file.
    segments : tuple of Segment
        From -z to +z (``[[segments]]`` tables).
    electrodes : tuple of ElectrodeSpec
        The electrodes (``[[electrodes]]`` tables).
    target_frequency : float
        Hz, for the elements-per-wavelength mesh size.
    elements_per_wavelength : float
        Elements per shear wavelength of each material at ``target_frequency``, dimensionless.
    materials : mapping of str to Material
        The design's own material records (table ``[materials]``, layout of ``materials.toml``),
        over the built-in library.
    """

    kind: Literal["stack"] = "stack"
    name: str = "stack"
    segments: tuple[Segment, ...] = ()
    electrodes: tuple[ElectrodeSpec, ...] = ()
    target_frequency: float = 20000.0
    elements_per_wavelength: float = 14.0
    materials: Mapping[str, Material] = field(default_factory=dict, hash=False)

    def __post_init__(self):
        check_choice("kind", self.kind, ("stack",))
        check_name("name", self.name)
        check_frequency("target_frequency", self.target_frequency)
        check_range("elements_per_wavelength", self.elements_per_wavelength, 1.0, 200.0)
        object.__setattr__(self, "segments", tuple(self.segments))
        object.__setattr__(self, "electrodes", tuple(self.electrodes))
        if not self.segments:
            raise ParameterError("segments", [], "need at least one segment")
        check_count("segments", len(self.segments), 1)
        check_count("electrodes", len(self.electrodes), 0, 2 * 64)
        names = [s.name for s in self.segments]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ParameterError(f"segments.{dup[0]}.name", dup[0], "segment names must be unique")
        self._check_materials()
        end = None
        for seg, (z0, z1) in zip(self.segments, self.segment_extents().values()):
            if end is not None and z0 < end[1] - 1e-12:
                raise ParameterError(f"segments.{seg.name}.start", z0,
                                     f"overlapping parts: starts before segment '{end[0]}' ends at {end[1]:g} m")
            if end is not None and z0 > end[1] + 1e-12:
                log.warning("segment %s starts %.3g m after %s: the mesh will have separate bodies",
                            seg.name, z0 - end[1], end[0])
            end = (seg.name, z1)
        parts = {}
        for seg in self.segments:
            parts.setdefault(seg.part, []).append(seg.name)
        enames = [e.name for e in self.electrodes]
        dup = sorted({n for n in enames if enames.count(n) > 1})
        if dup:
            raise ParameterError(f"electrodes.{dup[0]}.name", dup[0], "electrode names must be unique")
        bynames = {s.name: s for s in self.segments}
        for e in self.electrodes:
            p = f"electrodes.{e.name}"
            if e.segment not in bynames:
                raise ParameterError(f"{p}.segment", e.segment, "unknown segment; known: " + ", ".join(names))
            seg = bynames[e.segment]
            if seg.poling == "none":
                raise ParameterError(f"{p}.segment", e.segment, "must be a piezoceramic segment")
            if e.face in ("+x", "-x", "+y", "-y") and seg.kind != "box":
                raise ParameterError(f"{p}.face", e.face, "side faces exist on box segments only; use 'bottom' or 'top'")
            if e.name in names:
                raise ParameterError(f"{p}.name", e.name, "must differ from every segment name")
        for seg in self.segments:
            if seg.poling != "none" and not any(e.segment == seg.name for e in self.electrodes):
                log.info("piezo segment %s has no electrode (its potential floats)", seg.name)

    def material_uses(self) -> list[tuple[str, str, Any]]:
        return [(f"segments.{s.name}.material", s.material, ("poling", f"segments.{s.name}.poling", s.poling))
                for s in self.segments]

    # ------------------------------------------------------------------ layout
    def segment_extents(self) -> dict[str, tuple[float, float]]:
        """Segment name -> (z0, z1), m."""
        out = {}
        z = 0.0
        for seg in self.segments:
            z0 = z if seg.start is None else float(seg.start)
            out[seg.name] = (z0, z0 + seg.length)
            z = z0 + seg.length
        return out

    def tunable_lengths(self) -> tuple[str, ...]:
        return tuple(f"segments.{s.name}.length" for s in self.segments)

    @property
    def default_tuned(self) -> tuple[str, ...]:  # type: ignore[override]
        return tuple(f"segments.{s.name}.length" for s in self.segments if s.poling == "none")[:2]

    def _zones(self) -> list[tuple[str, str, float, float]]:
        ext = self.segment_extents()
        return [(s.name, s.part, *ext[s.name]) for s in self.segments]

    def axial_breakpoints(self) -> list[tuple[str, float]]:
        # with explicit starts, gaps are zones too (the map stays piecewise linear)
        pts = []
        for label, _part, z0, z1 in self._zones():
            pts.append((f"{label}:start", z0))
            pts.append((f"{label}:end", z1))
        return pts

    def region_table(self) -> list[tuple[str, str, str, float]]:
        return [(s.name, s.part, s.material, s.volume()) for s in self.segments]

    def electrode_planes(self) -> dict[str, list[tuple[str, float]]]:
        """Electrode name -> ``[(axis "x"/"y"/"z", coordinate m)]`` of its plane."""
        ext = self.segment_extents()
        bynames = {s.name: s for s in self.segments}
        out = {}
        for e in self.electrodes:
            seg = bynames[e.segment]
            z0, z1 = ext[seg.name]
            if e.face == "bottom":
                out[e.name] = [("z", z0)]
            elif e.face == "top":
                out[e.name] = [("z", z1)]
            else:
                half = seg.thickness / 2 if e.face[1] == "x" else seg.width / 2
                out[e.name] = [(e.face[1], half if e.face[0] == "+" else -half)]
        return out

    def sections_1d(self, n_taper: int = 200) -> list[tuple[float, float, str]]:
        """Uniform 1-D slices ``(length m, area m^2, material)`` from -z to +z (gaps skipped)."""
        out = []
        for s in self.segments:
            if s.kind == "cone":
                ds = s.length / n_taper
                out += [(ds, s.area_at((i + 0.5) * ds), s.material) for i in range(n_taper)]
            else:
                out.append((s.length, s.area_at(0.0), s.material))
        return out
