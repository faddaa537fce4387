"""Cyclic symmetry (fem.cyclic) against the whole drill, side by side in one run.

1. Same mesh, speed and agreement: the default design's 60-degree swept sector at the k = 0 rule
   of ``python -m fem.modal`` (``geometry.sector.AXIAL_RULE``, ``--refine``) and the whole drill
   replicated from it (geometry.sector.replicate), the stack in PZT-4 so that the drill is
   exactly 6-fold symmetric. Baseline: ``modal_analysis`` of the whole drill, 12 modes near
   20 kHz with anti-resonances. New: ``cyclic_modes`` of the sector, harmonics 0 and 1 (8 modes
   each; they hold those 12). Printed: best-of ``--repeat`` times and the largest relative
   difference of the whole drill's resonances from the harmonics'.
2. ``--rules``: the command line's rules (AXIAL_RULE for k = 0, LATERAL_RULE for k = 1) on the
   default design and on the design without slots and teeth; the latter against the converged
   (r, z) answers (tests/axisym_reference.py), ~40 s.

Usage: ``python benchmarks/bench_cyclic.py [--refine 1.0] [--repeat 2] [--rules]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _table import best_of, print_table  # noqa: E402

from fem.assembly import assemble  # noqa: E402
from fem.cyclic import cyclic_modes  # noqa: E402
from fem.modal import modal_analysis  # noqa: E402
from geometry.builder import build  # noqa: E402
from geometry.design import default_design  # noqa: E402
from geometry.sector import AXIAL_RULE, LATERAL_RULE, replicate  # noqa: E402

REFERENCE = {"f_r": 19682.31, "f_a": 21410.33, "torsion": 15286.16, "bending": 5161.55}
"""Converged (r, z) answers of the default design without slots and teeth (Hz; tests/axisym_reference.py)."""


def speed(refine: float, repeat: int) -> None:
    d = default_design()
    d = dataclasses.replace(d, stack=dataclasses.replace(d.stack, material="PZT-4"))
    r, meshing = AXIAL_RULE
    tm, _ = build(d, mesher="revolve", sectors=6, refine=r * refine, sector_meshing=meshing.scaled(refine))
    whole, _ = replicate(tm, 6)
    sw, ss = assemble(whole), assemble(tm)
    box = {}

    def full():
        box["full"] = modal_analysis(sw, 20000.0, 12)

    def cyc():
        box["cyc"] = [cyclic_modes(ss, 6, k, 20000.0, 8) for k in (0, 1)]

    t_full = best_of(full, repeat)
    t_cyc = best_of(cyc, repeat)
    f = np.concatenate([m.f_hz for m in box["cyc"]])
    diff = max(np.abs(f - x).min() / x for x in box["full"].f_r_hz)
    print(f"\nSame mesh: the whole drill {sw.ndof} DOFs, its 60-degree sector {ss.ndof} DOFs "
          f"(k = 0 rule at --refine {refine:g}; the whole drill's f_r {min(box['full'].f_r_hz):.0f}-"
          f"{max(box['full'].f_r_hz):.0f} Hz)\n")
    print_table([("whole drill: modal_analysis, 12 modes + anti-resonances", f"{t_full:.2f} s", "baseline"),
                 ("sector: cyclic_modes k = 0 and 1, 8 modes each (k = 0 with anti-resonances)", f"{t_cyc:.2f} s",
                  f"{t_full / t_cyc:.1f}x; largest difference {diff:.1e}")])


def rules() -> None:
    rows = []
    for plain in (False, True):
        d = default_design()
        if plain:
            d = dataclasses.replace(d, coupler=dataclasses.replace(d.coupler, n_slots=0, n_teeth=0))
        got, dofs, secs = {}, [], []
        for (refine, meshing), k, near in ((AXIAL_RULE, 0, 17000.0), (LATERAL_RULE, 1, 5000.0)):
            t0 = time.perf_counter()
            tm, _ = build(d, mesher="revolve", sectors=6, refine=refine, sector_meshing=meshing)
            system = assemble(tm)
            m = cyclic_modes(system, 6, k, near, 4 if k == 0 else 1)
            secs.append(time.perf_counter() - t0)
            dofs.append(system.ndof)
            if k == 0:
                w = np.argmin(abs(m.f_hz - 19800.0))
                got.update(f_r=m.f_hz[w], f_a=m.f_open_hz[w], torsion=m.f_hz[np.argmin(abs(m.f_hz - 15350.0))])
            else:
                got["bending"] = m.f_hz[0]
        cells = [f"{got[key]:.2f}" + (f" ({100 * (got[key] / REFERENCE[key] - 1):+.3f} %)" if plain else "")
                 for key in ("f_r", "f_a", "torsion", "bending")]
        rows.append(("without slots and teeth" if plain else "default design", f"{dofs[0]} / {dofs[1]}", *cells,
                     f"{secs[0]:.1f} / {secs[1]:.1f} s"))
    print("\nThe command line's sector rules (k = 0: AXIAL_RULE, k = 1: LATERAL_RULE); in brackets against the "
          "converged (r, z) answers\n")
    print_table(rows, ("design", "sector DOFs k=0 / k=1", "f_r Hz", "f_a Hz", "1st torsion Hz", "1st bending Hz",
                       "mesh + solve k=0 / k=1"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--refine", type=float, default=1.0)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--rules", action="store_true", help="also the command line's rules against the references")
    a = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    speed(a.refine, a.repeat)
    if a.rules:
        rules()
    return 0


if __name__ == "__main__":
    sys.exit(main())
