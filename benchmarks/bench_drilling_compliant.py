"""Drilling under load on the compliant model (the default design's FE horn, Hertz contacts, a rigid
tool) against the kinematic drilling model (kinematic horn, Newton impacts, elastic tool rod),
1-8 g, the same members and window, side by side in one run: CPU time and the predictions.

    PYTHONPATH=. python benchmarks/bench_drilling_compliant.py [--members N]

The FE horn is the pipeline compliant stage's headline horn (:func:`results.drilling.fe_drill_horn`):
every k = 0 mode up to twice the inverse of the shortest Hertz contact (1 and 8 g) plus the static
residual, Q_m 100, 225 V at the working resonance; its build is timed apart. CPU time is the
process's (all threads). Takes ~3 min CPU (16 members).
"""

import argparse
import time

from _table import print_table

MASSES = (0.001, 0.002, 0.003, 0.004, 0.005, 0.006, 0.007, 0.008)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--members", type=int, default=16, help="members per mass, both models (16)")
    args = ap.parse_args()
    from impact.drilling import DrillParams, DrillSettings, drilling_sweep
    from impact.kernel_drill_compliant import warmup
    from impact.params import ImpactParams

    import geometry
    from results.drilling import fe_drill_horn

    c0 = time.process_time()
    f, cut, ch = fe_drill_horn(geometry.default_design(), MASSES)
    c_horn = time.process_time() - c0
    warmup()
    p = DrillParams(impact=ImpactParams(freq=f, spring_force=5.0))
    st = DrillSettings(n_start=args.members, n_max=args.members)
    c0 = time.process_time()
    comp = drilling_sweep(p, MASSES, st, horn=ch)
    c_comp = time.process_time() - c0
    c0 = time.process_time()
    kin = drilling_sweep(p, MASSES, st, A0_values=[ch.tip_amplitude(f)] * len(MASSES))
    c_kin = time.process_time() - c0
    n = args.members * len(MASSES)
    print_table([
        ("FE horn build (k = 0 sector, wide-band modes)", f"{c_horn:.1f} s CPU",
         f"{ch.horn.n_modes} modes to {cut / 1e3:.0f} kHz, f_w {f:.1f} Hz, free tip {ch.tip_amplitude(f) * 1e6:.2f} um"),
        (f"compliant drilling, 8 masses x {args.members} members, 220 ms", f"{c_comp:.1f} s CPU",
         f"{c_comp / n * 1e3:.0f} ms CPU per member"),
        (f"baseline: kinematic drilling, same members (A0 = the FE horn's free tip)", f"{c_kin:.1f} s CPU",
         f"{c_kin / n * 1e3:.0f} ms CPU per member; compliant/kinematic {c_comp / c_kin:.1f}x"),
    ], headers=("benchmark", "time", "note"))
    rows = []
    for a, b in zip(comp, kin):
        rows.append((f"{a.m_free * 1e3:g}", format(a["blow_rate_hz"]), format(a["drilling_rate_m_s"].scaled(6e4)),
                     format(a.depth_m.scaled(1e3)), f"{a['ledger_rel'].mean:.2g} ± {a['ledger_rel'].half_width:.1g}",
                     format(b["blow_rate_hz"]),
                     format(b["drilling_rate_m_s"].scaled(6e4)), format(b.depth_m.scaled(1e3))))
    print_table(rows, headers=("free mass (g)", "compliant blows (Hz)", "compliant rate (mm/min)",
                               "compliant depth 5 min (mm)", "ledger / drive work", "kinematic blows (Hz)",
                               "kinematic rate (mm/min)", "kinematic depth 5 min (mm)"))


if __name__ == "__main__":
    main()
