"""Gmsh/OpenCASCADE builder: a design in, a conformal tagged tetrahedral mesh out.

Every part is built as an OpenCASCADE solid (:mod:`geometry.solids`: cylinders, cones, lofts,
boxes; coupler slots as helical lofts and tooth gaps as sector prisms, both cut away; thin stack
layers as structured extrusions, :mod:`geometry.layers`), all solids are fragmented into
one conformal model, physical groups are named (one volume group per region, surface groups
``horn_tip``, ``teeth_tops``, ``flange``, ``electrode_*``...), and the model is meshed with
first- or second-order (curved) tetrahedra. The size rules live in :mod:`geometry.sizing`: an
elements-per-wavelength rule per region capped near small features (slots, teeth, rings,
shims); a layer far thinner than that size keeps the in-plane size of its neighbours and is
swept through its thickness; optional grading toward the re-entrant edges (``grade``); one
refinement factor (``refine``) scaling them all.

gmsh is imported inside the functions, so importing this module is cheap.
"""

from __future__ import annotations

import logging
import math
import os
import signal
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rpud_common import cli as common
from rpud_common import ParameterError, check_choice, check_range
from .design_base import DesignBase
from .design_cad import CadDesign
from .design_rpud import RPUDDesign
from .design_stack import StackDesign
from .cad import apply_rules, import_step
from .tagging import parametric_model
from .revolve import (MESHERS, orient, place_midnodes, quad_triangles, resolve_mesher, sectors_per_quarter,
                      split_to_tets, straighten, swept_quality, STRAIGHTEN_STEP, VTK_EDGES)
from .mesh import Electrode, Region, TaggedMesh
from .sector import SectorMeshing, check_sectors, keep_periodic, set_periodic
from .sector_sweep import mesh_swept_sector
from .sizing import apply_fields, check_refine, mesh_layers, region_sizes, revolve_sizes, shear_wavelength

__all__ = ["build", "build_mesh", "BuildReport", "MESHERS", "shear_wavelength", "region_sizes", "mesh_layers", "ALGORITHMS",
           "DEFAULT_ORDER", "MIN_QUALITY", "MIN_SICN_DEFAULT", "GMSH_TIME_LIMIT", "GMSH_TIME_RANGE"]

log = logging.getLogger(__name__)

ALGORITHMS = {"delaunay": 1, "frontal": 4, "hxt": 10}
"""Gmsh 3-D algorithms by name (Mesh.Algorithm3D)."""

DEFAULT_ORDER = 2
"""Curved 10-node tetrahedra by default: volumes of round parts exact to ~1e-5 at coarse sizes."""

MIN_QUALITY = 0.05
"""Lower bound on the minimum gamma (inscribed / circumscribed radius ratio x 3, of the straight
tetrahedron on the corner nodes) of every element, checked by the tests for the article's drill,
its variants and the textbook stacks. Curved elements must also have a positive scaled inverse
condition number (SICN, which sees the curvature: <= 0 means inverted)."""

MIN_SICN_DEFAULT = 0.1
"""Lower bound on the minimum SICN of the article's drill at its default size (tested)."""

OPTIMISE_BELOW = 0.1
"""Minimum gamma of the linear mesh below which a Netgen optimisation pass runs (a sliver just
above ``MIN_QUALITY`` still curves badly at second order). A drawing (``kind = "cad"``) gets the
pass always: the parametric article drill triggers it (min gamma 0.067), its STEP export, whose
linear mesh differs by a few elements, does not, and the pass alone moves the working mode by
0.1 % (10 798 vs 12 925 tetrahedra); with the pass on both sides they agree within 2e-4."""

GMSH_TIME_LIMIT = 600.0
"""Default wall-clock limit of one Gmsh build, s (the environment variable ``RPUD_GMSH_TIMEOUT``
overrides it). Meshes inside the resource guard's budget take well under a minute."""

GMSH_TIME_RANGE = (0.1, 86400.0)
"""Accepted Gmsh time limits, s (below 0.1 s not even Gmsh's start-up fits)."""

SNAP_M = 2.0 ** -40
"""Grid of the mesh coordinates, m (0.91 pm, 1e-11 of a 0.1 m drill): every node Gmsh returns is
rounded to it, so that identical builds give bit-identical meshes (see ``_extract``)."""

