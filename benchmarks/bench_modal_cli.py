"""``python -m fem.modal`` on the default design as a whole process: this checkout against the
code of a baseline commit (default ``BASELINE``, whose defaults are the free 68.6k-DOF mesh and
the ARPACK modal path), same run, alternating A B A B.

Each run is a fresh interpreter: imports, meshing, assembly, short- and open-circuit modes (12
near 20 kHz), mode classification and the table, as a user sees it. The baseline runs from a
temporary ``git worktree`` of that commit with this checkout's virtual environment. Prints the
median wall and CPU time of each, their ratio per pair, and the DOFs and working mode each run
reported.

    python benchmarks/bench_modal_cli.py [--runs 3] [--baseline COMMIT] [-- extra fem.modal options]
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _table import print_table

ROOT = Path(__file__).resolve().parents[1]
BASELINE = "e56a14d"
"""The baseline commit: free mesh and ARPACK open circuit from scratch by default, the cost the
swept mesher and the block Lanczos path are measured against."""


def timed(cmd: list[str], cwd: Path) -> tuple[float, float, str]:
    """Wall and CPU seconds (user + sys of the child) of one run, and its standard output."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    env = {**os.environ, "PYTHONPATH": str(cwd)}
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, check=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, proc.stdout


def summary(stdout: str) -> tuple[str, str]:
    """DOFs and the longitudinal mode's f_r / f_a (kHz) from a fem.modal table."""
    dofs = re.search(r"^(\d+) DOFs", stdout, re.M)
    # a cyclic run (fem.cyclic_cli): a harmonic column before f_r, the reduced unknowns per harmonic
    mode = (re.search(r"^\s*\d+\s+0\s+([\d.]+)\s+([\d.]+).*longitudinal", stdout, re.M)
            or re.search(r"^\s*\d+\s+([\d.]+)\s+([\d.]+).*longitudinal", stdout, re.M))
    if dofs is None:
        cyc = re.search(r"reduced unknowns (k=0 \d+), (k=1 \d+)", stdout)
        if cyc:
            return (f"{cyc.group(1)} / {cyc.group(2)} (sector)",
                    f"{float(mode.group(1)) * 1e3:.1f} / {float(mode.group(2)) * 1e3:.1f}" if mode else "?")
    return (f"{int(dofs.group(1)):,}" if dofs else "?",
            f"{float(mode.group(1)) * 1e3:.1f} / {float(mode.group(2)) * 1e3:.1f}" if mode else "?")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3, help="counted runs of each (after one warm-up each)")
    ap.add_argument("--baseline", default=BASELINE, help="commit to compare against")
    ap.add_argument("extra", nargs="*", help="more fem.modal options for this checkout (after --)")
    args = ap.parse_args()
    if not 1 <= args.runs <= 50:
        ap.error(f"--runs = {args.runs}: must lie in [1, 50]")
    cmd = [sys.executable, "-m", "fem.modal"]
    runs, outs = {"new": []}, {}
    with tempfile.TemporaryDirectory(prefix="rpud-baseline-") as tmp:
        old = Path(tmp) / "old"
        made = subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-q", str(old), args.baseline],
                              capture_output=True, text=True)
        if made.returncode:
            print(f"baseline commit {args.baseline} not available ({made.stderr.strip() or 'no git'}): "
                  "this checkout only")
        else:
            runs["old"] = []
        try:
            for i in range(args.runs + 1):
                for key, cwd, extra in (("new", ROOT, args.extra), ("old", old, [])):
                    if key not in runs:
                        continue
                    wall, cpu, out = timed(cmd + extra, cwd)
                    outs[key] = out
                    if i:                       # the first of each is the warm-up (caches, numba)
                        runs[key].append((wall, cpu))
        finally:
            if "old" in runs:
                subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(old)], check=False)
    rows = []
    for key, label in (("new", "this checkout: python -m fem.modal " + " ".join(args.extra)),
                       ("old", f"commit {args.baseline}: python -m fem.modal")):
        if key not in runs:
            continue
        wall = statistics.median(w for w, _ in runs[key])
        cpu = statistics.median(c for _, c in runs[key])
        dofs, f = summary(outs[key])
        rows.append((label.strip(), dofs, f, f"{wall:.2f}", f"{min(w for w, _ in runs[key]):.2f}-"
                     f"{max(w for w, _ in runs[key]):.2f}", f"{cpu:.2f}"))
    print_table(rows, headers=("command", "DOFs", "working f_r / f_a Hz", "wall s (median)", "wall min-max",
                               "CPU s (median)"))
    if "old" not in runs:
        return
    ratios = [n[0] / o[0] for n, o in zip(runs["new"], runs["old"])]
    print(f"wall ratio this / baseline, pair by pair: median {statistics.median(ratios):.2f} "
          f"(min {min(ratios):.2f}, max {max(ratios):.2f}; {args.runs} pairs)")


if __name__ == "__main__":
    main()
