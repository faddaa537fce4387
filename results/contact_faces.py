"""The free mass's contact faces: design data of the compliant contacts (:mod:`results.stage_compliant`).

The free mass strikes the flat horn tip and the flat tool face with the same two faces. Its face
is either

- **crowned**: a spherical cap of radius ``face_radius`` (m); without a radius, that of a sphere of
  the free mass's own mass and material (each free mass its own radius), or
- **flat with a rounded rim**: a flat face of radius ``face_radius`` whose rim is rounded with
  ``edge_radius`` (m), meeting the flat tilted by ``face_tilt_deg`` (degrees), so the rim touches
  first (:meth:`impact.hertz.ContactGeometry.rounded_edge`); the three are given together.

The face sets the Hertz stiffness of both contacts (:func:`impact.hertz.hertz_stiffness`), and
with it the contact time from which the stage picks its mode cut-off. Stored in a ``[contact]``
table of a TOML file (:meth:`ContactFaces.from_toml`), or given on the command line of
``python -m results`` (``--face-radius``, ``--edge-radius``, ``--face-tilt``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from rpud_common import ParameterError, check_range, dump_toml, from_mapping, load_toml, to_mapping, toml_section

__all__ = ["ContactFaces"]


@dataclass(frozen=True)
class ContactFaces:
    """The free mass's faces and the materials of the contact (SI units; see the module docstring).

    Attributes
    ----------
    face_radius : crowned: crown radius, m (None: a sphere of the free mass's own mass and
        material); flat: radius of the flat face, m. In [1e-4, 1] m.
    edge_radius : rim radius of a flat face, m (None: a crowned face), in [1e-6, face_radius]
    face_tilt_deg : tilt of the flat face against the flat it strikes, degrees, in (0, 90)
        (with ``edge_radius`` only)
    free_mass_material, tool_material : materials of the free mass and of the tool face (the
        horn tip's is the design's horn material)
    """

    face_radius: float | None = None
    edge_radius: float | None = None
    face_tilt_deg: float | None = None
    free_mass_material: str = "steel_45"
    tool_material: str = "steel_45"

    def __post_init__(self):
        if self.face_radius is not None:
            check_range("face_radius", self.face_radius, 1e-4, 1.0, "m")
        if self.edge_radius is None:
            if self.face_tilt_deg is not None:
                raise ParameterError("face_tilt_deg", self.face_tilt_deg, "applies to a flat face only: give "
                                     "edge_radius (and face_radius) with it, or drop it for a crowned face")
            return
        if self.face_radius is None or self.face_tilt_deg is None:
            raise ParameterError("edge_radius", self.edge_radius, "makes the face flat: give face_radius (the flat "
                                 "face's radius, m) and face_tilt_deg (degrees) with it")
        check_range("edge_radius", self.edge_radius, 1e-6, self.face_radius, "m")
        check_range("face_tilt_deg", self.face_tilt_deg, 0.0, 90.0, "degrees", lo_open=True, hi_open=True)

    @property
    def flat(self) -> bool:
        """True for a flat face with a rounded rim."""
        return self.edge_radius is not None

    def geometry(self, m_free: float, density: float):
        """The :class:`impact.hertz.ContactGeometry` of the face for a free mass ``m_free`` (kg) of
        ``density`` (kg/m^3: the crown radius of a sphere of its own mass when none is given)."""
        from impact.hertz import ContactGeometry

        if self.flat:
            return ContactGeometry.rounded_edge(self.edge_radius, self.face_radius, math.radians(self.face_tilt_deg))
        radius = self.face_radius or (3.0 * m_free / (4.0 * math.pi * density)) ** (1.0 / 3.0)
        return ContactGeometry.crowned(radius)

    def text(self) -> str:
        """The faces in words with units (the inputs line)."""
        if self.flat:
            return (f"flat face a = {self.face_radius * 1e3:g} mm, edge radius {self.edge_radius * 1e3:g} mm, "
                    f"tilt {self.face_tilt_deg:g} deg")
        if self.face_radius is not None:
            return f"crowned face R = {self.face_radius * 1e3:g} mm"
        return f"crowned faces, R of a {self.free_mass_material} sphere of each free mass"

    def to_dict(self) -> dict:
        return to_mapping(self)

    @classmethod
    def from_dict(cls, data) -> "ContactFaces":
        return from_mapping(cls, data)

    def to_toml(self) -> str:
        """TOML text with one ``[contact]`` table (unset radii left out)."""
        return dump_toml({"contact": self.to_dict()})

    @classmethod
    def from_toml(cls, path) -> "ContactFaces":
        """Load from a TOML file: top-level keys, or a ``[contact]`` table (beside other tables, such
        as the ``[impact]`` table of ``python -m impact --config``)."""
        data = load_toml(path, "--contact")
        tables = {k: v for k, v in data.items() if isinstance(v, dict) and k != "contact"}
        if "contact" not in data and tables:
            raise ParameterError("--contact", str(path), f"has no [contact] table (tables: {', '.join(tables)})")
        rest = {k: v for k, v in data.items() if k not in tables}        # other tables belong to other commands
        return from_mapping(cls, dict(toml_section(rest, "contact", str(path))), "contact")
