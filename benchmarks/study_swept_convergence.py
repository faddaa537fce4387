"""Mesh convergence of the swept mesh (``mesher="revolve"``) on the default design: bending, torsion, working mode.

Refines the swept mesh of the default design (every size rule and graded edge scaled by
``refine``, ``ceil(3 / refine)`` element layers per quarter turn) and follows, identified by
their motion (``fem.modeshape`` labels, not by index): the first and second bending pairs (mean
of the pair), the first torsion mode and the working (longitudinal) mode's f_r / f_a (12 modes
near 20 kHz, short and open circuit, as ``python -m fem.modal --mesher revolve``). From the last
three levels (``h = DOFs^(-1/3)``, :class:`fem.convergence.ConvergenceStudy`): the observed
order p, the Richardson value and the error of the refine-1 level against it, checked against
the targets (0.1 % bending / torsion, 0.05 % working f_r / f_a). Where the observed order is not
reliable (changes of opposite sign, p outside ``fem.convergence.ORDER_RANGE``, or p above
:data:`P_MAX` = 4, the P2 eigenvalue rate of a smooth solution) the error of refine 1 is bounded
instead by its distance to the finest level plus that level's own error
extrapolated with p = 2 from the last change, ``|q1 - q3| + |q3 - q2| / ((h2 / h3)^2 - 1)``
(column "p=2 bound"; printed for every quantity). Also the working mode of the design without
slots and teeth at refine 1 against its converged axisymmetric (r, z) answer.

    python benchmarks/study_swept_convergence.py [--quick] [--levels 1 0.8 0.64] [--max-dofs 400000]
                                                 [--sectors 3 4 5 6] [--variants SPEC ...] [--no-slots]
                                                 [--no-crosscheck]
    # --quick: refine 1 and 0.8 only (no order); levels whose mesh has more than --max-dofs
    # (3 x mesh nodes, counted before assembly) are skipped; --sectors N ...: refine 1 with N
    # element layers per quarter turn instead of the study; --variants: single meshes with knobs
    # (sectors=N, refine=F, horn=MM / ring=MM / flange=MM section caps, comma-joined); --no-slots:
    # the design without slots and teeth, every level's (or variant's) true error against the
    # converged (r, z) values of tests/axisym_reference.py (bending and torsion harmonics, working mode)

Measured on this machine (2 cores, 24 GB, another job running), 1 min 43 s wall for
the whole run (peak 5.6 GB; levels refine 1 / 0.8 / 0.64; refine 0.5, 551k DOFs, passed 9.9 GB
in the factorisation and was stopped, so the default --max-dofs is 400k)::

    refine 1: 111,619 DOFs, mesh 1.7 s, modal 11.0 s, bending 5213.83 / 10632.58, torsion 15411.07, working 19915.19 / 21666.38 Hz, pair splits 1.2e-06 / 8.1e-06, min gamma 0.1284, inverted 0, peak RSS 1.7 GB; labels bending bending bending bending torsional bending bending longitudinal torsional torsional bending bending
    refine 0.8: 181,786 DOFs, mesh 2.1 s, modal 20.5 s, bending 5208.55 / 10624.16, torsion 15399.53, working 19906.22 / 21658.08 Hz, pair splits 2.5e-05 / 1.5e-04, min gamma 0.0005, inverted 0, peak RSS 2.9 GB; labels bending bending bending bending torsional bending bending longitudinal torsional torsional bending bending
    refine 0.64: 313,149 DOFs, mesh 3.2 s, modal 47.1 s, bending 5206.44 / 10621.30, torsion 15393.96, working 19905.27 / 21657.38 Hz, pair splits 9.7e-07 / 6.4e-06, min gamma 0.1182, inverted 0, peak RSS 5.6 GB; labels bending bending bending bending torsional bending bending longitudinal torsional torsional bending bending

    | refine | sectors/quarter | DOFs | mesh s | modal s (assembly + 12 modes) | 1st bending Hz | 2nd bending Hz | 1st torsion Hz | working f_r Hz | working f_a Hz |
    |--------|---|---|---|---|---|---|---|---|---|
    | 1      | 3 | 111,619 | 1.7 | 11.0 | 5213.83 | 10632.58 | 15411.07 | 19915.19 | 21666.38 |
    | 0.8    | 4 | 181,786 | 2.1 | 20.5 | 5208.55 | 10624.16 | 15399.53 | 19906.22 | 21658.08 |
    | 0.64   | 5 | 313,149 | 3.2 | 47.1 | 5206.44 | 10621.30 | 15393.96 | 19905.27 | 21657.38 |

    | mode                       | observed p | Richardson Hz | error of refine 1 % | p=2 bound % | target % | met | met by p=2 bound | changes |
    |----------------------------|---|---|---|---|---|---|---|---|
    | 1st bending pair (mean) Hz | 6.00 (> 4: not used) | 5201.60 (p=2) | +0.2351 | 0.2351 | 0.1 | NO (by p=2 bound) | NO | monotone |
    | 2nd bending pair (mean) Hz | 6.99 (> 4: not used) | 10614.75 (p=2) | +0.1680 | 0.1680 | 0.1 | NO (by p=2 bound) | NO | monotone |
    | 1st torsion Hz             | 4.90 (> 4: not used) | 15381.21 (p=2) | +0.1941 | 0.1941 | 0.1 | NO (by p=2 bound) | NO | monotone |
    | working f_r Hz             | - | 19903.10 (p=2) | +0.0608 | 0.0608 | 0.05 | NO (by p=2 bound) | NO | monotone |
    | working f_a Hz             | - | 21655.79 (p=2) | +0.0489 | 0.0489 | 0.05 | yes (by p=2 bound) | yes | monotone |

    | cross-check              | DOFs | s | working f_r / f_a Hz | converged (r, z) Hz | error |
    |--------------------------|---|---|---|---|---|
    | no slots/teeth, refine 1 | 80,230 | 8.7 | 19690.39 / 21419.78 | 19682.31 / 21410.33 | +0.041 % / +0.044 % |

    peak RSS 5.6 GB

Reading: the refine-1 swept mesh does **not** give the first bending pair or the first torsion
within 0.1 %, and the working f_r is not shown within 0.05 %. Every quantity decreases
monotonically with refinement, and the refine-1 level is already further from the finest level
(0.64) than the target: bending -0.142 % (2nd pair -0.106 %), torsion -0.110 %, f_r -0.050 %,
f_a -0.042 %; so, converging from above, the error of refine 1 is at least that. The observed
orders are not credible (bending 6.0 / 7.0, torsion 4.9, f_r 14, f_a 15: above the P2 rate 4 and
far above the h^1.1 the re-entrant edges allow): the first step (1 -> 0.8) moves every quantity
2.5-12x more than the second (0.8 -> 0.64), i.e. the levels are not in the asymptotic range (the
sweep's sectors go 3 -> 4 -> 5 per quarter while the section refines by 1.25 per step, and the
section meshes are not nested). The errors above are therefore the p = 2 bound; with p = 4 (the
largest credible order) the refine-1 errors would be bending ~0.18 %, torsion ~0.15 %, f_r ~0.055 %,
f_a ~0.045 %. Only f_a is within its target (0.049 % by the p = 2 bound). The axisymmetric variant's
working mode at refine 1 is +0.041 % / +0.044 % from its converged (r, z) answer (the cross-check),
so the default design's slotted, toothed (free-meshed) coupler adds error to f_r.
For torsion, f_r and f_a, however, the p = 2 bound is too small: the coupler's notch
edges converge at a corner's rate; refined alone (``study_coupler_convergence.py``) they put the
refine-1 errors at torsion ~+0.28 %, f_r ~+0.09 to +0.11 %, f_a ~+0.07 to +0.09 % (bending +0.20 %).

The sweep's share (``--sectors 3 4 5 6``: refine 1 with more element layers per quarter turn;
``geometry.sizing.revolve_sizes`` then also caps the swept regions' section sizes at the shorter
sector arc, so this is not a purely circumferential refinement), same machine and day::

    | sectors/quarter at refine 1 | DOFs | modal s | 1st bending pair (mean) Hz | 2nd bending pair (mean) Hz | 1st torsion Hz | working f_r Hz | working f_a Hz |
    |-----------------------------|---|---|---|---|---|---|---|
    | 3                           | 111,619 | 11.0 | 5213.83 (+0.0000 %) | 10632.58 (+0.0000 %) | 15411.07 (+0.0000 %) | 19915.19 (+0.0000 %) | 21666.38 (+0.0000 %) |
    | 4                           | 141,129 | 14.0 | 5210.91 (-0.0558 %) | 10627.88 (-0.0442 %) | 15404.79 (-0.0407 %) | 19910.85 (-0.0218 %) | 21661.84 (-0.0210 %) |
    | 5                           | 175,751 | 21.6 | 5209.11 (-0.0904 %) | 10626.74 (-0.0550 %) | 15406.36 (-0.0305 %) | 19912.40 (-0.0140 %) | 21663.42 (-0.0137 %) |
    | 6                           | 220,411 | 25.5 | 5207.71 (-0.1174 %) | 10624.77 (-0.0734 %) | 15404.77 (-0.0409 %) | 19910.78 (-0.0221 %) | 21661.85 (-0.0209 %) |

More sectors alone move the first bending pair by -0.12 % (3 -> 6 per quarter, still -0.027 % per
step), the second pair by -0.07 %, torsion and the working mode by only -0.03..-0.04 % / -0.02 %,
and not monotonically (the section mesh changes with the cap: ~0.01 % scatter). So the sweep's
resolution (with the section cap it brings) makes about two thirds of the bending pair's change
from refine 1 to 0.64 (3 -> 5 per quarter: -0.090 % of -0.142 %) and converges slowly; the swept
rule was tuned on the working mode only (``geometry.sizing.REVOLVE_GROWTH``).
"""

