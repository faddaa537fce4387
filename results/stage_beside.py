"""The harmonic stage's pieces that run side by side on two cores (:func:`results.pipeline.run_pipeline`).

Two rounds, each of pieces that share no data that any of them writes:

1. :func:`harmonic_beside_teeth_mesh`: the modal basis and working point
   (:func:`results.stage_harmonic.harmonic_stage`: solves on the matched factorisation) and
   the bolt's unit preload state (:func:`results.operating_point.preload_unit`: a static
   factorisation) in two worker threads, while the calling (main) thread has Gmsh mesh the
   teeth motion's finer sector (:func:`results.stage_teeth.start_job`; Gmsh is started from the
   main thread only). The teeth mesh needs the matched design, so it cannot start earlier, and
   Gmsh meshes on one core: alone it would leave the other idle.
2. :func:`response_beside_estimate`: the bolt's preload window, the operating quantities, the
   band response and the stress fields and peaks of the working point (a worker thread) beside
   the discretisation-error estimate on the coarser mesh (this thread: Gmsh again), which
   gives the stress rows their error estimates afterwards.

The teeth motion's worker thread started in round 1 assembles its finer mesh beside round 2 (it
shares nothing with it either) and solves it after (memory).

PARDISO, NumPy and Gmsh release the interpreter, so the pieces overlap; each piece computes
what it computed alone (same calls, same inputs), so the numbers do not depend on which runs
when. In round 2 OpenBLAS stays on one thread across both (the eigen solves limit it anyway):
no thread count changes under the other's dense products.
"""

from __future__ import annotations

import logging
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Callable

log = logging.getLogger(__name__)

__all__ = ["Lines", "harmonic_beside_teeth_mesh", "response_beside_estimate"]


class Lines:
    """Progress lines of a stage run beside another, kept and shown afterwards in the stage order
    (the terminal reads the same whichever finishes first)."""

    def __init__(self):
        self.lines: list[str] = []

    def __call__(self, msg: str) -> None:
        self.lines.append(msg)

    def replay(self, say) -> None:
        for line in self.lines:
            say(line)


def harmonic_beside_teeth_mesh(matched, settings, start_teeth: Callable[[], object]) -> tuple:
    """The harmonic stage and the bolt's unit preload state of ``matched``
    (:class:`results.stage_fe.Matched`) with the losses and voltage of ``settings``
    (:class:`results.pipeline.PipelineSettings`), in worker threads, while ``start_teeth()``
    runs in this thread. Returns ``(Harmonic, unit preload state or the error of a design
    without a bolt to model, what start_teeth returned)``."""
    from .operating_point import preload_unit
    from .stage_harmonic import harmonic_stage

    with ThreadPoolExecutor(max_workers=2, thread_name_prefix="harmonic") as pool:
        harm = pool.submit(harmonic_stage, matched, loss=settings.losses().loss_model(), voltage=settings.voltage)
        unit = pool.submit(preload_unit, matched.system)
        teeth = start_teeth()
        return harm.result(), unit.result(), teeth


def response_beside_estimate(run, clock, unit) -> tuple[Lines, Lines, object]:
    """The bolt's preload window, the operating quantities, the band response and the working
    point's stress state (a worker thread) beside the discretisation-error estimate (this
    thread: its coarse mesh is made by Gmsh, which is started from here), on the pipeline's
    ``run`` (its ``preload``, ``op_fine``, ``resp`` and ``est`` set here, ``run.bolt`` read;
    ``clock`` times the estimate); ``unit``: :func:`results.operating_point.preload_unit` of
    the run's system.

    The estimate meshes, assembles and solves the tuned design afresh on the coarser mesh; of the
    bolt it needs only the force (``run.bolt``). Returns the progress lines of the worker (the
    preload window's) and of the estimate, to be shown in the stage order, and the stress state
    without its error estimates (:func:`fem.stress_state.working_point_state`, for
    :func:`results.stress_stage.stress_stage`).
    """
    from fem.operating_errors import CoarseOperatingPoint, operating_quantities
    from fem.solvers import blas_threads
    from fem.stress_state import working_point_state

    from .errors import estimate_stage
    from .operating_point import preload_stage
    from .stage_harmonic import response_stage
    from .stress_stage import coarse_hook

    st, m, h = run.settings, run.matched, run.harm
    beside, lines = Lines(), Lines()
    loss = st.losses().loss_model()

    def response():
        _, run.preload = preload_stage(m.design, m.system, h.wp, say=beside, unit=unit)     # the window
        run.op_fine = operating_quantities(m.system, h.wp, loss)     # what the window and the heat scale with
        run.resp = response_stage(h, m.f_a_hz, voltage=st.voltage, band=st.band, n_points=st.n_points)
        return working_point_state(m.system, h.wp, run.bolt, m.options.label(m.design))

    with blas_threads(1), ThreadPoolExecutor(max_workers=1, thread_name_prefix="response") as pool:
        job = pool.submit(response)
        t0 = time.perf_counter()          # one solve on a 1.4x coarser mesh: the error of every FE output
        run.est = estimate_stage(m.design, m.options, st, m.system, m.modal, m.w, h.wp, h.surfaces,
                                 float(m.design.target_frequency), lines,
                                 extra=CoarseOperatingPoint(loss, coarse_hook(h.wp.voltage, run.bolt)))
        clock.took("discretisation_error_s", t0)
        state = job.result()
    return beside, lines, state
