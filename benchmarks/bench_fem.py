"""Benchmarks of the piezo-elastic FE core, side by side in one run.

1. Assembly at ~100k DOFs (default design, refined mesh): our vectorised assembly (median of
   three runs) against a plain scikit-fem ``BilinearForm`` assembly of the same coupled system
   (one run; same quadrature; target 10x). scikit-fem is imported before either is timed.
2. Factorisation of ``K - sigma M`` (short circuit, sigma = (2 pi 20 kHz)^2): PARDISO against
   scipy's default ``splu`` (target 5x).
3. End to end: modal analysis (assembly + 12 modes near 20 kHz, short + open circuit) of the
   default design at its default mesh (target < 15 s on 2 cores).
4. Mesh convergence of the working longitudinal mode of the default design (default sizes:
   11 mm in horn/coupler, capped by ring/slot/tooth features -> uniform 4 mm -> 2.6 mm).

Usage: ``python benchmarks/bench_fem.py [--quick] [--skip-splu] [--no-convergence]``.
``--quick`` uses the default mesh for 1-2 (about 55k DOFs) and skips the convergence study.
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
from _table import print_table  # noqa: E402
from fem.assembly import assemble  # noqa: E402
from fem.modal import modal_analysis  # noqa: E402
from fem.solvers import factorize  # noqa: E402


def _mesh(size):
    d = geometry.default_design()
    t = time.perf_counter()
    tm = geometry.build_mesh(d, mesh_size=size)
    return tm, time.perf_counter() - t


def _working_mode(res):
    i = int(np.argmax(res.shares[:, 0] * (res.k_eff > 0.05)))
    return res.f_r_hz[i], res.f_a_hz[i], res.k_eff[i]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--skip-splu", action="store_true", help="do not run scipy's default splu")
    ap.add_argument("--no-convergence", action="store_true")
    ap.add_argument("--size", type=float, default=0.0026,
                    help="mesh size (m) of the ~100k-DOF mesh (default 0.0026)")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    rows = []

    # ---------------------------------------------------------------- 1. assembly
    size = None if args.quick else args.size
    tm, t_mesh = _mesh(size)
    import skfem  # noqa: F401  -- both paths use it: its import time is not assembly time

    runs = []
    for _ in range(3):
        t = time.perf_counter()
        fast = assemble(tm)
        runs.append(time.perf_counter() - t)
    t_fast = float(np.median(runs))
    t = time.perf_counter()
    ref = assemble(tm, reference=True)
    t_ref = time.perf_counter() - t
    t_ref_default = np.nan
    if not args.quick:
        t = time.perf_counter()
        assemble(tm, reference=True, intorder="skfem")
        t_ref_default = time.perf_counter() - t
    diff = max(abs(fast.K - ref.K).max() / abs(ref.K).max(), abs(fast.M - ref.M).max() / abs(ref.M).max())
    print(f"mesh: default design, mesh size {'default' if size is None else f'{size * 1e3:g} mm'}, {tm.n_cells} P2 tetrahedra, "
          f"{fast.ndof} DOFs (meshing {t_mesh:.1f} s)")
    print(f"assembly   ours {t_fast:7.2f} s (median of {', '.join(f'{r:.2f}' for r in runs)}) | "
          f"plain skfem BilinearForm {t_ref:7.2f} s | "
          f"speed-up {t_ref / t_fast:5.1f}x | max rel. difference {diff:.1e}")
    if np.isfinite(t_ref_default):
        print(f"           plain skfem with its default quadrature {t_ref_default:7.2f} s | "
              f"speed-up {t_ref_default / t_fast:5.1f}x")
    del ref

    # ---------------------------------------------------------------- 2. factorisation
    sigma = (2 * np.pi * 20e3) ** 2
    K, M, _ = fast.reduce("short")
    A = (K - sigma * M).tocsr()
    Fp = factorize(A, backend="pardiso")
    b = np.random.default_rng(0).normal(size=A.shape[0])
    t = time.perf_counter()
    xp = Fp(b)
    t_solve = time.perf_counter() - t
    res_p = np.linalg.norm(A @ xp - b) / np.linalg.norm(b)
    line = (f"factorise  PARDISO {Fp.seconds:7.2f} s (solve {t_solve * 1e3:.0f} ms, residual {res_p:.0e})")
    t_lu = np.nan
    if not args.skip_splu:
        import scipy.sparse.linalg as spla

        t = time.perf_counter()
        lu = spla.splu(A.tocsc())          # scipy's default: COLAMD column ordering
        t_lu = time.perf_counter() - t
        res_l = np.linalg.norm(A @ lu.solve(b) - b) / np.linalg.norm(b)
        line += f" | scipy splu {t_lu:7.2f} s (residual {res_l:.0e}) | speed-up {t_lu / Fp.seconds:5.1f}x"
        del lu
    print(line)
    rows.append((fast.ndof, t_fast, t_ref, t_ref_default, Fp.seconds, t_lu))
    del Fp, A, K, M, fast

    # ---------------------------------------------------------------- 3. end to end
    tm0, t_mesh0 = _mesh(None)
    t = time.perf_counter()
    s0 = assemble(tm0)
    res = modal_analysis(s0, 20e3, 12)
    t_e2e = time.perf_counter() - t
    tt = res.timings
    fr, fa, k = _working_mode(res)
    print(f"end to end default design: {res.ndof} DOFs, assembly {tt['assembly_s']:.2f} s, "
          f"factorisation {tt['factorisation_s']:.2f} s, eigen {tt['eigen_s']:.2f} s "
          f"(short + open circuit, 12 pairs), total {t_e2e:.2f} s [{res.backend}] "
          f"(+ meshing {t_mesh0:.2f} s)")
    print(f"  working longitudinal mode: f_r {fr:.1f} Hz, f_a {fa:.1f} Hz, k_eff {k:.4f}")

    # ---------------------------------------------------------------- 4. convergence
    if not (args.quick or args.no_convergence):
        print("mesh convergence of the working longitudinal mode (default design):")
        prev = None
        for e in (None, 0.004, 0.0026):
            tm_e, _ = _mesh(e)
            s_e = assemble(tm_e)
            r_e = modal_analysis(s_e, 20e3, 6)
            fr, fa, k = _working_mode(r_e)
            change = "" if prev is None else f"  change f_r {100 * (fr - prev[0]) / prev[0]:+.3f} %, f_a {100 * (fa - prev[1]) / prev[1]:+.3f} %"
            print(f"  size {'default' if e is None else f'{e * 1e3:g} mm':>8} {s_e.ndof:7d} DOFs  f_r {fr:9.1f} Hz  f_a {fa:9.1f} Hz  k_eff {k:.4f}{change}")
            prev = (fr, fa)

    print()
    print_table([(str(n), f"{a:.2f}", f"{r:.2f}", f"{rd:.2f}", f"{f:.2f}", f"{l:.1f}") for n, a, r, rd, f, l in rows],
                ("DOFs", "assembly ours s", "plain skfem (same quadrature) s", "plain skfem (its default quadrature) s",
                 "factorisation PARDISO s", "scipy splu s"))
    print()
    print_table([("default design, 12 modes near 20 kHz (short + open)", str(res.ndof), f"{tt['assembly_s']:.2f}",
                  f"{tt['factorisation_s']:.2f}", f"{tt['eigen_s']:.2f}", f"{t_e2e:.2f}")],
                ("case", "DOFs", "assembly s", "factorisation s", "eigen s", "total s"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
