"""The pipeline's pictures and VTUs, drawn and written in a worker process while the pipeline
goes on (:class:`Renders`)."""

from __future__ import annotations

from pathlib import Path

__all__ = ["Renders", "render_files"]


class Renders:
    """The pictures and VTUs, drawn and written in a worker process while the pipeline goes on
    (``with`` block; :meth:`collect` waits): the stress picture and VTU (:meth:`submit`, from the
    stress stage), then the mode-shape PNGs of the working mode and its neighbours and the VTU
    with every mode (:meth:`modes`). ``run`` is the pipeline's record of the run (its settings,
    matched system and output folder; the mode files are put into it).

    Rendering (VTK) and the VTUs' compression are single-threaded and the impact kernels hold the
    interpreter, so a thread would not overlap them; a process does. It is started fresh
    (``spawn``: no forked MKL or OpenGL state) and given the whole drill's meshes and fields; its
    files are the same whichever finishes first.
    """

    def __init__(self, run):
        self.run, self.pool, self.jobs, self.mode_job = run, None, [], None

    def __enter__(self) -> "Renders":
        return self

    def submit(self, fn, *args) -> None:
        """Run ``fn(*args)`` in the worker (started at the first job)."""
        if self.pool is None:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor

            self.pool = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"))
        self.jobs.append(self.pool.submit(fn, *args))

    def modes(self) -> None:
        """Submit the mode-shape renders and VTU (the whole drill on the sector path)."""
        run = self.run
        if not run.settings.render:
            return
        from fem.render import around
        from fem.sector_system import SectorSystem

        m = run.matched
        mesh, shapes = m.mesh, m.modal.shapes
        if isinstance(m.system, SectorSystem):          # the sector's modes shown on the whole drill
            mesh, shapes = m.system.whole_mesh()[0], m.system.whole_shapes(m.modal.vectors)
        idx = around(m.w, m.modal.n_modes, 2)
        self.submit(render_files, mesh, shapes, run.out, idx, m.modal.f_r_hz, m.modal.labels)
        self.mode_job = self.jobs[-1]

    def collect(self) -> None:
        """Wait for every file; the mode files go into the run (an error in the worker is raised here)."""
        for job in self.jobs:
            job.result()
        if self.mode_job is not None:
            self.run.renders, self.run.vtu = self.mode_job.result()

    def __exit__(self, *exc) -> None:
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)


def render_files(mesh, shapes, out: Path, modes, frequencies, labels) -> tuple[list, Path]:
    """``(PNG paths, VTU path)``: ``modes`` rendered into ``out/renders`` and every mode written
    to ``out/modes.vtu`` (the worker of :class:`Renders`)."""
    from fem.render import render_modes, write_modes_vtu

    pngs = render_modes(mesh, shapes, out / "renders", modes=modes, frequencies=frequencies, labels=labels)
    return pngs, write_modes_vtu(mesh, shapes, out / "modes.vtu", frequencies=frequencies)
