"""rpud.geometry: design data, the material library and Gmsh meshing of the drill.

Importing this package does not import gmsh; the mesher is loaded on first use
(:func:`build_mesh`, :func:`build`).
"""

from .common import ParameterError
from .design import (CouplerDesign, DesignBase, ElectrodeSpec, FlangeDesign, HornDesign, RPUDDesign, Segment,
                     StackDesign, StackRings, default_design, design_from_mapping, load_design)
from .mesh import Electrode, Region, TaggedMesh

__all__ = ["ParameterError", "TaggedMesh", "Region", "Electrode",
           "RPUDDesign", "HornDesign", "StackRings", "FlangeDesign", "CouplerDesign",
           "StackDesign", "Segment", "ElectrodeSpec", "DesignBase",
           "default_design", "load_design", "design_from_mapping", "build_mesh", "build"]


def build_mesh(design, mesh_size=None, order=2, elements_per_wavelength=None, **kw):
    """Mesh a design into a :class:`TaggedMesh` (see :func:`geometry.builder.build`)."""
    from .builder import build_mesh as _build_mesh

    return _build_mesh(design, mesh_size=mesh_size, order=order, elements_per_wavelength=elements_per_wavelength, **kw)


def build(design, **kw):
    """Mesh a design; returns ``(TaggedMesh, BuildReport)`` (see :func:`geometry.builder.build`)."""
    from .builder import build as _build

    return _build(design, **kw)