from __future__ import annotations

import argparse
import math
import resource
import sys
import time

import numpy as np

import geometry
from _table import print_table
from fem.assembly import assemble
from fem.convergence import ConvergenceStudy, Level
from fem.modal import modal_analysis, working_mode
from geometry.design_rpud import default_design
from geometry.revolve import sectors_per_quarter
from geometry.sizing import REFINE_RANGE

F_R, F_A = 19682.31, 21410.33
"""Converged working mode of the default design without slots and teeth (axisymmetric (r, z), tests/axisym_reference.py)."""

TRUE_NO_SLOTS = {"bend1": 5161.55, "bend2": 10512.14, "tors1": 15286.155, "f_r": F_R, "f_a": F_A}
"""Converged values (Hz) of the design without slots and teeth: the (r, z) model's harmonics n = 1
(bending pairs) and n = 0 (torsion, u_theta alone) and its working mode (tests/axisym_reference.py
BENDING_19, TORSION_19; tests/test_axisym_reference.py asserts them to 2e-5)."""

NEAR_HZ, N_MODES = 20e3, 12

P_MAX = 4.0
"""Largest credible observed order: 2 x 2, the eigenvalue rate of P2 on a smooth solution (the
re-entrant edges allow less: h^1.1 ungraded); a larger fitted p means the levels are not in the
asymptotic range and the Richardson value is not used."""

