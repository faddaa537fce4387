"""The utilisation table with two-mesh error estimates, on the path that ran.

The discretisation-error estimator (:func:`fem.errors.estimate`) already solves the working mode
once more on a mesh :data:`fem.errors.ESTIMATOR_RATIO` times coarser, on the same path (the
``k = 0`` sector or the whole drill). :class:`CoarseTable` is the hook it calls on that coarse
working point: the same state (the drive voltage, the bolt preload) recovered there, as a
:class:`fem.stress_table.StressTable`. :func:`with_error` then gives the fine table each row's
two-mesh (Richardson) estimate (:func:`fem.stress_table.converged_table`, order
:data:`fem.stress_table.STRESS_ORDER` in the ``h`` ratio of the two meshes' DOFs): the filleted
corners' peaks converge, and the rows whose peak sits on a singular edge are estimated on their
off-edge headline. Without a coarse table (no estimate ran) the rows keep the recovered-minus-raw
estimate of :func:`fem.stress_table.stress_table`, and the table's note says so.

Each mesh is at its own working frequency (the coarse mesh's own f_r), as every other two-level
estimate of :mod:`fem.errors`: the peaks compared are those of the working point itself.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from .stress_table import StressTable, converged_table, stress_table

__all__ = ["CoarseTable", "with_error", "ZZ_NOTE"]

ZZ_NOTE = ("error estimates: recovered minus raw element values near each peak (no coarser mesh ran: "
           "a single-mesh indicator, not a two-mesh estimate)")
"""The note of a table whose rows keep the single-mesh estimate."""


@dataclass(frozen=True)
class CoarseTable:
    """``CoarseTable(voltage, preload_n)(system, wp) -> {"stress": StressTable}``: the utilisation
    table of the working point ``wp`` (solved at 1 V on ``system``) scaled to ``voltage`` (V), with
    the bolt preload ``preload_n`` (N, 0: none) added; the ``extra`` hook of
    :func:`fem.errors.estimate`."""

    voltage: float
    preload_n: float = 0.0

    def __call__(self, system, wp) -> dict:
        from .stress import StressRecovery

        rec = StressRecovery(system)         # on a k = 0 sector: the whole drill's recovered field
        static = None
        if self.preload_n > 0:
            from .preload import preload_solve

            static = preload_solve(system, self.preload_n).field(rec)
        table = stress_table(rec.field(wp.x * self.voltage), static, freq_hz=float(wp.freq_hz), voltage=self.voltage,
                             preload_n=self.preload_n)
        return {"stress": table}


def with_error(table: StressTable, est) -> StressTable:
    """``table`` (the mesh that ran) with every row's two-mesh estimate from the coarse table in
    ``est.extra["stress"]`` (``est``: :class:`fem.errors.ErrorEstimate` run with a
    :class:`CoarseTable`; its ``ratio`` is the element-size ratio). Without one (``est`` None or
    no coarse table), ``table`` with :data:`ZZ_NOTE`."""
    coarse = None if est is None else est.extra.get("stress")
    if coarse is None:
        return dataclasses.replace(table, note=ZZ_NOTE + (f"; {table.note}" if table.note else ""))
    out = converged_table(coarse, table, float(est.ratio))
    out.note += (f" (fine {est.ndof} DOFs at refine {est.refine:g}, coarse {est.coarse_ndof} DOFs at refine "
                 f"{est.coarse_refine:g})")
    return out
