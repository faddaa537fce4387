"""The CAD design kind (``kind = "cad"``): a STEP file and a rule table that names its pieces.

A :class:`CadDesign` takes its geometry from a STEP file (``step``, relative to the design's
TOML file) and says what every piece is with small rules:

- ``[[volumes]]`` (:class:`VolumeRule`): each rule selects **exactly one** solid of the file and
  gives it a region name, a part, a material and, for piezoceramics, a poling (``"+z"``,
  ``"-z"``, ...). Several rules may share a region (a region of several solids); every solid
  must be claimed by one rule.
- ``[[surfaces]]`` (:class:`SurfaceRule`): each rule selects one or more faces for a named
  facet set (``horn_tip``, ``teeth_tops``, ``flange``, ``electrode_0``...); ``role = "hot"`` or
  ``"ground"`` makes it an electrode. Rules with the same name add up.
- ``[[sizes]]`` (:class:`SizeRule`, optional): element-size caps (m, before ``refine``) for a
  region or inside a box, on top of the elements-per-wavelength rule of every region.
- ``[[lengths]]`` (:class:`LengthRule`, optional): named axial lengths, each a z band of the
  drawing whose nodes are stretched linearly to ``value`` (nodes above move with it), so that
  resonance matching can tune them (``lengths.<name>.value``) without a new drawing.

Selectors (:class:`Selector`, ``select = {...}``): ``name`` (the solid's label in the STEP
file: the whole label or its last ``/`` component), ``point`` (a point inside the solid, or on
the face), ``box`` (``[xmin, ymin, zmin, xmax, ymax, zmax]``: the solid's or face's bounding box
lies inside), ``plane`` (faces only: planar faces in the plane ``normal . x = offset``) and
``regions`` (faces only: faces bounding one of these regions). All given criteria must hold.
A rule that matches nothing, or a volume rule matching two solids, is a
:class:`~rpud_common.ParameterError` naming the rule.

All coordinates are SI (m) in the frame of the STEP file after conversion to metres (OCC reads
the file's declared unit). The resolution of the rules against the file needs Gmsh and lives in
:mod:`geometry.cad`; it is cached per file and rule table.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from rpud_common import ParameterError, check_choice, check_range
from .cad import resolve as _resolve
from .cad import zone_table
from .design_base import POLING_VECTORS, DesignBase
from .design_materials import check_material_name
from .materials import Material
from .validate import check_count, check_frequency, check_length, check_name

__all__ = ["Plane", "Selector", "VolumeRule", "SurfaceRule", "SizeRule", "LengthRule", "CadDesign", "step_path"]

_COORD = 10.0
"""Largest |coordinate| of a selector, m."""


def _check_coords(name: str, value, n: int) -> tuple[float, ...]:
    if value is None:
        return value
    if len(value) != n:
        raise ParameterError(name, list(value), f"must be a list of {n} numbers (m)")
    for v in value:
        check_range(name, v, -_COORD, _COORD, "m")
    return tuple(float(v) for v in value)


def _check_step_text(value) -> None:
    """A STEP path as text: a non-empty string without NUL or control characters (a NUL ends a
    path for the operating system, and no user means a tab or newline in a file name)."""
    if not isinstance(value, str) or not value:
        raise ParameterError("step", value, "must name a STEP file (.step or .stp)")
    if any(not ch.isprintable() for ch in value):
        raise ParameterError("step", value, "must not contain NUL or control characters")


def step_path(value: Any, base_dir: str | os.PathLike | None = None) -> Any:
    """The ``step`` entry of a design file as a path: ``~`` and ``~user`` expanded, a relative
    path taken from ``base_dir`` (the TOML file's folder). Anything but a usable string is a
    :class:`ParameterError` naming ``step``; a value that is no string is returned as is for the
    design's own check to name it."""
    if not isinstance(value, str):
        return value
    _check_step_text(value)
    try:
        step = Path(value).expanduser()
    except (RuntimeError, KeyError):     # ~user of an unknown user, or no home folder at all
        raise ParameterError("step", value, "names the home folder of an unknown user: give the path "
                             "without ~ or relative to the design file") from None
    if step.is_absolute() or base_dir is None:
        return str(step)
    try:
        return str((Path(base_dir) / step).resolve())
    except (OSError, RuntimeError) as exc:  # a loop of symbolic links
        raise ParameterError("step", value, f"cannot be resolved ({exc})") from None


@dataclass(frozen=True)
class Plane:
    """The plane ``normal . x = offset`` (normal: any non-zero vector, normalised here; m).

    Attributes
    ----------
    normal : tuple of 3 float
        Normal vector, any length but not zero, dimensionless (normalised on construction).
    offset : float
        Signed distance of the plane from the origin along the unit normal, m.
    """

    normal: tuple[float, float, float]
    offset: float

    def __post_init__(self):
        n = np.asarray(_check_coords("select.plane.normal", self.normal, 3))
        norm = float(np.linalg.norm(n))
        if norm < 1e-9:
            raise ParameterError("select.plane.normal", list(self.normal), "must be a non-zero vector")
        object.__setattr__(self, "normal", tuple(float(x) for x in n / norm))
        check_range("select.plane.offset", self.offset, -_COORD, _COORD, "m")

    @property
    def axis(self) -> str | None:
        """``"x"``, ``"y"`` or ``"z"`` when the normal lies along an axis (either sign)."""
        n = np.abs(self.normal)
        i = int(np.argmax(n))
        return "xyz"[i] if n[i] > 1 - 1e-9 else None

    @property
    def coordinate(self) -> float:
        """The plane's coordinate along its axis (valid when :attr:`axis` is not None), m."""
        return float(self.offset * np.sign(self.normal["xyz".index(self.axis)]))


@dataclass(frozen=True)
class Selector:
    """Which solids or faces of the STEP file a rule takes; every given criterion must hold.

    Attributes
    ----------
    name : str or None
        Label of a solid in the STEP file (solids only).
    point : tuple of 3 float or None
        A point inside the solid or on the face, m.
    box : tuple of 6 float or None
        ``[xmin, ymin, zmin, xmax, ymax, zmax]``, m: the solid or face lies inside it.
    plane : Plane or None
        Faces lying in this plane (faces only).
    regions : tuple of str
        Faces bounding these regions (faces only).
    """

    name: str | None = None
    point: tuple[float, float, float] | None = None
    box: tuple[float, float, float, float, float, float] | None = None
    plane: Plane | None = None
    regions: tuple[str, ...] = ()

    def __post_init__(self):
        if self.name is not None and (not isinstance(self.name, str) or not self.name):
            raise ParameterError("select.name", self.name, "must be a non-empty label")
        object.__setattr__(self, "point", _check_coords("select.point", self.point, 3))
        box = _check_coords("select.box", self.box, 6)
        if box is not None and any(box[i] > box[i + 3] for i in range(3)):
            raise ParameterError("select.box", list(box), "must be [xmin, ymin, zmin, xmax, ymax, zmax] with min <= max")
        object.__setattr__(self, "box", box)
        object.__setattr__(self, "regions", tuple(self.regions))
        if self.is_empty():
            raise ParameterError("select", {}, "give at least one of name, point, box, plane, regions")

    def is_empty(self) -> bool:
        return self.name is None and self.point is None and self.box is None and self.plane is None \
            and not self.regions

    def describe(self) -> str:
        """The criteria as they would read in TOML (for messages)."""
        parts = []
        if self.name is not None:
            parts.append(f"name = {self.name!r}")
        if self.point is not None:
            parts.append(f"point = {list(self.point)}")
        if self.box is not None:
            parts.append(f"box = {list(self.box)}")
        if self.plane is not None:
            parts.append(f"plane = {{normal = {[round(x, 6) for x in self.plane.normal]}, offset = {self.plane.offset:g}}}")
        if self.regions:
            parts.append(f"regions = {list(self.regions)}")
        return "{" + ", ".join(parts) + "}"


@dataclass(frozen=True)
class VolumeRule:
    """One solid of the STEP file: its region, part, material and poling.

    Attributes
    ----------
    region : str
        Mesh region name (several rules may share one: a region of several solids).
    material : str
        Material name (built-in library or the design's ``[materials]`` table).
    select : Selector
        ``name``, ``point`` and/or ``box``; must match exactly one solid.
    part : str
        Part name (defaults to the region name; e.g. ``"horn"``, ``"stack"``, ``"coupler"``).
    poling : {"none", "+z", "-z", "+x", "-x", "+y", "-y"}
        Poling of a piezoceramic (required for piezo materials, forbidden otherwise).
    """

    region: str
    material: str
    select: Selector
    part: str = ""
    poling: Literal["none", "+z", "-z", "+x", "-x", "+y", "-y"] = "none"

    def __post_init__(self):
        check_name("volumes.region", self.region, dots=False)
        p = f"volumes.{self.region}"
        check_material_name(f"{p}.material", self.material)
        check_choice(f"{p}.poling", self.poling, tuple(POLING_VECTORS))
        if self.part != "":
            check_name(f"{p}.part", self.part, dots=False)
        else:
            object.__setattr__(self, "part", self.region)
        if not isinstance(self.select, Selector):
            raise ParameterError(f"{p}.select", self.select, "must be a selector table")
        if self.select.plane is not None or self.select.regions:
            raise ParameterError(f"{p}.select", self.select.describe(), "a volume is selected by name, point or box")

    @property
    def poling_vector(self) -> tuple[float, float, float] | None:
        return POLING_VECTORS[self.poling]


@dataclass(frozen=True)
class SurfaceRule:
    """Faces of the STEP file that form (part of) the facet set ``name``.

    Attributes
    ----------
    name : str
        Facet-set name (``horn_tip``, ``teeth_tops``, ``flange``, ``electrode_1``...); rules with
        the same name add up.
    select : Selector
        ``plane``, ``point``, ``box`` and/or ``regions``; must match at least one face.
    role : {"none", "hot", "ground"}
        ``hot``/``ground`` make the facet set an electrode (one role per name).
    """

    name: str
    select: Selector
    role: Literal["none", "hot", "ground"] = "none"

    def __post_init__(self):
        check_name("surfaces.name", self.name, dots=False)
        p = f"surfaces.{self.name}"
        check_choice(f"{p}.role", self.role, ("none", "hot", "ground"))
        if not isinstance(self.select, Selector):
            raise ParameterError(f"{p}.select", self.select, "must be a selector table")
        if self.select.name is not None:
            raise ParameterError(f"{p}.select.name", self.select.name, "faces are selected by plane, point, box "
                                 "or regions (names label solids)")


@dataclass(frozen=True)
class SizeRule:
    """An element-size cap (m, at ``refine`` 1): over a region, or inside a box (6 numbers).

    Attributes
    ----------
    size : float
        Largest element edge, m (at ``refine`` 1).
    region : str
        Region the cap applies to (give this or ``box``).
    box : tuple of 6 float or None
        ``[xmin, ymin, zmin, xmax, ymax, zmax]``, m: the cap applies inside it (give this or
        ``region``).
    """

    size: float
    region: str = ""
    box: tuple[float, float, float, float, float, float] | None = None

    def __post_init__(self):
        check_length("sizes.size", self.size, 1e-5)
        object.__setattr__(self, "box", _check_coords("sizes.box", self.box, 6))
        if (self.region == "") == (self.box is None):
            raise ParameterError("sizes", {"region": self.region, "box": self.box}, "give exactly one of region, box")


@dataclass(frozen=True)
class LengthRule:
    """A named axial length: the band ``z0..z1`` (m) of the drawing, stretched to ``value``.

    Nodes inside the band are stretched linearly, nodes above it shift with its end, so the
    geometry is exact where it is a function of z alone inside the band (prismatic or conical
    sections). ``part`` says which part it belongs to (resonance matching tunes a front part,
    ``horn``/``flange``, and a back part, ``coupler``/``stack``). ``value`` defaults to the
    drawn length ``z1 - z0``.

    Attributes
    ----------
    name : str
        Length name; resonance matching and studies address it as ``lengths.<name>.value``.
    z0, z1 : float
        Ends of the band in the drawing, m.
    part : str
        Part the length belongs to (``horn``, ``flange``: front; ``coupler``, ``stack``: back).
    value : float or None
        The length to stretch the band to, m (default: the drawn ``z1 - z0``).
    """

    name: str
    z0: float
    z1: float
    part: str
    value: float | None = None

    def __post_init__(self):
        check_name("lengths.name", self.name, dots=False)
        p = f"lengths.{self.name}"
        check_range(f"{p}.z0", self.z0, -_COORD, _COORD, "m")
        check_range(f"{p}.z1", self.z1, -_COORD, _COORD, "m")
        if self.z1 - self.z0 < 1e-5:
            raise ParameterError(f"{p}.z1", self.z1, f"must exceed z0 = {self.z0:g} m by >= 1e-05 m")
        check_name(f"{p}.part", self.part, dots=False)
        if self.value is None:
            object.__setattr__(self, "value", float(self.z1 - self.z0))
        check_length(f"{p}.value", self.value, 1e-5)

    @property
    def drawn(self) -> float:
        """The band's length in the drawing, m."""
        return float(self.z1 - self.z0)


@dataclass(frozen=True)
class CadDesign(DesignBase):
    """A design drawn in CAD: a STEP file and the rules that name its pieces (see the module).

    Attributes
    ----------
    kind : "cad"
        The design kind.
    name : str
        Design name; it names the results folder and the tuned design file.
    step : str
        Path of the STEP file (``.step``/``.stp``); relative paths are taken from the TOML
        file's folder when loaded from a file.
    volumes, surfaces, sizes, lengths : tuples of rules
        The rule tables ``[[volumes]]``, ``[[surfaces]]``, ``[[sizes]]``, ``[[lengths]]``
        (:class:`VolumeRule`, :class:`SurfaceRule`, :class:`SizeRule`, :class:`LengthRule`).
    target_frequency : float
        Hz (elements-per-wavelength mesh size; default of the modal and matching target).
    elements_per_wavelength : float
        Elements per shear wavelength of each material at ``target_frequency``, dimensionless.
    default_tuned : tuple of str
        Lengths tuned by resonance matching unless the user names others
        (``lengths.<name>.value``; default: the first front and first back length declared).
    materials : mapping of str to Material
        The design's own material records (table ``[materials]``, layout of ``materials.toml``),
        over the built-in library.
    """

    kind: Literal["cad"] = "cad"
    name: str = "cad"
    step: str = ""
    target_frequency: float = 20000.0
    elements_per_wavelength: float = 14.0
    volumes: tuple[VolumeRule, ...] = ()
    surfaces: tuple[SurfaceRule, ...] = ()
    sizes: tuple[SizeRule, ...] = ()
    lengths: tuple[LengthRule, ...] = ()
    default_tuned: tuple[str, ...] = ()
    materials: Mapping[str, Material] = field(default_factory=dict, hash=False)

    def __post_init__(self):
        check_choice("kind", self.kind, ("cad",))
        check_name("name", self.name)
        check_frequency("target_frequency", self.target_frequency)
        check_range("elements_per_wavelength", self.elements_per_wavelength, 1.0, 200.0)
        for key in ("volumes", "surfaces", "sizes", "lengths", "default_tuned"):
            object.__setattr__(self, key, tuple(getattr(self, key)))
        self._check_step()
        if not self.volumes:
            raise ParameterError("volumes", [], "need at least one [[volumes]] rule")
        check_count("volumes", len(self.volumes), 1, 4 * 64)
        check_count("surfaces", len(self.surfaces), 0, 4 * 64)
        regions: dict[str, VolumeRule] = {}
        for rule in self.volumes:
            first = regions.setdefault(rule.region, rule)
            if (first.part, first.material, first.poling) != (rule.part, rule.material, rule.poling):
                raise ParameterError(f"volumes.{rule.region}", rule.region, "rules of one region must agree on "
                                     "part, material and poling")
        roles: dict[str, str] = {}
        for s in self.surfaces:
            if s.name in regions:
                raise ParameterError(f"surfaces.{s.name}.name", s.name, "must differ from every region name")
            for r in s.select.regions:
                if r not in regions:
                    raise ParameterError(f"surfaces.{s.name}.select.regions", r,
                                         "unknown region; known: " + ", ".join(regions))
            if roles.setdefault(s.name, s.role) != s.role:
                raise ParameterError(f"surfaces.{s.name}.role", s.role, f"differs from the role {roles[s.name]!r} "
                                     "of another rule of that name")
        for s in self.sizes:
            if s.region and s.region not in regions:
                raise ParameterError("sizes.region", s.region, "unknown region; known: " + ", ".join(regions))
        names = [x.name for x in self.lengths]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ParameterError(f"lengths.{dup[0]}.name", dup[0], "length names must be unique")
        bands = sorted(self.lengths, key=lambda x: x.z0)
        for a, b in zip(bands, bands[1:]):
            if b.z0 < a.z1 - 1e-12:
                raise ParameterError(f"lengths.{b.name}.z0", b.z0, f"overlaps length {a.name!r} ({a.z0:g}..{a.z1:g} m)")
        for path in self.default_tuned:
            if path not in self.tunable_lengths():
                raise ParameterError("default_tuned", path, "unknown; tunable: " + (", ".join(self.tunable_lengths())
                                                                                      or "none (no [[lengths]])"))
        if not self.default_tuned and self.lengths:
            object.__setattr__(self, "default_tuned", self._pick_tuned())
        self._check_materials()

    def _check_step(self) -> None:
        _check_step_text(self.step)
        if Path(self.step).suffix.lower() not in (".step", ".stp"):
            raise ParameterError("step", self.step, "must end in .step or .stp")
        p = Path(self.step)
        try:
            if not p.is_file():
                raise ParameterError("step", self.step, "file does not exist" if not p.exists()
                                     else "is not a regular file")
            readable = os.access(p, os.R_OK)
        except OSError as exc:      # a name too long, a loop of links: the file system refuses the path
            raise ParameterError("step", self.step, f"cannot be read ({exc.strerror or exc})") from None
        if not readable:
            raise ParameterError("step", self.step, "cannot be read")

    def _pick_tuned(self) -> tuple[str, ...]:
        front = [x for x in self.lengths if x.part in ("horn", "flange")]
        back = [x for x in self.lengths if x.part in ("coupler", "stack", "electrodes")]
        if front and back:
            return (f"lengths.{front[0].name}.value", f"lengths.{back[0].name}.value")
        return (f"lengths.{self.lengths[0].name}.value",)

    def save(self, path: str | os.PathLike) -> None:
        """Write the design as TOML, atomically, its ``step`` path relative to the file's folder."""
        from rpud_common import atomic_write_text, dump_toml

        data = self.to_mapping()
        folder = Path(path).resolve().parent
        data["step"] = os.path.relpath(Path(self.step).resolve(), folder)
        atomic_write_text(path, dump_toml(data))

    # ------------------------------------------------------------------ the resolved drawing
    def resolve(self):
        """The rules applied to the STEP file (:class:`geometry.cad.Resolved`; needs Gmsh, cached).

        Raises :class:`ParameterError` on a rule that matches nothing, a volume rule matching
        several solids, a solid no rule claims, or a length band outside the drawing.
        """
        return _resolve(self)

    def drawn(self) -> "CadDesign":
        """This design with every length at its drawn value (the geometry of the STEP file)."""
        if all(x.value == x.drawn for x in self.lengths):
            return self
        return self.replace({f"lengths.{x.name}.value": x.drawn for x in self.lengths})

    def material_uses(self) -> list[tuple[str, str, Any]]:
        seen, out = set(), []
        for r in self.volumes:
            if r.region not in seen:
                seen.add(r.region)
                out.append((f"volumes.{r.region}.material", r.material, ("poling", f"volumes.{r.region}.poling",
                                                                        r.poling)))
        return out

    def region_rules(self) -> dict[str, VolumeRule]:
        """Region name -> its (first) rule, in rule order."""
        out: dict[str, VolumeRule] = {}
        for r in self.volumes:
            out.setdefault(r.region, r)
        return out

    @property
    def electrodes(self) -> tuple[Any, ...]:
        """``(name, role)`` records of the electrode facet sets (rules with a role), in rule order."""
        from .mesh import Electrode

        out: dict[str, str] = {}
        for s in self.surfaces:
            if s.role != "none":
                out.setdefault(s.name, s.role)
        return tuple(Electrode(n, r) for n, r in out.items())

    def surface_names(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(s.name for s in self.surfaces))

    # ------------------------------------------------------------------ layout
    def tunable_lengths(self) -> tuple[str, ...]:
        return tuple(f"lengths.{x.name}.value" for x in self.lengths)

    def length_part(self, path: str) -> str:
        for x in self.lengths:
            if path == f"lengths.{x.name}.value":
                return x.part
        return super().length_part(path)

    def _zones(self) -> list[tuple[str, str, float, float]]:
        """Axial zones at the current lengths: the declared bands and the fixed stretches
        between them (part ``""``: a zone of the drawing, not of a part)."""
        return zone_table(self.lengths, *self.resolve().z_range)

    def axial_map(self, z: np.ndarray | float) -> np.ndarray:
        """z of the drawing (m) -> z of this design (the declared bands at their values)."""
        drawn = self.drawn()
        zo = np.array([b[1] for b in drawn.axial_breakpoints()])
        zn = np.array([b[1] for b in self.axial_breakpoints()])
        z = np.asarray(z, dtype=float)
        out = np.interp(z, zo, zn)
        return np.where(z < zo[0], zn[0] + (z - zo[0]), np.where(z > zo[-1], zn[-1] + (z - zo[-1]), out))

    def part_extents(self) -> dict[str, tuple[float, float]]:
        res = self.resolve()
        out: dict[str, tuple[float, float]] = {}
        for region, rule in self.region_rules().items():
            z0, z1 = (float(v) for v in self.axial_map(np.array(res.region_z[region])))
            if rule.part in out:
                z0, z1 = min(out[rule.part][0], z0), max(out[rule.part][1], z1)
            out[rule.part] = (z0, z1)
        return out

    def region_table(self) -> list[tuple[str, str, str, float]]:
        """``(region, part, material, volume m^3)``: the drawing's volumes (OpenCASCADE), each
        zone's share scaled by its stretch."""
        res = self.resolve()
        stretch = {f"length:{x.name}": x.value / x.drawn for x in self.lengths}
        rows = []
        for region, rule in self.region_rules().items():
            vol = sum(v * stretch.get(zone, 1.0) for zone, v in res.zone_volumes[region].items())
            rows.append((region, rule.part, rule.material, float(vol)))
        return rows

    def electrode_planes(self) -> dict[str, list[tuple[str, float]]]:
        """Electrode name -> planes ``(axis, coordinate m)`` of its faces (flat faces only; z
        planes mapped through the declared lengths)."""
        res = self.resolve()
        out = {}
        for e in self.electrodes:
            planes = []
            for axis, value in res.surface_planes.get(e.name, []):
                planes.append((axis, float(self.axial_map(value)) if axis == "z" else value))
            out[e.name] = sorted(set(planes))
        return out

    def morph_points(self, points: np.ndarray, new: "DesignBase") -> np.ndarray:
        if isinstance(new, CadDesign) and Path(new.step).resolve() != Path(self.step).resolve():
            raise ParameterError("design", new.name, "is drawn in another STEP file; re-mesh instead of morphing")
        return super().morph_points(points, new)