@dataclass
class BuildReport:
    """What a build did: counts, quality, groups, sizes and timings (JSON friendly)."""

    design: str
    order: int
    algorithm: str
    mesher: str = "free"
    sectors: int | None = None
    """The mesh is one of this many identical sectors (:mod:`geometry.sector`); None: the whole drill."""
    n_nodes: int = 0
    n_elements: int = 0
    region_sizes: dict[str, float] = field(default_factory=dict)
    physical_groups: dict[str, dict[str, int]] = field(default_factory=dict)
    quality: dict[str, float] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return {
            "design": self.design, "order": self.order, "algorithm": self.algorithm, "mesher": self.mesher,
            "sectors": self.sectors, "n_nodes": self.n_nodes, "n_elements": self.n_elements,
            "mesh_size_m": self.region_sizes, "physical_groups": self.physical_groups,
            "quality": self.quality, "timings_s": self.timings,
        }

# ============================================================================ build


def build_mesh(design: DesignBase, mesh_size: float | None = None, order: int = DEFAULT_ORDER,
               elements_per_wavelength: float | None = None, **kw) -> TaggedMesh:
    """Mesh a design; see :func:`build` (this returns only the :class:`TaggedMesh`)."""
    return build(design, mesh_size=mesh_size, order=order, elements_per_wavelength=elements_per_wavelength, **kw)[0]


def build(design: DesignBase, mesh_size: float | None = None, order: int = DEFAULT_ORDER,
          elements_per_wavelength: float | None = None, algorithm: str = "delaunay",
          verbose: bool = False, msh_path: str | None = None,
          time_limit: float | None = None, refine: float = 1.0,
          grade: bool = False, mesher: str = "free", sectors: int | None = None,
          sector_meshing: SectorMeshing | None = None) -> tuple[TaggedMesh, BuildReport]:
    """Build, fragment, tag and mesh a design with Gmsh, within a wall-clock limit.

    Gmsh runs in a worker thread while this (main) thread waits, so SIGINT/SIGTERM are
    handled at once (Gmsh's own native loop would hold them until it returns) and a run that
    exceeds ``time_limit`` seconds (default :data:`GMSH_TIME_LIMIT` or ``RPUD_GMSH_TIMEOUT``)
    ends with a :class:`ParameterError` instead of hanging. An abandoned Gmsh run cannot be
    stopped: it is recorded (:func:`rpud_common.cli.abandon_native_run`) and the CLI wrapper
    (:func:`rpud_common.cli.run_cli`) then ends the process by ``os._exit`` after its line.
    See :func:`_build` for the other parameters and the result.
    """
    refine, mesher, sectors = _check_build(design, order, msh_path, refine, mesher, sectors, sector_meshing)
    time_limit = _time_limit(time_limit)
    _check_startable(design, grade)
    _start_gmsh()
    tm, report = _run_gmsh(lambda: _build(design, mesh_size, order, elements_per_wavelength, algorithm, verbose,
                                          msh_path, refine, grade, mesher, sectors, sector_meshing),
                           design, mesh_size, time_limit)
    if isinstance(design, CadDesign) and design.drawn() is not design:
        # declared lengths away from the drawing: the drawing's mesh, stretched band by band
        tm = tm.replace(points=design.drawn().morph_points(tm.points, design))
    return tm, report


def _check_build(design, order, msh_path, refine, mesher, sectors, sector_meshing):
    """``(refine, mesher, sectors)`` checked and resolved for ``design``, or a ParameterError."""
    refine = check_refine(refine)
    mesher = resolve_mesher(design, mesher)
    if sectors is not None:
        sectors = check_sectors(design, sectors)
    if sectors and mesher == "revolve":
        if order != 2:
            raise ParameterError("--order", order, "must be 2 for a swept sector (its sweep builds 10-node cells)")
        if msh_path is not None:
            raise ParameterError("msh_path", msh_path, "is not available for a swept sector (most of it is swept "
                                 "outside Gmsh)")
    if sector_meshing is not None:
        if not (sectors and mesher == "revolve"):
            raise ParameterError("sector_meshing", sector_meshing, "applies to swept sectors only (sectors= with "
                                 "mesher='revolve')")
        check_refine(sector_meshing.coupler_refine, "coupler_refine")
        if sector_meshing.layer_deg is not None:
            check_range("layer_deg", sector_meshing.layer_deg, 0.5, 120.0, "degrees")
        if sector_meshing.notch_fraction is not None:
            check_range("notch_fraction", sector_meshing.notch_fraction, 0.01, 1.0)
    return refine, mesher, sectors


