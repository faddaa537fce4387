"""Modal analysis (short + open circuit, 12 modes near 20 kHz), side by side in one run.

* today's path: ARPACK (scipy ``eigsh``, one right-hand side per call) for the short circuit,
  then the open circuit from scratch (ARPACK on the bordered operator, same factorisation):
  ``modal_analysis(..., eigen="arpack", open_circuit="scratch")``;
* the new path: block shift-invert Lanczos (``fem.eigen``, block right-hand sides) for the short
  circuit, the open circuit seeded with the short-circuit modes: ``modal_analysis(...)``;

Both paths share the factorisation code; times are the best of ``--repeat`` alternating runs
(the machine is shared: the ratio of the same run is what counts). Meshes: the default design
at its default mesh and a finer one (``--size``, about 4x the DOF; ``--no-fine`` skips it).

Usage: ``python benchmarks/bench_modal.py [--repeat 2] [--size 0.002] [--no-fine]``.
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import geometry  # noqa: E402
from fem.assembly import assemble  # noqa: E402
from fem.modal import modal_analysis  # noqa: E402
from fem.solvers import backend_name  # noqa: E402

NEAR, N_MODES = 20e3, 12


def _run(system, **kw):
    t = time.perf_counter()
    r = modal_analysis(system, NEAR, N_MODES, **kw)
    return time.perf_counter() - t, r


def _case(label, mesh, repeat):
    system = assemble(mesh)
    best = {"old": (np.inf, None), "new": (np.inf, None)}
    for _ in range(repeat):
        for key, kw in (("old", dict(eigen="arpack", open_circuit="scratch")), ("new", {})):
            t, r = _run(system, **kw)
            if t < best[key][0]:
                best[key] = (t, r)
    (t_old, r_old), (t_new, r_new) = best["old"], best["new"]
    d_r = float(np.max(np.abs(r_new.f_r_hz / r_old.f_r_hz - 1)))
    d_a = float(np.nanmax(np.abs(r_new.f_a_hz / r_old.f_a_hz - 1)))

    def split(r):
        t = r.timings
        return f"{t['factorisation_s']:.2f} / {t['eigen_short_s']:.2f} / {t['eigen_open_s']:.2f}"

    row = (f"| {label} | {system.ndof} | {t_old:.2f} ({split(r_old)}) | {t_new:.2f} ({split(r_new)}) | "
           f"{t_old / t_new:.2f}x | {d_r:.1e} | {d_a:.1e} |")
    return row, system, r_new, t_new


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--size", type=float, default=0.002, help="mesh size (m) of the finer mesh")
    ap.add_argument("--no-fine", action="store_true")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    backend_name()                                   # load PARDISO/MKL before any timing
    design = geometry.default_design()
    rows = []
    mesh0 = geometry.build_mesh(design)
    row, *_ = _case("default design, default mesh", mesh0, args.repeat)
    rows.append(row)
    print(row, flush=True)
    if not args.no_fine:
        mesh1 = geometry.build_mesh(design, mesh_size=args.size)
        if 3 * len(mesh1.points) > 300_000:
            print(f"finer mesh skipped: {3 * len(mesh1.points)} displacement DOF > 300k (memory budget)")
        else:
            row, *_ = _case(f"default design, mesh size {args.size * 1e3:g} mm", mesh1, max(1, args.repeat - 1))
            rows.append(row)
            print(row, flush=True)
    print()
    print("| case | DOF | today's path s (factorise / SC eigen / OC eigen) | new path s (same split) "
          "| speed-up | max rel. diff f_r | max rel. diff f_a |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(r)

    return 0


if __name__ == "__main__":
    sys.exit(main())
