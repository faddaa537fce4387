"""Preload and stress in the stack
================================

Example 6: the stress peaks of the drill at its drive, with and without a bolt preload on the
piezo stack, against the material limits.

The state is the harmonic working point: 225 V at the working resonance, with the
assembled-transducer quality factor Q_m = 100 of the pipeline. ``fem.StressRecovery`` recovers
stress and electric field from the solution; the utilisation table gives per region the peak
over one cycle (von Mises for the metals; the largest tensile and compressive principal stress
and the peak field ``|E|`` for the ceramic rings), where it sits and its ratio to the limit in the
material record (``geometry/materials.toml``). A bolt preload is a static solve
(``fem.preload_solve``: on the default drill, whose M12 bolt is an elastic part, a shrink of the
bolt's shank between the stack's end faces that puts the force on the stack; on a design without
a bolt part, equal and opposite tractions on those faces) whose stress is added to the dynamic
one before the peaks are taken. The 20 kN is the preload of the worked
example on the stress page of the Theory manual.

Peaks at re-entrant corners and on the bonded ring edges are singular in the elastic solution
and grow with mesh refinement: the "off edges" columns leave those cells out. On the coarse mesh
of ``--fast`` the numbers are a sketch; the same table on the default mesh comes from
``python -m fem.harmonic --q-mech 100 --stress out/ --preload 20000``.

Run it with ``python results/examples/ex06_preload_stress.py`` (``--fast``: coarse mesh).
"""

import sys
from pathlib import Path

import fem
import geometry

fast = "--fast" in sys.argv
out = Path("example_output")
out.mkdir(exist_ok=True)

VOLTAGE = 225.0            # V, drive amplitude (the pipeline's and fem.harmonic's default)
PRELOAD = 20e3             # N, bolt force on the stack
loss = fem.LossModel(q_mech=100.0)

design = geometry.default_design()
system = fem.assemble(geometry.build_mesh(design, mesh_size=0.008 if fast else None))
modes = fem.modal_analysis(system, near_hz=design.target_frequency, n_modes=8)
f_w = modes.f_r_hz[modes.working]
basis = fem.modal_basis(system, f_w, loss=loss, modes=modes)
wp = fem.working_point(system, f_w, VOLTAGE, loss=loss, basis=basis)
print(f"working point: {VOLTAGE:g} V at {f_w:.1f} Hz, horn tip {wp.tip_per_volt_m * VOLTAGE * 1e6:.1f} um")

# %%
# Without preload: the dynamic stress alone.
rec = fem.StressRecovery(system)
dynamic = rec.field(wp.x)
bare = fem.utilisation_table(dynamic, freq_hz=wp.freq_hz, voltage=VOLTAGE)
print(bare.text())

# %%
# With the bolt preload: its static stress added to the cycle.
pre = fem.preload_solve(system, PRELOAD)
print(f"preload {PRELOAD:g} N on {pre.faces[0]} / {pre.faces[1]}: "
      f"{PRELOAD / pre.areas_m2[0] * 1e-6:.1f} MPa on the {pre.areas_m2[0] * 1e6:.1f} mm^2 ring face")
preloaded = fem.utilisation_table(dynamic, pre.field(rec), freq_hz=wp.freq_hz, voltage=VOLTAGE,
                                  preload_n=PRELOAD)
print(preloaded.text())

# %%
# What the preload does to the ceramic's tension, ring by ring (utilisation away from the
# singular bonded edges): it keeps the rings in compression over the cycle.
def tension(table):
    return {r.region: r.utilisation_off_edges for r in table.rows if r.quantity == "principal_max"}


without, with_preload = tension(bare), tension(preloaded)
for ring in without:
    print(f"  {ring}: tension {100 * without[ring]:.1f} % of its rating without preload, "
          f"{100 * with_preload[ring]:.1f} % with {PRELOAD / 1e3:g} kN")
print(f"worst with preload: {preloaded}")

# %%
# The von Mises peak over the cycle on the surface, with the preload.
fields = fem.stress_node_fields(dynamic, pre.field(rec))
fem.render_stress(system, fields["von_mises"], out / "stress_preloaded.png",
                  title=f"von Mises peak over one cycle, {VOLTAGE:g} V + {PRELOAD / 1e3:g} kN preload")
