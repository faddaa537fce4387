"""Meshing the default RPUD design and the bonded sandwich: chosen settings next to baselines, same run.

Prints two tables. Default design: seconds (best of ``--repeat``), tetrahedra, nodes, min/median
SICN, the worst part-volume error against the closed form, and whether the 5 s target is met.
Bonded sandwich (55 mm discs, two 0.275 mm epoxy bonds, ``geometry.examples.bonded_sandwich``):
the structured layers at the default size and one refinement (``refine`` 1/1.5) against the
free tetrahedral mesh the builder made before (its resource-guard estimate; ``--try-free S``
also runs it for up to S seconds, last, since an abandoned Gmsh run ends further builds), and
whether the 15 s target is met.

    python benchmarks/bench_geometry.py [--repeat 3] [--try-free 60]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import geometry.layers
from geometry.builder import build
from geometry.design_rpud import default_design
from geometry.examples import bonded_sandwich
from geometry.guard import estimate
from geometry.report import mesh_part_volumes

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _table import print_table  # noqa: E402

CASES = [
    ("chosen: order 2, Delaunay", dict(order=2, algorithm="delaunay")),
    ("baseline: order 1, Delaunay", dict(order=1, algorithm="delaunay")),
    ("baseline: order 2, HXT", dict(order=2, algorithm="hxt")),
    ("baseline: order 2, Delaunay, epw 24", dict(order=2, algorithm="delaunay", elements_per_wavelength=24.0)),
]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--try-free", type=float, default=None, metavar="S",
                    help="also mesh the sandwich with free tetrahedra, for at most S seconds")
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
    print_table([(label, f"{t:.2f}", str(n), str(p), f"{qmin:.3f}", f"{qmed:.3f}", f"{err * 100:.4f}",
                  "yes" if t < 5 else "no") for label, t, n, p, qmin, qmed, err in rows],
                ("case", "s", "tets", "nodes", "min SICN", "med SICN", "vol err %", "< 5 s"))
    print()
    sandwich(args.repeat, args.try_free)


def sandwich(repeat: int, try_free: float | None) -> None:
    """The bonded sandwich: structured layers vs the free mesh."""
    design = bonded_sandwich()
    closed = design.part_volumes()
    rows = []
    for label, factor in (("chosen: structured layers", 1.0), ("same, one refinement (sizes / 1.5)", 1 / 1.5)):
        best = float("inf")
        for _ in range(repeat):
            t0 = time.perf_counter()
            tm, rep = build(design, refine=factor)
            best = min(best, time.perf_counter() - t0)
        vols, _ = mesh_part_volumes(tm)
        err = max(abs(vols[p] / closed[p] - 1) for p in closed)
        rows.append((label, f"{best:.2f}", str(tm.n_cells), str(tm.n_points), str(rep.quality["layer_elements"]),
                     f"{err * 100:.4f}", "yes" if best < 15 else "no"))
    ratio = geometry.layers.LAYER_RATIO
    geometry.layers.LAYER_RATIO = 0.0  # no layers: the free mesh of the builder before them
    try:
        est = estimate(design)
        rows.append(("baseline: free tetrahedra (guard estimate)", "-", str(est.elements), str(est.nodes), "0",
                     "-", "-"))
        if try_free:
            t0 = time.perf_counter()
            try:
                tm, _ = build(design, time_limit=try_free)
                rows.append(("baseline: free tetrahedra", f"{time.perf_counter() - t0:.2f}", str(tm.n_cells),
                             str(tm.n_points), "0", "-", "no"))
            except Exception as exc:  # noqa: BLE001 - the time limit, reported as a row
                rows.append(("baseline: free tetrahedra", f">{try_free:g}", f"(did not finish: {type(exc).__name__})",
                             "-", "-", "-", "no"))
    finally:
        geometry.layers.LAYER_RATIO = ratio
    print_table(rows, ("bonded sandwich, 55 mm, 2 x 0.275 mm bonds", "s", "tets", "nodes", "layer tets", "vol err %",
                       "< 15 s"))


if __name__ == "__main__":
    main()
