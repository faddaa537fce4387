"""Compliant contacts (impact.compliant_loop, Python reference) vs the Newton coupled kernel, same run.

The default design's k = 0 modes to 70 kHz (16 modes, results.coupled.wideband_horn; Q_m 100,
225 V, drive at the working resonance), free mass 8 g, device spring (5 N), 20 ms from the steady
response. Baseline: the Newton coupled model (impact.coupled, compiled kernel) with the same horn.
The compliant engine here is the Python reference (engine="python": closed-form flights,
integrated contacts); its reference mode integrates the flights too. The compiled engine and the
converged KE-vs-mass table are bench_compliant's. Times: best of several calls (the FE once).
"""

import time

import numpy as np
from _table import best_of, print_table


def main():
    import geometry
    from fem.matching import working_mode
    from fem.sector_system import axial_sector
    from geometry.materials import get_material
    from impact.compliant_loop import simulate_compliant
    from impact.coupled import simulate_coupled
    from impact.hertz import ContactGeometry, HertzLaw, effective_modulus, hertz_stiffness
    from impact.params import ImpactParams
    from results.coupled import wideband_horn, wideband_modes

    t0 = time.perf_counter()
    design = geometry.default_design()
    system = axial_sector(design)
    modes = wideband_modes(system, 70e3)
    w = working_mode(system, modes.f_r_hz, modes.vectors, float(design.target_frequency))
    f = float(np.round(modes.f_r_hz[w], 1))
    horn, g, info = wideband_horn(system, f, 70e3, 225.0, modes=modes)
    t_fe = time.perf_counter() - t0
    m = 0.008
    tip = get_material(design.part_material("horn"), design.library)
    ball = get_material("steel_45", design.library)
    radius = (3 * m / (4 * np.pi * ball.density)) ** (1 / 3)
    k_h = hertz_stiffness(effective_modulus(tip.youngs_modulus, tip.poisson_ratio, ball.youngs_modulus,
                                            ball.poisson_ratio), ContactGeometry.crowned(radius))
    k_t = hertz_stiffness(effective_modulus(ball.youngs_modulus, ball.poisson_ratio, ball.youngs_modulus,
                                            ball.poisson_ratio), ContactGeometry.crowned(radius))
    p = ImpactParams(m_free=m, t_end=0.02, spring_force=5.0, freq=f)
    laws = dict(horn_law=HertzLaw(k_h, p.e2), tool_law=HertzLaw(k_t, p.e1), horn_residual=g)
    simulate_coupled(p, horn, series=False)                  # compile / load the kernel
    run = simulate_compliant(p, horn, **laws, engine="python")
    n_newton = simulate_coupled(p, horn, series=False).impact.n_events
    t_newton = best_of(lambda: simulate_coupled(p, horn, series=False), 5)
    t_compliant = best_of(lambda: simulate_compliant(p, horn, **laws, engine="python"), 2)
    t_reference = best_of(lambda: simulate_compliant(p, horn, **laws, flights="integrated", engine="python"), 1)
    rows = [
        ("FE: sector mesh, modes 0-70 kHz, tip body, driven horn", f"{t_fe:.1f} s",
         f"{horn.n_modes} modes, residual {g:.3g} m/N"),
        ("20 ms, Newton coupled kernel (baseline)", f"{t_newton * 1e3:.1f} ms", f"{n_newton} impacts"),
        ("20 ms, compliant engine (closed-form flights)", f"{t_compliant:.2f} s",
         f"{len(run.contacts)} contacts; **{t_compliant / t_newton:.0f}x** the baseline; ledger "
         f"{abs(run.ledger['residual_j']) / run.ledger['drive_j']:.1e} of the drive work"),
        ("20 ms, compliant engine, flights integrated (reference)", f"{t_reference:.2f} s",
         f"{t_reference / t_compliant:.1f}x the closed-form flights"),
    ]
    print_table(rows, headers=("case", "time", "notes"))


if __name__ == "__main__":
    main()