QUANTITIES = (
    # key, label, target (relative)
    ("bend1", "1st bending pair (mean) Hz", 1e-3),
    ("bend2", "2nd bending pair (mean) Hz", 1e-3),
    ("tors1", "1st torsion Hz", 1e-3),
    ("f_r", "working f_r Hz", 5e-4),
    ("f_a", "working f_a Hz", 5e-4),
)


def peak_rss_gb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6  # kB on Linux


def modes(design, refine: float) -> dict:
    """Mesh, assemble and solve one level; the followed modes by their motion labels."""
    t0 = time.perf_counter()
    tm, rep = geometry.build(design, mesher="revolve", refine=refine)
    t1 = time.perf_counter()
    system = assemble(tm)
    res = modal_analysis(system, NEAR_HZ, N_MODES)
    t2 = time.perf_counter()
    f = np.asarray(res.f_r_hz)
    labels = res.labels
    order = np.argsort(f)
    bending = [int(i) for i in order if labels[i] == "bending"]
    torsion = [int(i) for i in order if labels[i] == "torsional"]
    w = working_mode(system, res.f_r_hz, res.vectors, NEAR_HZ)
    if len(bending) < 4 or not torsion or labels[w] != "longitudinal":
        raise RuntimeError(f"refine {refine}: modes not identified: {list(zip(np.round(f, 1), labels))}")
    if int(order[0]) not in bending[:2]:
        raise RuntimeError(f"refine {refine}: lowest computed mode is not bending ({labels[order[0]]})")
    pairs = [bending[:2], bending[2:4]]
    split = [abs(f[a] - f[b]) / f[a] for a, b in pairs]
    if max(split) > 1e-3:
        print(f"warning: refine {refine}: bending pair split {max(split):.2e} (not a degenerate pair?)",
              file=sys.stderr)
    return {"refine": refine, "sectors": sectors_per_quarter(refine), "ndof": int(system.ndof),
            "mesh_s": t1 - t0, "modal_s": t2 - t1,
            "bend1": float(f[pairs[0]].mean()), "bend2": float(f[pairs[1]].mean()),
            "tors1": float(f[torsion[0]]), "f_r": float(f[w]), "f_a": float(res.f_a_hz[w]),
            "split1": split[0], "split2": split[1],
            "min_gamma": rep.quality.get("min_gamma", float("nan")), "n_inverted": rep.quality.get("n_inverted", -1),
            "labels": labels}


