"""The design options every command line that takes a design shares (one definition, one check).

``add_design_options(parser)`` adds ``--design``, ``--select``, ``--materials``,
``--mesh-size``, ``--refine`` and ``--grade``; ``design_from_options(ns)`` checks them (one-line
:class:`~rpud_common.ParameterError`, exit 2, before anything is meshed) and returns the design,
whose material names resolve in the built-in library, its own ``[materials]`` table and the
``--materials`` file. To add an option for every design CLI, add it here (``DESIGN_OPTIONS``
lists what ``add_design_options`` offers; each CLI picks the ones it honours).
"""

from __future__ import annotations

from pathlib import Path

from rpud_common import ParameterError, check_range

__all__ = ["add_design_options", "design_from_options", "check_design_options", "design_inputs", "mesh_options",
           "mesher_of",
           "DESIGN_OPTIONS", "MESH_OPTIONS", "MESH_SIZE_RANGE"]

DESIGN_OPTIONS = ("design", "select", "materials", "mesh_size", "refine", "grade", "mesher")
"""Options :func:`add_design_options` can add (attribute names on the namespace)."""

MESH_SIZE_RANGE = (1e-5, 1.0)
"""Accepted ``--mesh-size`` values, m."""

MESH_OPTIONS = ("mesh_size", "refine", "grade", "mesher")
"""The meshing options of :data:`DESIGN_OPTIONS` (what every CLI that meshes offers)."""

REFINE_HELP = ("refinement factor scaling every mesh-size rule together (region sizes, feature caps, layers, "
               "graded edges, curvature): F < 1 refines, DOFs grow about as F^-3 (default 1; accepted 0.2-5)")
MESHER_HELP = ("auto (default): revolve where the design can be swept (an RPUD with a stepped or conical horn), "
               "else free; a match meshes freely under auto (--mesher revolve: a swept match, ~3x the time). "
               "revolve: the stack, flange and "
               "horn swept from a graded (r, z) section, long elements along the circular edges, the coupler free: "
               "working mode +0.04 %% from the converged answer without slots and teeth, ~+0.1 %% on the slotted article drill, "
               "at ~1.6x the DOFs of free. free: every part meshed freely (fast; ~+0.5 %% on the working mode of the "
               "article's drill)")
GRADE_HELP = ("grade the mesh toward the re-entrant edges (flange/horn, horn step; the coupler's slot and tooth "
              "notches): free mesh +0.12 %% instead of +0.45 %% on the working mode of the design without slots and teeth, "
              "~2.3x the DOFs of the article's drill; swept mesh (notches only) 1.22x the DOFs (default: off)")

_DEFAULT_WORD = "default"

EXAMPLES_FILE = Path(__file__).with_name("examples.toml")
"""The named example designs (``--design NAME`` picks one of its tables, e.g. ``bolted``)."""


def add_design_options(parser, *, include=DESIGN_OPTIONS, design_default: str | None = None,
                       mesh_size_help: str = "base element size, m: replaces the elements-per-wavelength rule of "
                                             "every region; the feature caps, layers, edge grading and curvature "
                                             "rule stay, so it does not refine uniformly (use --refine)",
                       number_type=float, metavar="FILE", mesher_default: str = "auto"):
    """Add the design options to ``parser`` (or an argument group).

    Parameters
    ----------
    include : iterable of str
        Which of :data:`DESIGN_OPTIONS` to add.
    design_default : str, optional
        Default of ``--design`` (``"default"`` means the built-in design, as ``None`` does).
    number_type : callable
        Parser of ``--mesh-size`` and ``--refine`` (a CLI's own finite-number type, if it has one).
    mesher_default : str
        Default of ``--mesher`` (``"free"`` where a time budget is set on the free mesh).
    """
    include = tuple(include)
    if "design" in include:
        parser.add_argument("--design", metavar=metavar, default=design_default,
                            help="design TOML (default: the built-in RPUD design, its M12 stack bolt threaded "
                                 "in as an elastic part); it may hold its own [materials] table. A bare NAME picks "
                                 "that design of geometry/examples.toml (e.g. article: the drill as the article's "
                                 "Table 1 draws it, no bolt part; bolted: the bolt bonded at the stack's faces)")
    if "select" in include:
        parser.add_argument("--select", metavar="NAME", help="pick one design from a TOML file holding several "
                            "(e.g. geometry/examples.toml: k33_rod, k31_bar, langevin, slender_rod, "
                            "bonded_sandwich, rpud, article, bolted)")
    if "materials" in include:
        parser.add_argument("--materials", metavar="FILE",
                            help="material library TOML (layout of geometry/materials.toml; stress-charge c_E, e, "
                                 "eps_S or strain-charge s_E, d, eps_T, SI units, relative permittivities): adds "
                                 "to and overrides the built-in records")
    if "mesh_size" in include:
        parser.add_argument("--mesh-size", type=number_type, metavar="M", help=mesh_size_help)
    if "refine" in include:
        parser.add_argument("--refine", type=number_type, metavar="F", default=1.0, help=REFINE_HELP)
    if "grade" in include:
        parser.add_argument("--grade", action="store_true", help=GRADE_HELP)
    if "mesher" in include:
        note = "" if mesher_default == "auto" else f"default here: {mesher_default}. "
        text = MESHER_HELP if mesher_default == "auto" else MESHER_HELP.replace(" (default)", "")
        parser.add_argument("--mesher", choices=("auto", "free", "revolve"), default=mesher_default,
                            help=note + text)
    return parser


