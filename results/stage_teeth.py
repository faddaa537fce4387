"""The teeth motion on a finer mesh than the run's, with a two-level error of <= 5 %.

The teeth's ellipse ratio (tangential / axial) is the slowest of the run's outputs to converge:
on the article drill's ``k = 0`` sector at refine 1 (89 498 DOFs) it is 0.1727 against a
converged 0.1791 (two mesh families, tests/test_discretisation_error.py), and the two-level
estimate between refine 1.4 and 1 states 0.010 (5.8 %). One level finer, refine 0.8
(:data:`TEETH_REFINE` x the run's refine: 154 759 DOFs, one more element layer across the
sector) gives 0.1756, and the two-level estimate between the run's mesh and it states 0.0067
(3.8 %) against a true 0.0035: covered 1.9x. So the run solves the teeth motion once more on
that mesh and reports it (the rotary unit is driven by it), the run's own mesh being the coarse
level of its estimate.

Like with like: the finer mesh is solved as the run's is, the harmonic response at the mesh's
own short-circuit resonance on its modes + residual (:func:`fem.convergence.working_mode_level`,
``harmonic_method="modal"``) with the run's losses and drive voltage. At its own resonance,
not the run's frequency: the ratio moves by ~5e-4 over the few hertz between the two meshes'
resonances, a detuning that would enter the level difference; the converged reference is the
limit of each mesh at its own resonance, as the drive tracks the resonance.

Orders (:func:`fem.errors.teeth_estimate`): 2 for every quantity when the two meshes differ by
an element layer across the sector (the observed orders of the consistent triple 1 / 0.8 / 0.64
are 3.3 for the ratio and 4.8 for the phase); when they have the same layers the phase keeps
:data:`fem.convergence.SECTOR_PHASE_ORDER` (its layers' error is then not seen by the pair).

Cost: one mesh (Gmsh, in the caller's thread: Gmsh is one per process and sets signal handlers
from the main thread only), then in a daemon worker thread the assembly at once, and a 4-mode
modal solve and the modal basis from the end of the run's band response and two-level estimate
on, ~16 s CPU on the article's drill (solved from its meshing on, its factorisation beside the
estimate's and the compliant stage's wide-band modes would take the default drill's run to
~6.6 GB).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from typing import Any

log = logging.getLogger(__name__)

__all__ = ["TEETH_REFINE", "TEETH_QUANTITIES", "TeethMotion", "teeth_refine", "teeth_mesh_text", "teeth_motion", "TeethJob",
           "start_job", "collect_job"]

TEETH_REFINE = 0.8
"""Refine factor of the teeth motion's mesh relative to the run's (one step of the refinement
studies: 1.73x the DOFs, h ratio 1.20, and one more element layer across the sector at refine 1)."""

TEETH_QUANTITIES = ("teeth_ellipse_ratio", "teeth_phase_deg", "teeth_axial_per_volt_m")
"""What the finer mesh gives the run (the rotary unit's inputs)."""


@dataclass(frozen=True)
class TeethMotion:
    """The teeth motion on the finer mesh (:func:`teeth_motion`).

    Attributes
    ----------
    wp : fem.harmonic.WorkingPoint
        At the finer mesh's own resonance and the run's drive voltage, ``teeth_tops`` among its surfaces.
    f_hz : float
        That resonance, Hz.
    refine, ndof, label
        The finer mesh: refine factor, DOFs, words (:func:`fem.sector_system.path_label`).
    est : fem.errors.ErrorEstimate
        Two-level estimate, the run's mesh the coarse level.
    seconds : float
        Wall time of the solve (assembly on), s.
    """

    wp: Any
    f_hz: float
    refine: float
    ndof: int
    label: str
    est: Any
    seconds: float

    def record(self) -> dict:
        """The ``teeth_mesh`` block of ``summary.json``."""
        return {"refine": self.refine, "ndof": self.ndof, "label": self.label, "f_r_hz": self.f_hz,
                "method": "harmonic response at the mesh's own resonance on its modes + residual, the run's losses "
                          "and voltage", "seconds": self.seconds, "discretisation_error": self.est.to_dict()}


def teeth_refine(design, options, surfaces) -> tuple[float | None, str]:
    """The refine factor of the teeth motion's mesh for a run meshed by ``options``
    (:class:`results.stage_fe.MeshOptions`, resolved) reading ``surfaces``, or None and why not:
    only on the sector path, for a design with teeth, where the finer mesh stays in the refine
    range and the resource budget (:func:`geometry.guard.sector_estimate`)."""
    from geometry.guard import MAX_DOFS, sector_estimate
    from geometry.sector import symmetry_order

    # the mesh names the coupler's end face teeth_tops on a design without teeth too: its motion
    # there drives nothing, so the design decides
    has_teeth = getattr(getattr(design, "coupler", None), "n_teeth", 0)
    if options.path != "sector" or "teeth_tops" not in surfaces or not has_teeth:
        return None, "the teeth motion is the run's mesh's (not a k = 0 sector run with teeth)"
    refine = options.refine * TEETH_REFINE
    if refine < 0.2:
        return None, f"the teeth motion is the run's mesh's (refine x {TEETH_REFINE:g} = {refine:g} is below 0.2)"
    dofs = sector_estimate(design, symmetry_order(design) or 6, options.mesh_size, refine).dofs
    if dofs > MAX_DOFS:
        return None, (f"the teeth motion is the run's mesh's (refine {refine:g} would need ~{dofs:,} DOFs, "
                      f"above the budget {MAX_DOFS:,})")
    return refine, ""


def teeth_mesh_text(design, options) -> str:
    """The inputs line's words for the teeth motion's mesh of a run meshed by ``options``
    (resolved) on ``design``."""
    from fem.sector_system import path_label

    refine, why = teeth_refine(design, options, ("teeth_tops",))
    if refine is None:
        return why.removeprefix("the teeth motion is ")
    return path_label(design, "sector", refine=refine, grade=options.grade, mesh_size=options.mesh_size)


def _sector_mesh(design, refine: float, options):
    from fem.sector_system import sector_mesh

    return sector_mesh(design, refine=refine, grade=options.grade, mesh_size=options.mesh_size)


def _system(design, mesh, sectors: int, refine: float, options):
    """The finer sector mesh assembled and restricted to ``k = 0``: ``(system, seconds)``."""
    from fem.assembly import assemble
    from fem.sector_system import path_label, sector_system

    t0 = time.perf_counter()
    system = sector_system(assemble(mesh, order=2), sectors,
                           label=path_label(design, "sector", refine=refine, grade=options.grade,
                                            mesh_size=options.mesh_size))
    return system, time.perf_counter() - t0


def _solve(assembled: tuple, loss, near_hz: float, voltage: float, surfaces: tuple[str, ...]) -> tuple:
    """The working point of the finer sector's system (:func:`_system`): ``(wp, f_r, ndof, label,
    seconds)``, ``seconds`` the assembly's and the solve's."""
    from fem.harmonic import modal_basis, working_point
    from fem.modal import modal_analysis, working_mode

    system, seconds = assembled
    t0 = time.perf_counter()
    # short-circuit modes only, keeping the factorisation for the residual: the shift off the working
    # mode (as fem.harmonic.modal_basis sets it) so that the residual can use it as it is
    import numpy as np

    res = modal_analysis(system, near_hz, 4, open_circuit=False, keep_factor=True,
                         sigma=(2 * np.pi * near_hz) ** 2 * (1 - 2e-3))
    w = working_mode(system, res.f_r_hz, res.vectors, near_hz)
    f = float(res.f_r_hz[w])
    basis = modal_basis(system, f, loss=loss, modes=res)
    wp = working_point(system, f, voltage, loss=loss, surfaces=surfaces, basis=basis)
    return wp, f, int(system.ndof), system.label, seconds + time.perf_counter() - t0


def _motion(design, refine: float, options, solved: tuple, coarse) -> TeethMotion:
    """The :class:`TeethMotion` of a solve (:func:`_solve`) with its estimate against ``coarse``."""
    from fem.convergence import Level, harmonic_quantities
    from fem.errors import teeth_estimate

    wp, f, ndof, label, seconds = solved
    fine = Level(refine, ndof, {q: v for q, v in harmonic_quantities(wp).items() if q in TEETH_QUANTITIES})
    est = teeth_estimate(design, fine, coarse, mesh_size=options.mesh_size)
    return TeethMotion(wp, f, refine, ndof, label, est, seconds)


def teeth_motion(design, options, *, loss, near_hz: float, voltage: float, surfaces: tuple[str, ...], coarse,
                 refine: float | None = None) -> TeethMotion:
    """The teeth motion of ``design`` on the finer sector mesh (``refine``, default the run's x
    :data:`TEETH_REFINE`), in the calling thread.

    Parameters
    ----------
    design : the tuned design
    options : the run's resolved :class:`results.stage_fe.MeshOptions` (sector path)
    loss : fem.harmonic.LossModel, the run's
    near_hz : the run's working frequency, Hz (where the finer mesh's working mode is sought)
    voltage : drive amplitude, V
    surfaces : the run's working-point surfaces (tip first, ``teeth_tops`` among them)
    coarse : fem.convergence.Level, the run's mesh and its values (:data:`TEETH_QUANTITIES`)
    """
    refine = options.refine * TEETH_REFINE if refine is None else refine
    mesh, sectors = _sector_mesh(design, refine, options)
    solved = _solve(_system(design, mesh, sectors, refine, options), loss, near_hz, voltage, tuple(surfaces))
    return _motion(design, refine, options, solved, coarse)


class TeethJob:
    """:func:`teeth_motion` beside the caller's stages: :meth:`start` meshes in the calling (main)
    thread and starts a daemon worker thread, which assembles at once (no factorisation: little
    memory, and it fills the cores' gaps in the caller's stages) and solves from :meth:`release`
    on (PARDISO and NumPy release the interpreter; the caller releases it once its own largest
    solves are done, so the factorisations do not add up in memory); :meth:`collect` takes the
    run's own values, the estimate's coarse level. A run ended by a
    signal or an error does not wait for the thread (its answer is dropped;
    :func:`rpud_common.cli.start_native_worker`)."""

    def __init__(self):
        import threading

        self.thread, self.done, self.box, self.refine, self.note = None, None, {}, None, ""
        self.design = self.options = None
        self.go = threading.Event()

    def start(self, design, options, surfaces, **solve) -> None:
        """Mesh and start the solve when :func:`teeth_refine` allows it (else :attr:`note` says
        why); ``solve``: ``loss``, ``near_hz``, ``voltage`` of :func:`teeth_motion`."""
        from rpud_common.cli import start_native_worker

        self.refine, self.note = teeth_refine(design, options, surfaces)
        if self.refine is None:
            return
        self.design, self.options = design, options
        mesh, sectors = _sector_mesh(design, self.refine, options)

        def work():
            try:
                assembled = _system(design, mesh, sectors, self.refine, options)    # no factorisation yet
                self.go.wait()
                self.box["out"] = _solve(assembled, surfaces=tuple(surfaces), **solve)
            except BaseException as exc:          # handed to the caller at collect
                self.box["error"] = exc

        self.thread, self.done = start_native_worker(work, "teeth")

    def release(self) -> None:
        """Let the worker solve."""
        self.go.set()

    def wait(self) -> None:
        """Wait until the worker has ended (solved or failed; :meth:`collect` takes the result)."""
        if self.thread is not None:
            self.release()
            self.done.wait()

    def collect(self, coarse) -> TeethMotion | None:
        """Wait for the solve (an error in it is raised here) and estimate its error with the run's
        own values ``coarse`` (:class:`fem.convergence.Level`); None when it did not run."""
        if self.thread is None:
            return None
        self.wait()
        if "error" in self.box:
            raise self.box["error"]
        return _motion(self.design, self.refine, self.options, self.box["out"], coarse)


def start_job(matched, settings) -> TeethJob:
    """Mesh the finer sector of the matched drill ``matched`` (:class:`results.stage_fe.Matched`)
    and start its solve in a worker thread with the run's losses and voltage (``settings``:
    :class:`results.pipeline.PipelineSettings`); the job's ``note`` says why when it does not run."""
    from .stage_harmonic import tip_surfaces

    job = TeethJob()
    job.start(matched.design, matched.options, tip_surfaces(matched.mesh), loss=settings.losses().loss_model(),
              near_hz=matched.f_r_hz, voltage=settings.voltage)
    return job


def collect_job(job: TeethJob, wp, matched, run_estimate, say) -> tuple:
    """The teeth motion the rotary unit is driven by: ``(TeethMotion or None, working point,
    error estimate)``, the finer mesh's when ``job`` ran (its coarse level the run's own values
    ``wp`` on ``matched``'s mesh), else the run's working point and ``run_estimate``."""
    from fem.convergence import Level, harmonic_quantities
    from fem.errors import plus_minus

    own = Level(matched.options.refine, int(matched.system.ndof),
                {q: v for q, v in harmonic_quantities(wp).items() if q in TEETH_QUANTITIES})
    t = job.collect(own)
    if t is None:
        return None, wp, run_estimate
    e = t.est
    say(f"      teeth motion on {t.label} ({t.ndof} DOFs, {t.seconds:.1f} s beside the run): ellipse "
        f"{plus_minus(t.wp.teeth_ellipse_ratio, e.error('teeth_ellipse_ratio'))}, phase "
        f"{plus_minus(t.wp.teeth_phase_deg, e.error('teeth_phase_deg'), 'deg')} (two-level against the run's mesh, "
        f"{own.values.get('teeth_ellipse_ratio', float('nan')):.4f})")
    return t, t.wp, e
