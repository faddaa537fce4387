"""The coupler's share of the default design's discretisation error (swept mesh, refine 1).

The uniform refinement of ``study_swept_convergence.py`` refines the swept section and the
coupler together; the slotted coupler's notch edges (V-groove apex lines, slot end walls, tooth
roots: :mod:`geometry.notches`) converge at a corner's rate there, so its p = 2 bound is not a bound.
This study keeps the swept parts at refine 1 and refines the coupler alone: its size, its slot and
teeth zone caps, and the notch grading (``grade=True``: edge size and growth) all scaled by ``s``.
Prints each level, the p = 2 extrapolation of the last two (in ``s``, the coupler's element size),
and the default mesh's error estimated as the coupler's share (ungraded default minus the
extrapolation) plus the swept parts' true error at refine 1 (the design without slots and teeth
against its converged (r, z) values: tests/axisym_reference.py, README "true errors").

    python benchmarks/study_coupler_convergence.py [--levels 1 0.7 0.5 0.4]

Not scaled by ``s``: the curvature rule (12 elements per circle caps the coupler's bore region at
3.9 mm, below its scaled size down to s ~ 0.36) and the coupler's face against the first ring
(its triangles are the swept stack's). Both lie in smooth parts of the field, away from the notches.

Measured on this machine (2 cores, 24 GB) (levels 1 / 0.7 / 0.5 / 0.4, peak 12.2 GB):

    | s | DOFs | first torsion Hz | working f_r Hz | working f_a Hz | 1st bending Hz |
    | ungraded default | 111,619 | 15411.07 | 19915.19 | 21666.38 | 5213.83 |
    | 1   | 136,009 | 15399.73 | 19910.52 | 21663.21 | 5213.62 |
    | 0.7 | 220,009 | 15390.02 | 19906.97 | 21660.88 | 5213.47 |
    | 0.5 | 403,837 | 15384.80 | 19903.97 | 21658.80 | 5213.35 |
    | 0.4 | 673,015 | 15382.86 | 19904.31 | 21659.71 | 5213.35 |

Torsion follows p = 2 in ``s`` (changes 9.71 / 5.22 / 1.94 Hz against 9.7 / 4.6 / 1.7 predicted);
f_r and f_a settle within about 1 Hz from s = 0.5 on (their last change has the other sign).
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

import geometry
import geometry.builder as builder
from _table import print_table
from fem.assembly import assemble
from fem.modal import modal_analysis, working_mode
from geometry.design import default_design

SWEPT_TRUE_ERROR = {"tors1": 6.9e-4, "f_r": 4.1e-4, "f_a": 4.4e-4, "bend1": 1.95e-3}
"""True relative error of the swept parts at refine 1 (the design without slots and teeth against
its converged (r, z) values; README, "true errors")."""

KEYS = (("tors1", "first torsion Hz"), ("f_r", "working f_r Hz"), ("f_a", "working f_a Hz"),
        ("bend1", "1st bending pair Hz"))


def level(design, s: float | None) -> dict:
    """The default swept mesh with the coupler scaled by ``s`` and graded (``None``: ungraded default)."""
    old = builder.revolve_sizes

    def sizes(design, sz, per_quarter):
        out = old(design, sz, per_quarter)
        for key in ("coupler", "@slots", "@teeth"):
            out[key] *= s
        return out

    import geometry.notches as notches

    growth = notches.NOTCH_GROWTH
    try:
        if s is not None:
            builder.revolve_sizes = sizes
            notches.NOTCH_GROWTH = growth * s      # the whole graded size function h(d) scales by s
        t0 = time.perf_counter()
        tm, _rep = geometry.build(design, mesher="revolve", grade=s is not None)
    finally:
        builder.revolve_sizes, notches.NOTCH_GROWTH = old, growth
    system = assemble(tm)
    res = modal_analysis(system, 20e3, 12)
    f = np.asarray(res.f_r_hz)
    order = np.argsort(f)
    tors = [i for i in order if res.labels[i] == "torsional"]
    bend = [i for i in order if res.labels[i] == "bending"]
    w = working_mode(system, res.f_r_hz, res.vectors, 20e3)
    if not tors or len(bend) < 2 or res.labels[w] != "longitudinal":
        raise RuntimeError(f"s = {s}: modes not identified: {res.labels}")
    return {"s": s, "ndof": int(system.ndof), "seconds": time.perf_counter() - t0, "tors1": float(f[tors[0]]),
            "f_r": float(f[w]), "f_a": float(res.f_a_hz[w]), "bend1": float(f[bend[:2]].mean())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", type=float, nargs="+", default=[1.0, 0.7, 0.5, 0.4],
                    help="coupler scale factors s, decreasing (each in [0.3, 1])")
    args = ap.parse_args()
    s = args.levels
    if len(s) < 2 or any(not (math.isfinite(v) and 0.3 <= v <= 1) for v in s) or any(a <= b for a, b in zip(s, s[1:])):
        print(f"--levels {' '.join(map(str, s))}: need two or more decreasing values in [0.3, 1]", file=sys.stderr)
        raise SystemExit(2)
    design = default_design()
    rows = [level(design, None)] + [level(design, v) for v in s]
    for r in rows:
        print(f"s {r['s'] or 'ungraded'}: {r['ndof']:,} DOFs, {r['seconds']:.1f} s", flush=True)
    print_table([("ungraded default" if r["s"] is None else f"{r['s']:g}", f"{r['ndof']:,}", f"{r['seconds']:.1f}",
                  *(f"{r[k]:.2f}" for k, _ in KEYS)) for r in rows],
                headers=("s", "DOFs", "s wall", *(label for _, label in KEYS)))
    a, b = rows[-2], rows[-1]
    out = []
    for key, label in KEYS:
        # p = 2 in s: q(s) = q* + C s^2
        limit = b[key] - (a[key] - b[key]) * b["s"] ** 2 / (a["s"] ** 2 - b["s"] ** 2)
        coupler = rows[0][key] / limit - 1
        total = coupler + SWEPT_TRUE_ERROR[key]
        out.append((label, f"{limit:.2f}", f"{100 * coupler:+.3f}", f"{100 * SWEPT_TRUE_ERROR[key]:+.3f}",
                    f"{100 * total:+.3f}", f"{rows[0][key] / (1 + total):.2f}"))
    print_table(out, headers=("quantity", "coupler limit Hz (p=2)", "coupler share of the default %",
                              "swept parts at refine 1 %", "default mesh error %", "converged estimate Hz"))


if __name__ == "__main__":
    main()
