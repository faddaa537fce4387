"""Cyclic symmetry (fem.cyclic) against the whole drill, side by side in one run.

1. Speed, same mesh: the default design's 60-degree sector (free mesh, ``--refine``) and the
   whole drill replicated from it (geometry.sector.replicate), the stack in PZT-4 so that the
   drill is exactly 6-fold symmetric. Baseline: ``modal_analysis`` of the whole drill, 16 modes
   near 15 kHz with anti-resonances. New: ``cyclic_modes`` of the sector, 8 modes of each
   harmonic k = 0 .. 3 (they hold those 16 and more). Printed: best-of ``--repeat`` times and
   the largest relative difference of the whole drill's 16 resonances from the harmonics'.
2. Accuracy per cost (``--study``): the design without slots and teeth, k = 0 (f_r, f_a,
   torsion) and k = 1 (first bending pair) of free and graded sector meshes at several
   ``refine``, against the converged (r, z) answers of issue 19 (tests/axisym_reference.py).

Usage: ``python benchmarks/bench_cyclic.py [--refine 1.0] [--repeat 2] [--study]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _table import best_of, print_table  # noqa: E402

from fem.assembly import assemble  # noqa: E402
from fem.cyclic import cyclic_modes, harmonics  # noqa: E402
from fem.modal import modal_analysis  # noqa: E402
from geometry.builder import build  # noqa: E402
from geometry.design import default_design  # noqa: E402
from geometry.sector import replicate  # noqa: E402

REFERENCE = {"f_r": 19682.31, "f_a": 21410.33, "torsion": 15286.16, "bending": 5161.55}
"""Converged (r, z) answers of the default design without slots and teeth (Hz; README, issue 19)."""


def speed(refine: float, repeat: int) -> None:
    d = default_design()
    d = dataclasses.replace(d, stack=dataclasses.replace(d.stack, material="PZT-4"))
    tm, _ = build(d, mesher="free", sectors=6, refine=refine)
    whole, _ = replicate(tm, 6)
    sw, ss = assemble(whole), assemble(tm)
    box = {}

    def full():
        box["full"] = modal_analysis(sw, 15000.0, 16)

    def cyc():
        box["cyc"] = {k: cyclic_modes(ss, 6, k, 15000.0, 8) for k in harmonics(6)}

    t_full = best_of(full, repeat)
    t_cyc = best_of(cyc, repeat)
    f = np.concatenate([m.f_hz for m in box["cyc"].values()])
    diff = max(np.abs(f - x).min() / x for x in box["full"].f_r_hz)
    print(f"\nSame mesh: the whole drill {sw.ndof} DOFs, its sector {ss.ndof} DOFs (refine {refine})\n")
    print_table([("whole drill: modal_analysis, 16 modes + anti-resonances", f"{t_full:.2f} s", "baseline"),
                 ("sector: cyclic_modes k = 0..3, 8 modes each (k = 0 with anti-resonances)", f"{t_cyc:.2f} s",
                  f"{t_full / t_cyc:.1f}x; largest difference {diff:.1e}")])


def study() -> None:
    d = default_design()
    d = dataclasses.replace(d, coupler=dataclasses.replace(d.coupler, n_slots=0, n_teeth=0))
    rows = []
    for grade in (False, True):
        for refine in (1.0, 0.7, 0.5):
            tm, _ = build(d, mesher="free", sectors=6, refine=refine, grade=grade)
            s = assemble(tm)
            k0 = cyclic_modes(s, 6, 0, 17000.0, 4)
            k1 = cyclic_modes(s, 6, 1, 5000.0, 1)
            i, j = np.argmin(abs(k0.f_hz - 19700)), np.argmin(abs(k0.f_hz - 15300))
            err = [k0.f_hz[i] / REFERENCE["f_r"] - 1, k0.f_open_hz[i] / REFERENCE["f_a"] - 1,
                   k0.f_hz[j] / REFERENCE["torsion"] - 1, k1.f_hz[0] / REFERENCE["bending"] - 1]
            rows.append((f"{'graded' if grade else 'free'}, refine {refine}", f"{k0.ndof} / {k1.ndof}",
                         *[f"{100 * e:+.3f} %" for e in err],
                         f"{k0.timings['total_s']:.1f} / {k1.timings['total_s']:.1f} s"))
    print("\nDesign without slots and teeth, 60-degree sector, against the converged (r, z) answers\n")
    print_table(rows, ("sector mesh", "unknowns k=0 / k=1", "f_r", "f_a", "1st torsion", "1st bending",
                       "solve k=0 / k=1"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--refine", type=float, default=1.0)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--study", action="store_true", help="also the accuracy study (~1 min)")
    a = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    speed(a.refine, a.repeat)
    if a.study:
        study()
    return 0


if __name__ == "__main__":
    sys.exit(main())
