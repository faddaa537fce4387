"""The stress state of a harmonic working point: the utilisation table, its node fields and files.

One function for every caller (the pipeline's stress stage, ``python -m fem.harmonic --stress``),
so that a design gives one table whichever command runs it: the dynamic field of the working
point, the bolt's static field added, the peaks of :func:`fem.stress_table.stress_table` with the
two-mesh estimate of the discretisation-error stage's coarse table
(:func:`fem.stress_converged.with_error`), on the system that ran. On the ``k = 0`` sector
(:class:`fem.sector_system.SectorSystem`) the recovery completes the sector's field itself
(:meth:`~fem.sector_system.SectorSystem.displacement`), and the picture and the VTU show the
whole drill replicated from the sector (:func:`fem.stress_output.whole_drill_fields`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["WorkingPointStress", "working_point_stress", "working_point_state", "with_estimate"]


@dataclass(frozen=True)
class WorkingPointStress:
    """What :func:`working_point_stress` returns.

    Attributes
    ----------
    system : fem.assembly.PiezoSystem
        The system that ran (a :class:`fem.sector_system.SectorSystem` on the sector path).
    recovery : fem.stress.StressRecovery
        Its gradient tables (reused for the preload window and the band sweep).
    dynamic : fem.stress.StressField
        The working point's harmonic field (Pa, V/m phasors).
    static : fem.stress.StressField or None
        The bolt's static field (None without a preload).
    table : fem.stress_table.StressTable
        The utilisation table, each row with its error estimate (the note says which).
    mesh : str
        The mesh that ran, in words (:func:`fem.sector_system.system_label` unless given).
    """

    system: Any
    recovery: Any
    dynamic: Any
    static: Any
    table: Any
    mesh: str

    @property
    def preload_n(self) -> float:
        """The bolt preload in the state, N (0: none)."""
        return float(self.table.preload_n)

    def write_files(self, png: Path | None, vtu: Path | None, state: str) -> dict:
        """The von Mises picture ``png`` (titled with ``state`` and the metal peak, marked) and
        the node fields ``vtu`` (von Mises, principal extremes, ``|E|`` over the cycle), on the
        whole drill; either may be None (not written). Returns ``{"png": path, "vtu": path}``."""
        write, args = self.file_job(png, vtu, state)
        return write(*args)

    def file_job(self, png: Path | None, vtu: Path | None, state: str) -> tuple:
        """``(write, args)``: :meth:`write_files` as a picklable function and its arguments (the
        whole drill's mesh and node fields, made here), so a caller can draw and write the files
        in a worker process; ``write(*args)`` returns what :meth:`write_files` returns."""
        from .stress_output import node_fields, peak_title, whole_drill_fields, write_stress_files

        mesh, fields = whole_drill_fields(self.system, node_fields(self.dynamic, self.static))
        title, mark = peak_title(state, self.table)
        return write_stress_files, (mesh, fields, png, vtu, title, mark)


def working_point_stress(system, wp, preload=None, est=None, mesh: str | None = None) -> WorkingPointStress:
    """The stress state of the working point ``wp`` (:class:`fem.harmonic.WorkingPoint`, its
    solution ``wp.x`` on ``system``) with the bolt's static state ``preload``
    (:class:`fem.preload.PreloadState` solved on ``system``, or None; a zero force adds none).

    ``est``: the discretisation-error estimate (:class:`fem.errors.ErrorEstimate`) run with the
    hook :class:`fem.stress_converged.CoarseTable` of this state: every row gets its two-mesh
    estimate; None: the single-mesh estimate, said in the table's note. ``mesh``: the mesh in
    words (default :func:`fem.sector_system.system_label`)."""
    return with_estimate(working_point_state(system, wp, preload, mesh), est)


def working_point_state(system, wp, preload=None, mesh: str | None = None) -> WorkingPointStress:
    """:func:`working_point_stress` without the rows' error estimates (same arguments but
    ``est``): the fields and the peaks, the costly part, which need no coarse mesh, so a caller
    can compute them while its discretisation-error estimate runs; :func:`with_estimate` then
    adds the estimates."""
    from .sector_system import system_label
    from .stress import StressRecovery
    from .stress_table import stress_table

    rec = StressRecovery(system)
    dyn = rec.field(wp.x)
    static = preload.field(rec) if preload is not None and preload.force_n > 0 else None
    force = float(preload.force_n) if static is not None else 0.0
    table = stress_table(dyn, static, freq_hz=wp.freq_hz, voltage=wp.voltage, preload_n=force)
    return WorkingPointStress(system, rec, dyn, static, table, mesh or system_label(system))


def with_estimate(state: WorkingPointStress, est) -> WorkingPointStress:
    """``state`` (:func:`working_point_state`) with every row's error estimate: the two-mesh one
    of ``est`` (as in :func:`working_point_stress`), or the single-mesh one (None)."""
    from .stress_converged import with_error

    return dataclasses.replace(state, table=with_error(state.table, est))
