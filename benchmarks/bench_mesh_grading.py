"""Swept and graded meshes against the ungraded free mesh, same run, same machine.

For the default design and for it without slots and teeth (whose converged working mode is
known: f_r 19 682.31 Hz, f_a 21 410.33 Hz, tests/axisym_reference.py), prints DOFs, meshing and modal time
(12 modes near 20 kHz, short and open circuit, as ``python -m fem.modal``) and the working
mode's f_r / f_a (with the error against the axisymmetric answer where it is known).

Also the swept mesher (``mesher="revolve"``, geometry/revolve.py) on both designs, and the free
default solved with the reference modal path (ARPACK one vector at a time, open circuit from
scratch) in this process. The whole-process comparison (``python -m fem.modal`` of a baseline
commit against this checkout's) is benchmarks/bench_modal_cli.py.

    python benchmarks/bench_mesh_grading.py [--quick] [--study]
    # --quick: the axisymmetric design only; --study: also the finer grading rules of the
    # grading study (geometry.sizing's knobs) on the axisymmetric design, up to ~260k DOFs (minutes)
"""

from __future__ import annotations

import argparse
import contextlib
import time

import geometry
import geometry.sizing as sizing
from _table import print_table
from fem.assembly import assemble
from fem.modal import modal_analysis, working_mode
from geometry.design_rpud import default_design

F_R, F_A = 19682.31, 21410.33

STUDY = (
    ("graded, edge 0.12 x region size", dict(EDGE_FRACTION=0.12)),
    ("graded, growth 0.35", dict(GROWTH=0.35)),
    ("graded, edge 0.04", dict(EDGE_FRACTION=0.04)),
    ("graded, edge 0.04, bore edges 0.08, growth 0.4", dict(EDGE_FRACTION=0.04, GRADE_BORES=True, GROWTH=0.4)),
)
"""Finer grading rules (geometry.sizing's study knobs) measured against the axisymmetric answer."""


@contextlib.contextmanager
def knobs(**values):
    old = {k: getattr(sizing, k) for k in values}
    try:
        for k, v in values.items():
            setattr(sizing, k, v)
        yield
    finally:
        for k, v in old.items():
            setattr(sizing, k, v)


def run(design, graded: bool, mesher: str = "free", old: bool = False):
    t0 = time.perf_counter()
    mesh = geometry.build_mesh(design, grade=graded, mesher=mesher)
    t1 = time.perf_counter()
    s = assemble(mesh)
    res = modal_analysis(s, 20e3, 12, eigen="arpack") if old else modal_analysis(s, 20e3, 12)
    t2 = time.perf_counter()
    w = working_mode(s, res.f_r_hz, res.vectors, 20e3)
    return s.ndof, t1 - t0, t2 - t1, float(res.f_r_hz[w]), float(res.f_a_hz[w])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--study", action="store_true")
    args = ap.parse_args()
    d = default_design()
    designs = [("no slots/teeth", d.replace({"coupler.n_slots": 0, "coupler.n_teeth": 0}), True)]
    if not args.quick:
        designs.append(("default", d, False))
    rows = []
    for name, design, known in designs:
        cases = [("free, ungraded (library default)", False, "free", False),
                 ("free, graded (--grade)", True, "free", False),
                 ("swept (--mesher revolve, the command lines' default)", False, "revolve", False)]
        if not known:
            cases.insert(0, ("free, ungraded, earlier modal path (ARPACK)", False, "free", True))
            cases.append(("swept, notch edges graded (--mesher revolve --grade)", True, "revolve", False))
        for label, graded, mesher, old in cases:
            n, tm, tmod, fr, fa = run(design, graded, mesher, old)
            err = f"{100 * (fr / F_R - 1):+.3f} % / {100 * (fa / F_A - 1):+.3f} %" if known else "-"
            rows.append((f"{name}, {label}", f"{n:,}", f"{tm:.1f}", f"{tmod:.1f}", f"{fr:.2f} / {fa:.2f}", err))
    if args.study:
        design = designs[0][1]
        for name, values in STUDY:
            with knobs(**values):
                n, tm, tmod, fr, fa = run(design, True)
            rows.append((f"no slots/teeth, {name}", f"{n:,}", f"{tm:.1f}", f"{tmod:.1f}", f"{fr:.2f} / {fa:.2f}",
                         f"{100 * (fr / F_R - 1):+.3f} % / {100 * (fa / F_A - 1):+.3f} %"))
    print_table(rows, headers=("mesh", "DOFs", "mesh s", "modal s (assembly + 12 modes)", "f_r / f_a Hz",
                               "vs axisymmetric"))


if __name__ == "__main__":
    main()
