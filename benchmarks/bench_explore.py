"""Design-study throughput: Dask (local cluster, one process per core) against the best
hand-scheduled sequential loop over the same points in one process (same stage functions, each
unique mesh / FE analysis computed once, BLAS and PARDISO free to use every core).

The study: the default drill as built (no matching), four slot angles x two free masses, stages
mesh -> modal -> harmonic -> impact statistics (5 % CI rule): four FE chains and eight impact
points. Target (issue): Dask throughput within 15 % of the sequential loop, or better.

    python benchmarks/bench_explore.py [--quick]
"""

import argparse
import os
import tempfile
import time
from pathlib import Path

from _table import print_table

from results.explore import explore, run_sequential
from results.study import study_from_mapping


def study(quick: bool):
    angles = [20.0, 40.0] if quick else [15.0, 25.0, 35.0, 45.0]
    return study_from_mapping({
        "study": {"name": "bench", "stages": ["mesh", "match", "harmonic", "impact"], "seed": 1},
        "settings": {"match": False, "rel_tol": 0.05, "max_members": 2048},
        "parameters": {"coupler.slot_angle_deg": {"values": angles},
                       "impact.m_free": {"values": [0.004, 0.008]}}})


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="two slot angles instead of four")
    args = ap.parse_args()
    s = study(args.quick)
    n = len(s.points())
    from impact.kernel import warmup

    warmup()
    t0 = time.perf_counter()
    seq = run_sequential(s, threads=None)
    t_seq = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        res = explore(s, Path(tmp) / "out", workers=os.cpu_count(), figures=False)
    t_dask = res.seconds
    same = all(a["A0_m"] == b["A0_m"] and a["tool_ke_j"] == b["tool_ke_j"] for a, b in zip(seq, res.rows))
    rows = [
        (f"sequential loop, {n} points", f"{t_seq:.1f} s", f"{60 * n / t_seq:.1f} points/min (one process, all cores)"),
        (f"dask LocalCluster, {res.workers} workers", f"{t_dask:.1f} s",
         f"{60 * n / t_dask:.1f} points/min; {t_seq / t_dask:.2f}x the loop's throughput (target >= 0.87x); "
         f"impact numbers identical to the loop: {same}"),
    ]
    print_table(rows)


if __name__ == "__main__":
    main()
