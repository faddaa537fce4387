"""The guaranteed search for a free flight's first touch on a 16-mode horn (20-70 kHz): the tip
turned along the grid by per-mode factors (this checkout's impact.kernel_blocks.search) against the
library's exp, cos and sin of every mode at every grid point (impact/kernel_blocks.py at BASELINE,
loaded from git), side by side on the same flights; the roots must be equal to the last bit.

Flights: a free mass falling under 50-400 m/s^2 from just above the tip's reach, touching after
hundreds of grid points (the compliant engine's own flights at 8 g take ~25 grid points and a
Brent location each, so a device member gains a few per cent). CPU time of this process, one thread.
Run: ``PYTHONPATH=. python benchmarks/bench_flight_search.py`` (~10 s).
"""

import math
import subprocess
import time
import types
from pathlib import Path

import numpy as np
from _table import print_table

#: the search with the library's exp, cos and sin of every mode at every grid point
BASELINE = "4632f31"
N_FLIGHTS = 200
REPEAT = 20


def _git_blocks():
    src = subprocess.run(["git", "show", f"{BASELINE}:impact/kernel_blocks.py"], capture_output=True, text=True,
                         check=True, cwd=Path(__file__).resolve().parent).stdout
    mod = types.ModuleType("impact.kernel_blocks_baseline")
    mod.__package__ = "impact"
    exec(compile(src.replace("cache=True", "cache=False"), f"kernel_blocks.py@{BASELINE}", "exec"), mod.__dict__)
    return mod


def _flights(KB, rng):
    """(cp, tab, ho, B, lo, hi, h) of N_FLIGHTS falls onto a random 16-mode tip."""
    from impact.horn import H_A, H_B, H_MASS, H_OMEGA, H_TIP, H_ZETA

    n, W = 16, 2 * math.pi * 20e3
    out = []
    for _ in range(N_FLIGHTS):
        tab = np.zeros((n, 12))
        tab[:, H_OMEGA] = 2 * math.pi * np.linspace(20e3, 70e3, n)
        tab[:, H_ZETA], tab[:, H_MASS], tab[:, H_TIP] = 0.005, rng.uniform(0.02, 0.2, n), rng.uniform(-1.5, 1.5, n)
        tab[:, H_A], tab[:, H_B] = rng.normal(0, 1e-6, n), rng.normal(0, 1e-6, n)
        t0 = rng.uniform(0.0, 0.2)
        ho = np.empty((n, KB.O_N))
        hb0, hb2, _ = KB.horn_records(ho, tab, n, W, t0, rng.normal(0, 1e-6, n), rng.normal(0, 0.3, n))
        cp = np.zeros(KB.C_N)
        cp[KB.C_T0], cp[KB.C_W], cp[KB.C_UC], cp[KB.C_US] = t0, W, 15e-6, -6e-6
        a = -rng.uniform(50.0, 400.0)
        cp[KB.C_W0], cp[KB.C_WD0], cp[KB.C_A] = 16.2e-6 + hb0 + rng.uniform(0, 5e-6), rng.uniform(-0.02, 0.02), a
        B = abs(a) + 16.2e-6 * W * W + hb2
        out.append((cp, tab, ho, B, t0, t0 + 2e-3, KB.grid_step(B, 1.0, 1e-7)))
    return out


def _time(KB, flights, o, stack):
    roots = [KB.search(KB.FN_HORN, cp, o, tab, ho, 16, B, lo, hi, h, stack) for cp, tab, ho, B, lo, hi, h in flights]
    c0 = time.process_time()
    for _ in range(REPEAT):
        for cp, tab, ho, B, lo, hi, h in flights:
            KB.search(KB.FN_HORN, cp, o, tab, ho, 16, B, lo, hi, h, stack)
    return (time.process_time() - c0) / (REPEAT * len(flights)), roots


def main():
    from impact import kernel_blocks as KB

    old = _git_blocks()
    flights = _flights(KB, np.random.default_rng(2026))
    o, stack = np.zeros(KB.O_N), np.empty((128, 6))
    rows, cost, roots = [], {}, {}
    for name, mod in ((f"{BASELINE}: exp, cos, sin per mode and grid point", old),
                      ("this checkout: modes turned along the grid", KB)):
        cost[name], roots[name] = _time(mod, flights, o, stack)
    (n0, c0), (n1, c1) = cost.items()
    same = roots[n0] == roots[n1]
    touched = sum(r[0] for r in roots[n1])
    for name, cpu in cost.items():
        rows.append((name, f"{cpu * 1e6:.2f} us",
                     f"per search, {N_FLIGHTS} flights ({touched} touch), one thread"
                     + (f"; **{c0 / cpu:.2f}x**; roots bit for bit equal: {same}" if name == n1 else "")))
    print_table(rows, headers=("first-touch search on a 16-mode horn", "CPU time", "notes"))


if __name__ == "__main__":
    main()
