"""rpud.geometry: design data, the material library and Gmsh meshing of the drill.

Importing this package imports nothing else: the names below load their modules on first use
(PEP 562), so ``python -m geometry`` and every other entry point can install their signal
handlers (:mod:`rpud_common.launch`) before numpy, scipy or gmsh are imported. gmsh itself loads
only when a mesh is built (:func:`build_mesh`, :func:`build`).
"""

from rpud_common.lazy import exports

__all__ = ["ParameterError", "TaggedMesh", "Region", "Electrode",
           "RPUDDesign", "HornDesign", "StackRings", "FlangeDesign", "CouplerDesign",
           "StackDesign", "Segment", "ElectrodeSpec", "DesignBase", "CadDesign",
           "default_design", "load_design", "design_from_mapping", "build_mesh", "build"]

_LAZY = {"ParameterError": "rpud_common.errors",
         **{name: "design_rpud" for name in ("CouplerDesign", "FlangeDesign", "HornDesign", "RPUDDesign",
                                             "StackRings", "default_design")},
         **{name: "design_stack" for name in ("ElectrodeSpec", "Segment", "StackDesign")},
         "CadDesign": "design_cad", "DesignBase": "design_base",
         **{name: "design" for name in ("design_from_mapping", "load_design")},
         **{name: "mesh" for name in ("Electrode", "Region", "TaggedMesh")}}
# not one of these names: ``from geometry import builder`` falls back to the submodule import
__getattr__, __dir__ = exports(__name__, _LAZY)


def build_mesh(design, mesh_size=None, order=2, elements_per_wavelength=None, **kw):
    """Mesh a design into a :class:`TaggedMesh` (see :func:`geometry.builder.build`)."""
    from .builder import build_mesh as _build_mesh

    return _build_mesh(design, mesh_size=mesh_size, order=order, elements_per_wavelength=elements_per_wavelength, **kw)


def build(design, **kw):
    """Mesh a design; returns ``(TaggedMesh, BuildReport)`` (see :func:`geometry.builder.build`)."""
    from .builder import build as _build

    return _build(design, **kw)