def mesh_dofs(design, refine: float) -> int:
    """DOFs of a level from its mesh alone (3 per P2 node; the potential DOFs are few)."""
    tm, _ = geometry.build(design, mesher="revolve", refine=refine)
    return 3 * tm.n_points


def estimates(rows: list[dict]) -> list[tuple]:
    """Order / Richardson / error of refine 1 per quantity from the last three levels."""
    levels = tuple(Level(r["refine"], r["ndof"], {k: r[k] for k, *_ in QUANTITIES}) for r in rows)
    st = ConvergenceStudy(levels)
    first = rows[0]
    h2, h3 = (float(r["ndof"]) ** (-1 / 3) for r in rows[-2:])
    out = []
    for key, label, target in QUANTITIES:
        q1, q2, q3 = first[key], rows[-2][key], rows[-1][key]
        p = st.order(key)  # NaN if the changes differ in sign or p is outside fem.convergence.ORDER_RANGE
        ok = np.isfinite(p) and p <= P_MAX
        q_inf2 = q3 + (q3 - q2) / ((h2 / h3) ** 2 - 1)  # p = 2 extrapolation from the last two
        bound2 = (abs(q1 - q3) + abs(q3 - q2) / ((h2 / h3) ** 2 - 1)) / abs(q_inf2)
        q_inf = st.richardson(key) if ok else q_inf2
        err = abs(q1 - q_inf) / abs(q_inf) if ok else bound2
        signs = np.sign(np.diff([r[key] for r in rows]))
        p_txt = "-" if not np.isfinite(p) else f"{p:.2f}" + ("" if ok else f" (> {P_MAX:g}: not used)")
        out.append((label, p_txt, f"{q_inf:.2f}" + ("" if ok else " (p=2)"),
                    f"{100 * (q1 - q_inf) / q_inf:+.4f}", f"{100 * bound2:.4f}", f"{100 * target:g}",
                    ("yes" if err < target else "NO") + ("" if ok else " (by p=2 bound)"),
                    "yes" if bound2 < target else "NO",
                    "monotone" if len(set(signs)) == 1 else "NOT monotone"))
    return out


def true_errors(rows: list[dict]) -> None:
    """Each level's error against the converged (r, z) values (design without slots and teeth),
    and whether the study's p=2 bound of refine 1 covers the true error of refine 1."""
    out = []
    for key, label, target in QUANTITIES:
        ref = TRUE_NO_SLOTS[key]
        errs = [r[key] / ref - 1 for r in rows]
        bound = None
        if len(rows) >= 3:
            h2, h3 = (float(r["ndof"]) ** (-1 / 3) for r in rows[-2:])
            q1, q2, q3 = rows[0][key], rows[-2][key], rows[-1][key]
            bound = (abs(q1 - q3) + abs(q3 - q2) / ((h2 / h3) ** 2 - 1)) / ref
        out.append((label, f"{ref:.2f}", *(f"{100 * e:+.4f}" for e in errs), f"{100 * target:g}",
                    "-" if bound is None else f"{100 * bound:.4f} ({'covers' if bound >= abs(errs[0]) else 'DOES NOT cover'})"))
    print_table(out, headers=("mode", "converged (r, z) Hz", *(f"true error refine {r['refine']:g} %" for r in rows),
                              "target %", "p=2 bound of refine 1 %"))


