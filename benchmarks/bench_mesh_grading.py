"""Graded mesh (``grade=True``, ``--grade``) against the ungraded default, same run, same machine.

For the default design and for it without slots and teeth (whose converged working mode is
known: f_r 19 682.31 Hz, f_a 21 410.33 Hz, issue 19), prints DOFs, meshing and modal time
(12 modes near 20 kHz, short and open circuit, as ``python -m fem.modal``) and the working
mode's f_r / f_a (with the error against the axisymmetric answer where it is known).

    python benchmarks/bench_mesh_grading.py [--quick]   # --quick: the axisymmetric design only
"""

from __future__ import annotations

import argparse
import time

import geometry
from _table import print_table
from fem.assembly import assemble
from fem.modal import modal_analysis, working_mode
from geometry.design_rpud import default_design

F_R, F_A = 19682.31, 21410.33


def run(design, graded: bool):
    t0 = time.perf_counter()
    mesh = geometry.build_mesh(design, grade=graded)
    t1 = time.perf_counter()
    s = assemble(mesh)
    res = modal_analysis(s, 20e3, 12)
    t2 = time.perf_counter()
    w = working_mode(s, res.f_r_hz, res.vectors, 20e3)
    return s.ndof, t1 - t0, t2 - t1, float(res.f_r_hz[w]), float(res.f_a_hz[w])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    d = default_design()
    designs = [("no slots/teeth", d.replace({"coupler.n_slots": 0, "coupler.n_teeth": 0}), True)]
    if not args.quick:
        designs.append(("default", d, False))
    rows = []
    for name, design, known in designs:
        for graded in (False, True):
            n, tm, tmod, fr, fa = run(design, graded)
            err = f"{100 * (fr / F_R - 1):+.3f} % / {100 * (fa / F_A - 1):+.3f} %" if known else "-"
            rows.append((f"{name}, {'graded (--grade)' if graded else 'ungraded (default)'}",
                         f"{n:,}", f"{tm:.1f}", f"{tmod:.1f}", f"{fr:.2f} / {fa:.2f}", err))
    print_table(rows, headers=("mesh", "DOFs", "mesh s", "modal s (assembly + 12 modes)", "f_r / f_a Hz",
                               "vs axisymmetric"))


if __name__ == "__main__":
    main()
