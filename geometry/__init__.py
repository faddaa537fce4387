"""rpud.geometry: design data, the material library and Gmsh meshing of the drill.

Importing this package does not import gmsh; the mesher is loaded on first use.
"""

from .common import ParameterError
from .mesh import Electrode, Region, TaggedMesh

__all__ = ["ParameterError", "TaggedMesh", "Region", "Electrode"]