def parse_variant(text: str) -> dict:
    """``"sectors=4,refine=0.8,horn=3"`` -> {"sectors": 4, "refine": 0.8, "caps": {"horn": 3e-3}}: element
    layers per quarter turn (fixed, whatever the refine), the refine factor, and caps (mm) on the
    section size of every swept region whose name starts with the key (horn, ring, flange)."""
    out = {"sectors": None, "refine": 1.0, "caps": {}, "name": text}
    for item in filter(None, text.split(",")):
        key, _, value = item.partition("=")
        try:
            v = float(value)
        except ValueError:
            v = math.nan
        lo, hi = {"sectors": (1, 24), "refine": REFINE_RANGE}.get(key, (0.1, 100.0))   # caps in mm
        if not key or not lo <= v <= hi or (key == "sectors" and v != int(v)):
            raise ValueError(f"--variants: {item!r} must be key=number with {key or 'key'} in [{lo:g}, {hi:g}]"
                             + (" (an integer)" if key == "sectors" else ""))
        if key == "sectors":
            out["sectors"] = int(v)
        elif key == "refine":
            out["refine"] = v
        else:
            out["caps"][key] = v * 1e-3
    return out


def variant_study(design, variants: list[dict], truth: bool) -> None:
    """Single meshes with one knob changed each: what the sweep's circumferential resolution, the
    refine factor and the section caps move (against the converged values when ``truth``, else
    against the first variant)."""
    import geometry.builder as builder
    import geometry.revolve as revolve

    rows, base = [], None
    old_sectors, old_sizes = revolve.SECTORS_PER_QUARTER, builder.revolve_sizes
    try:
        for v in variants:
            def sizes(design, sizes, per_quarter, caps=v["caps"]):
                out = old_sizes(design, sizes, per_quarter)
                for key, cap in caps.items():
                    for region in out:
                        if region.startswith(key):
                            out[region] = min(out[region], cap)
                return out

            builder.revolve_sizes = sizes
            # sectors_per_quarter(refine) = ceil(SECTORS_PER_QUARTER / refine): fix it at v["sectors"]
            revolve.SECTORS_PER_QUARTER = old_sectors if v["sectors"] is None else v["sectors"] * v["refine"]
            r = modes(design, v["refine"])
            base = base or r
            ref = TRUE_NO_SLOTS if truth else base
            rows.append((v["name"], str(sectors_per_quarter(v["refine"])), f"{r['ndof']:,}", f"{r['modal_s']:.1f}") + tuple(
                f"{r[k]:.2f} ({100 * (r[k] / ref[k] - 1):+.4f} %)" for k, *_ in QUANTITIES))
    finally:
        revolve.SECTORS_PER_QUARTER, builder.revolve_sizes = old_sectors, old_sizes
    print_table(rows, headers=("variant", "sectors/quarter", "DOFs", "modal s",
                               *(label + (" (true error)" if truth else "") for _k, label, _t in QUANTITIES)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", type=float, nargs="+", default=[1.0, 0.8, 0.64],
                    help="refine factors, coarse to fine (the first is the level whose error is judged)")
    ap.add_argument("--quick", action="store_true", help="refine 1 and 0.8 only")
    ap.add_argument("--max-dofs", type=int, default=400_000,
                    help="skip levels above this many DOFs (counted on the mesh; 313k DOFs peaked at 5.6 GB, "
                         "refine 0.5's 551k passed 9.9 GB and was stopped)")
    ap.add_argument("--sectors", type=int, nargs="+", default=None, metavar="N",
                    help="instead of the study: refine 1 with N element layers per quarter turn (the sweep's "
                         "share of the refinement; revolve_sizes caps the swept regions at the sector arc)")
    ap.add_argument("--variants", nargs="+", default=None, metavar="SPEC",
                    help="instead of the study: single meshes, e.g. sectors=4 refine=0.8,sectors=3 horn=3 "
                         "(layers per quarter turn, refine factor, section caps in mm by region prefix)")
    ap.add_argument("--no-crosscheck", action="store_true", help="skip the design without slots and teeth")
    ap.add_argument("--no-slots", action="store_true",
                    help="study the design without slots and teeth and print every level's true error against "
                         "the converged (r, z) values (bending, torsion, working mode)")
    args = ap.parse_args()
    levels = [1.0, 0.8] if args.quick else sorted(args.levels, reverse=True)
    d = default_design()
    if args.no_slots:
        d = d.replace({"coupler.n_slots": 0, "coupler.n_teeth": 0})
        args.no_crosscheck = True
    if args.sectors or args.variants:
        specs = [f"sectors={n}" for n in args.sectors or []] + list(args.variants or [])
        try:
            variants = [parse_variant(t) for t in specs]
        except ValueError as exc:      # before any meshing: one line, exit 2
            print(f"error: {exc}", file=sys.stderr)
            sys.exit(2)
        variant_study(d, variants, truth=args.no_slots)
        return

    rows = []
    for refine in levels:
        if refine < 1:  # count the DOFs on the mesh first (a few s)
            n = mesh_dofs(d, refine)
            if n > args.max_dofs:
                print(f"refine {refine:g}: ~{n:,} DOFs from the mesh > {args.max_dofs:,}: skipped", flush=True)
                continue
        r = modes(d, refine)
        rows.append(r)
        print(f"refine {refine:g}: {r['ndof']:,} DOFs, mesh {r['mesh_s']:.1f} s, modal {r['modal_s']:.1f} s, "
              f"bending {r['bend1']:.2f} / {r['bend2']:.2f}, torsion {r['tors1']:.2f}, "
              f"working {r['f_r']:.2f} / {r['f_a']:.2f} Hz, pair splits {r['split1']:.1e} / {r['split2']:.1e}, "
              f"min gamma {r['min_gamma']:.4f}, inverted {r['n_inverted']}, peak RSS {peak_rss_gb():.1f} GB; "
              f"labels {' '.join(r['labels'])}", flush=True)
    print()
    print_table([(f"{r['refine']:g}", str(r["sectors"]), f"{r['ndof']:,}", f"{r['mesh_s']:.1f}", f"{r['modal_s']:.1f}",
                  f"{r['bend1']:.2f}", f"{r['bend2']:.2f}", f"{r['tors1']:.2f}", f"{r['f_r']:.2f}", f"{r['f_a']:.2f}")
                 for r in rows],
                headers=("refine", "sectors/quarter", "DOFs", "mesh s", "modal s (assembly + 12 modes)",
                         "1st bending Hz", "2nd bending Hz", "1st torsion Hz", "working f_r Hz", "working f_a Hz"))
    if len(rows) >= 3:
        print()
        print_table(estimates(rows), headers=("mode", "observed p", "Richardson Hz", "error of refine 1 %",
                                              "p=2 bound %", "target %", "met", "met by p=2 bound", "changes"))
    elif len(rows) == 2:
        print()
        print_table([(label, f"{100 * (rows[1][k] / rows[0][k] - 1):+.4f}", f"{100 * t:g}") for k, label, t in QUANTITIES],
                    headers=("mode", f"change refine {rows[0]['refine']:g} -> {rows[1]['refine']:g} %", "target %"))
    if args.no_slots:
        print()
        true_errors(rows)

    if not args.no_crosscheck:
        dn = d.replace({"coupler.n_slots": 0, "coupler.n_teeth": 0})
        t0 = time.perf_counter()
        tm = geometry.build_mesh(dn, mesher="revolve")
        s = assemble(tm)
        res = modal_analysis(s, NEAR_HZ, N_MODES)
        w = working_mode(s, res.f_r_hz, res.vectors, NEAR_HZ)
        fr, fa = float(res.f_r_hz[w]), float(res.f_a_hz[w])
        print()
        print_table([("no slots/teeth, refine 1", f"{s.ndof:,}", f"{time.perf_counter() - t0:.1f}",
                      f"{fr:.2f} / {fa:.2f}", f"{F_R:.2f} / {F_A:.2f}",
                      f"{100 * (fr / F_R - 1):+.3f} % / {100 * (fa / F_A - 1):+.3f} %")],
                    headers=("cross-check", "DOFs", "s", "working f_r / f_a Hz", "converged (r, z) Hz", "error"))
    print(f"\npeak RSS {peak_rss_gb():.1f} GB")


if __name__ == "__main__":
    main()