def _check_startable(design, grade) -> None:
    """A ParameterError if Gmsh cannot start on ``design``: an abandoned run still going, or a
    drawing's rules or grading refused (checked before Gmsh meshes anything)."""
    if common.native_code_running():
        raise ParameterError("design", getattr(design, "name", design),
                             "an abandoned Gmsh run is still going in this process; start a new one")
    if isinstance(design, CadDesign):
        if grade:
            raise ParameterError("--grade", True, "is not available for cad designs (the re-entrant edges of a "
                                 "drawing are not known); use --refine or [[sizes]] rules")
        design.resolve()        # the rules checked, in one line, before Gmsh meshes anything


def _time_limit(time_limit: float | None) -> float:
    """The Gmsh wall-clock limit, s: ``time_limit``, else ``RPUD_GMSH_TIMEOUT``, else the default; checked."""
    if time_limit is None:
        env = os.environ.get("RPUD_GMSH_TIMEOUT")
        try:
            time_limit = float(env) if env else GMSH_TIME_LIMIT
        except ValueError:
            raise ParameterError("RPUD_GMSH_TIMEOUT", env, "must be a number of seconds") from None
    check_range("gmsh time limit", time_limit, *GMSH_TIME_RANGE, "s")
    return time_limit


def _start_gmsh() -> None:
    """Initialise Gmsh in the calling (main) thread and give the signals back to Python.

    Gmsh's initialisation installs its own native signal handlers (SIGTERM would kill the
    process outright): they are replaced by Python's again.
    """
    import gmsh

    gmsh.initialize(readConfigFiles=False, interruptible=False)
    try:
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                handler = signal.getsignal(sig)
                if handler is not None:
                    signal.signal(sig, handler)
    except BaseException:
        gmsh.finalize()  # interrupted before the worker took Gmsh over
        raise


def _run_gmsh(job, design, mesh_size, time_limit: float):
    """``job()`` run in a worker thread within ``time_limit`` s, its result or its error raised here.

    A Gmsh failure becomes a ParameterError naming the mesh size; a run past the limit is
    abandoned (:func:`rpud_common.cli.abandon_native_run`) and reported as a ParameterError.
    """
    box: dict[str, Any] = {}
    # Set by the worker after its last native call (gmsh.finalize): the only reliable sign that
    # Gmsh stopped, since Thread.is_alive() lies after a join interrupted by a signal.
    done = threading.Event()

    def work():
        try:
            box["result"] = job()
        except ParameterError as exc:
            box["error"] = exc
        except Exception as exc:  # noqa: BLE001 - Gmsh raises bare Exceptions
            box["error"] = ParameterError("--mesh-size", mesh_size, f"Gmsh failed on design "
                                          f"{getattr(design, 'name', '?')!r} ({exc}); change the mesh "
                                          "size or the design's smallest features")
        except BaseException as exc:  # noqa: BLE001 - handed to the caller's thread
            box["error"] = exc

    try:
        # signals go to the waiting main thread only (blocked in the worker)
        common.start_native_worker(work, "gmsh", done)
        # an Event, not a join: an interrupted join marks the thread stopped (see above)
        finished = done.wait(time_limit)
    except BaseException:
        # even a signal inside start() may leave the thread starting: treat it as running
        common.abandon_native_run(done)
        raise
    if not finished:
        common.abandon_native_run(done)
        raise ParameterError("--gmsh-timeout", time_limit,
                             f"Gmsh did not finish {getattr(design, 'name', '?')!r} within the limit: use a "
                             "coarser --mesh-size or allow more time (--gmsh-timeout / RPUD_GMSH_TIMEOUT, s)")
    if "error" in box:
        raise box["error"]
    return box["result"]


