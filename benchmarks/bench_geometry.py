"""Meshing the default RPUD design: chosen settings next to baselines, same run.

Prints one table: seconds (best of ``--repeat``), tetrahedra, nodes, min/median SICN, the worst
part-volume error against the closed form, and whether the 5 s target is met.

    python benchmarks/bench_geometry.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import time

from geometry.builder import build
from geometry.design import default_design
from geometry.report import mesh_part_volumes

CASES = [
    ("chosen: order 2, Delaunay", dict(order=2, algorithm="delaunay")),
    ("baseline: order 1, Delaunay", dict(order=1, algorithm="delaunay")),
    ("baseline: order 2, HXT", dict(order=2, algorithm="hxt")),
    ("baseline: order 2, Delaunay, epw 24", dict(order=2, algorithm="delaunay", elements_per_wavelength=24.0)),
]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    design = default_design()
    closed = design.part_volumes()
    rows = []
    for label, kw in CASES:
        best = float("inf")
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            tm, rep = build(design, **kw)
            best = min(best, time.perf_counter() - t0)
        vols, _ = mesh_part_volumes(tm)
        err = max(abs(vols[p] / closed[p] - 1) for p in closed)
        rows.append((label, best, tm.n_cells, tm.n_points, rep.quality["min_sicn"], rep.quality["median_sicn"], err))
    print(f"{'case':<38} {'s':>6} {'tets':>7} {'nodes':>7} {'min SICN':>9} {'med SICN':>9} {'vol err %':>9} {'< 5 s':>6}")
    for label, t, n, p, qmin, qmed, err in rows:
        print(f"{label:<38} {t:6.2f} {n:7d} {p:7d} {qmin:9.3f} {qmed:9.3f} {err * 100:9.4f} {'yes' if t < 5 else 'no':>6}")


if __name__ == "__main__":
    main()
