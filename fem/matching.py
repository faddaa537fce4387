"""Resonance matching of the percussive horn and the V-LT coupler (``python -m fem.modal --match``).

The composition works when the horn side and the coupler side resonate together at the drive
frequency (article section 2, Fig. 3): then the working longitudinal mode sits at the target,
the horn tip and the coupler's teeth are both antinodes, and the mounting flange is a node.

Method (two bracketed 1-D root findings)
----------------------------------------
1. **Horn side.** The mesh is cut at the nodal plane: the electrode plane in the middle of the
   ceramic stack (the article: "the PZT ceramics are fixed at the nodal plane"; two rings on
   each side, the classic Langevin layout). The front half (rings 3-4, flange, horn) gets
   ``u_z = 0`` on the cut and short-circuited electrodes, and the front length parameter
   (default ``horn.length``) is tuned by Brent's method until that half's longitudinal mode
   is at the target: a quarter-wave section with its node on the cut.
2. **Whole composition.** The back length parameter (default ``coupler.length``) is tuned,
   again by Brent's method, until the free-free composition's working mode is at the target;
   the horn side being resonant there, the coupler side must be too, and the node stays in the
   stack (reported: axial motion of the mounting flange relative to the tip).

If the search reaches the ends of the bracket without passing the target, the match stops with
a clear error (``ParameterError``: "outside the bracket") instead of extrapolating.

What is reused between iterations
---------------------------------
The mesh is never rebuilt: :meth:`geometry.design_base.DesignBase.morph_points` maps it exactly onto
the design with the new length (piecewise-linear in z between the zone breakpoints), so an
iteration is one fast assembly, one factorisation and a few eigenvectors near the target (started from
the previous trial's: about a third fewer block solves on the article's drill); the
half model's cell selection is computed once. The working mode is followed from iteration to
iteration by the modal assurance criterion (same mesh topology), not by index. (Interpolating
the matrices in the stretch factor is exact only for cells inside one zone; cells that straddle a
zone boundary deform non-affinely, so every iteration assembles the true matrices.) Each
iteration's few modes come from the block shift-invert solver (:mod:`fem.eigen`, smooth start
fields). The final paired modal analysis runs at the same shift as the search, on the
evaluation Brent's method returned (it is one of its evaluated points): that system and its
factorisation are kept (only the one nearest the target, to bound memory) and reused, so the
final step neither assembles nor factorises again (``MatchSettings.reuse``; identical results).

Re-meshing: the result must not depend on where the search started, so when the tuned design's
axial zones differ from those the mesh was built for by more than ``max_stretch`` (2 %), the
tuned design is meshed afresh and both stages run again from there (few iterations: the start is
already close).

Bracketing, Brent's method and the 10 nm lattice of trial lengths: :mod:`fem.tuning`.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from rpud_common import ParameterError, check_choice, check_integer, check_positive, check_range
from rpud_common.result import Result
from geometry.mesh import TaggedMesh

from .assembly import PiezoSystem, assemble
from .eigen import block_eigs, smooth_start
from .modal import working_mode
from .modeshape import surface_motion
from .solvers import blas_threads, factorize
from .tuning import CELL, find_length, snap, valid_bounds

__all__ = ["MatchSettings", "MatchResult", "match", "working_mode", "front_half", "nodal_plane", "default_tune"]

log = logging.getLogger(__name__)

FRONT_PARTS = ("horn", "flange")
BACK_PARTS = ("coupler", "stack", "electrodes")


@dataclass(frozen=True)
class MatchSettings:
    """Settings of a resonance match.

    Attributes
    ----------
    target_hz : float
        Target working frequency, Hz.
    tolerance : float
        Relative frequency tolerance of the match (0.005 = 0.5 %).
    tune : tuple of str
        Design length paths to tune: ``(front, back)`` (a horn/flange length, then a
        coupler/stack length) or a single path (then only step 2 runs with it).
    bracket : (float, float)
        Search interval of each tuned length as factors of its starting value.
    xtol : float
        Length tolerance of the root finding, m.
    n_modes : int
        Modes computed per iteration around the target (the working mode is chosen among them).
    max_stretch : float
        Largest relative stretch of a mesh zone accepted for the final result; beyond it the
        tuned design is re-meshed and matched again (at most ``max_rounds`` rounds).
    mesh_size : float or None
        Mesh size override, m (None: the design's elements-per-wavelength rule).
    refine : float
        Mesh refinement factor (:mod:`geometry.sizing`; < 1 refines, DOFs ~ refine^-3).
    grade : bool
        Grade the mesh toward the re-entrant edges (off by default; ~2x the DOFs).
    mesher : str
        How a re-mesh of the tuned design is built (``geometry.build``): ``"free"`` (default),
        ``"revolve"`` (stack, flange and horn swept) or ``"auto"``; the mesh passed to
        :func:`match` should be built the same way.
    order : int
        Field order (2: P2).
    reuse : bool
        Reuse the assembled system and factorisation of the whole composition at the tuned
        value (evaluated during the search) for the final modal analysis instead of assembling
        and factorising it again; the result is identical either way.
    """

    target_hz: float = 20000.0
    tolerance: float = 0.005
    tune: tuple[str, ...] = ("horn.length", "coupler.length")
    bracket: tuple[float, float] = (0.5, 2.0)
    xtol: float = 1e-5
    n_modes: int = 4
    max_stretch: float = 0.02
    max_rounds: int = 3
    mesh_size: float | None = None
    order: int = 2
    refine: float = 1.0
    grade: bool = False
    mesher: str = "free"
    reuse: bool = True

    def __post_init__(self):
        check_positive("target_hz", self.target_hz, "Hz")
        check_range("tolerance", self.tolerance, 0.0, 0.2, lo_open=True)
        if not self.tune or len(self.tune) > 2:
            raise ParameterError("tune", self.tune, "name one or two design lengths (front, back)")
        lo, hi = self.bracket
        if not (0 < lo < 1 < hi):
            raise ParameterError("bracket", self.bracket, "must be two factors lo < 1 < hi, lo > 0")
        check_range("xtol", self.xtol, CELL, 1e-3, "m (not below the 10 nm lattice of trial lengths)")
        check_integer("max_rounds", self.max_rounds, 1)
        check_range("max_stretch", self.max_stretch, 0.0, 1.0, lo_open=True)
        check_integer("n_modes", self.n_modes, 1)
        if self.mesh_size is not None:
            check_positive("mesh_size", self.mesh_size, "m")
        from geometry.sizing import check_refine

        check_refine(self.refine)
        from geometry.revolve import MESHERS

        check_choice("mesher", self.mesher, MESHERS)


# --------------------------------------------------------------------------- morphing


def _check_morphable(design, path: str) -> None:
    """A tuned length must change axial zone lengths only (so the mesh can be morphed)."""
    value = float(design.get(path))
    new = design.replace({path: value * 1.05})
    zo = np.diff([b[1] for b in design.axial_breakpoints()])
    zn = np.diff([b[1] for b in new.axial_breakpoints()])
    if np.allclose(zo, zn, rtol=0, atol=1e-12):
        raise ParameterError("tune", path, "does not change any axial length of the design")


def _distortion(mesh_design, design) -> float:
    """Largest relative change of an axial zone length between two designs."""
    zo = np.diff([b[1] for b in mesh_design.axial_breakpoints()])
    zn = np.diff([b[1] for b in design.axial_breakpoints()])
    return float(np.max(np.abs(zn / zo - 1.0)))


def _morphed(design, mesh: TaggedMesh, path: str, value: float):
    """The design with ``path = value`` and the mesh morphed onto it (validated by the design)."""
    new = design.replace({path: float(value)})
    return new, mesh.replace(points=design.morph_points(mesh.points, new))


# --------------------------------------------------------------------------- modes


SHIFT_BELOW = 6e-3
"""Relative distance of the matching's shift below the target's eigenvalue ``(2 pi f)^2``. The
final modal analysis keeps the factorisation at that shift, and the harmonic residual
(:func:`fem.harmonic.modal_basis`) reuses it only where the shift is more than 1e-3 (relative)
clear of every mode of its basis: 6e-3 keeps a matched mode anywhere within 0.25 % of the
target (a match converges far closer) clear of it, so the matched drill's harmonic response
needs no second factorisation."""


def _shift(near_hz: float) -> float:
    """Shift of the matching solves, rad^2/s^2: :data:`SHIFT_BELOW` below the target (the matched
    working mode sits at the target; the final modal analysis reuses the same shift)."""
    return (2 * np.pi * near_hz) ** 2 * (1 - SHIFT_BELOW)


def _modes(system: PiezoSystem, free: np.ndarray, near_hz: float, k: int, keep: bool = False,
           warm: np.ndarray | None = None):
    """Short-circuit modes near ``near_hz`` on the given free set: (f_hz, full vectors), and
    with ``keep`` also the factorisation (for reuse by the final modal analysis). ``warm``: the
    full mode vectors of the same model on a morphed mesh (same DOF layout), put in place of the
    first smooth start columns: the modes move little between trial lengths, so fewer block
    solves reach the same tolerance."""
    K = system.K[free][:, free].tocsr()
    M = system.M[free][:, free].tocsr()
    sigma = _shift(near_hz)
    F = factorize((K - sigma * M).tocsr(), matching=False)    # as fem.modal: reuse is bit-identical
    b = max(8, k // 2 + 2)
    n_random = max(2, b // 4)
    start = smooth_start(system.nodes, free, system.ndof, b, n_random=n_random)
    if warm is not None:
        w = min(warm.shape[1], b - n_random)              # the random columns stay (no mode is missed)
        start[:, :w] = warm[free][:, :w]
    with blas_threads(1):
        res = block_eigs(F, K, M, sigma, start, n_wanted=min(k, len(free) - 2), tol=1e-12)
    log.debug("match modes: %d block solves", res.n_solves)
    f = np.sign(res.lam) * np.sqrt(np.abs(res.lam)) / (2 * np.pi)
    full = np.zeros((system.ndof, res.vectors.shape[1]))
    full[free] = res.vectors
    return (f, full, F) if keep else (f, full)


def nodal_plane(design) -> float:
    """z (m) of the nodal plane: the electrode plane nearest the middle of the ceramic stack
    (the article's ceramics sit at the node; an electrode plane is a mesh interface)."""
    planes = sorted(z for faces in design.electrode_planes().values() for axis, z in faces if axis == "z")
    if not planes:
        raise ParameterError("design", getattr(design, "name", "?"), "has no axial electrode plane to cut at")
    mid = 0.5 * (planes[0] + planes[-1])
    return float(min(planes, key=lambda z: abs(z - mid)))


def _front_cells(mesh: TaggedMesh, z_cut: float) -> np.ndarray:
    return mesh.points[mesh.cells[:, :4]].mean(axis=1)[:, 2] > z_cut


def _select(mesh: TaggedMesh, cells: np.ndarray) -> TaggedMesh:
    """The selected cells with the cut face (boundary faces on the lowest z) as ``node_plane``."""
    sub = mesh.submesh(cells)
    tri = sub.boundary_triangles()
    z_cut = sub.points[:, 2].min()
    on_cut = np.all(np.abs(sub.points[tri, 2] - z_cut) < 1e-9 * max(1.0, abs(z_cut)) + 1e-12, axis=1)
    return sub.replace(facet_sets={**sub.facet_sets, "node_plane": tri[on_cut]})


def front_half(mesh: TaggedMesh, z_cut: float) -> TaggedMesh:
    """The cells above ``z_cut`` with the cut face as facet set ``node_plane``."""
    cells = _front_cells(mesh, z_cut)
    if not cells.any() or cells.all():
        raise ParameterError("z_cut", z_cut, "does not cut the mesh")
    return _select(mesh, cells)


# --------------------------------------------------------------------------- matching


@dataclass(eq=False, repr=False)
class MatchResult(Result):
    """Outcome of :func:`match` (SI units): the tuned design, its mesh, system and modes.

    ``repr`` shows target, matched frequency and iterations; :meth:`to_dict` the JSON record.
    """

    target_hz: float
    matched_hz: float
    converged: bool
    tuned: dict
    start: dict
    iterations: list
    design: object
    mesh: TaggedMesh
    system: PiezoSystem
    modal: object
    working_index: int
    teeth: dict
    tip: dict
    node_ratio: float
    timings: dict

    def _headline(self) -> str:
        state = "converged" if self.converged else "NOT converged"
        ratio = self.teeth.get("ellipse_ratio") if isinstance(self.teeth, dict) else None
        teeth = f"; teeth ellipse ratio {ratio:.3f}" if isinstance(ratio, float) else ""
        return (f"{state}: target {self.target_hz:.1f} Hz, matched {self.matched_hz:.1f} Hz "
                f"({self.matched_hz / self.target_hz - 1:+.2%}) in {len(self.iterations)} iterations; "
                f"working mode {self.working_index}{teeth}; {self.system.ndof} DOF")

    def _record(self) -> dict:
        modes = self.modal.to_dict()["modes"]
        return ({
            "target_hz": self.target_hz, "matched_hz": self.matched_hz,
            "error_rel": self.matched_hz / self.target_hz - 1.0, "converged": self.converged,
            "iterations": self.iterations, "n_iterations": len(self.iterations),
            "tuned": self.tuned, "start": self.start, "working_mode": self.working_index,
            "teeth_tops": self.teeth, "horn_tip": self.tip,
            "flange_to_tip_axial_ratio": self.node_ratio,
            "modes": modes, "ndof": self.system.ndof, "backend": self.modal.backend,
            "design": self.design.to_mapping(), "timings": self.timings,
            "materials": self.system.materials_block(),
        })


def default_tune(design) -> tuple[str, ...]:
    """The lengths a match tunes unless the user names others (the design's ``default_tuned``);
    a design without any (a cad design that declares no ``[[lengths]]``) is refused in one line."""
    tune = tuple(getattr(design, "default_tuned", ()) or ())
    if not tune:
        raise ParameterError("--match", getattr(design, "name", "?"), "has no lengths to tune: a cad design is "
                             "matched on declared lengths ([[lengths]] z bands of its drawing); declare them or "
                             "run without --match")
    return tune


def _side(design, path: str) -> str:
    head = design.length_part(path) if hasattr(design, "length_part") else path.split(".")[0]
    if head in FRONT_PARTS:
        return "front"
    if head in BACK_PARTS:
        return "back"
    raise ParameterError("tune", path, "must be a length of the horn/flange (front) or coupler/stack (back)")


def match(design, settings: MatchSettings = MatchSettings(), *, mesh: TaggedMesh | None = None,
          progress: Callable[[dict], None] | None = None,
          system_of: Callable[[TaggedMesh], PiezoSystem] | None = None,
          remesh: Callable[[object], TaggedMesh] | None = None) -> MatchResult:
    """Tune the design lengths until horn and coupler resonate together at the target.

    Parameters
    ----------
    design : geometry.RPUDDesign (or a design with the tuned paths)
    settings : MatchSettings
    mesh : an existing mesh of ``design`` (built here otherwise)
    progress : called with a dict after every iteration (stage, path, value_m, f_hz, seconds)
    system_of : ``system_of(mesh)``, the system a (morphed or cut) mesh is solved as (default: its
        assembly, :func:`fem.assembly.assemble`); the ``k = 0`` system of a swept sector mesh
        (:func:`fem.sector_system.sector_system`) matches on the sector
    remesh : ``remesh(design)``, the mesh of a tuned design when the morphed one is stretched too
        far, and of ``design`` when ``mesh`` is not given (default: :func:`geometry.build_mesh`
        with the settings' mesh options)
    """
    system_of = system_of or (lambda m: assemble(m, order=settings.order))
    remesh = remesh or (lambda d: _default_remesh(d, settings))
    search = _Search(settings, system_of, progress)
    front, back = _tuned_paths(design, settings)
    if mesh is None:
        mesh = remesh(design)
    search.timings["mesh_s"] = time.perf_counter() - search.t_start
    start = {p: float(design.get(p)) for p in settings.tune}
    design, mesh, last_shape, reuse = _rounds(search, design, mesh, front, back, remesh)

    # ---- final: one true assembly of the tuned geometry, paired resonance/anti-resonance
    t0 = time.perf_counter()
    system, factor = reuse if reuse is not None else (system_of(mesh), None)   # reuse: the same mesh and shift
    modal, w, motion = _final_modes(system, mesh, factor, settings.target_hz, settings.n_modes, last_shape)
    search.timings["final_s"] = time.perf_counter() - t0
    search.timings["total_s"] = time.perf_counter() - search.t_start
    matched = float(modal.f_r_hz[w])
    return MatchResult(target_hz=settings.target_hz, matched_hz=matched,
                       converged=abs(matched / settings.target_hz - 1) <= settings.tolerance,
                       tuned={p: float(design.get(p)) for p in settings.tune}, start=start,
                       iterations=search.iterations, design=design, mesh=mesh, system=system, modal=modal,
                       working_index=w, **motion, timings=search.timings)


def _default_remesh(design, settings: MatchSettings) -> TaggedMesh:
    """The mesh of ``design`` with the settings' mesh options (:func:`geometry.build_mesh`)."""
    import geometry

    return geometry.build_mesh(design, mesh_size=settings.mesh_size, refine=settings.refine, grade=settings.grade,
                               mesher=settings.mesher)


def _tuned_paths(design, settings: MatchSettings) -> tuple[str | None, str]:
    """``(front, back)``: the tuned lengths, checked (``front`` None when only one is tuned)."""
    for path in settings.tune:
        if path not in design.tunable_lengths():
            raise ParameterError("tune", path, "unknown; tunable: " + ", ".join(design.tunable_lengths()))
    if len(settings.tune) == 1:
        return None, settings.tune[0]
    front, back = settings.tune
    if _side(design, front) != "front" or _side(design, back) != "back":
        raise ParameterError("tune", settings.tune, "give a front (horn/flange) length, then a back "
                             "(coupler/stack) length")
    return front, back


def _rounds(search: "_Search", design, mesh: TaggedMesh, front: str | None, back: str, remesh):
    """The two stages, repeated on a fresh mesh of the tuned design while the morphed mesh is
    stretched beyond ``max_stretch`` (at most ``max_rounds`` rounds). Returns ``(design, mesh,
    last working-mode shape, (system, factor) to reuse or None)``."""
    settings = search.settings
    mesh_design = design                   # the design the current mesh was built for
    for round_ in range(settings.max_rounds):
        # ---- stage 1: horn side against a node in the middle of the stack
        if front is not None:
            t0 = time.perf_counter()
            z_cut = nodal_plane(design)
            design, mesh, _, _ = search.tune(
                "horn", front, design, mesh, lambda m: _front_cells(m, z_cut),
                lambda sy: np.setdiff1d(sy.free_dofs("short"), sy.dofs_on("node_plane", (2,))))
            search.add_time("horn_side_s", t0)

        # ---- stage 2: the whole composition (free-free; rigid modes lie far below the shift)
        t0 = time.perf_counter()
        design, mesh, last_shape, reuse = search.tune("whole", back, design, mesh, None,
                                                      lambda sy: sy.free_dofs("short"), keep=settings.reuse)
        search.add_time("whole_s", t0)
        # a mesh stretched far from the design it was built for is re-made at the tuned design
        # (and the match repeated from there), so the result does not depend on the start
        if _distortion(mesh_design, design) <= settings.max_stretch or round_ == settings.max_rounds - 1:
            return design, mesh, last_shape, reuse
        t0 = time.perf_counter()
        log.info("match: re-meshing the tuned design (zones stretched by %.1f %%)",
                 100 * _distortion(mesh_design, design))
        mesh_design = design
        mesh = remesh(design)
        search.add_time("mesh_s", t0)
    raise AssertionError("unreachable: the last round returns")


class _Search:
    """The trials of one match: their record (``iterations``, reported through ``progress``), the
    stage timings, and :meth:`tune`, one length tuned on the morphed mesh."""

    def __init__(self, settings: MatchSettings, system_of, progress):
        self.settings, self.system_of, self.progress = settings, system_of, progress
        self.iterations: list[dict] = []
        self.timings: dict[str, float] = {}
        self.t_start = time.perf_counter()

    def add_time(self, key: str, t0: float) -> None:
        self.timings[key] = self.timings.get(key, 0.0) + time.perf_counter() - t0

    def record(self, stage: str, path: str, value: float, f: float) -> None:
        rec = {"stage": stage, "parameter": path, "value_m": float(value), "f_hz": float(f),
               "seconds": time.perf_counter() - self.t_start}
        self.iterations.append(rec)
        log.info("match %-5s %s = %.4f mm -> %.2f Hz", stage, path, value * 1e3, f)
        if self.progress:
            self.progress(rec)

    def tune(self, name, path, design, mesh, select, free_of, keep=False):
        """Tune ``path`` so that the (selected) model's working mode is at the target. With
        ``keep``, the system and factorisation of the evaluation nearest the target are kept
        (Brent's method returns one of its evaluated points). Returns ``(design, mesh, working
        shape, (system, factor) or None)``."""
        _check_morphable(design, path)
        target, settings = self.settings.target_hz, self.settings
        idx = {"keep": None}
        prev = {"shape": None, "vectors": None}
        cache, best = {}, {}

        def evaluate(value):
            value = snap(value)
            if value in cache:
                return cache[value]
            _, m = _morphed(design, mesh, path, value)
            if select is not None:
                if idx["keep"] is None:
                    idx["keep"] = select(m)
                m = _select(m, idx["keep"])
            sy = self.system_of(m)
            f, vec, F = _modes(sy, free_of(sy), target, settings.n_modes, keep=True, warm=prev["vectors"])
            prev["vectors"] = vec
            i = working_mode(sy, f, vec, target, prev["shape"])
            prev["shape"] = sy.displacement(vec[:, i])
            self.record(name, path, value, f[i])
            cache[value] = f[i]
            if keep and (not best or abs(f[i] - target) <= abs(best["f"] - target)):
                best.clear()
                best.update(value=value, f=f[i], system=sy, factor=F)
            return f[i]

        v0 = float(design.get(path))
        tuned = find_length(evaluate, v0, target, valid_bounds(design, path, settings.bracket), settings.xtol,
                            path, "the horn side" if name == "horn" else "the working mode")
        new, m = _morphed(design, mesh, path, tuned)
        reuse = (best["system"], best["factor"]) if best.get("value") == tuned else None
        return new, m, prev["shape"], reuse


def _final_modes(system: PiezoSystem, mesh: TaggedMesh, factor, target: float, n_modes: int, last_shape):
    """The tuned system's modes (``factor``: the last stage's factorisation at the same shift, or
    None), the working mode followed into them by MAC from ``last_shape``, and its surface motion
    (``teeth``, ``tip`` and the flange-to-tip ``node_ratio`` of :class:`MatchResult`)."""
    from .modal import modal_analysis

    modal = modal_analysis(system, target, n_modes, sigma=_shift(target), factor=factor, keep_factor=True)
    log.info("match: final modal analysis %s", "reuses the last stage's system and factorisation"
             if factor is not None else "assembles and factorises afresh")
    w = working_mode(system, modal.f_r_hz, modal.vectors, target, last_shape)
    shape = modal.shapes[w]
    teeth, tip, flange = ({} if name not in mesh.facet_sets else surface_motion(system, shape, name)
                          for name in ("teeth_tops", "horn_tip", "flange"))
    node_ratio = (flange.get("axial_mean", np.nan) / tip["axial_mean"]) if tip and flange else float("nan")
    keep = ("axial", "tangential", "radial", "axial_mean", "tangential_mean", "ellipse_ratio")
    return modal, w, {"teeth": {k: teeth[k] for k in keep if k in teeth}, "tip": {k: tip[k] for k in keep if k in tip},
                      "node_ratio": float(node_ratio)}
