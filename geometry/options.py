"""The design options every command line that takes a design shares (one definition, one check).

``add_design_options(parser)`` adds ``--design``, ``--select``, ``--materials`` and
``--mesh-size``; ``design_from_options(ns)`` checks them (one-line
:class:`~rpud_common.ParameterError`, exit 2, before anything is meshed) and returns the design,
whose material names resolve in the built-in library, its own ``[materials]`` table and the
``--materials`` file. To add an option for every design CLI, add it here (``DESIGN_OPTIONS``
lists what ``add_design_options`` offers; each CLI picks the ones it honours).
"""

from __future__ import annotations

from rpud_common import ParameterError, check_range

__all__ = ["add_design_options", "design_from_options", "check_design_options", "design_inputs",
           "DESIGN_OPTIONS", "MESH_SIZE_RANGE"]

DESIGN_OPTIONS = ("design", "select", "materials", "mesh_size")
"""Options :func:`add_design_options` can add (attribute names on the namespace)."""

MESH_SIZE_RANGE = (1e-5, 1.0)
"""Accepted ``--mesh-size`` values, m."""

_DEFAULT_WORD = "default"


def add_design_options(parser, *, include=DESIGN_OPTIONS, design_default: str | None = None,
                       mesh_size_help: str = "base element size in m (replaces the elements-per-wavelength rule; "
                                             "feature caps still apply)", number_type=float, metavar="FILE"):
    """Add the design options to ``parser`` (or an argument group).

    Parameters
    ----------
    include : iterable of str
        Which of :data:`DESIGN_OPTIONS` to add.
    design_default : str, optional
        Default of ``--design`` (``"default"`` means the built-in design, as ``None`` does).
    number_type : callable
        Parser of ``--mesh-size`` (a CLI's own finite-number type, if it has one).
    """
    include = tuple(include)
    if "design" in include:
        parser.add_argument("--design", metavar=metavar, default=design_default,
                            help="design TOML (default: the built-in RPUD design); it may hold its own "
                                 "[materials] table")
    if "select" in include:
        parser.add_argument("--select", metavar="NAME", help="pick one design from a TOML file holding several "
                            "(e.g. geometry/examples.toml: k33_rod, k31_bar, langevin, slender_rod, "
                            "bonded_sandwich, rpud)")
    if "materials" in include:
        parser.add_argument("--materials", metavar="FILE",
                            help="material library TOML (layout of geometry/materials.toml; stress-charge c_E, e, "
                                 "eps_S or strain-charge s_E, d, eps_T, SI units, relative permittivities): adds "
                                 "to and overrides the built-in records")
    if "mesh_size" in include:
        parser.add_argument("--mesh-size", type=number_type, metavar="M", help=mesh_size_help)
    return parser


def _design_path(ns):
    value = getattr(ns, "design", None)
    return None if value is None or str(value) == _DEFAULT_WORD else value


def design_inputs(ns) -> dict:
    """The input files of the options, for ``rpud_common.check_output_paths(inputs=...)``."""
    out = {"--design": _design_path(ns)}
    if getattr(ns, "materials", None) is not None:
        out["--materials"] = ns.materials
    return out


def check_design_options(ns) -> None:
    """Cheap checks of the options (numbers and combinations), no file read."""
    if getattr(ns, "mesh_size", None) is not None:
        check_range("--mesh-size", ns.mesh_size, *MESH_SIZE_RANGE, "m")
    if getattr(ns, "select", None) is not None and _design_path(ns) is None:
        raise ParameterError("--select", ns.select, "needs --design FILE")


def design_from_options(ns):
    """The design the options name, validated with its materials (one-line errors, no meshing).

    ``--design`` absent or ``default``: the built-in design. ``--materials FILE``: its records
    resolve the design's names; those the design uses go into its own table (so its TOML, JSON
    and results carry them).
    """
    from .design import default_design, load_design
    from .design_materials import with_records
    from .materials import records_from_mapping

    from rpud_common import load_toml

    check_design_options(ns)
    extra = None
    if getattr(ns, "materials", None) is not None:
        extra = records_from_mapping(load_toml(ns.materials, "--materials"), str(ns.materials))
        if not extra:
            raise ParameterError("--materials", ns.materials, "holds no material records")
    path = _design_path(ns)
    if path is None:
        design = default_design()
        return with_records(design, extra, str(ns.materials)) if extra else design
    return load_design(path, getattr(ns, "select", None), materials=extra)
