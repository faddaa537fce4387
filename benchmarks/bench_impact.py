"""Impact model speed, all sides measured in the same run: compiled kernel vs the Python
reference engine (same events), vs a solve_ivp-with-events baseline (same model, impact times
agree to <= 1e-9 s on the first impacts), and a 1,000-member ensemble on 2 cores."""

import math
import time

import numba
import numpy as np
from _table import best_of, print_table

from impact import kernel
from impact.model import simulate
from impact.params import ImpactParams
from impact.reference import simulate_ivp


def main():
    numba.set_num_threads(2)
    p = ImpactParams()                      # article case, 50 ms
    pv = kernel.pack(p)

    t0 = time.perf_counter()
    kernel.run_events(pv, p.t_end, p.max_events)
    t_first_run = time.perf_counter() - t0
    t0 = time.perf_counter()
    kernel.ensemble_stats(pv[None, :], 0.0, p.t_end, p.max_events)
    t_first_ens = time.perf_counter() - t0

    rk = simulate(p, series=False, engine="kernel")
    rp = simulate(p, series=False, engine="python")
    n_ev = rk.n_events
    same = (rk.t.size == rp.t.size and np.array_equal(rk.contact, rp.contact)
            and np.abs(rk.t - rp.t).max(initial=0.0) <= 1e-12)
    t_py = best_of(lambda: simulate(p, series=False, engine="python"), 5)
    t_k = best_of(lambda: kernel.run_events(pv, p.t_end, p.max_events), 50)
    t_ks = best_of(lambda: simulate(p, series=False, engine="kernel"), 50)

    t0 = time.perf_counter()
    ref = simulate_ivp(p)
    t_ivp = time.perf_counter() - t0
    n = 5
    dt = np.abs(rk.t[:n] - np.array(ref["t"][:n])).max()

    # 1,000 members differing in v0, m_free and A0 (50 ms each)
    rng = np.random.default_rng(1)
    members = [p.with_(v0=float(rng.uniform(3.0, 5.0)), m_free=float(rng.uniform(0.004, 0.012)),
                       A0=float(rng.uniform(12e-6, 18e-6))) for _ in range(1000)]
    pmat = np.array([kernel.pack(m) for m in members])
    t_ens = best_of(lambda: kernel.ensemble_stats(pmat, 0.01, p.t_end, p.max_events), 3)
    st = kernel.ensemble_stats(pmat, 0.01, p.t_end, p.max_events)
    n_fail = int(np.count_nonzero(st[:, kernel.S_STATUS]))
    ev_tot = int(st[:, kernel.S_N_EVENTS].sum())

    rows = [
        ("50 ms article case, Python reference engine", f"{t_py * 1e3:.2f} ms",
         f"{n_ev} events, {t_py / n_ev * 1e6:.1f} µs/event"),
        ("50 ms article case, kernel run_events", f"{t_k * 1e3:.3f} ms",
         f"{t_k / n_ev * 1e6:.2f} µs/event; same events: {same}"),
        ("50 ms article case, simulate(engine='kernel')", f"{t_ks * 1e3:.3f} ms",
         "incl. ImpactResult construction"),
        ("speed-up kernel vs Python", f"{t_py / t_k:.0f}x", f"target >= 30x; via simulate {t_py / t_ks:.0f}x"),
        ("50 ms article case, solve_ivp DOP853 + events", f"{t_ivp * 1e3:.0f} ms",
         f"{len(ref['t'])} impacts, {ref['nfev']} rhs evals; kernel {t_ivp / t_k:.0f}x faster"),
        ("", "", f"first {n} impact times agree to {dt:.1e} s"),
        ("ensemble_stats: 1,000 members x 50 ms, 2 threads", f"{t_ens:.3f} s",
         f"{ev_tot} events ({t_ens / ev_tot * 1e6:.2f} µs/event), {n_fail} failed; target < 0.5 s"),
        ("first call run_events (compile or disk-cache load)", f"{t_first_run:.2f} s", "not in the times above"),
        ("first call ensemble_stats (compile or disk-cache load)", f"{t_first_ens:.2f} s", "not in the times above"),
    ]
    print_table(rows)


if __name__ == "__main__":
    main()