def _build(design: DesignBase, mesh_size: float | None = None, order: int = DEFAULT_ORDER,
           elements_per_wavelength: float | None = None, algorithm: str = "delaunay",
           verbose: bool = False, msh_path: str | None = None,
           refine: float = 1.0, grade: bool = False, mesher: str = "free",
           sectors: int | None = None, sector_meshing: SectorMeshing | None = None) -> tuple[TaggedMesh, BuildReport]:
    """Build, fragment, tag and mesh a design with Gmsh (OpenCASCADE kernel).

    Parameters
    ----------
    design : RPUDDesign, StackDesign or CadDesign
    mesh_size : float, optional
        Base element size in m for every region, replacing the elements-per-wavelength rule
        (feature caps, layers, edge grading and the curvature rule still apply).
    order : {1, 2}
        1: 4-node tetrahedra; 2: 10-node curved tetrahedra (nodes on the true geometry).
    elements_per_wavelength : float, optional
        Elements per shear wavelength at the design's target frequency (default: the design's).
    algorithm : {"delaunay", "frontal", "hxt"}
        Gmsh 3-D algorithm.
    verbose : bool
        Let Gmsh print to the terminal.
    msh_path : str, optional
        Also write Gmsh's native ``.msh`` (4.1) of the model to this path (caller handles
        atomicity).
    refine : float
        Scales every size rule together (region sizes, feature caps, layers, graded edges,
        curvature; :mod:`geometry.sizing`): ``refine < 1`` refines, element count ~ ``refine**-3``.
    grade : bool
        Grade the mesh toward the major re-entrant edges (:func:`geometry.sizing.graded_edges`):
        off by default (about twice the elements of the article's drill).
    mesher : {"free", "revolve", "auto"}
        ``"revolve"``: an RPUD's stack, flange and horn swept from a graded (r, z) section
        (:mod:`geometry.revolve`), the coupler free; ``"free"``: every part meshed freely (the
        library's default: fast, the pipeline and the studies use it); ``"auto"``: ``revolve``
        where the design can be swept, else ``free`` (the command lines' default).
    sectors : int, optional
        Mesh only the sector ``0 <= theta <= 2 pi / sectors`` of a cyclically symmetric RPUD
        (:mod:`geometry.sector`), its far cut face a rotated copy of the near one (swept:
        :mod:`geometry.sector_sweep`).
    sector_meshing : SectorMeshing, optional
        Swept sectors: the coupler refined further, its notch edges graded, the layers narrowed
        (:class:`geometry.sector.SectorMeshing`; the command line's rules per harmonic).

    Returns
    -------
    (TaggedMesh, BuildReport)
    """
    import gmsh

    if order not in (1, 2) or isinstance(order, bool):
        raise ParameterError("order", order, "must be 1 or 2")
    check_choice("algorithm", algorithm, tuple(ALGORITHMS))
    if not isinstance(design, (RPUDDesign, StackDesign, CadDesign)):
        raise ParameterError("design", type(design).__name__, "must be an RPUDDesign, a StackDesign or a CadDesign")
    sizes, per_quarter = _sizes(design, mesh_size, elements_per_wavelength, refine, mesher, sectors, sector_meshing)
    report = BuildReport(design=design.name, order=order, algorithm=algorithm, mesher=mesher, sectors=sectors,
                         region_sizes={k: float(v) for k, v in sizes.items()})
    t_start = time.perf_counter()
    # initialised by build() in the main thread (not interruptible: Gmsh would set SIGINT to
    # SIG_DFL, death by the signal; the waiting main thread handles signals instead)
    try:
        _gmsh_options(gmsh, design.name, verbose)
        if sectors and per_quarter:
            tm = _swept_sector(gmsh, design, sizes, refine, grade, order, sectors, per_quarter, algorithm,
                               sector_meshing, report)
            return _finish(tm, report, t_start)
        layers = mesh_layers(design, mesh_size, elements_per_wavelength, refine)
        model = _solids(gmsh, design, layers, per_quarter, sectors, report)
        apply_fields(gmsh, design, sizes, model.region_vols, refine, layers=layers, grade=grade,
                     revolve=bool(per_quarter))
        free_tags = _mesh_linear(gmsh, design, model, algorithm, report)
        folded = _curve(gmsh, free_tags, report) if order == 2 else False
        if msh_path is not None:
            gmsh.write(str(msh_path))
        tm, swept = _extract_straightened(gmsh, design, model, order, sectors, folded, report)
        _report_quality(gmsh, tm, swept, model, report)
    finally:
        gmsh.finalize()
    return _finish(tm, report, t_start)


