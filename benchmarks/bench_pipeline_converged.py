"""The default path against the whole drill's free pipeline refined until it is as accurate,
side by side in one run: ``python -m results --design article`` and ``python -m fem.modal --design
article``.

Equal accuracy
--------------
Both sides run on the article's drill (Table 1, no bolt part:
``geometry.examples.article_design``), the design the equal-accuracy calibration below was
measured on; the default drill (its threaded bolt part, longer horn and coupler) has other meshes
and errors, and ``benchmarks/bench_pipeline.py`` times its run. The default path solves the ``k = 0``
swept sector (89 435 DOFs at refine 1); its working mode on the article's drill is within its stated error (about 10 Hz, 0.05 %) of the converged value. The
baseline is the whole drill meshed freely and graded toward the re-entrant edges. Its accuracy
was measured once, on the article's drill as it is (no matching), with ``python -m fem.modal
--sectors off --mesher free --grade --modes 4 --refine F`` (:data:`FREE_LEVELS`) against the
converged value :data:`REFERENCE` (Richardson, order 2, from the sector at refine 1 and 0.7):
+0.173 % / +0.178 % (f_r / f_a) at refine 1 (108 380 DOFs), +0.128 % / +0.130 % at refine 0.8
(173 515 DOFs), an observed order of 1.35 in h. Reaching 0.05 % takes refine ~0.40
(:func:`needed_refine`), about 0.75 million DOFs (they grew as refine^-2.1 between the two
levels, :func:`needed_dofs`) and ~15 GB: more than a 2-core machine shared with other jobs holds. So the baseline runs at refine 1 and 0.8 (as accurate as 3.5x and 2.6x the target error,
a lower bound on the equally accurate run's cost), and the table adds the equally accurate
baseline's CPU time extrapolated from those two by the measured growth of CPU time with DOFs
(marked as such).

Each row gives wall and CPU seconds (the process's user + system time, threads included) and the
load average: on a machine shared with other jobs the CPU time is the comparable figure.

    PYTHONPATH=. python benchmarks/bench_pipeline_converged.py [--no-baseline]

Takes about 1 min (default pipeline) + 0.5 min (fem.modal) + ~5 min and ~4 GB (the two
baseline pipelines and the baseline fem.modal) on a quiet 2-core machine.
"""

import argparse
import math
import os
import sys

from _table import print_table
from bench_modal_cli import ROOT, summary, timed
from bench_pipeline import row, run

from geometry.examples import article_design
from results.pipeline import PipelineSettings

REFERENCE = {"f_r_hz": 19994.8, "f_a_hz": 21794.4}
"""Converged working mode of the article's drill as it is, Hz: Richardson (order 2, h ratio 1/0.7)
of the sector's 19998.0 / 21798.8 Hz at refine 1 (89 435 DOFs) and 19997.4 / 21796.6 Hz at refine
0.7 (223 972 DOFs); the difference of the two levels bounds its error by ~2.6 Hz (0.013 %)."""

FREE_LEVELS = (
    # refine, DOFs, f_r Hz, f_a Hz: python -m fem.modal --sectors off --mesher free --grade --modes 4
    (1.0, 108_380, 20029.4, 21833.1),
    (0.8, 173_515, 20020.4, 21822.7),
)
"""The whole drill's free graded mesh on the article's drill (no matching), as measured."""

TARGET = 5e-4
"""Equal accuracy: f_r and f_a within 0.05 % of :data:`REFERENCE`."""


def needed_refine() -> float:
    """The refine at which the free graded mesh's f_r and f_a errors reach :data:`TARGET`:
    ``err ~ refine^p`` with ``p`` observed between the two :data:`FREE_LEVELS` (the smaller of
    the two quantities' refines)."""
    (r1, _, *v1), (r2, _, *v2) = FREE_LEVELS
    out = 1.0
    for k, key in enumerate(("f_r_hz", "f_a_hz")):
        e1, e2 = (abs(v[k] / REFERENCE[key] - 1) for v in (v1, v2))
        p = math.log(e1 / e2) / math.log(r1 / r2)
        out = min(out, r2 * (TARGET / e2) ** (1 / p))
    return out


