"""The compliant stage's cost (results.stage_compliant) beside the Newton coupled model's statistics.

The default design's k = 0 sector, drive at its working resonance, 225 V, Q_m 100. Rows: the FE
part (wide-band modes to 2 / t_c; the driven horn and its tip residual twice, side by side: from a
basis of its own over the wide modes, the path without ``drive=``, and reusing the working-band
basis the pipeline already has, ``drive=``, whose cost is the harmonic stage's and not counted),
then ensembles of the device scenario (20 ms discarded, 200 ms window) at 1 g and 8 g with 16
members each: the compliant batch at the headline cut-off and at 0.5 / t_c, and the baseline, the
Newton coupled batch (impact.coupled.coupled_batch) on the same horn. CPU time (process_time: both
the main thread and numba's workers), measured once; the stage runs ~10 such ensembles per end
mass plus one per other mass.

    PYTHONPATH=. python benchmarks/bench_compliant_stage.py       # ~1.5 min CPU
"""

import time

import numpy as np
from _table import print_table


def _cpu(fn):
    t0 = time.process_time()
    out = fn()
    return time.process_time() - t0, out


def main():
    import geometry
    from fem.harmonic import LossModel, modal_basis
    from fem.matching import working_mode
    from fem.modal import modal_analysis
    from fem.sector_system import axial_sector
    from impact.coupled import coupled_batch
    from impact.params import ImpactParams
    from impact.stats import StatsSettings
    from results.coupled import truncated_horn, wideband_horn, wideband_modes
    from results.stage_compliant import CompliantSettings, compliant_ensembles, contact_laws, shortest_contact_time

    design = geometry.default_design()
    system = axial_sector(design)
    st = CompliantSettings(members=16, max_members=16)
    base = ImpactParams()
    t_c = shortest_contact_time(design, [0.001, 0.008], base, st)
    cut = round(2.0 / t_c, -2)
    t_modes, modes = _cpu(lambda: wideband_modes(system, cut))
    f = float(np.round(modes.f_r_hz[working_mode(system, modes.f_r_hz, modes.vectors,
                                                  float(design.target_frequency))], 1))
    t_own, (_, g_own, _) = _cpu(lambda: wideband_horn(system, f, cut, 225.0, modes=modes))
    target = float(design.target_frequency)
    near = modal_analysis(system, target, 12, keep_factor=True)
    drive = modal_basis(system, f, loss=LossModel(q_mech=100.0), modes=near)
    t_horn, (horn, g, _) = _cpu(lambda: wideband_horn(system, f, cut, 225.0, modes=modes, drive=drive))
    low, g_low = truncated_horn(horn, g, 0.5 / t_c, f)
    cases = [base.with_(m_free=m, freq=f) for m in (0.001, 0.008)]
    laws = [contact_laws(design, m, base.e2, base.e1, st)[:2] for m in (0.001, 0.008)]
    t_top, top = _cpu(lambda: compliant_ensembles(cases, horn, laws, g, st))
    t_low, _ = _cpu(lambda: compliant_ensembles(cases, low, laws, g_low, st))
    coupled_batch(cases[:1], horn, "device", StatsSettings(n_start=2, n_max=2))      # compile / load
    t_newton, _ = _cpu(lambda: coupled_batch(cases, horn, "device", StatsSettings(n_start=16, n_max=16)))
    ke = ", ".join(f"{r['mean_tool_ke_after_j'].scaled(1e3)} mJ" for r in top)
    rows = [
        (f"FE: wide-band modes to {cut / 1e3:.0f} kHz (t_c {t_c * 1e6:.1f} us)", f"{t_modes:.1f} s",
         f"{int(np.sum(modes.f_r_hz <= cut))} modes below the cut-off"),
        ("FE: driven horn and tip residual, own basis over the wide modes (baseline)", f"{t_own:.1f} s",
         f"residual {g_own:.4g} m/N"),
        ("FE: driven horn and tip residual, reusing the working-band basis", f"{t_horn:.1f} s",
         f"{horn.n_modes} modes, residual {g:.4g} m/N (x{t_own / max(t_horn, 1e-9):.0f} less CPU)"),
        (f"compliant, modes to {cut / 1e3:.0f} kHz, 1 g + 8 g x 16 members", f"{t_top:.1f} s", f"tool KE {ke}"),
        (f"compliant, modes to {0.5 / t_c / 1e3:.0f} kHz (truncated), same", f"{t_low:.1f} s",
         f"{low.n_modes} modes"),
        (f"Newton coupled, {horn.n_modes} modes, same (baseline)", f"{t_newton:.2f} s",
         f"compliant / Newton: {t_top / max(t_newton, 1e-9):.0f}x"),
    ]
    print_table(rows, headers=("case (CPU time)", "time", "notes"))


if __name__ == "__main__":
    main()