@dataclass(frozen=True)
class _Model:
    """The tagged Gmsh model of a design: volumes and facet surfaces by name, which are swept."""

    region_vols: dict
    """Region name -> its Gmsh volume tags."""
    region_meta: dict
    """Region name -> (part, material, poling)."""
    facet_surfs: dict
    """Surface group name -> its Gmsh surface tags."""
    layer_vols: frozenset
    """Volumes of the structured layers (flat by design: no quality checks or optimisation)."""
    swept_vols: frozenset
    """Volumes swept from a section (every region but the coupler of a revolved build)."""

    def free(self) -> list[tuple[int, int]]:
        """Gmsh dim-tags of the freely meshed volumes."""
        return [(3, v) for vs in self.region_vols.values() for v in vs if v not in self.layer_vols | self.swept_vols]


def _sizes(design, mesh_size, elements_per_wavelength, refine, mesher, sectors, sector_meshing):
    """``(region sizes, m; sectors per quarter turn of a revolved build or None)``."""
    sizes = region_sizes(design, mesh_size, elements_per_wavelength, refine)
    per_quarter = sectors_per_quarter(refine) if mesher == "revolve" else None
    if per_quarter and sectors and sector_meshing is not None and sector_meshing.layer_deg is not None:
        # the section's triangles no longer than the layers' arcs (revolve_sizes)
        per_quarter = max(per_quarter, math.ceil(90.0 / sector_meshing.layer_deg - 1e-9))
    if per_quarter:
        sizes = revolve_sizes(design, sizes, per_quarter)
    return sizes, per_quarter


def _gmsh_options(gmsh, name: str, verbose: bool) -> None:
    """Gmsh's output, one thread and a fixed seed (identical builds give identical meshes); a new model."""
    gmsh.option.setNumber("General.Terminal", 1 if verbose else 0)
    gmsh.option.setNumber("General.Verbosity", 5 if verbose else 1)
    gmsh.option.setNumber("General.NumThreads", 1)
    for dim in ("1D", "2D", "3D"):
        gmsh.option.setNumber(f"Mesh.MaxNumThreads{dim}", 1)
    gmsh.option.setNumber("Mesh.RandomSeed", 1)
    gmsh.model.add(name)


def _swept_sector(gmsh, design, sizes, refine, grade, order, sectors, per_quarter, algorithm, sector_meshing,
                  report: BuildReport) -> TaggedMesh:
    """A swept sector (:mod:`geometry.sector_sweep`), its free elements straightened, its quality in ``report``."""
    t0 = time.perf_counter()
    tm, swept = mesh_swept_sector(gmsh, design, sizes, refine, grade, order, sectors, per_quarter,
                                  ALGORITHMS[algorithm], SNAP_M, sector_meshing or SectorMeshing())
    points, report.quality["straightened_elements"] = straighten(tm.points, tm.cells, ~swept, step=1.0)
    tm = tm.replace(points=keep_periodic(tm.points, points, sectors))
    report.quality.update(swept_quality(tm, swept))
    report.timings["mesh"] = time.perf_counter() - t0
    return tm


def _above_free_coupler(gmsh, design, vol: int) -> bool:
    """True for a coupler volume swept with the stack (a threaded bolt's thread zone, above the
    coupler's freely meshed part: :attr:`geometry.design_rpud.RPUDDesign.coupler_top`)."""
    top = getattr(design, "coupler_top", 0.0)
    return top < 0 and gmsh.model.getBoundingBox(3, vol)[2] > top - 1e-6


