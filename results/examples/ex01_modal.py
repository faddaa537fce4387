"""Modes of the default drill
===========================

Example 1: the modes of the default drill, and a picture of its working mode.

The default design is the article's drill (Table 1): percussive horn, four PZT-8 rings and the
V-type coupler. ``fem.default_system`` builds the design on its default FE path: the drill is
unchanged by a turn of 60 degrees (6 slots, 6 teeth), so its working mode and every response to
the stack's voltage lie in the circumferential harmonic k = 0, solved exactly on one swept
60-degree sector (``fem.sector_system``; a design that cannot be swept gets the whole drill,
graded). ``fem.modal_analysis`` returns the short-circuit resonances f_r, the open-circuit
anti-resonances f_a and the effective coupling factor of every k = 0 mode near the target
frequency (the bending pairs are k = 1: ``python -m fem.modal`` lists them).

Run it with ``python results/examples/ex01_modal.py`` (about 15 s); ``--fast`` uses a coarse
mesh (the test suite runs every example that way).
"""

import sys
from pathlib import Path

import fem
import geometry

fast = "--fast" in sys.argv
out = Path("example_output")

design = geometry.default_design()                       # SI units: m, Hz
system = fem.default_system(design, refine=2.0 if fast else 1.0)
print(f"mesh: {fem.system_label(system)}")
modes = fem.modal_analysis(system, near_hz=design.target_frequency, n_modes=8 if fast else 12)
print(modes)                                             # band, nearest mode, DOF

# The working mode is the longitudinal one nearest the target (the largest axial
# kinetic-energy share), not simply the nearest frequency.
w = modes.working
print(f"working mode {w}: {modes.labels[w]}, f_r = {modes.f_r_hz[w]:.1f} Hz, "
      f"f_a = {modes.f_a_hz[w]:.1f} Hz, k_eff = {modes.k_eff[w]:.3f}")

# Off-screen picture of the mode on the whole drill (the sector's field turned onto every
# sector; colour: displacement magnitude), the whole record as JSON + NPZ (frequencies and
# the sector's mode shapes), and every mode on the whole drill for ParaView.
whole, _ = system.whole_mesh()
shapes = system.whole_shapes(modes.vectors)
fem.render_mode(whole, shapes[w], out / "working_mode.png",
                title=f"Mode {w} - {modes.f_r_hz[w] / 1e3:.3f} kHz - {modes.labels[w]}")
modes.save(out)
fem.write_modes_vtu(whole, shapes, out / "modes.vtu", frequencies=modes.f_r_hz)
print(f"written: {sorted(p.name for p in out.iterdir())}")
