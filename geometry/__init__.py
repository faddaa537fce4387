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
           "default_design", "filleted", "HORN_MAKER_FILLET", "load_design", "design_from_mapping", "build_mesh", "build"]

_LAZY = {"ParameterError": "rpud_common.errors",
         **{name: "design_rpud" for name in ("CouplerDesign", "FlangeDesign", "HornDesign", "RPUDDesign",
                                             "StackRings", "default_design", "filleted", "HORN_MAKER_FILLET")},
         **{name: "design_stack" for name in ("ElectrodeSpec", "Segment", "StackDesign")},
         "CadDesign": "design_cad", "DesignBase": "design_base",
         **{name: "design" for name in ("design_from_mapping", "load_design")},
         **{name: "mesh" for name in ("Electrode", "Region", "TaggedMesh")}}
# not one of these names: ``from geometry import builder`` falls back to the submodule import
__getattr__, __dir__ = exports(__name__, _LAZY)


def build_mesh(design, mesh_size=None, order=2, elements_per_wavelength=None, **kw):
    """Mesh a design into a :class:`TaggedMesh` with Gmsh (see :func:`geometry.builder.build`).

    Parameters
    ----------
    design : DesignBase
        An RPUD, stack or CAD design (:func:`default_design`, :func:`load_design`,
        :mod:`geometry.examples`).
    mesh_size : float, optional
        Global cap on the element size, m (default: the design's size rules alone).
    order : {1, 2}
        Geometry order of the tetrahedra: 2 (default) gives curved 10-node cells.
    elements_per_wavelength : float, optional
        Elements per shear wavelength at the design's target frequency.
    **kw
        The other options of :func:`geometry.builder.build`: ``refine``, ``grade``,
        ``mesher``, ``algorithm``, ``time_limit``, ``sectors``...

    Returns
    -------
    TaggedMesh
        Nodes (m), cells, named regions and surfaces, electrodes, and the material records the
        design resolved.

    Examples
    --------
    A PZT-4 rod (40 mm long, 4 mm across) poled along its length, electrodes on its ends:

    >>> from geometry.examples import k33_rod
    >>> mesh = build_mesh(k33_rod(), mesh_size=0.01, order=1)
    >>> [r.name for r in mesh.regions], [(e.name, e.role) for e in mesh.electrodes]
    (['rod'], [('electrode_bottom', 'ground'), ('electrode_top', 'hot')])

    Straight cells facet the circular section: the meshed volume is that of the inscribed
    polygon, a few per cent below ``pi r^2 L``:

    >>> import math
    >>> round(float(mesh.cell_volumes().sum()) / (math.pi * 0.002 ** 2 * 0.04), 3)
    0.967
    """
    from .builder import build_mesh as _build_mesh

    return _build_mesh(design, mesh_size=mesh_size, order=order, elements_per_wavelength=elements_per_wavelength, **kw)


def build(design, **kw):
    """Mesh a design; returns ``(TaggedMesh, BuildReport)`` (see :func:`geometry.builder.build`).

    Parameters
    ----------
    design : DesignBase
        The design to mesh.
    **kw
        The options of :func:`geometry.builder.build` (as :func:`build_mesh`).

    Returns
    -------
    mesh : TaggedMesh
    report : geometry.builder.BuildReport
        Counts, mass per part, mesh quality and timings (``to_dict()`` for JSON).

    Examples
    --------
    >>> from geometry.examples import k33_rod
    >>> mesh, report = build(k33_rod(), mesh_size=0.01, order=1)
    >>> report.n_elements == len(mesh.cells), report.mesher
    (True, 'free')
    """
    from .builder import build as _build

    return _build(design, **kw)
