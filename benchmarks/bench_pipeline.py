"""The default end-to-end run (what `make run` does after the install) against the whole-drill
free pipeline refined toward the same accuracy, side by side in one run, per stage.

The default run solves the k = 0 swept sector (its working mode +0.034 % / +0.031 % on f_r /
f_a of the default design at refine 1). The baseline is the whole drill's free mesh, graded
toward the re-entrant edges (ungraded it is +0.5 % high and converges as h^1.1), at
``--baseline-refine``; each row prints its f_r and f_a with the discretisation error the run
estimates, so the table shows what accuracy each time buys. Target: the default under 45 s on
2 cores and at least 5x faster than the baseline at equal accuracy; its compliant-contact stage
(the headline, in a worker thread beside the other stages) at most 15 s of wall time over the
same run without it (``compliant_members=0``, timed in the same session). Each row gives wall and CPU
seconds (the process's user + system time, threads included: the run is one process); on a
machine shared with other jobs the CPU time is the comparable figure, the load average at the
start and the end is printed and written with the table. Writes into temporary folders.

    PYTHONPATH=. python benchmarks/bench_pipeline.py [--baseline-refine F] [--no-baseline]
"""

import argparse
import os
import tempfile
import time

from _table import print_table

import geometry
from results.pipeline import PipelineSettings, run_pipeline


def run(settings: PipelineSettings, design=None) -> tuple[dict, float, float]:
    """The run's summary, wall and CPU seconds, on ``design`` (default: the default drill)."""
    design = geometry.default_design() if design is None else design
    with tempfile.TemporaryDirectory() as tmp:
        t0, c0 = time.perf_counter(), time.process_time()
        s = run_pipeline(design, settings, tmp, progress=lambda msg: None).summary
        return s, time.perf_counter() - t0, time.process_time() - c0


def row(name: str, s: dict, wall: float, cpu: float, base: float | None = None) -> tuple:
    wm = s["working_mode"]
    acc = (f"f_r {wm['f_r_hz']:.1f} ± {wm.get('f_r_hz_error') or float('nan'):.1f} Hz, "
           f"f_a {wm['f_a_hz']:.1f} ± {wm.get('f_a_hz_error') or float('nan'):.1f} Hz")
    stages = ", ".join(f"{k.removesuffix('_s')} {v:.1f}" for k, v in s["timings"].items() if k != "total_s")
    speed = "" if base is None else f"{base / cpu:.1f}x less CPU than the baseline"
    return (name, s["mesh"]["label"], f"{s['mesh']['ndof']:,}", acc, f"{wall:.1f} s", f"{cpu:.1f} s", speed, stages)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--baseline-refine", type=float, default=0.6,
                    help="refine of the whole-drill free, graded baseline (default 0.6)")
    ap.add_argument("--no-baseline", action="store_true", help="time the default run only")
    args = ap.parse_args()
    load = os.getloadavg()[0]
    s, wall, cpu = run(PipelineSettings())
    plain = run(PipelineSettings(compliant_members=0))
    rows = [row(f"default without the compliant stage (it adds {wall - plain[1]:.1f} s wall, {cpu - plain[2]:.1f} s "
                "CPU; target <= 15 s wall)", *plain)]
    if not args.no_baseline:
        b, b_wall, b_cpu = run(PipelineSettings(path="whole", mesher="free", grade=True,
                                                refine=args.baseline_refine))
        rows.append(row(f"whole drill, free, graded, refine {args.baseline_refine:g} (baseline)", b, b_wall, b_cpu))
        rows.append(row("default: k = 0 sector (target < 45 s)", s, wall, cpu, b_cpu))
    else:
        rows.append(row("default: k = 0 sector (target < 45 s)", s, wall, cpu))
    print_table(rows, ("run", "mesh", "DOFs", "working mode (± estimated error)", "wall", "CPU", "speed-up (CPU)",
                       "stages (wall s)"))
    print(f"load average (1 min) at the start: {load:.1f}, at the end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