def _solids(gmsh, design, layers, per_quarter, sectors, report: BuildReport) -> _Model:
    """The design's solids (parametric or imported), fragmented, with named physical groups."""
    t0 = time.perf_counter()
    if isinstance(design, CadDesign):
        vols, labels = import_step(gmsh, design.step)
        region_vols, region_meta, facet_surfs = apply_rules(gmsh, design, vols, labels)
    else:
        region_vols, region_meta, facet_surfs = parametric_model(gmsh, design, layers, per_quarter, sectors)
        if sectors:
            set_periodic(gmsh, [v for vs in region_vols.values() for v in vs], sectors)
    report.timings["geometry"] = time.perf_counter() - t0
    clash = sorted(set(region_vols) & set(facet_surfs))
    if clash:
        raise ParameterError("design", design.name, f"region name(s) {', '.join(clash)} clash with surface names")
    for region, vols in region_vols.items():
        gmsh.model.addPhysicalGroup(3, vols, name=region)
    for name, surfs in facet_surfs.items():
        gmsh.model.addPhysicalGroup(2, sorted(surfs), name=name)
    layer_vols = frozenset(v for name in layers for v in region_vols[name])
    swept_vols = frozenset(v for name, vs in region_vols.items() if per_quarter for v in vs
                           if name != "coupler" or _above_free_coupler(gmsh, design, v))
    return _Model(region_vols, region_meta, facet_surfs, layer_vols, swept_vols)


def _mesh_linear(gmsh, design, model: _Model, algorithm, report: BuildReport) -> np.ndarray:
    """The first-order mesh, with a Netgen pass where slivers remain; the free tetrahedra's tags.

    The sizes are already set (:func:`geometry.sizing.apply_fields`).
    """
    gmsh.option.setNumber("Mesh.Algorithm", 6)
    gmsh.option.setNumber("Mesh.Algorithm3D", ALGORITHMS[algorithm])
    gmsh.option.setNumber("Mesh.Optimize", 1)
    gmsh.option.setNumber("Mesh.ElementOrder", 1)
    t0 = time.perf_counter()
    gmsh.model.mesh.generate(3)
    report.timings["mesh_linear"] = time.perf_counter() - t0
    # Slivers the default optimiser left (seen at some sizes near the slot ends): one
    # Netgen pass, only when needed, keeps the default run fast. Layers are flat by design
    # and structured: the checks and optimisers see the freely meshed volumes only.
    t0 = time.perf_counter()
    free = model.free()
    free_tags = _element_tags(gmsh, free, tets_only=True)
    gamma = np.asarray(gmsh.model.mesh.getElementQualities(free_tags.tolist(), "gamma"))
    if len(gamma) and (gamma.min() < OPTIMISE_BELOW or isinstance(design, CadDesign)):
        log.info("min gamma %.3g: Netgen optimisation pass", gamma.min())
        gmsh.model.mesh.optimize("Netgen", dimTags=free)
        gmsh.model.mesh.optimize("", dimTags=free)
        free_tags = _element_tags(gmsh, free, tets_only=True)
    report.timings["optimise"] = time.perf_counter() - t0
    return free_tags


def _curve(gmsh, free_tags: np.ndarray, report: BuildReport) -> bool:
    """Second order: nodes on the true geometry; True if a free element folded (min SICN too low).

    Curving the edges onto the geometry can fold an element near the slots at some lengths
    (seen: SICN 4e-4): such elements are pulled toward straight edges (revolve.straighten, after
    the extraction). Gmsh's high-order optimiser repairs them too, but it is not deterministic
    (it moved nodes by ~3e-8 m from one identical build to the next) and stalls on the pyramids
    of swept builds.
    """
    t0 = time.perf_counter()
    gmsh.model.mesh.setOrder(2)
    sicn = np.asarray(gmsh.model.mesh.getElementQualities(free_tags.tolist(), "minSICN"))
    folded = bool(len(sicn) and sicn.min() < MIN_SICN_DEFAULT)
    if folded:
        log.info("min SICN %.3g < %.3g after curving: folded elements straightened", sicn.min(),
                 MIN_SICN_DEFAULT)
    report.timings["order_2"] = time.perf_counter() - t0
    return folded