def needed_dofs() -> int:
    """DOFs of the free graded mesh at :func:`needed_refine` (DOFs ~ refine^-q, ``q`` observed
    between the two :data:`FREE_LEVELS`)."""
    (r1, n1, *_), (r2, n2, *_) = FREE_LEVELS
    q = math.log(n2 / n1) / math.log(r1 / r2)
    return int(round(n2 * (r2 / needed_refine()) ** q, -3))


def extrapolated_cpu(dofs: tuple[int, int], cpu: tuple[float, float], target_dofs: int) -> float:
    """CPU seconds at ``target_dofs`` from two timed runs: ``cpu ~ dofs^a`` with ``a`` from them."""
    a = math.log(cpu[1] / cpu[0]) / math.log(dofs[1] / dofs[0])
    return cpu[1] * (target_dofs / dofs[1]) ** a


def modal_rows(baseline_refine: float | None) -> list[tuple]:
    """``python -m fem.modal`` (default: the sector) and, unless None, on the whole drill's free
    graded mesh at ``baseline_refine``: DOFs, working mode, wall and CPU seconds."""
    cmds = [("python -m fem.modal --design article (k = 0 and 1 sectors, with its error estimate)", ["--design", "article"])]
    if baseline_refine is not None:
        cmds.append((f"python -m fem.modal --design article --sectors off --mesher free --grade --refine {baseline_refine:g}",
                     ["--design", "article", "--sectors", "off", "--mesher", "free", "--grade", "--refine", f"{baseline_refine:g}"]))
    rows = []
    for name, extra in cmds:
        wall, cpu, out = timed([sys.executable, "-m", "fem.modal", *extra], ROOT)
        dofs, mode = summary(out)
        rows.append((name, dofs, mode, f"{wall:.1f} s", f"{cpu:.1f} s"))
    return rows


def _with_ratio(cells: tuple, ratio: str) -> tuple:
    """A :func:`bench_pipeline.row` with its speed-up cell replaced by ``ratio``."""
    return cells[:6] + (ratio,) + cells[7:]


def baseline_rows(s_cpu: float) -> list[tuple]:
    """The whole drill's free graded pipeline at the two measured refines, and the equally
    accurate one's CPU time extrapolated from them; each with the default's CPU speed-up."""
    rows, dofs, cpus = [], [], []
    for refine, *_ in FREE_LEVELS:
        b, wall, cpu = run(PipelineSettings(path="whole", mesher="free", grade=True, refine=refine), article_design())
        rows.append(_with_ratio(row(f"whole drill, free, graded, refine {refine:g}", b, wall, cpu),
                                f"{cpu / s_cpu:.1f}x"))
        dofs.append(b["mesh"]["ndof"])
        cpus.append(cpu)
    need = needed_dofs()
    est = extrapolated_cpu(tuple(dofs), tuple(cpus), need)
    rows.append((f"whole drill, free, graded, refine {needed_refine():.2f}: as accurate (extrapolated)",
                 "extrapolated from the two rows above (CPU ~ DOFs^a)", f"~{need:,}",
                 f"f_r, f_a within {TARGET:.2%} (by the measured order)", "-", f"~{est:.0f} s", f"{est / s_cpu:.0f}x",
                 "-"))
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-baseline", action="store_true", help="time the default runs only")
    args = ap.parse_args()
    load = os.getloadavg()[0]
    # the FE pipeline compared like for like: the whole-drill path skips the compliant-contact stage,
    # so the default is timed without it here (benchmarks/bench_pipeline.py times what the stage adds)
    s, wall, cpu = run(PipelineSettings(compliant_members=0), article_design())
    rows = [_with_ratio(row("article's drill, default path: k = 0 sector, compliant stage off", s, wall, cpu),
                        "1x (reference)")]
    if not args.no_baseline:
        rows += baseline_rows(cpu)
    print_table(rows, ("run", "mesh", "DOFs", "working mode (± estimated error)", "wall", "CPU",
                       "CPU / the default's (target >= 5x at equal accuracy)", "stages (wall s)"))
    print_table(modal_rows(None if args.no_baseline else FREE_LEVELS[-1][0]),
                ("command", "DOFs", "working f_r / f_a Hz", "wall", "CPU"))
    print(f"load average (1 min) at the start: {load:.1f}, at the end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
