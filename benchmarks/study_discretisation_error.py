"""The default design's discretisation error: a refinement study against the cheap two-level estimate.

Levels (ungraded unless ``--grade``): refine 1.4 (the estimator's coarse mesh), 1 (the default
mesh), 0.8, 0.64 (~160k DOFs, below the 250k budget of one run). Each level meshes the design,
computes the working mode's f_r, f_a, k_eff (modal), the horn-tip amplitude per volt and the
teeth ellipse ratio (direct harmonic solve at the level's own f_r, Q = 100: the pipeline's
setting), as :func:`fem.convergence.working_mode_level`. Prints the study table (observed order,
Richardson estimate and error of the finest level, :class:`fem.convergence.ConvergenceStudy`)
and, for the default mesh (refine 1), the two-level estimate (:mod:`fem.errors`, one solve at
refine 1.4) next to the difference from the finest level and from the study's extrapolation.

    python benchmarks/study_discretisation_error.py [--grade] [--levels 1.4,1,0.8,0.64] [--json OUT]

A long study (minutes): not a test. The README's convergence table comes from it.
"""

from __future__ import annotations

import argparse
import json
import time

from fem.convergence import ConvergenceStudy, working_mode_level
from fem.errors import QUANTITIES, estimate_from_levels
from geometry.design import default_design


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grade", action="store_true")
    ap.add_argument("--levels", default="1.4,1,0.8,0.64")
    ap.add_argument("--json", metavar="OUT")
    args = ap.parse_args()
    refines = [float(v) for v in args.levels.split(",")]
    d = default_design()
    levels = []
    for F in refines:
        t0 = time.perf_counter()
        lev = working_mode_level(d, F, grade=args.grade)
        levels.append(lev)
        print(f"refine {F:.3f}: {lev.ndof} DOFs, {lev.values} ({time.perf_counter() - t0:.1f} s)", flush=True)
    st = ConvergenceStudy(tuple(levels[1:]) if len(levels) > 3 else tuple(levels))
    print(st.table())
    by = {lev.refine: lev for lev in levels}
    out = {"grade": args.grade, "levels": [{"refine": l.refine, "ndof": l.ndof, "seconds": l.seconds, **l.values}
                                           for l in levels], "study": st.to_dict()}
    if 1.0 in by and 1.4 in by:
        est = estimate_from_levels(by[1.0], by[1.4], grade=args.grade, corners=True)
        finest = levels[-1]
        print(f"\ntwo-level estimate at refine 1 ({by[1.0].ndof} DOFs) from refine 1.4 ({by[1.4].ndof} DOFs), "
              f"order {est.order:g}, h ratio {est.ratio:.3f}:")
        print(f"{'quantity':>22} {'refine 1':>14} {'estimate':>12} {'|q1 - finest|':>14} {'|q1 - Richardson|':>18}")
        for q in QUANTITIES:
            if q not in est.errors or q not in finest.values:
                continue
            q1 = by[1.0].values[q]
            rich = st.richardson(q) if len(st.levels) >= 3 and q in st.quantities else float("nan")
            print(f"{q:>22} {q1:14.6g} {est.errors[q]:12.4g} {abs(q1 - finest.values[q]):14.4g} {abs(q1 - rich):18.4g}")
        out["two_level_at_refine_1"] = est.to_dict()
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=1, default=float)


if __name__ == "__main__":
    main()