def _extract_straightened(gmsh, design, model: _Model, order, sectors, folded, report: BuildReport):
    """``(TaggedMesh, swept-cell mask)`` from Gmsh; swept or folded second-order elements straightened.

    The moved nodes are handed back to Gmsh, whose quality measures follow.
    """
    t0 = time.perf_counter()
    tm, tags, swept = _extract(gmsh, design, model.region_vols, model.region_meta, model.facet_surfs, order,
                               model.swept_vols)
    if order == 2 and (swept.any() or folded):
        # swept builds straighten whole edges (their measured error tables); a free build
        # keeps what curvature it can
        step = 1.0 if swept.any() else STRAIGHTEN_STEP
        points, report.quality["straightened_elements"] = straighten(tm.points, tm.cells, ~swept, step=step)
        if sectors:
            points = keep_periodic(tm.points, points, sectors)
        # the free elements' quality below is Gmsh's: hand it the nodes moved here
        moved = np.unique(tm.cells[~swept])
        moved = moved[np.any(points[moved] != tm.points[moved], axis=1)]
        for k in moved:
            gmsh.model.mesh.setNode(int(tags[k]), points[k].tolist(), [])
        tm = tm.replace(points=points)
    report.timings["extract"] = time.perf_counter() - t0
    return tm, swept


def _report_quality(gmsh, tm: TaggedMesh, swept: np.ndarray, model: _Model, report: BuildReport) -> None:
    """The elements' quality and the physical groups' element counts, into ``report``."""
    t0 = time.perf_counter()
    unswept = [(3, v) for vs in model.region_vols.values() for v in vs if v not in model.swept_vols]
    report.quality.update(_quality(gmsh, _element_tags(gmsh, unswept, tets_only=True),
                                   _element_tags(gmsh, [(3, v) for v in sorted(model.layer_vols)])))
    if swept.any():
        report.quality.update(swept_quality(tm, swept))
    report.timings["quality"] = time.perf_counter() - t0
    for name, vols in model.region_vols.items():
        report.physical_groups[name] = {"dim": 3, "entities": len(vols),
                                        "elements": int(len(tm.cells_in(region=name)))}
    for name, surfs in model.facet_surfs.items():
        report.physical_groups[name] = {"dim": 2, "entities": len(surfs),
                                        "elements": int(len(tm.facet_sets[name]))}


def _finish(tm: TaggedMesh, report: BuildReport, t_start: float) -> tuple[TaggedMesh, BuildReport]:
    report.n_nodes, report.n_elements = tm.n_points, tm.n_cells
    report.timings["total"] = time.perf_counter() - t_start
    log.info("meshed %s: %d nodes, %d order-%d tetrahedra in %.2f s (min SICN %.3f)", report.design,
             tm.n_points, tm.n_cells, report.order, report.timings["total"], report.quality.get("min_sicn", float("nan")))
    return tm, report


