"""Coupled model (FE transducer in the impact loop) vs the kinematic kernel, same run.

The default design's reduced transducer with 8 modes (the working mode and the 7 other basis
modes of largest tip participation; Q_m 100, 225 V, drive at the working resonance), free mass 8 g,
article scenario (50 ms), modes started on their steady response. The kinematic case runs the
same parameters with A0 = the unloaded FE tip amplitude. Target: one 50 ms coupled case
with 8 modes costs at most 5x the kinematic kernel case. Times: best of several calls, compiled
code loaded from numba's disk cache before timing; 2 threads for the ensembles. The last rows
run the same 8 modes behind a 50 ohm source resistance (the series drive's pseudo-modes and
quadratic-form energy integrals, :mod:`impact.drive`).
"""

import math
import time

import numba
import numpy as np
from _table import best_of, print_table


def main():
    import geometry
    from impact import kernel, kernel_modal
    from impact.coupled import simulate_coupled
    from impact.params import ImpactParams
    from results.coupled import build_transducer, horn_from_reduced

    numba.set_num_threads(2)
    t0 = time.perf_counter()
    fe = build_transducer(geometry.default_design(), voltage=225.0, n_modes=8)
    t_fe = time.perf_counter() - t0
    horn = horn_from_reduced(fe.reduced, 225.0, start="steady")
    p = ImpactParams(m_free=0.008, freq=fe.freq_hz, A0=float(f"{fe.tip_amplitude_m:.4e}"), t_end=0.05)
    pv = kernel.pack(p)
    tab, xs, lam, G1, G2 = kernel_modal._kernel_data(horn, p.freq)
    # load / compile both kernels
    kernel.run_events(pv, p.t_end, p.max_events)
    kernel_modal.run_events(p, horn)
    stats = np.zeros(kernel_modal.N_CSTATS)

    def coupled_core():
        # the events only, as the kinematic run_events (no window: the energy integrals are skipped)
        kernel_modal._core(pv, tab, xs, np.zeros(2), p.t_end, p.max_events, True, math.inf, stats, lam, G1, G2)

    def coupled_core_integrals():
        # and with the closed-form energy / fundamental integrals of every segment (statistics)
        kernel_modal._core(pv, tab, xs, np.zeros(2), p.t_end, p.max_events, True, 0.0, stats, lam, G1, G2)

    n_kin = kernel.run_events(pv, p.t_end, p.max_events)[-1]
    n_cop = kernel_modal.run_events(p, horn)[7]
    t_kin = best_of(lambda: kernel.run_events(pv, p.t_end, p.max_events), 50)
    t_cop = best_of(coupled_core, 50)
    t_copi = best_of(coupled_core_integrals, 50)
    t_cop_sim = best_of(lambda: simulate_coupled(p, horn, series=False), 20)
    t_py = best_of(lambda: simulate_coupled(p, horn, series=False, engine="python"), 3)

    rng = np.random.default_rng(1)
    pmat = np.array([kernel.pack(p.with_(v0=float(rng.uniform(3.0, 5.0)))) for _ in range(1000)])
    kernel.ensemble_stats(pmat[:2], 0.0, p.t_end, p.max_events)
    kernel_modal.ensemble_coupled(pmat[:2], horn, p.freq, 0.0, p.t_end, p.max_events)
    t_ek = best_of(lambda: kernel.ensemble_stats(pmat, 0.0, p.t_end, p.max_events), 3)
    t_ec = best_of(lambda: kernel_modal.ensemble_coupled(pmat, horn, p.freq, 0.0, p.t_end, p.max_events), 3)
    ek = kernel.ensemble_stats(pmat, 0.0, p.t_end, p.max_events)[:, kernel.S_N_EVENTS].sum()
    ec = kernel_modal.ensemble_coupled(pmat, horn, p.freq, 0.0, p.t_end, p.max_events)[:, kernel.S_N_EVENTS].sum()
    hr = horn.with_(series_resistance=50.0)
    n_ser = simulate_coupled(p, hr, series=False).impact.n_events
    t_ser = best_of(lambda: simulate_coupled(p, hr, series=False), 20)
    kernel_modal.ensemble_coupled(pmat[:2], hr, p.freq, 0.0, p.t_end, p.max_events)
    t_es = best_of(lambda: kernel_modal.ensemble_coupled(pmat, hr, p.freq, 0.0, p.t_end, p.max_events), 3)
    rows = [
        ("FE: mesh, modal analysis, basis, reduced transducer (8 modes)", f"{t_fe:.1f} s", "once per design"),
        ("50 ms case, kinematic kernel (run_events)", f"{t_kin * 1e3:.3f} ms",
         f"{n_kin} events, {t_kin / n_kin * 1e6:.2f} µs/event; A0 = {p.A0 * 1e6:.2f} µm"),
        ("50 ms case, coupled kernel, 8 modes", f"{t_cop * 1e3:.3f} ms",
         f"{n_cop} events, {t_cop / n_cop * 1e6:.2f} µs/event; **{t_cop / t_kin:.1f}x** the kinematic case "
         f"(target <= 5x; per event {(t_cop / n_cop) / (t_kin / n_kin):.1f}x)"),
        ("same, with the window integrals (energy, fundamental)", f"{t_copi * 1e3:.3f} ms",
         f"{t_copi / t_kin:.1f}x the kinematic case"),
        ("50 ms case, simulate_coupled (kernel, incl. integrals and result)", f"{t_cop_sim * 1e3:.3f} ms", ""),
        ("50 ms case, coupled Python reference engine", f"{t_py * 1e3:.1f} ms",
         f"kernel {t_py / t_cop:.0f}x faster"),
        ("1,000 members x 50 ms, kinematic, 2 threads", f"{t_ek:.3f} s", f"{int(ek)} events"),
        ("1,000 members x 50 ms, coupled 8 modes, 2 threads", f"{t_ec:.3f} s",
         f"{int(ec)} events; {t_ec / t_ek:.1f}x (includes the closed-form window integrals)"),
        ("50 ms case, simulate_coupled, 50 ohm series source", f"{t_ser * 1e3:.3f} ms",
         f"{n_ser} events; {t_ser / t_cop_sim:.1f}x the voltage drive"),
        ("1,000 members x 50 ms, 50 ohm series source, 2 threads", f"{t_es:.3f} s",
         f"{t_es / t_ec:.1f}x the voltage drive; {t_es / t_ek:.1f}x kinematic"),
    ]
    print_table(rows)


if __name__ == "__main__":
    main()
