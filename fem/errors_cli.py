"""What the command lines print and write about discretisation errors (:mod:`fem.errors`,
:mod:`fem.convergence`): the ``±`` lines of ``--error`` and the ``--converge TOL`` study run.

Shared by ``python -m fem.modal`` and ``python -m fem.harmonic`` so both state errors the same way.
"""

from __future__ import annotations

import math
from typing import Callable

from .errors import ErrorEstimate, plus_minus

__all__ = ["error_lines", "run_study", "MODE_KEYS", "POINT_KEYS"]

MODE_KEYS = {"f_r_hz": "f_r_hz", "f_a_hz": "f_a_hz", "k_eff": "k_eff"}
"""Keys of a working-mode record and the quantity whose error each carries (:func:`fem.errors.annotate`)."""

POINT_KEYS = {"tip_per_volt_m": "tip_per_volt_m", "tip_amplitude_m": "tip_per_volt_m",
              "teeth_ellipse_ratio": "teeth_ellipse_ratio"}
"""Keys of a harmonic working-point record (:meth:`fem.harmonic.WorkingPoint.to_dict`) and their quantities."""


def error_lines(est: ErrorEstimate, *, tip_surface: str = "horn_tip", voltage: float | None = None,
                teeth: str = "teeth ellipse ratio") -> list[str]:
    """The ``±`` lines of an estimate: f_r, f_a, k_eff; the tip amplitude per volt (and at
    ``voltage``); the teeth ellipse ratio; the method last."""
    v, e = est.values, est.error
    lines = ["estimated discretisation error:",
             f"  f_r {plus_minus(v['f_r_hz'], e('f_r_hz'), 'Hz')}, f_a {plus_minus(v['f_a_hz'], e('f_a_hz'), 'Hz')}, "
             f"k_eff {plus_minus(v['k_eff'], e('k_eff'))}"]
    more = []
    if "tip_per_volt_m" in v:
        tip = f"{tip_surface} {plus_minus(v['tip_per_volt_m'], e('tip_per_volt_m'), 'nm/V', 1e9)}"
        if voltage is not None:
            a = v["tip_per_volt_m"] * voltage
            tip += f" ({plus_minus(a, est.scaled('tip_per_volt_m', a), 'um', 1e6)} at {voltage:g} V)"
        more.append(tip)
    if "teeth_ellipse_ratio" in v and math.isfinite(v["teeth_ellipse_ratio"]):
        more.append(f"{teeth} {plus_minus(v['teeth_ellipse_ratio'], e('teeth_ellipse_ratio'))}")
    if more:
        lines.append("  " + "; ".join(more))
    lines.append(f"  ({est.method})")
    return lines


def run_study(args, design, near: float, level: Callable[[float], object], describe: Callable[[object], str],
              record: dict) -> int:
    """``--converge TOL``: the refinement study from ``--refine`` (0.8 per level) within the DOF
    budget; prints each level (``describe(level)``) and the table, writes ``record`` +
    ``convergence`` to ``--json``. Exit status 0 if converged, else 1."""
    from rpud_common import atomic_write_text, json_text
    from geometry.guard import MAX_DOFS, estimate, sector_estimate
    from geometry.options import mesher_of
    from geometry.sector import symmetry_order

    from .convergence import study

    mesher = mesher_of(args, design)
    path = getattr(args, "fe_path", "whole")

    def size(F):
        if path == "sector":
            return sector_estimate(design, symmetry_order(design) or 6, args.mesh_size, F).dofs
        return estimate(design, args.mesh_size, getattr(args, "order", 2), refine=F, grade=args.grade,
                        mesher=mesher).dofs

    def run(refine):
        lev = level(refine)
        print(f"  refine {refine:.4f}: {lev.ndof} DOFs, {describe(lev)} ({lev.seconds:.1f} s)", flush=True)
        return lev

    st = study(run, tol=args.converge, start=args.refine,
               estimate_dofs=size, max_dofs=None if args.allow_large else MAX_DOFS)
    print(st.table())
    if args.json:
        atomic_write_text(args.json, json_text({**record, "mesh_size": args.mesh_size, "grade": args.grade, "mesher": mesher,
                                                "path": path, "convergence": st.to_dict()}, nonfinite="null"))
    return 0 if st.converged else 1