def _extract(gmsh, design, region_vols, region_meta, facet_surfs, order, swept_vols=frozenset()):
    node_tags, coords, _ = gmsh.model.mesh.getNodes()
    node_tags = np.asarray(node_tags, dtype=np.int64)
    # Gmsh (one thread, fixed seed) still places the odd vertex differently in its last bit from
    # run to run (seen: one horn-surface vertex of 7 978 nodes, 1.3e-18 m apart in 6 of 12
    # identical builds), and the matching and the chaotic stage downstream would carry that into
    # every output: coordinates are rounded to a binary grid, exact in floating point
    coords = np.round(np.asarray(coords).reshape(-1, 3) / SNAP_M) * SNAP_M
    index = np.full(int(node_tags.max()) + 1, -1, dtype=np.int64)
    index[node_tags] = np.arange(len(node_tags))
    allowed = {1: (4, 6, 7), 2: (11, 13, 14)}[order]
    props = {}
    cells, cell_region, swept = [], [], []
    regions = []
    for i, (region, vols) in enumerate(region_vols.items()):
        part, material, poling = region_meta[region]
        regions.append(Region(region, part, material, None if poling is None else tuple(float(x) for x in poling)))
        for v in vols:
            types, etags, enodes = gmsh.model.mesh.getElements(3, v)
            by_type = {}
            for t, et, en in zip(types, etags, enodes):
                t = int(t)
                if t not in allowed:
                    raise RuntimeError(f"unexpected gmsh element type {t} in volume {v}")
                if t not in props:
                    p = gmsh.model.mesh.getElementProperties(t)
                    props[t] = (int(p[5]), np.asarray(p[4]).reshape(-1, 3))
                by_type[t] = index[np.asarray(en, dtype=np.int64).reshape(len(et), -1)]
            for conn in split_to_tets(props, by_type).values():
                cells.append(conn)
                cell_region.append(np.full(len(conn), i, dtype=np.int64))
                swept.append(np.full(len(conn), v in swept_vols))
    cells = np.concatenate(cells)
    cell_region = np.concatenate(cell_region)
    swept = np.concatenate(swept)
    if order == 2:
        # the rounding moved the mid-nodes of straight edges off their corners' midpoint (by up to
        # one grid step): put them back on it exactly, so that fem.fastasm still finds those
        # elements affine (constant Jacobian; about two thirds of a free mesh)
        ends = np.asarray(VTK_EDGES)
        mids = cells[:, 4:]
        exact = 0.5 * (coords[cells[:, ends[:, 0]]] + coords[cells[:, ends[:, 1]]])
        straight = np.abs(coords[mids] - exact).max(axis=2) <= 2 * SNAP_M
        coords[mids[straight]] = exact[straight]
    if order == 2 and swept.any():
        coords = place_midnodes(coords, cells[swept])
    cells = orient(cells, coords)
    facet_sets = {}
    for name, surfs in facet_surfs.items():
        tris = []
        for sf in surfs:
            types, etags, enodes = gmsh.model.mesh.getElements(2, sf)
            for t, et, en in zip(types, etags, enodes):
                conn = index[np.asarray(en, dtype=np.int64).reshape(len(et), -1)]
                if int(t) in (3, 10, 16):      # swept quadrilaterals: the cut of the elements behind them
                    quads = conn[:, :4]
                    conn = np.take_along_axis(quads[:, None, :], quad_triangles(quads), axis=2).reshape(-1, 3)
                else:
                    conn = conn[:, :3]
                tris.append(conn)
        facet_sets[name] = np.concatenate(tris)
    # compress to the nodes used by cells
    used = np.unique(cells)
    renum = np.full(len(coords), -1, dtype=np.int64)
    renum[used] = np.arange(len(used))
    if isinstance(design, RPUDDesign):
        roles = design.electrode_roles()
        electrodes = tuple(Electrode(n, roles[n]) for n in sorted(roles, key=lambda s: int(s.split("_")[1])))
    else:
        electrodes = tuple(Electrode(e.name, e.role) for e in design.electrodes)
    tm = TaggedMesh(points=coords[used], cells=renum[cells], cell_region=cell_region, regions=tuple(regions),
                    facet_sets={k: renum[v] for k, v in facet_sets.items()}, electrodes=electrodes,
                    materials=design.used_materials())
    return tm, node_tags[used], swept


def _element_tags(gmsh, dimtags, tets_only: bool = False) -> np.ndarray:
    """Tags of the 3-D elements of the given volumes (``tets_only``: of their tetrahedra; the
    pyramids against a swept face have no gamma)."""
    tags = [np.asarray(t, dtype=np.int64) for dim, v in dimtags
            for typ, t in zip(*gmsh.model.mesh.getElements(dim, v)[:2]) if not tets_only or typ in (4, 11)]
    return np.concatenate(tags) if tags else np.zeros(0, dtype=np.int64)


def _quality(gmsh, elem_tags, layer_tags) -> dict[str, float]:
    """min / median of SICN (curvature aware) and gamma (straight corners) of the freely meshed
    elements (of all elements if there are only layers); inverted count of all; the layers' own
    minima and element count (``layer_*``: flat by design, gamma ~ thickness / in-plane size)."""
    out: dict[str, float] = {}
    layer = np.isin(elem_tags, layer_tags)
    free = ~layer if (~layer).any() else np.ones_like(layer)
    for key, name in (("sicn", "minSICN"), ("gamma", "gamma")):
        q = np.asarray(gmsh.model.mesh.getElementQualities(elem_tags.tolist(), name))
        out[f"min_{key}"] = float(q[free].min())
        out[f"median_{key}"] = float(np.median(q[free]))
        if key == "sicn":
            out["n_inverted"] = int(np.sum(q <= 0))
        if layer.any():
            out[f"layer_min_{key}"] = float(q[layer].min())
    out["layer_elements"] = int(layer.sum())
    return out
