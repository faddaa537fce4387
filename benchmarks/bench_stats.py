"""Converged impact statistics: the KE-vs-mass table (1-8 g, both scenarios, every driving 95 % CI
within 3 %) with the compiled kernel, against the readable Python event loop on the same members
(the Python side runs one mass's first members and is scaled by events: the full table would
take it many minutes).

    python benchmarks/bench_stats.py [--quick]
"""

import argparse
import time

import numpy as np
from _table import print_table

from impact.model import simulate
from impact.params import ImpactParams
from impact.stats import SCENARIOS, StatsSettings, ensemble_members, member_stats
from impact.sweeps import sweep

MASSES = (0.001, 0.002, 0.003, 0.004, 0.005, 0.006, 0.007, 0.008)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="fewer Python-engine members")
    args = ap.parse_args()
    p = ImpactParams()
    t0 = time.perf_counter()
    member_stats(ensemble_members(p, 2, StatsSettings()), 0.0, 0.01)      # compile / load the cache
    t_compile = time.perf_counter() - t0
    rows = [("kernel compile or cache load (first call)", f"{t_compile:.2f} s", "once per process")]
    total_events, total_s = 0, 0.0
    for name in ("article", "device"):
        t0 = time.perf_counter()
        sw = sweep(p, MASSES, scenario=name)
        dt = time.perf_counter() - t0
        ev = sum(r.events for r in sw.rows)
        total_events += ev
        total_s += dt
        n = [r.members for r in sw.rows]
        worst = max(max(r.estimates[q].rel_half_width for q in ("tool_impact_rate_hz", "mean_tool_ke_after_j",
                                                                 "mean_ke_gain_j", "tool_power_w")) for r in sw.rows)
        rows.append((f"{name}: 8 masses to 3 % (kernel, all cores)", f"{dt:.2f} s",
                     f"{sum(n)} members ({min(n)}-{max(n)} per mass), {ev / 1e6:.2f} M events, widest CI "
                     f"{100 * worst:.1f} %, converged {sw.converged}"))
    rows.append(("both scenarios, converged table", f"{total_s:.2f} s", "target < 15 s"))
    # the Python reference on the first members of the 8 g article ensemble, per event
    members = ensemble_members(SCENARIOS["article"].apply(p), 8 if args.quick else 32, StatsSettings())
    t0 = time.perf_counter()
    n_py = sum(simulate(q, series=False, engine="python").t.size for q in members)
    t_py = time.perf_counter() - t0
    us_py = 1e6 * t_py / n_py
    rows.append(("Python event loop, same model (8 g article members)", f"{us_py:.1f} µs/event",
                 f"{len(members)} members, {n_py} events"))
    rows.append(("table with the Python loop (scaled by events)", f"{total_events * us_py * 1e-6:.0f} s",
                 f"{total_events * us_py * 1e-6 / total_s:.0f}x the kernel's time"))
    print_table(rows)
    print(f"\nkernel: {1e6 * total_s / total_events:.2f} µs per event on all cores, including the statistics")


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
