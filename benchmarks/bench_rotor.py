"""The rotary unit (impact.rotor): the event-driven cycle against a return-mapping march, same run.

One tooth, one drive cycle at 30 % of the crest speed, a compliant contact (2e7 / 1e7 N/m per
tooth, ellipse ratio 0.2, phase 120 deg, 3 um): the event-driven solve (stick/slip phases by root
finding, Gauss-Legendre integrals) against the baseline, a first-order return mapping on a grid
across the contact window with N steps, each row with its error in the mean tangential force
against the event solution (exact to round-off: the energy balance closes to 1e-9, tests/test_rotor.py).
Then the whole command's work: the default coupler's torque-speed curve (41 speeds), the load
point and the hovering check, and the pipeline stage (nominal and the 8 corners of the error box).
Times: best of several calls.
"""

from _table import best_of, print_table


def main():
    from impact.rotor import RotorParams, TeethMotion, marched_mean_force, rotor_performance, solve_cycle
    from results.rotor_stage import TeethReport, rotor_stage

    tm = TeethMotion.from_ellipse(20e3, 3e-6, 0.2, 120.0)
    p = RotorParams(k_normal=2e7, k_tangential=1e7)
    speed = 0.3 * tm.crest_speed
    exact = solve_cycle(tm, p, speed).mean_force
    t_event = best_of(lambda: solve_cycle(tm, p, speed), 20)
    cyc = solve_cycle(tm, p, speed)
    rows = [("event-driven cycle", f"{t_event * 1e3:.2f} ms",
             f"{len(cyc.phases)} phases; mean force {exact:.6g} N (reference)")]
    for n in (1000, 10000, 100000):
        t = best_of(lambda n=n: marched_mean_force(tm, p, speed, n), 3)
        err = abs(marched_mean_force(tm, p, speed, n) - exact) / abs(exact)
        rows.append((f"baseline: return mapping, {n} steps", f"{t * 1e3:.1f} ms",
                     f"relative error {err:.1e}; {t / t_event:.0f}x the event solve"))
    teeth = TeethMotion.from_ellipse(20000.0, 9.88e-6, 0.173, 171.2)      # the default run's teeth motion
    t_curve = best_of(lambda: rotor_performance(teeth, RotorParams(), 2.8e-3, check_hover=False), 3)
    rows.append(("default coupler: curve (41 speeds) + load point", f"{t_curve * 1e3:.0f} ms", "no hovering check"))
    t_full = best_of(lambda: rotor_performance(teeth, RotorParams(), 2.8e-3), 3)
    rows.append(("  + hovering check (60 cycles, RK4)", f"{t_full * 1e3:.0f} ms", "the command's solve"))
    rep = TeethReport(20000.0, 9.88e-6, 1.1e-8, 0.173, 0.012, 171.2, 0.18)   # with its estimated errors
    t_stage = best_of(lambda: rotor_stage(rep, RotorParams(), 2.8e-3, 270.0), 3)
    rows.append(("pipeline stage: nominal + 8 corners", f"{t_stage * 1e3:.0f} ms", "hovering checked once"))
    print_table(rows)


if __name__ == "__main__":
    main()