def named_example(value) -> str | None:
    """``value`` when it names a design of :data:`EXAMPLES_FILE` (a bare name, no file of that
    name), else None: ``--design bolted`` reads the ``[bolted]`` table without a path."""
    if value is None:
        return None
    text = str(value)
    if not text.isidentifier() or Path(text).exists():
        return None
    from rpud_common import load_toml

    return text if text in load_toml(EXAMPLES_FILE, "design") else None


def _design_path(ns):
    value = getattr(ns, "design", None)
    if value is None or str(value) == _DEFAULT_WORD:
        return None
    return EXAMPLES_FILE if named_example(value) else value


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
    if getattr(ns, "refine", None) is not None:
        from .sizing import check_refine

        check_refine(ns.refine, "--refine")
    if getattr(ns, "select", None) is not None and _design_path(ns) is None:
        raise ParameterError("--select", ns.select, "needs --design FILE")
    if getattr(ns, "select", None) is not None and named_example(getattr(ns, "design", None)):
        raise ParameterError("--select", ns.select, f"needs --design FILE, not the example name {ns.design!r}")


def _matching(ns) -> bool:
    """True when the command matches: ``--match`` given, or a pipeline without ``--no-match``."""
    return getattr(ns, "match", None) not in (None, False) or getattr(ns, "no_match", True) is False


def mesh_options(ns, design=None) -> dict:
    """``refine``, ``grade`` and ``mesher`` of the options as keyword arguments of
    ``geometry.build_mesh``, :func:`geometry.guard.check_budget` and the settings that carry them
    (defaults if absent). ``--mesher auto`` is ``free`` when the command matches (a swept match
    takes ~3x the time; ``--mesher revolve`` asks for it), else the swept mesher where ``design``
    can be swept; without ``design`` it stays ``auto`` (resolved by the builder)."""
    from .revolve import resolve_mesher

    refine = getattr(ns, "refine", None)
    out = {"refine": 1.0 if refine is None else float(refine), "grade": bool(getattr(ns, "grade", False))}
    mesher = getattr(ns, "mesher", "free")
    if mesher == "auto" and _matching(ns):
        mesher = "free"
    if mesher == "auto" and design is not None:
        mesher = resolve_mesher(design, mesher)
    if mesher != "free":
        out["mesher"] = mesher
    return out


def mesher_of(ns, design) -> str:
    """The mesher the options give for ``design``: ``"free"`` or ``"revolve"``."""
    return mesh_options(ns, design).get("mesher", "free")


def design_from_options(ns):
    """The design the options name, validated with its materials (one-line errors, no meshing).

    ``--design`` absent or ``default``: the built-in design. ``--materials FILE``: its records
    resolve the design's names; those the design uses go into its own table (so its TOML, JSON
    and results carry them).
    """
    from .design import load_design
    from .design_rpud import default_design
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
    name = named_example(getattr(ns, "design", None))
    return load_design(path, name or getattr(ns, "select", None), materials=extra)
